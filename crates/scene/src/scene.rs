//! The scene: everything a renderer needs, in one value.

use std::path::PathBuf;

use glam::{Vec2, Vec3, Vec4Swizzles};
use pathlight_core::color::luminance;

use crate::camera::Camera;
use crate::environment::Environment;
use crate::light::{random_point_lights, Bounds, EmissiveTriangle, PunctualLight};
use crate::material::Material;
use crate::mesh::{Instance, Mesh};
use crate::texture::Texture;

#[derive(Debug, Clone, Default)]
pub struct Scene {
    /// A short name for messages (the file name, or "built-in Cornell box").
    pub name: String,
    /// The main scene file, if it came from disk.
    pub path: Option<PathBuf>,
    pub meshes: Vec<Mesh>,
    pub instances: Vec<Instance>,
    pub materials: Vec<Material>,
    pub textures: Vec<Texture>,
    pub lights: Vec<PunctualLight>,
    /// Filled by [`Scene::collect_emissive_triangles`] (the loaders call it).
    pub emissive_triangles: Vec<EmissiveTriangle>,
    pub environment: Option<Environment>,
    pub cameras: Vec<Camera>,
    /// Everything the load warned about, "file: message".
    pub warnings: Vec<String>,
    /// Triangles the loader dropped (non-finite corners or zero area), counted per mesh.
    pub dropped_triangles: u64,
}

/// Counts for `pathlight info`.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneStats {
    /// Triangles over all instances (what is traced).
    pub triangles: u64,
    /// Triangles stored once per mesh.
    pub unique_triangles: u64,
    /// Triangles the file holds that were dropped as degenerate or non-finite.
    pub dropped_triangles: u64,
    pub vertices: u64,
    pub meshes: usize,
    pub instances: usize,
    pub materials: usize,
    pub textures: usize,
    pub texture_pixels: u64,
    pub emissive_triangles: usize,
    pub punctual_lights: usize,
    pub cameras: usize,
    pub environment: bool,
    pub bounds: Bounds,
    /// Heap bytes of geometry and textures.
    pub heap_bytes: u64,
    pub warnings: usize,
}

impl Scene {
    /// The world-space corners of triangle `triangle` of instance `instance` (the mesh's
    /// object-space corners through the instance's transform).
    #[inline]
    pub fn world_triangle(&self, instance: u32, triangle: u32) -> [Vec3; 3] {
        let inst = &self.instances[instance as usize];
        self.meshes[inst.mesh as usize]
            .triangle(triangle as usize)
            .map(|p| inst.transform.transform_point3(p))
    }

    /// World-space bounds of all instanced geometry.
    pub fn bounds(&self) -> Bounds {
        let mut b = Bounds::EMPTY;
        for inst in &self.instances {
            for &p in &self.meshes[inst.mesh as usize].positions {
                b.grow(inst.transform.transform_point3(p));
            }
        }
        b
    }

    /// Triangles over all instances.
    pub fn triangle_count(&self) -> u64 {
        self.instances
            .iter()
            .map(|i| self.meshes[i.mesh as usize].indices.len() as u64)
            .sum()
    }

    /// Finds every emitting triangle of every instance, with its world area, mean radiance and
    /// power. The mean radiance of a textured emitter averages the texture at the triangle's
    /// corners and centroid.
    pub fn collect_emissive_triangles(&mut self) {
        let mut out = Vec::new();
        for (ii, inst) in self.instances.iter().enumerate() {
            let mesh = &self.meshes[inst.mesh as usize];
            let mat = &self.materials[mesh.material as usize];
            if !mat.is_emissive() {
                continue;
            }
            for (t, tri) in mesh.indices.iter().enumerate() {
                let [a, b, c] = mesh.triangle(t).map(|p| inst.transform.transform_point3(p));
                let area = 0.5 * (b - a).cross(c - a).length();
                if !(area > 0.0 && area.is_finite()) {
                    continue;
                }
                let mut radiance = mat.emissive;
                if let Some(tex) = &mat.emissive_texture {
                    let uvs = match tex.texcoord {
                        0 => mesh.uv0.as_ref(),
                        _ => mesh.uv1.as_ref(),
                    };
                    if let Some(uvs) = uvs {
                        let [ua, ub, uc] = tri.map(|i| uvs[i as usize]);
                        let texture = &self.textures[tex.texture as usize];
                        let mean = [ua, ub, uc, (ua + ub + uc) / 3.0]
                            .into_iter()
                            .map(|uv: Vec2| texture.sample(tex.apply(uv), &tex.sampler).xyz())
                            .sum::<Vec3>()
                            / 4.0;
                        radiance *= mean;
                    }
                }
                if radiance.max_element() <= 0.0 {
                    continue;
                }
                let sides = if mat.emits_from_back { 2.0 } else { 1.0 };
                out.push(EmissiveTriangle {
                    instance: ii as u32,
                    triangle: t as u32,
                    area,
                    radiance,
                    power: radiance * (std::f32::consts::PI * area * sides),
                    two_sided: mat.emits_from_back,
                });
            }
        }
        self.emissive_triangles = out;
    }

    /// Adds `count` random point lights inside the scene's bounds (seed 004's `--point-lights`),
    /// their intensity scaled by `scale` (`--point-light-intensity`).
    pub fn add_random_point_lights(&mut self, count: usize, seed: u64, scale: f32) {
        let lights = random_point_lights(count, &self.bounds(), seed, scale);
        self.lights.extend(lights);
    }

    /// True when nothing in the scene emits light.
    pub fn is_unlit(&self) -> bool {
        self.emissive_triangles.is_empty() && self.lights.is_empty() && self.environment.is_none()
    }

    /// Total emitted power of the emissive triangles, as luminance (W).
    pub fn emissive_power(&self) -> f32 {
        self.emissive_triangles
            .iter()
            .map(|t| luminance(t.power))
            .sum()
    }

    pub fn stats(&self) -> SceneStats {
        let heap = self.meshes.iter().map(Mesh::heap_bytes).sum::<usize>()
            + self.textures.iter().map(Texture::heap_bytes).sum::<usize>()
            + self.environment.as_ref().map_or(0, Environment::heap_bytes);
        SceneStats {
            triangles: self.triangle_count(),
            unique_triangles: self.meshes.iter().map(|m| m.indices.len() as u64).sum(),
            dropped_triangles: self.dropped_triangles,
            vertices: self.meshes.iter().map(|m| m.positions.len() as u64).sum(),
            meshes: self.meshes.len(),
            instances: self.instances.len(),
            materials: self.materials.len(),
            textures: self.textures.len(),
            texture_pixels: self
                .textures
                .iter()
                .map(|t| t.width() as u64 * t.height() as u64)
                .sum(),
            emissive_triangles: self.emissive_triangles.len(),
            punctual_lights: self.lights.len(),
            cameras: self.cameras.len(),
            environment: self.environment.is_some(),
            bounds: self.bounds(),
            heap_bytes: heap as u64,
            warnings: self.warnings.len(),
        }
    }
}
