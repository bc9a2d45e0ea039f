//! glTF loader (in progress).
use std::path::Path;

use crate::error::{Result, SceneError};
use crate::limits::Limits;
use crate::scene::Scene;

pub fn load(path: &Path, _limits: &Limits) -> Result<Scene> {
    Err(SceneError::new(path, "glTF loading is not written yet"))
}
