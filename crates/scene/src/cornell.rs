//! The built-in Cornell box (in progress).
use crate::scene::Scene;

pub fn cornell_box() -> Scene {
    Scene::default()
}
