//! Single-ray traversal of the 4-wide BVH: closest hit (children visited near to far) and any
//! hit (first hit wins), generic over the lane type so SSE and scalar share one code path.
//!
//! The slab test uses `1 / d` with infinities for zero direction components. A ray starting
//! exactly on a slab plane with a zero component gives `0 * inf = NaN` there, which the min/max
//! chain ignores (the NaN is always the first operand), so the slab counts as unbounded, as it
//! should. Far distances use `1 / d` scaled up by a few ulps (Ize 2013, "Robust BVH Ray
//! Traversal") so rounding can't make a ray miss a box it grazes.

use std::mem::MaybeUninit;

use super::wide::{leaf_range, Node4, LEAF_BIT};
use crate::ray::Ray;
use crate::simd::F32x4;
use crate::triangle::{intersect_packet, lane_f64, RayShear, RayShearLanes, TriPacket};

/// Traversal stack entries. The builder bounds the tree depth by `SAH_MAX_DEPTH + 32 = 80`,
/// and each level pushes at most three entries.
const STACK: usize = 256;
const _: () = assert!(STACK > 3 * (super::build::SAH_MAX_DEPTH as usize + 32));

/// `1 + 2 * gamma(3)` of Ize's paper, plus one ulp for rounding the scaled reciprocal.
const FAR_SCALE: f32 = 1.0 + 4.0 * f32::EPSILON;

/// The per-ray constants of the slab test, in lanes.
struct RayBox<S: F32x4> {
    o: [S; 3],
    inv: [S; 3],
    inv_far: [S; 3],
    /// Index into `Node4::b` of the near and far bound along each axis.
    near: [usize; 3],
    far: [usize; 3],
}

impl<S: F32x4> RayBox<S> {
    #[inline(always)]
    fn new(ray: &Ray) -> Self {
        let inv = ray.direction.recip().to_array();
        let near = [0, 1, 2].map(|a| 2 * a + (inv[a] < 0.0) as usize);
        Self {
            o: ray.origin.to_array().map(S::splat),
            inv: inv.map(S::splat),
            inv_far: inv.map(|i| S::splat(i * FAR_SCALE)),
            near,
            far: near.map(|n| n ^ 1),
        }
    }

    /// The children whose boxes overlap `[t_min, t_max]` (bit mask), and their entry distances.
    #[inline(always)]
    fn test(&self, n: &Node4, t_min: S, t_max: S) -> (u32, S) {
        let tn = |a: usize| S::load(&n.b[self.near[a]]).sub(self.o[a]).mul(self.inv[a]);
        let tf = |a: usize| {
            S::load(&n.b[self.far[a]])
                .sub(self.o[a])
                .mul(self.inv_far[a])
        };
        let t_near = tn(0).max(tn(1).max(tn(2).max(t_min)));
        let t_far = tf(0).min(tf(1).min(tf(2).min(t_max)));
        (S::bits(t_near.le(t_far)), t_near)
    }
}

/// The closest hit: (triangle id, t, u, v).
#[inline(always)]
pub(crate) fn closest<S: F32x4>(
    nodes: &[Node4],
    packets: &[TriPacket],
    ray: &Ray,
) -> Option<(u32, f32, f32, f32)> {
    let shear = RayShear::new(ray)?;
    let lanes = RayShearLanes::<S>::new(&shear);
    let rb = RayBox::<S>::new(ray);
    let t_min = S::splat(ray.t_min);
    let mut best_t = ray.t_max;
    let mut best: Option<(u32, f32, f32)> = None;
    let mut stack = [MaybeUninit::<(u32, f32)>::uninit(); STACK];
    let mut sp = 0usize;
    let mut code = 0u32;
    loop {
        if code & LEAF_BIT == 0 {
            let node = &nodes[code as usize];
            let (mut m, t_near) = rb.test(node, t_min, S::splat(best_t));
            if m != 0 {
                let i0 = m.trailing_zeros() as usize;
                m &= m - 1;
                if m == 0 {
                    code = node.child[i0];
                    continue;
                }
                let d = t_near.to_array();
                let i1 = m.trailing_zeros() as usize;
                m &= m - 1;
                if m == 0 {
                    let (a, b) = if d[i1] < d[i0] { (i1, i0) } else { (i0, i1) };
                    stack[sp].write((node.child[b], d[b]));
                    sp += 1;
                    code = node.child[a];
                    continue;
                }
                let mut e = [
                    (node.child[i0], d[i0]),
                    (node.child[i1], d[i1]),
                    (0, 0.0),
                    (0, 0.0),
                ];
                let mut k = 2;
                while m != 0 {
                    let i = m.trailing_zeros() as usize;
                    m &= m - 1;
                    e[k] = (node.child[i], d[i]);
                    k += 1;
                }
                // Sort by distance, farthest first; push all but the nearest.
                for a in 1..k {
                    let x = e[a];
                    let mut j = a;
                    while j > 0 && e[j - 1].1 < x.1 {
                        e[j] = e[j - 1];
                        j -= 1;
                    }
                    e[j] = x;
                }
                for x in &e[..k - 1] {
                    stack[sp].write(*x);
                    sp += 1;
                }
                code = e[k - 1].0;
                continue;
            }
        } else {
            let (first, count) = leaf_range(code);
            for p in &packets[first..first + count] {
                let h = intersect_packet(p, &lanes, t_min, S::splat(best_t));
                if h.hits != 0 {
                    let (lane, t, u, v) = h.nearest();
                    best_t = t;
                    best = Some((p.id[lane], u, v));
                }
                let mut redo = h.redo;
                while redo != 0 {
                    let lane = redo.trailing_zeros() as usize;
                    redo &= redo - 1;
                    if let Some((t, u, v)) = lane_f64(p, lane, &shear, ray.t_min, best_t) {
                        best_t = t;
                        best = Some((p.id[lane], u, v));
                    }
                }
            }
        }
        // Pop the next entry still in front of the closest hit.
        loop {
            if sp == 0 {
                return best.map(|(id, u, v)| (id, best_t, u, v));
            }
            sp -= 1;
            // SAFETY: entries below `sp` were all written before (the stack only grows by
            // `write` followed by `sp += 1`).
            let (c, d) = unsafe { stack[sp].assume_init() };
            if d <= best_t {
                code = c;
                break;
            }
        }
    }
}

/// True when any triangle lies on the ray within `[t_min, t_max]`.
#[inline(always)]
pub(crate) fn occluded<S: F32x4>(nodes: &[Node4], packets: &[TriPacket], ray: &Ray) -> bool {
    let Some(shear) = RayShear::new(ray) else {
        return false;
    };
    let lanes = RayShearLanes::<S>::new(&shear);
    let rb = RayBox::<S>::new(ray);
    let t_min = S::splat(ray.t_min);
    let t_max = S::splat(ray.t_max);
    let mut stack = [MaybeUninit::<u32>::uninit(); STACK];
    let mut sp = 0usize;
    let mut code = 0u32;
    loop {
        if code & LEAF_BIT == 0 {
            let node = &nodes[code as usize];
            let (mut m, _) = rb.test(node, t_min, t_max);
            if m != 0 {
                let i0 = m.trailing_zeros() as usize;
                m &= m - 1;
                while m != 0 {
                    let i = m.trailing_zeros() as usize;
                    m &= m - 1;
                    stack[sp].write(node.child[i]);
                    sp += 1;
                }
                code = node.child[i0];
                continue;
            }
        } else {
            let (first, count) = leaf_range(code);
            for p in &packets[first..first + count] {
                let h = intersect_packet(p, &lanes, t_min, t_max);
                if h.hits != 0 {
                    return true;
                }
                let mut redo = h.redo;
                while redo != 0 {
                    let lane = redo.trailing_zeros() as usize;
                    redo &= redo - 1;
                    if lane_f64(p, lane, &shear, ray.t_min, ray.t_max).is_some() {
                        return true;
                    }
                }
            }
        }
        if sp == 0 {
            return false;
        }
        sp -= 1;
        // SAFETY: entries below `sp` were all written before.
        code = unsafe { stack[sp].assume_init() };
    }
}
