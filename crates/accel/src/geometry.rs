//! The world-space triangles of a scene, flattened over its instances: the input every backend
//! builds from.

use glam::Vec3;
use pathlight_scene::Scene;

/// World-space triangles with their (instance, triangle) origin.
#[derive(Debug, Clone, Default)]
pub struct SceneTriangles {
    /// Three corners per triangle.
    pub corners: Vec<[Vec3; 3]>,
    /// For each triangle: (instance, triangle index within the instance's mesh).
    pub ids: Vec<(u32, u32)>,
}

impl SceneTriangles {
    /// Transforms every instance's triangles to world space.
    pub fn from_scene(scene: &Scene) -> Self {
        let n = scene.triangle_count() as usize;
        let mut corners = Vec::with_capacity(n);
        let mut ids = Vec::with_capacity(n);
        for (i, inst) in scene.instances.iter().enumerate() {
            let mesh = &scene.meshes[inst.mesh as usize];
            let world: Vec<Vec3> = mesh
                .positions
                .iter()
                .map(|&p| inst.transform.transform_point3(p))
                .collect();
            for (t, tri) in mesh.indices.iter().enumerate() {
                corners.push(tri.map(|v| world[v as usize]));
                ids.push((i as u32, t as u32));
            }
        }
        Self { corners, ids }
    }

    pub fn len(&self) -> usize {
        self.corners.len()
    }

    pub fn is_empty(&self) -> bool {
        self.corners.is_empty()
    }
}
