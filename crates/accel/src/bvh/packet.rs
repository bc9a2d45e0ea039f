//! Packet traversal: eight coherent rays (camera rays of neighbouring pixels) through the
//! 8-wide BVH together, one ray per lane. Each box and each triangle is loaded once for the
//! eight rays instead of once per ray, and the per-ray overhead of the single-ray traversal
//! (its setup, stack and leaf bookkeeping) is shared.
//!
//! Every lane computes the single-ray traversal's arithmetic on its own ray (the same slab
//! test, the same watertight triangle test from [`edge_test`]), and hits are ordered by
//! [`before`], which doesn't depend on the order triangles are tested in. So each ray gets
//! exactly the hit [`traverse::closest`](super::traverse::closest) gives it, bit for bit: the
//! frame pipeline's packets and the reference renderer's single rays see the same surfaces.
//!
//! The rays must share the watertight test's axis permutation and the signs of their
//! direction components (so that they share the near and far planes of every box); camera
//! rays of eight neighbouring pixels nearly always do. Otherwise the caller traces them one by
//! one.

use super::traverse::{child, closest_in, leaf_at, node_at, slab, Best, Near, Stack, FAR_SCALE};
use super::wide::{Node, EMPTY_CHILD, LEAF_BIT, WIDTH};
use crate::ray::Ray;
use crate::simd::{BoxLanes, F32x4, SetBits};
use crate::triangle::{before, edge_test, lane_f64, shear, RayShear, TriPacket};

/// Rays per packet ([`NativeBvh::intersect_packet`](crate::NativeBvh::intersect_packet)): as
/// many as a node has children, so one lane type serves both.
pub const PACKET: usize = WIDTH;

/// A subtree that at most this many of the packet's rays enter is traversed by each of them
/// alone: one ray is cheaper through the single-ray code, which tests a node's children or a
/// leaf's four triangles at once, than as one lane of eight.
const ALONE: u32 = 3;

/// A deferred subtree and the distances at which the rays enter its box.
#[derive(Clone, Copy)]
struct Entry<L> {
    code: u32,
    /// Where the first ray entering the box enters it: the order children are visited in.
    near: f32,
    t_near: L,
}

impl<L: Copy> Near for Entry<L> {
    #[inline(always)]
    fn near(&self) -> f32 {
        self.near
    }
}

/// Each ray's closest hit so far: distance, barycentrics and triangle id (its bits; `u32::MAX`
/// for none).
#[derive(Clone, Copy)]
struct BestLanes<L> {
    t: L,
    u: L,
    v: L,
    id: L,
}

/// [`BestLanes`] as arrays, for lane-by-lane updates.
struct BestArrays([[f32; PACKET]; 4]);

impl<L: BoxLanes<PACKET>> BestLanes<L> {
    #[inline(always)]
    fn arrays(&self) -> BestArrays {
        BestArrays([
            self.t.to_array(),
            self.u.to_array(),
            self.v.to_array(),
            self.id.to_array(),
        ])
    }

    #[inline(always)]
    fn set(&mut self, a: &BestArrays) {
        let [t, u, v, id] = &a.0;
        (self.t, self.u, self.v, self.id) = (L::load(t), L::load(u), L::load(v), L::load(id));
    }
}

impl BestArrays {
    /// Lane `i` as `(id, t, u, v)`.
    #[inline(always)]
    fn get(&self, i: usize) -> Best {
        let [t, u, v, id] = &self.0;
        (id[i].to_bits(), t[i], u[i], v[i])
    }

    #[inline(always)]
    fn put(&mut self, i: usize, (id, t, u, v): Best) {
        let [ts, us, vs, ids] = &mut self.0;
        (ids[i], ts[i], us[i], vs[i]) = (f32::from_bits(id), t, u, v);
    }
}

/// The entry and exit distances of each ray into child `i` of `node` (the single-ray slab
/// test, lane by lane; `near` picks each axis's near bound, shared by the rays).
#[inline(always)]
fn slabs<L: BoxLanes<PACKET>>(
    node: &Node<WIDTH>,
    i: usize,
    near: &[usize; 3],
    ray: [&[L; 3]; 3],
    t_min: L,
    t_max: L,
) -> (L, L) {
    let b = |k: usize| L::splat(node.b[k][i]);
    slab(|a| b(near[a]), |a| b(near[a] ^ 1), ray, t_min, t_max)
}

/// Corner `c` of triangle `j` of `p` in each ray's sheared frame: axes permuted by `k`,
/// origins `so`, shear constants `ss`.
#[inline(always)]
fn corner<L: BoxLanes<PACKET>>(
    p: &TriPacket,
    c: usize,
    j: usize,
    k: &[usize; 3],
    so: &[L; 3],
    ss: &[L; 3],
) -> (L, L, L) {
    let v = &p.v[c];
    shear(
        [
            L::splat(v[k[0]][j]),
            L::splat(v[k[1]][j]),
            L::splat(v[k[2]][j]),
        ],
        so,
        ss,
    )
}

/// The closest hits of `rays` (as `traverse::closest` gives them) into `out`, or `false` when
/// the rays can't be traced as one packet (see the module docs); `out` is then untouched.
#[inline(always)]
pub(crate) fn closest<L: BoxLanes<PACKET>, S: F32x4>(
    nodes: &[Node<WIDTH>],
    packets: &[TriPacket],
    rays: &[Ray; PACKET],
    out: &mut [Option<(u32, f32, f32, f32)>; PACKET],
) -> bool {
    // The cheap test first (incoherent rays, such as bounces, mostly fail it at the second
    // ray). A sign bit set is a negative `1 / d`, as the single-ray box test reads it (`-0`
    // included); non-finite directions fail `RayShear::new` below.
    let signs = rays[0].direction.is_negative_bitmask();
    if !rays[1..]
        .iter()
        .all(|r| r.direction.is_negative_bitmask() == signs)
    {
        return false;
    }
    let mut shears = [None; PACKET];
    for (s, r) in shears.iter_mut().zip(rays) {
        *s = RayShear::new(r);
    }
    let Some(first) = shears[0] else {
        return false;
    };
    if !shears.iter().all(|s| s.is_some_and(|s| s.k == first.k)) {
        return false;
    }
    let shears = shears.map(|s| s.expect("checked above"));
    let k = first.k;
    // The near bound of each axis in `Node::b` (as `RayBox` picks it for one ray).
    let near = [0, 1, 2].map(|a| 2 * a + (signs >> a & 1) as usize);

    // The per-ray constants as arrays first, lane by lane, then loaded as lanes.
    let mut c = [[[0.0f32; PACKET]; 3]; 5];
    let (mut t_min, mut t_max) = ([0.0f32; PACKET], [0.0f32; PACKET]);
    for (i, (r, s)) in rays.iter().zip(&shears).enumerate() {
        let inv = r.direction.recip();
        for a in 0..3 {
            c[0][a][i] = r.origin[a];
            c[1][a][i] = inv[a];
            c[2][a][i] = inv[a] * FAR_SCALE;
            c[3][a][i] = s.o[a];
            c[4][a][i] = s.s[a];
        }
        (t_min[i], t_max[i]) = (r.t_min, r.t_max);
    }
    let mut lanes = [[L::splat(0.0); 3]; 5];
    for (l, c) in lanes.iter_mut().zip(&c) {
        for (l, c) in l.iter_mut().zip(c) {
            *l = L::load(c);
        }
    }
    let [o, inv, inv_far, so, ss] = lanes;
    let t_min = L::load(&t_min);

    let mut best = BestLanes {
        t: L::load(&t_max),
        u: L::splat(0.0),
        v: L::splat(0.0),
        id: L::splat(f32::from_bits(u32::MAX)),
    };

    let mut stack = Stack::<Entry<L>>::new();
    let mut code = 0u32;
    // The rays that enter `code`'s box in front of their closest hits so far.
    let mut active = L::ALL;
    loop {
        if active.count_ones() <= ALONE {
            alone::<L, S>(nodes, packets, code, active, rays, &shears, &mut best);
        } else if code & LEAF_BIT == 0 {
            let node = node_at(nodes, code);
            // The children some ray enters go on the stack, nearest on top.
            let mut n = 0;
            for i in 0..WIDTH as u32 {
                let c = child(node, i);
                if c == EMPTY_CHILD {
                    // Unused slots come last.
                    break;
                }
                let (t_near, t_far) =
                    slabs(node, i as usize, &near, [&o, &inv, &inv_far], t_min, best.t);
                let entered = t_near.le_bits(t_far);
                if entered != 0 {
                    let first = t_near.to_array()[entered.trailing_zeros() as usize];
                    stack.push(Entry {
                        code: c,
                        near: first,
                        t_near,
                    });
                    n += 1;
                }
            }
            stack.sort_top(n);
        } else {
            for p in leaf_at(packets, code) {
                for j in 0..4 {
                    let id = p.id[j];
                    if j > 0 && id == p.id[j - 1] {
                        // The padding of a short leaf repeats its last triangle.
                        break;
                    }
                    let h = edge_test(
                        corner(p, 0, j, &k, &so, &ss),
                        corner(p, 1, j, &k, &so, &ss),
                        corner(p, 2, j, &k, &so, &ss),
                        ss[2],
                        t_min,
                        best.t,
                    );
                    let (hits, redo_lanes) = (h.hits & active, h.redo & active);
                    if hits != 0 {
                        let nearer = L::bits(h.t.lt(best.t)) & hits;
                        let tied = L::bits(h.t.eq(best.t)) & hits & !nearer;
                        let mut update = nearer;
                        if tied != 0 {
                            let ids = best.id.to_array();
                            for i in SetBits(tied) {
                                if id < ids[i].to_bits() {
                                    update |= 1 << i;
                                }
                            }
                        }
                        if update != 0 {
                            let m = L::mask(update);
                            best = BestLanes {
                                t: L::select(m, h.t, best.t),
                                u: L::select(m, h.v.div(h.det), best.u),
                                v: L::select(m, h.w.div(h.det), best.v),
                                id: L::select(m, L::splat(f32::from_bits(id)), best.id),
                            };
                        }
                    }
                    if redo_lanes != 0 {
                        redo(p, j, redo_lanes, &shears, rays, &mut best);
                    }
                }
            }
        }
        // Pop the next entry some ray still enters in front of its closest hit.
        loop {
            let Some(e) = stack.pop() else {
                let a = best.arrays();
                for (i, o) in out.iter_mut().enumerate() {
                    let b = a.get(i);
                    *o = (b.0 != u32::MAX).then_some(b);
                }
                return true;
            };
            active = e.t_near.le_bits(best.t);
            if active != 0 {
                code = e.code;
                break;
            }
        }
    }
}

/// Traverses the subtree of code `root` with each ray of `lanes` alone, from its best hit so
/// far.
#[inline(always)]
fn alone<L: BoxLanes<PACKET>, S: F32x4>(
    nodes: &[Node<WIDTH>],
    packets: &[TriPacket],
    root: u32,
    lanes: u32,
    rays: &[Ray; PACKET],
    shears: &[RayShear; PACKET],
    best: &mut BestLanes<L>,
) {
    let mut a = best.arrays();
    for i in SetBits(lanes) {
        let b = closest_in::<WIDTH, L, S>(nodes, packets, &rays[i], &shears[i], root, a.get(i));
        a.put(i, b);
    }
    best.set(&a);
}

/// The f64 fallback of the watertight test for the lanes `lanes` of triangle `j` of `p`
/// (edge and vertex hits), merged into the best hits by [`before`].
#[cold]
#[inline(never)]
fn redo<L: BoxLanes<PACKET>>(
    p: &TriPacket,
    j: usize,
    lanes: u32,
    shears: &[RayShear; PACKET],
    rays: &[Ray; PACKET],
    best: &mut BestLanes<L>,
) {
    let mut a = best.arrays();
    for i in SetBits(lanes) {
        let (id, t, ..) = a.get(i);
        if let Some((ht, hu, hv)) = lane_f64(p, j, &shears[i], rays[i].t_min, t) {
            if before(ht, p.id[j], t, id) {
                a.put(i, (p.id[j], ht, hu, hv));
            }
        }
    }
    best.set(&a);
}
