//! Ray tracing: one interface ([`Accel`]) over acceleration structures built from a
//! [`Scene`](pathlight_scene::Scene), with closest-hit and any-hit queries for single rays and
//! batches.

pub mod brute;
mod bvh;
#[cfg(feature = "embree")]
pub mod embree;
pub mod geometry;
pub mod native;
pub mod ray;
pub mod rays;
mod simd;
pub mod triangle;

pub use brute::BruteForce;
#[cfg(feature = "embree")]
pub use embree::{EmbreeAccel, EmbreeError, EmbreeOptions};
/// The Embree bindings, for [`EmbreeOptions`]' build quality and flags.
#[cfg(feature = "embree")]
pub use embree3;
pub use geometry::SceneTriangles;
pub use native::{BuildStats, Isa, NativeBvh};
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
