//! Ray tracing: one interface ([`Accel`]) over acceleration structures built from a
//! [`Scene`](pathlight_scene::Scene), with closest-hit and any-hit queries for single rays and
//! batches.

pub mod brute;
mod bvh;
#[cfg(feature = "embree")]
pub mod embree;
pub mod geometry;
pub mod instanced;
pub mod native;
pub mod ray;
pub mod rays;
pub mod recorder;
mod simd;
pub mod triangle;

pub use brute::BruteForce;
#[cfg(feature = "embree")]
pub use embree::{EmbreeAccel, EmbreeError, EmbreeOptions};
/// The Embree bindings, for [`EmbreeOptions`]' build quality and flags.
#[cfg(feature = "embree")]
pub use embree3;
pub use geometry::SceneTriangles;
pub use instanced::InstancedBvh;
pub use native::{BuildStats, Isa, NativeBvh, PACKET};
pub use ray::{Hit, Ray};
pub use rays::{RayKind, RaySets};

/// An acceleration structure over the triangles of a scene.
///
/// Hits report the instance and the triangle index within the instance's mesh, so callers find
/// materials and attributes through the scene.
pub trait Accel: Send + Sync {
    /// A short name ("native", "embree", "brute").
    fn name(&self) -> &'static str;

    /// The closest hit with `ray.t_min <= t <= ray.t_max`, if any.
    fn intersect(&self, ray: &Ray) -> Option<Hit>;

    /// True when anything lies on the ray with `ray.t_min <= t <= ray.t_max` (shadow rays).
    fn occluded(&self, ray: &Ray) -> bool;

    /// Closest hits for many rays at once (`hits.len() == rays.len()`). Backends may override
    /// this with packet or stream traversal; the default traces one ray at a time.
    fn intersect_batch(&self, rays: &[Ray], hits: &mut [Option<Hit>]) {
        for (r, h) in rays.iter().zip(hits.iter_mut()) {
            *h = self.intersect(r);
        }
    }

    /// Occlusion for many rays at once (`occluded.len() == rays.len()`).
    fn occluded_batch(&self, rays: &[Ray], occluded: &mut [bool]) {
        for (r, o) in rays.iter().zip(occluded.iter_mut()) {
            *o = self.occluded(r);
        }
    }

    /// Heap bytes held by the structure (nodes and triangle data).
    fn memory_bytes(&self) -> usize;
}

/// True when some mesh is placed by more than one instance (two-level instancing pays off).
pub fn has_shared_meshes(scene: &pathlight_scene::Scene) -> bool {
    let mut uses = vec![0u32; scene.meshes.len()];
    scene.instances.iter().any(|i| {
        let u = &mut uses[i.mesh as usize];
        *u += 1;
        *u > 1
    })
}

/// The native structure for a scene: an [`InstancedBvh`] when some mesh is used by more than
/// one instance, otherwise a [`NativeBvh`] over the flattened world-space triangles.
pub fn build_accel(scene: &pathlight_scene::Scene) -> Box<dyn Accel> {
    if has_shared_meshes(scene) {
        Box::new(InstancedBvh::new(scene))
    } else {
        Box::new(NativeBvh::new(&SceneTriangles::from_scene(scene)))
    }
}
