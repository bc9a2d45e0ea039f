//! Rays and hits.

use glam::Vec3;

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ray {
    pub origin: Vec3,
    /// Not necessarily unit length; `t` is measured in multiples of it.
    pub direction: Vec3,
    pub t_min: f32,
    pub t_max: f32,
}

impl Ray {
    pub fn new(origin: Vec3, direction: Vec3) -> Self {
        Self {
            origin,
            direction,
            t_min: 0.0,
            t_max: f32::INFINITY,
        }
    }

    pub fn segment(origin: Vec3, direction: Vec3, t_min: f32, t_max: f32) -> Self {
        Self {
            origin,
            direction,
            t_min,
            t_max,
        }
    }

    #[inline]
    pub fn at(&self, t: f32) -> Vec3 {
        self.origin + t * self.direction
    }
}

/// A ray's intersection with a triangle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    /// Distance along the ray, in multiples of its direction.
    pub t: f32,
    /// Barycentric coordinates: the hit point is (1 - u - v) * p0 + u * p1 + v * p2.
    pub u: f32,
    pub v: f32,
    /// Index into `Scene::instances`.
    pub instance: u32,
    /// Triangle index within the instance's mesh.
    pub triangle: u32,
}
