//! Watertight ray/triangle intersection (Woop, Benthin, Wald 2013, "Watertight Ray/Triangle
//! Intersection", JCGT 2(1)), four triangles at a time.
//!
//! The ray is made the +z axis of a sheared frame; each triangle corner is transformed into it
//! with the same float operations whichever triangle it belongs to, and the three 2D edge
//! functions `U, V, W` decide inside/outside. A shared edge therefore gets bit-identical (negated)
//! edge values in both of its triangles, so a ray through an edge or a vertex can't slip between
//! them. No fused multiply-add is used anywhere on that path: it would break the symmetry.
//!
//! When an edge function is exactly zero, or the f32 values can't be trusted (overflow with huge
//! coordinates, underflow with tiny ones), that lane is recomputed in double precision from the
//! same sheared f32 corners, as the paper does for the zero case.

use crate::ray::Ray;
use crate::simd::{F32x4, Lanes, Scalar4};

/// Four triangles in structure-of-arrays layout: `v[corner][axis][lane]`.
///
/// Leaves with fewer than four triangles repeat their last triangle in the unused lanes, so no
/// lane mask is needed: a repeated triangle gives the same hit as the original.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(16))]
pub(crate) struct TriPacket {
    pub v: [[[f32; 4]; 3]; 3],
    /// Index of each lane's triangle in the builder's input.
    pub id: [u32; 4],
}

impl TriPacket {
    /// Packs up to four triangles (at least one), repeating the last.
    pub fn new(tris: &[([glam::Vec3; 3], u32)]) -> Self {
        assert!(!tris.is_empty() && tris.len() <= 4);
        let mut p = TriPacket {
            v: [[[0.0; 4]; 3]; 3],
            id: [0; 4],
        };
        for lane in 0..4 {
            let (corners, id) = tris[lane.min(tris.len() - 1)];
            for (c, corner) in corners.iter().enumerate() {
                for axis in 0..3 {
                    p.v[c][axis][lane] = corner[axis];
                }
            }
            p.id[lane] = id;
        }
        p
    }

    #[inline]
    fn corner(&self, c: usize, lane: usize) -> [f32; 3] {
        [self.v[c][0][lane], self.v[c][1][lane], self.v[c][2][lane]]
    }
}

/// Below (or above) these magnitudes of `det = U + V + W` the f32 result is recomputed in f64.
const DET_LO: f32 = 1e-20;
const DET_HI: f32 = 1e30;

/// The per-ray constants of the watertight test.
#[derive(Clone, Copy, Debug)]
pub(crate) struct RayShear {
    /// Axis permutation: `k[2]` is the dominant axis of the direction.
    pub k: [usize; 3],
    /// Origin in the permuted axes.
    pub o: [f32; 3],
    /// Shear constants `Sx, Sy, Sz`.
    pub s: [f32; 3],
}

impl RayShear {
    /// `None` for a zero (or non-finite) direction, which can hit nothing.
    #[inline]
    pub fn new(ray: &Ray) -> Option<Self> {
        let d = ray.direction.to_array();
        let a = ray.direction.abs();
        if !(a.max_element() > 0.0 && ray.direction.is_finite() && ray.origin.is_finite()) {
            return None;
        }
        let kz = if a.x >= a.y && a.x >= a.z {
            0
        } else if a.y >= a.z {
            1
        } else {
            2
        };
        let mut kx = (kz + 1) % 3;
        let mut ky = (kx + 1) % 3;
        if d[kz] < 0.0 {
            std::mem::swap(&mut kx, &mut ky);
        }
        let o = ray.origin.to_array();
        Some(RayShear {
            k: [kx, ky, kz],
            o: [o[kx], o[ky], o[kz]],
            s: [d[kx] / d[kz], d[ky] / d[kz], 1.0 / d[kz]],
        })
    }
}

/// [`RayShear`] splatted into lanes.
#[derive(Clone, Copy)]
pub(crate) struct RayShearLanes<S: F32x4> {
    k: [usize; 3],
    o: [S; 3],
    s: [S; 3],
}

impl<S: F32x4> RayShearLanes<S> {
    #[inline(always)]
    pub fn new(r: &RayShear) -> Self {
        Self {
            // Already a permutation of 0..3; the clamp makes the in-bounds loads below evident.
            k: r.k.map(|a| a.min(2)),
            o: r.o.map(S::splat),
            s: r.s.map(S::splat),
        }
    }
}

/// The outcome of one test of lanes (four triangles against a ray, or a triangle against
/// several rays).
pub(crate) struct PacketHits<S: Lanes> {
    /// Lanes hit within `[t_min, t_max]` by the f32 test.
    pub hits: u32,
    /// Lanes whose f32 result is unreliable: call [`lane_f64`] for them.
    pub redo: u32,
    pub t: S,
    pub v: S,
    pub w: S,
    pub det: S,
}

/// True when a hit at `t` on triangle `id` goes before the best one so far, at `best_t` on
/// `best_id`: nearer, or as near and of a smaller id. The order of the tests can't change
/// which triangle wins, so single rays and ray packets find the same one.
#[inline(always)]
pub(crate) fn before(t: f32, id: u32, best_t: f32, best_id: u32) -> bool {
    t < best_t || (t == best_t && id < best_id)
}

impl<S: F32x4> PacketHits<S> {
    /// (lane, t, u, v) of the first lane in `hits` (which must be non-zero) by [`before`]:
    /// `ids` are the lanes' triangle ids.
    #[inline(always)]
    pub fn nearest(&self, ids: &[u32; 4]) -> (usize, f32, f32, f32) {
        let t = self.t.to_array();
        let mut m = self.hits;
        let mut best = m.trailing_zeros() as usize;
        m &= m - 1;
        while m != 0 {
            let i = m.trailing_zeros() as usize;
            m &= m - 1;
            if before(t[i], ids[i], t[best], ids[best]) {
                best = i;
            }
        }
        let v = self.v.to_array()[best];
        let w = self.w.to_array()[best];
        let det = self.det.to_array()[best];
        (best, t[best], v / det, w / det)
    }
}

/// The sheared corner of one triangle vertex (`x, y` in the plane, `z` along the ray, unscaled).
#[inline(always)]
fn shear_lanes<S: F32x4>(p: &TriPacket, c: usize, r: &RayShearLanes<S>) -> (S, S, S) {
    let corner = &p.v[c];
    // SAFETY: `RayShearLanes::new` clamps every `k` to 0..=2.
    let load = |a: usize| S::load(unsafe { corner.get_unchecked(r.k[a]) });
    shear([load(0), load(1), load(2)], &r.o, &r.s)
}

/// A triangle corner `[x, y, z]`, already in the ray's permuted axis order, in the sheared
/// frame of origin `o` and shear constants `s` (`x, y` in the plane, `z` along the ray,
/// unscaled): the arithmetic every lane layout shares.
#[inline(always)]
pub(crate) fn shear<S: Lanes>([x, y, z]: [S; 3], o: &[S; 3], s: &[S; 3]) -> (S, S, S) {
    let (ax, ay, az) = (x.sub(o[0]), y.sub(o[1]), z.sub(o[2]));
    (ax.sub(s[0].mul(az)), ay.sub(s[1].mul(az)), az)
}

/// Tests a ray against the four triangles of a packet.
#[inline(always)]
pub(crate) fn intersect_packet<S: F32x4>(
    p: &TriPacket,
    r: &RayShearLanes<S>,
    t_min: S,
    t_max: S,
) -> PacketHits<S> {
    edge_test(
        shear_lanes(p, 0, r),
        shear_lanes(p, 1, r),
        shear_lanes(p, 2, r),
        r.s[2],
        t_min,
        t_max,
    )
}

/// The watertight test from the sheared corners `a, b, c` (each `(x, y, z)`) and the shear
/// constant `sz`: the arithmetic every lane layout shares.
#[inline(always)]
pub(crate) fn edge_test<S: Lanes>(
    (ax, ay, az): (S, S, S),
    (bx, by, bz): (S, S, S),
    (cx, cy, cz): (S, S, S),
    sz: S,
    t_min: S,
    t_max: S,
) -> PacketHits<S> {
    let u = cx.mul(by).sub(cy.mul(bx));
    let v = ax.mul(cy).sub(ay.mul(cx));
    let w = bx.mul(ay).sub(by.mul(ax));
    let zero = S::splat(0.0);
    let neg = S::or(S::or(u.lt(zero), v.lt(zero)), w.lt(zero));
    let pos = S::or(S::or(u.gt(zero), v.gt(zero)), w.gt(zero));
    let miss = S::and(neg, pos);
    // Most tests miss in every lane: skip the distance computation for them.
    if S::bits(miss) == S::ALL {
        return PacketHits {
            hits: 0,
            redo: 0,
            t: zero,
            v: zero,
            w: zero,
            det: zero,
        };
    }
    let det = u.add(v).add(w);
    let tt = u
        .mul(sz.mul(az))
        .add(v.mul(sz.mul(bz)))
        .add(w.mul(sz.mul(cz)));
    let t = tt.div(det);
    let zeros = S::or(S::or(u.eq(zero), v.eq(zero)), w.eq(zero));
    let adet = det.abs();
    let bad = S::or(
        S::or(adet.not_ge(S::splat(DET_LO)), adet.not_le(S::splat(DET_HI))),
        tt.abs().not_le(S::splat(f32::MAX)),
    );
    let redo = S::andnot(miss, S::or(zeros, bad));
    let in_range = S::and(t.ge(t_min), t.le(t_max));
    let hits = S::andnot(S::or(miss, redo), in_range);
    PacketHits {
        hits: S::bits(hits),
        redo: S::bits(redo),
        t,
        v,
        w,
        det,
    }
}

/// The test for one lane, with the edge functions, determinant and distance in f64 (the
/// paper's fallback). The sheared corners are computed in f32 exactly as the lane code does.
#[cold]
#[inline(never)]
pub(crate) fn lane_f64(
    p: &TriPacket,
    lane: usize,
    r: &RayShear,
    t_min: f32,
    t_max: f32,
) -> Option<(f32, f32, f32)> {
    let shear = |c: usize| {
        let q = p.corner(c, lane);
        let ax = q[r.k[0]] - r.o[0];
        let ay = q[r.k[1]] - r.o[1];
        let az = q[r.k[2]] - r.o[2];
        (
            (ax - r.s[0] * az) as f64,
            (ay - r.s[1] * az) as f64,
            az as f64 * r.s[2] as f64,
        )
    };
    let (ax, ay, az) = shear(0);
    let (bx, by, bz) = shear(1);
    let (cx, cy, cz) = shear(2);
    let u = cx * by - cy * bx;
    let v = ax * cy - ay * cx;
    let w = bx * ay - by * ax;
    if (u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0) {
        return None;
    }
    let det = u + v + w;
    if det == 0.0 {
        return None;
    }
    // The range test is on the f32 distance the caller compares, so that whether a hit counts
    // doesn't depend on the order triangles are tested in (see [`before`]).
    let t = ((u * az + v * bz + w * cz) / det) as f32;
    if !(t >= t_min && t <= t_max) {
        return None;
    }
    Some((t, (v / det) as f32, (w / det) as f32))
}

/// One triangle against one ray, through the packet code (for tests and small callers).
pub fn intersect_triangle(ray: &Ray, tri: &[glam::Vec3; 3]) -> Option<(f32, f32, f32)> {
    let r = RayShear::new(ray)?;
    let p = TriPacket::new(&[(*tri, 0)]);
    let lanes = RayShearLanes::<Scalar4>::new(&r);
    let h = intersect_packet(
        &p,
        &lanes,
        Scalar4::splat(ray.t_min),
        Scalar4::splat(ray.t_max),
    );
    if h.redo & 1 != 0 {
        return lane_f64(&p, 0, &r, ray.t_min, ray.t_max);
    }
    (h.hits & 1 != 0).then(|| {
        let (_, t, u, v) = h.nearest(&p.id);
        (t, u, v)
    })
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;

    #[test]
    fn hits_centre_with_barycentrics() {
        let tri = [Vec3::ZERO, Vec3::X, Vec3::Y];
        let ray = Ray::new(Vec3::new(0.25, 0.5, 1.0), -Vec3::Z);
        let (t, u, v) = intersect_triangle(&ray, &tri).unwrap();
        assert!((t - 1.0).abs() < 1e-6);
        assert!((u - 0.25).abs() < 1e-6 && (v - 0.5).abs() < 1e-6, "{u} {v}");
        // Both windings.
        let tri2 = [Vec3::ZERO, Vec3::Y, Vec3::X];
        let (_, u, v) = intersect_triangle(&ray, &tri2).unwrap();
        assert!((u - 0.5).abs() < 1e-6 && (v - 0.25).abs() < 1e-6);
    }

    #[test]
    fn edges_and_vertices_hit_via_f64_fallback() {
        let tri = [Vec3::ZERO, Vec3::X, Vec3::Y];
        for o in [
            Vec3::new(0.5, 0.0, 1.0),
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(0.5, 0.5, 1.0),
        ] {
            assert!(
                intersect_triangle(&Ray::new(o, -Vec3::Z), &tri).is_some(),
                "{o}"
            );
        }
        assert!(intersect_triangle(&Ray::new(Vec3::new(0.6, 0.6, 1.0), -Vec3::Z), &tri).is_none());
    }

    #[test]
    fn t_range_and_degenerate_rays() {
        let tri = [Vec3::ZERO, Vec3::X, Vec3::Y];
        let o = Vec3::new(0.2, 0.2, 1.0);
        assert!(intersect_triangle(&Ray::segment(o, -Vec3::Z, 0.0, 0.99), &tri).is_none());
        assert!(intersect_triangle(&Ray::segment(o, -Vec3::Z, 1.01, 9.0), &tri).is_none());
        assert!(intersect_triangle(&Ray::segment(o, -Vec3::Z, 1.0, 1.0), &tri).is_some());
        assert!(intersect_triangle(&Ray::new(o, Vec3::ZERO), &tri).is_none());
        assert!(intersect_triangle(&Ray::new(o, Vec3::X), &tri).is_none());
    }

    #[test]
    fn huge_and_tiny_coordinates() {
        for s in [1e-20f32, 1e-10, 1e7, 1e20, 1e30] {
            let tri = [Vec3::ZERO, Vec3::X * s, Vec3::Y * s];
            let ray = Ray::new(Vec3::new(0.25, 0.25, 2.0) * s, -Vec3::Z);
            let (t, u, v) = intersect_triangle(&ray, &tri).unwrap_or_else(|| panic!("{s}"));
            assert!((t / s - 2.0).abs() < 1e-5, "{s} {t}");
            assert!((u - 0.25).abs() < 1e-5 && (v - 0.25).abs() < 1e-5, "{s}");
        }
    }
}
