//! The brute-force reference: every ray against every triangle with a double-precision
//! Möller–Trumbore test, deliberately simple and independent of the fast code it checks.

use glam::DVec3;

use crate::geometry::SceneTriangles;
use crate::ray::{Hit, Ray};
use crate::Accel;

/// Tests every triangle for every ray. Only for tests and small scenes.
pub struct BruteForce {
    triangles: SceneTriangles,
}

impl BruteForce {
    pub fn new(triangles: SceneTriangles) -> Self {
        Self { triangles }
    }
}

/// Möller–Trumbore in double precision: (t, u, v) of the hit, if any, with no culling.
pub fn intersect_triangle_f64(ray: &Ray, tri: &[glam::Vec3; 3]) -> Option<(f64, f64, f64)> {
    let o = ray.origin.as_dvec3();
    let d = ray.direction.as_dvec3();
    let [p0, p1, p2] = tri.map(|p| p.as_dvec3());
    let e1 = p1 - p0;
    let e2 = p2 - p0;
    let pv = d.cross(e2);
    let det = e1.dot(pv);
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let inv = 1.0 / det;
    let tv: DVec3 = o - p0;
    let u = tv.dot(pv) * inv;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let qv = tv.cross(e1);
    let v = d.dot(qv) * inv;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    let t = e2.dot(qv) * inv;
    (t >= ray.t_min as f64 && t <= ray.t_max as f64).then_some((t, u, v))
}

impl Accel for BruteForce {
    fn name(&self) -> &'static str {
        "brute"
    }

    fn intersect(&self, ray: &Ray) -> Option<Hit> {
        let mut best: Option<Hit> = None;
        for (k, tri) in self.triangles.corners.iter().enumerate() {
            if let Some((t, u, v)) = intersect_triangle_f64(ray, tri) {
                if best.is_none_or(|b| (t as f32) < b.t) {
                    let (instance, triangle) = self.triangles.ids[k];
                    best = Some(Hit {
                        t: t as f32,
                        u: u as f32,
                        v: v as f32,
                        instance,
                        triangle,
                    });
                }
            }
        }
        best
    }

    fn occluded(&self, ray: &Ray) -> bool {
        self.triangles
            .corners
            .iter()
            .any(|tri| intersect_triangle_f64(ray, tri).is_some())
    }

    fn memory_bytes(&self) -> usize {
        self.triangles.corners.len() * 36 + self.triangles.ids.len() * 8
    }
}
