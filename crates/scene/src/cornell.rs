//! The built-in Cornell box: the McGuire Computer Graphics Archive's "CornellBox-Original"
//! (public domain; see `assets/cornell-box/SOURCE.txt`), compiled into the program and read by
//! the OBJ loader, with a camera added.

use std::collections::HashMap;
use std::path::Path;

use glam::Vec3;

use crate::camera::Camera;
use crate::limits::Limits;
use crate::obj;
use crate::scene::Scene;
use crate::source::SceneSource;

const OBJ_NAME: &str = "CornellBox-Original.obj";
const MTL_NAME: &str = "CornellBox-Original.mtl";
const OBJ: &[u8] = include_bytes!("../assets/cornell-box/CornellBox-Original.obj");
const MTL: &[u8] = include_bytes!("../assets/cornell-box/CornellBox-Original.mtl");

/// Vertical field of view of the built-in camera, in degrees.
pub const FOV_DEGREES: f32 = 40.107;

/// The Cornell box: 36 triangles, 8 two-sided Lambertian materials, a light quad emitting
/// (17, 12, 4) under the ceiling, and a camera at (0, 1, 3.5) looking at (0, 1, 0).
pub fn cornell_box() -> Scene {
    let source = SceneSource::Memory(HashMap::from([(MTL_NAME.to_owned(), MTL.to_vec())]));
    let mut scene = obj::parse(OBJ, Path::new(OBJ_NAME), &source, &Limits::default())
        .expect("the built-in Cornell box is compiled in and parses (tested)");
    scene.name = "built-in Cornell box".to_owned();
    scene.cameras.push(Camera::look_at(
        "default",
        Vec3::new(0.0, 1.0, 3.5),
        Vec3::new(0.0, 1.0, 0.0),
        Vec3::Y,
        FOV_DEGREES,
    ));
    scene.collect_emissive_triangles();
    scene
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_box_loads_without_warnings() {
        let s = cornell_box();
        assert_eq!(s.name, "built-in Cornell box");
        assert!(s.warnings.is_empty(), "{:?}", s.warnings);
        assert_eq!(s.triangle_count(), 36);
        assert_eq!(s.materials.len(), 8);
        assert_eq!(s.cameras.len(), 1);
        assert_eq!(s.emissive_triangles.len(), 2);
        assert!(!s.is_unlit());
        assert!(s
            .materials
            .iter()
            .all(|m| m.double_sided && m.specular == 0.0));
    }
}
