//! Single-ray traversal of the wide BVH: closest hit (children visited near to far) and any
//! hit (first hit wins), generic over the node width and the lane types, so AVX2, SSE and
//! scalar code share one code path.
//!
//! The slab test uses `1 / d` with infinities for zero direction components. A ray starting
//! exactly on a slab plane with a zero component gives `0 * inf = NaN` there, which the min/max
//! chain ignores (the NaN is always the first operand), so the slab counts as unbounded, as it
//! should. Far distances use `1 / d` scaled up by a few ulps (Ize 2013, "Robust BVH Ray
//! Traversal") so rounding can't make a ray miss a box it grazes.

use std::mem::MaybeUninit;

use super::wide::{leaf_range, Node, LEAF_BIT};
use crate::ray::Ray;
use crate::simd::{BoxLanes, F32x4, Lanes};
use crate::triangle::{before, intersect_packet, lane_f64, RayShear, RayShearLanes, TriPacket};

/// Traversal stack entries. The builder bounds the tree depth by `SAH_MAX_DEPTH + 32 = 80`,
/// and each level pushes at most `WIDTH - 1` entries.
const STACK: usize = 640;
const _: () =
    assert!(STACK > (super::wide::WIDTH - 1) * (super::build::SAH_MAX_DEPTH as usize + 32));

/// `1 + 2 * gamma(3)` of Ize's paper, plus one ulp for rounding the scaled reciprocal.
pub(super) const FAR_SCALE: f32 = 1.0 + 4.0 * f32::EPSILON;

/// The per-ray constants of the slab test, in lanes.
struct RayBox<const W: usize, B: BoxLanes<W>> {
    o: [B; 3],
    inv: [B; 3],
    inv_far: [B; 3],
    /// Index into `Node::b` of the near bound along each axis (`2 * axis` or `2 * axis + 1`);
    /// the far bound is at `near ^ 1`.
    near: [usize; 3],
}

impl<const W: usize, B: BoxLanes<W>> RayBox<W, B> {
    #[inline(always)]
    fn new(ray: &Ray) -> Self {
        let inv = ray.direction.recip().to_array();
        Self {
            o: ray.origin.to_array().map(B::splat),
            inv: inv.map(B::splat),
            inv_far: inv.map(|i| B::splat(i * FAR_SCALE)),
            near: [
                (inv[0] < 0.0) as usize,
                2 + (inv[1] < 0.0) as usize,
                4 + (inv[2] < 0.0) as usize,
            ],
        }
    }

    /// The children whose boxes overlap `[t_min, t_max]` (bit mask, bits `0..W`), and their
    /// entry distances.
    #[inline(always)]
    fn test(&self, n: &Node<W>, t_min: B, t_max: B) -> (u32, B) {
        // SAFETY: `near[a]` is `2 * a` or `2 * a + 1` (see `new`), and so is `near[a] ^ 1`:
        // both are below 6, the length of `n.b`.
        let b = |i: usize| B::load(unsafe { n.b.get_unchecked(i) });
        let (t_near, t_far) = slab(
            |a| b(self.near[a]),
            |a| b(self.near[a] ^ 1),
            [&self.o, &self.inv, &self.inv_far],
            t_min,
            t_max,
        );
        (t_near.le_bits(t_far), t_near)
    }
}

/// The slab test's entry and exit distances, from the near and far bounds along axis `a`
/// (`near(a)`, `far(a)`) and the ray's `[origin, 1 / d, scaled 1 / d]`: the arithmetic every
/// lane layout shares (a node's children for one ray, or one child for a packet of rays).
#[inline(always)]
pub(super) fn slab<B: Lanes>(
    near: impl Fn(usize) -> B,
    far: impl Fn(usize) -> B,
    [o, inv, inv_far]: [&[B; 3]; 3],
    t_min: B,
    t_max: B,
) -> (B, B) {
    let tn = |a: usize| near(a).sub(o[a]).mul(inv[a]);
    let tf = |a: usize| far(a).sub(o[a]).mul(inv_far[a]);
    (
        tn(0).max(tn(1).max(tn(2).max(t_min))),
        tf(0).min(tf(1).min(tf(2).min(t_max))),
    )
}

/// A deferred subtree and the distance at which the ray enters its box.
#[derive(Clone, Copy)]
struct Entry {
    code: u32,
    dist: f32,
}

/// The fixed-size traversal stack.
pub(super) struct Stack<T: Copy> {
    items: [MaybeUninit<T>; STACK],
    len: usize,
}

impl<T: Copy> Stack<T> {
    #[inline(always)]
    pub(super) fn new() -> Self {
        Self {
            items: [const { MaybeUninit::uninit() }; STACK],
            len: 0,
        }
    }

    #[inline(always)]
    pub(super) fn push(&mut self, x: T) {
        debug_assert!(self.len < STACK);
        // SAFETY: a traversal pushes at most three entries per level of a tree at most
        // `SAH_MAX_DEPTH + 32` levels deep (the builder's bound), fewer than `STACK` in all.
        unsafe { self.items.get_unchecked_mut(self.len).write(x) };
        self.len += 1;
    }

    #[inline(always)]
    pub(super) fn pop(&mut self) -> Option<T> {
        if self.len == 0 {
            return None;
        }
        self.len -= 1;
        // SAFETY: entries below `len` were all written by `push` (or `sort_top`, which only
        // permutes written entries).
        Some(unsafe { self.items.get_unchecked(self.len).assume_init() })
    }
}

/// A stack entry with a distance to sort by.
pub(super) trait Near: Copy {
    /// The distance at which the ray (or the packet) enters the entry's box.
    fn near(&self) -> f32;
}

impl Near for Entry {
    #[inline(always)]
    fn near(&self) -> f32 {
        self.dist
    }
}

impl<T: Near> Stack<T> {
    /// Sorts the top `k` entries so the nearest is on top (insertion sort; `k <= WIDTH`).
    #[inline(always)]
    pub(super) fn sort_top(&mut self, k: usize) {
        debug_assert!(k <= self.len);
        let base = self.len - k;
        let s = self.items.as_mut_ptr();
        for a in base + 1..self.len {
            // SAFETY: `base..len` are initialised entries within the array (`k <= len`).
            unsafe {
                let x = (*s.add(a)).assume_init();
                let mut j = a;
                while j > base && (*s.add(j - 1)).assume_init().near() < x.near() {
                    *s.add(j) = *s.add(j - 1);
                    j -= 1;
                }
                s.add(j).write(MaybeUninit::new(x));
            }
        }
    }
}

/// Child `i` (below `W`) of `node`.
#[inline(always)]
pub(super) fn child<const W: usize>(node: &Node<W>, i: u32) -> u32 {
    debug_assert!((i as usize) < W);
    // SAFETY: `i` is a lane index of a `W`-bit hit mask (`BoxLanes::le_bits`).
    unsafe { *node.child.get_unchecked(i as usize) }
}

/// The inner node of code `code`.
#[inline(always)]
pub(super) fn node_at<const W: usize>(nodes: &[Node<W>], code: u32) -> &Node<W> {
    debug_assert!((code as usize) < nodes.len());
    // SAFETY: inner-node codes are indices into `nodes` by construction (`wide::collapse`
    // numbers each node it pushes), and the root `0` always exists.
    unsafe { nodes.get_unchecked(code as usize) }
}

/// The packets of the leaf of code `code`.
#[inline(always)]
pub(super) fn leaf_at(packets: &[TriPacket], code: u32) -> &[TriPacket] {
    let (first, count) = leaf_range(code);
    debug_assert!(first + count <= packets.len());
    // SAFETY: leaf codes name a range of packets `wide::collapse` emitted (empty slots have
    // `count == 0`).
    unsafe { packets.get_unchecked(first..first + count) }
}

/// A closest-hit query's answer so far: (triangle id, t, u, v), `u32::MAX` for no hit.
pub(super) type Best = (u32, f32, f32, f32);

/// The closest hit: (triangle id, t, u, v); of hits at the same `t`, the smallest id.
#[inline(always)]
pub(crate) fn closest<const W: usize, B: BoxLanes<W>, S: F32x4>(
    nodes: &[Node<W>],
    packets: &[TriPacket],
    ray: &Ray,
) -> Option<(u32, f32, f32, f32)> {
    let shear = RayShear::new(ray)?;
    let none = (u32::MAX, ray.t_max, 0.0, 0.0);
    let best = closest_in::<W, B, S>(nodes, packets, ray, &shear, 0, none);
    (best.0 != u32::MAX).then_some(best)
}

/// The closest hit of `ray` (whose watertight-test constants are `shear`) in the subtree of
/// code `root` that goes [`before`] `best`, or `best`.
#[inline(always)]
pub(super) fn closest_in<const W: usize, B: BoxLanes<W>, S: F32x4>(
    nodes: &[Node<W>],
    packets: &[TriPacket],
    ray: &Ray,
    shear: &RayShear,
    root: u32,
    best: Best,
) -> Best {
    let lanes = RayShearLanes::<S>::new(shear);
    let rb = RayBox::<W, B>::new(ray);
    let t_min = S::splat(ray.t_min);
    let box_t_min = B::splat(ray.t_min);
    let mut best_t = best.1;
    let mut t_max = S::splat(best_t);
    let mut box_t_max = B::splat(best_t);
    let mut best = (best.0, best.2, best.3);
    let mut stack = Stack::<Entry>::new();
    let mut code = root;
    loop {
        if code & LEAF_BIT == 0 {
            let node = node_at(nodes, code);
            let (mut m, t_near) = rb.test(node, box_t_min, box_t_max);
            if m != 0 {
                let i0 = m.trailing_zeros();
                m &= m - 1;
                if m == 0 {
                    code = child(node, i0);
                    continue;
                }
                let d = t_near.to_array();
                // SAFETY: lane indices of a `W`-bit mask are below `W`.
                let dist = |i: u32| unsafe { *d.get_unchecked(i as usize) };
                let i1 = m.trailing_zeros();
                m &= m - 1;
                if m == 0 {
                    let (d0, d1) = (dist(i0), dist(i1));
                    let (c0, c1) = (child(node, i0), child(node, i1));
                    if d1 < d0 {
                        stack.push(Entry { code: c0, dist: d0 });
                        code = c1;
                    } else {
                        stack.push(Entry { code: c1, dist: d1 });
                        code = c0;
                    }
                    continue;
                }
                stack.push(Entry {
                    code: child(node, i0),
                    dist: dist(i0),
                });
                stack.push(Entry {
                    code: child(node, i1),
                    dist: dist(i1),
                });
                let mut k = 2;
                while m != 0 {
                    let i = m.trailing_zeros();
                    m &= m - 1;
                    stack.push(Entry {
                        code: child(node, i),
                        dist: dist(i),
                    });
                    k += 1;
                }
                stack.sort_top(k);
                // The nearest is on top: visit it now.
                code = stack.pop().map_or(0, |e| e.code);
                continue;
            }
        } else {
            for p in leaf_at(packets, code) {
                let h = intersect_packet(p, &lanes, t_min, t_max);
                if h.hits != 0 {
                    let (lane, t, u, v) = h.nearest(&p.id);
                    if before(t, p.id[lane], best_t, best.0) {
                        best_t = t;
                        best = (p.id[lane], u, v);
                    }
                }
                let mut redo = h.redo;
                while redo != 0 {
                    let lane = redo.trailing_zeros() as usize;
                    redo &= redo - 1;
                    if let Some((t, u, v)) = lane_f64(p, lane, shear, ray.t_min, best_t) {
                        if before(t, p.id[lane], best_t, best.0) {
                            best_t = t;
                            best = (p.id[lane], u, v);
                        }
                    }
                }
                t_max = S::splat(best_t);
            }
            box_t_max = B::splat(best_t);
        }
        // Pop the next entry still in front of the closest hit.
        loop {
            let Some(e) = stack.pop() else {
                return (best.0, best_t, best.1, best.2);
            };
            if e.dist <= best_t {
                code = e.code;
                break;
            }
        }
    }
}

/// True when any triangle lies on the ray within `[t_min, t_max]`.
#[inline(always)]
pub(crate) fn occluded<const W: usize, B: BoxLanes<W>, S: F32x4>(
    nodes: &[Node<W>],
    packets: &[TriPacket],
    ray: &Ray,
) -> bool {
    let Some(shear) = RayShear::new(ray) else {
        return false;
    };
    let lanes = RayShearLanes::<S>::new(&shear);
    let rb = RayBox::<W, B>::new(ray);
    let t_min = S::splat(ray.t_min);
    let t_max = S::splat(ray.t_max);
    let (box_t_min, box_t_max) = (B::splat(ray.t_min), B::splat(ray.t_max));
    let mut stack = Stack::<u32>::new();
    let mut code = 0u32;
    loop {
        if code & LEAF_BIT == 0 {
            let node = node_at(nodes, code);
            let (mut m, _) = rb.test(node, box_t_min, box_t_max);
            if m != 0 {
                let i0 = m.trailing_zeros();
                m &= m - 1;
                while m != 0 {
                    let i = m.trailing_zeros();
                    m &= m - 1;
                    stack.push(child(node, i));
                }
                code = child(node, i0);
                continue;
            }
        } else {
            for p in leaf_at(packets, code) {
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
        match stack.pop() {
            Some(c) => code = c,
            None => return false,
        }
    }
}
