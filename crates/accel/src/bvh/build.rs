//! The binned SAH builder of the binary BVH that [`wide`](super::wide) collapses.
//!
//! Each node bins its primitives' centroids into [`BINS`] bins per axis, sweeps the bins for the
//! split of least surface area heuristic cost, and recurses on both halves in parallel (rayon)
//! above [`PARALLEL_SPLIT`] primitives. Costs count primitives in blocks of four, as the leaves
//! are tested four triangles at a time. The output depends only on the input, never on the
//! thread count: binning reduces with min/max and integer sums (exact in any order) and each
//! subtree is built from its own slice.

use glam::Vec3;
use rayon::prelude::*;

use super::aabb::Aabb;

/// Bins per axis.
pub(crate) const BINS: usize = 32;
/// Most primitives in a leaf (two packets of four).
pub(crate) const MAX_LEAF: usize = 8;
/// Below this depth nodes split by SAH; deeper ones split at the median, which bounds the
/// depth of any tree at `SAH_MAX_DEPTH + 32` (the traversal stack relies on it).
pub(crate) const SAH_MAX_DEPTH: u32 = 48;
/// Nodes with at least this many primitives build their two children in parallel.
const PARALLEL_SPLIT: usize = 2048;
/// Nodes with at least this many primitives bin and bound in parallel.
const PARALLEL_BIN: usize = 32 * 1024;
/// SAH cost of visiting a node, relative to testing one packet of four triangles.
pub(crate) const TRAVERSAL_COST: f64 = 1.0;
pub(crate) const PACKET_COST: f64 = 1.0;

/// A node of the binary BVH.
#[derive(Debug)]
pub(crate) enum Node2 {
    Leaf {
        bounds: Aabb,
        /// First index into [`Bvh2::prims`].
        first: u32,
        count: u32,
    },
    Inner {
        bounds: Aabb,
        children: Box<[Node2; 2]>,
    },
}

impl Node2 {
    pub fn bounds(&self) -> &Aabb {
        match self {
            Node2::Leaf { bounds, .. } | Node2::Inner { bounds, .. } => bounds,
        }
    }
}

/// A binary BVH over primitive indices.
#[derive(Debug)]
pub(crate) struct Bvh2 {
    /// `None` when there are no primitives.
    pub root: Option<Node2>,
    /// Primitive indices in leaf order.
    pub prims: Vec<u32>,
}

/// Packets of four needed for `n` primitives.
#[inline]
pub(crate) fn blocks(n: usize) -> f64 {
    n.div_ceil(4) as f64
}

struct Ctx<'a> {
    boxes: &'a [Aabb],
    centroids: &'a [Vec3],
}

#[derive(Clone, Copy)]
struct Bin {
    bounds: Aabb,
    count: u32,
}

const EMPTY_BIN: Bin = Bin {
    bounds: Aabb::EMPTY,
    count: 0,
};

type Bins = [[Bin; BINS]; 3];

/// Maps centroids to bins along one axis.
#[derive(Clone, Copy)]
struct Binning {
    lo: [f64; 3],
    scale: [f64; 3],
}

impl Binning {
    #[inline]
    fn bin(&self, c: Vec3, axis: usize) -> usize {
        (((c[axis] as f64 - self.lo[axis]) * self.scale[axis]) as usize).min(BINS - 1)
    }
}

/// Builds the BVH over `prims`, indices into `boxes` and `centroids`.
pub(crate) fn build(boxes: &[Aabb], centroids: &[Vec3], mut prims: Vec<u32>) -> Bvh2 {
    if prims.is_empty() {
        return Bvh2 { root: None, prims };
    }
    let ctx = Ctx { boxes, centroids };
    let (bounds, cb) = bounds_of(&ctx, &prims);
    let root = build_node(&ctx, &mut prims, 0, bounds, cb, 0);
    Bvh2 {
        root: Some(root),
        prims,
    }
}

/// Bounds of the primitives and of their centroids.
fn bounds_of(ctx: &Ctx, prims: &[u32]) -> (Aabb, Aabb) {
    let serial = |prims: &[u32]| {
        let mut b = Aabb::EMPTY;
        let mut c = Aabb::EMPTY;
        for &p in prims {
            b = b.union(ctx.boxes[p as usize]);
            c.grow(ctx.centroids[p as usize]);
        }
        (b, c)
    };
    if prims.len() < PARALLEL_BIN {
        return serial(prims);
    }
    prims.par_chunks(8192).map(serial).reduce(
        || (Aabb::EMPTY, Aabb::EMPTY),
        |a, b| (a.0.union(b.0), a.1.union(b.1)),
    )
}

fn fill_bins(ctx: &Ctx, prims: &[u32], binning: &Binning) -> Bins {
    let serial = |prims: &[u32]| {
        let mut bins = [[EMPTY_BIN; BINS]; 3];
        for &p in prims {
            let c = ctx.centroids[p as usize];
            let b = ctx.boxes[p as usize];
            for (axis, axis_bins) in bins.iter_mut().enumerate() {
                let bin = &mut axis_bins[binning.bin(c, axis)];
                bin.bounds = bin.bounds.union(b);
                bin.count += 1;
            }
        }
        bins
    };
    if prims.len() < PARALLEL_BIN {
        return serial(prims);
    }
    prims.par_chunks(8192).map(serial).reduce(
        || [[EMPTY_BIN; BINS]; 3],
        |mut a, b| {
            for (x, y) in a.iter_mut().flatten().zip(b.iter().flatten()) {
                x.bounds = x.bounds.union(y.bounds);
                x.count += y.count;
            }
            a
        },
    )
}

/// A split: primitives whose centroid falls in a bin below `pos` along `axis` go left.
struct Split {
    axis: usize,
    pos: usize,
    /// SAH cost relative to the node's area.
    cost: f64,
    binning: Binning,
}

/// The SAH split of least cost.
fn find_split(ctx: &Ctx, prims: &[u32], bounds: &Aabb, cb: &Aabb) -> Option<Split> {
    let ext = cb.max.as_dvec3() - cb.min.as_dvec3();
    let mut binning = Binning {
        lo: cb.min.as_dvec3().to_array(),
        scale: [0.0; 3],
    };
    let mut any = false;
    for axis in 0..3 {
        if ext[axis] > 0.0 {
            binning.scale[axis] = BINS as f64 / ext[axis];
            any = true;
        }
    }
    if !any {
        return None;
    }
    let bins = fill_bins(ctx, prims, &binning);
    let area = bounds.half_area();
    let inv_area = if area > 0.0 { 1.0 / area } else { 1.0 };
    let mut best: Option<(usize, usize, f64)> = None;
    for (axis, b) in bins.iter().enumerate() {
        if binning.scale[axis] == 0.0 {
            continue;
        }
        // Right-side areas and counts for splits at 1..BINS.
        let mut right_area = [0.0f64; BINS];
        let mut right_count = [0usize; BINS];
        let mut acc = Aabb::EMPTY;
        let mut n = 0usize;
        for i in (1..BINS).rev() {
            acc = acc.union(b[i].bounds);
            n += b[i].count as usize;
            right_area[i] = acc.half_area();
            right_count[i] = n;
        }
        let mut acc = Aabb::EMPTY;
        let mut n = 0usize;
        for i in 1..BINS {
            acc = acc.union(b[i - 1].bounds);
            n += b[i - 1].count as usize;
            if n == 0 || right_count[i] == 0 {
                continue;
            }
            let cost = TRAVERSAL_COST
                + PACKET_COST
                    * (acc.half_area() * blocks(n) + right_area[i] * blocks(right_count[i]))
                    * inv_area;
            if best.is_none_or(|(_, _, c)| cost < c) {
                best = Some((axis, i, cost));
            }
        }
    }
    best.map(|(axis, pos, cost)| Split {
        axis,
        pos,
        cost,
        binning,
    })
}

/// Moves the primitives for which `left` holds to the front; returns their count.
fn partition(prims: &mut [u32], left: impl Fn(u32) -> bool) -> usize {
    let mut i = 0;
    for j in 0..prims.len() {
        if left(prims[j]) {
            prims.swap(i, j);
            i += 1;
        }
    }
    i
}

fn build_node(
    ctx: &Ctx,
    prims: &mut [u32],
    first: u32,
    bounds: Aabb,
    cb: Aabb,
    depth: u32,
) -> Node2 {
    let n = prims.len();
    let leaf = Node2::Leaf {
        bounds,
        first,
        count: n as u32,
    };
    // A leaf of up to four is one packet test, which no split can beat.
    if n <= 4 {
        return leaf;
    }
    let split = if depth < SAH_MAX_DEPTH {
        find_split(ctx, prims, &bounds, &cb)
    } else {
        None
    };
    let mid = match split {
        Some(s) => {
            if n <= MAX_LEAF && blocks(n) * PACKET_COST <= s.cost {
                return leaf;
            }
            // The same bin function as the binning, so both sides are non-empty.
            partition(prims, |p| {
                s.binning.bin(ctx.centroids[p as usize], s.axis) < s.pos
            })
        }
        None => {
            if n <= MAX_LEAF {
                return leaf;
            }
            // All centroids equal, or too deep: split at the median along the widest
            // centroid axis (by index when the centroids coincide).
            let ext = cb.max - cb.min;
            let axis = if ext.x >= ext.y && ext.x >= ext.z {
                0
            } else if ext.y >= ext.z {
                1
            } else {
                2
            };
            let mid = n / 2;
            if ext[axis] > 0.0 {
                prims.select_nth_unstable_by(mid, |&a, &b| {
                    let ca = ctx.centroids[a as usize][axis];
                    let cb = ctx.centroids[b as usize][axis];
                    ca.total_cmp(&cb).then(a.cmp(&b))
                });
            }
            mid
        }
    };
    debug_assert!(mid > 0 && mid < n);
    let (left, right) = prims.split_at_mut(mid);
    let (lb, lcb) = bounds_of(ctx, left);
    let (rb, rcb) = bounds_of(ctx, right);
    let rfirst = first + mid as u32;
    let (l, r) = if n >= PARALLEL_SPLIT {
        rayon::join(
            || build_node(ctx, left, first, lb, lcb, depth + 1),
            || build_node(ctx, right, rfirst, rb, rcb, depth + 1),
        )
    } else {
        (
            build_node(ctx, left, first, lb, lcb, depth + 1),
            build_node(ctx, right, rfirst, rb, rcb, depth + 1),
        )
    };
    Node2::Inner {
        bounds,
        children: Box::new([l, r]),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check(node: &Node2, prims: &[u32], boxes: &[Aabb], depth: u32, max_depth: &mut u32) {
        *max_depth = (*max_depth).max(depth);
        match node {
            Node2::Leaf {
                bounds,
                first,
                count,
            } => {
                assert!(*count as usize <= MAX_LEAF && *count > 0);
                for &p in &prims[*first as usize..(*first + *count) as usize] {
                    assert_eq!(bounds.union(boxes[p as usize]), *bounds);
                }
            }
            Node2::Inner { bounds, children } => {
                for c in children.iter() {
                    assert_eq!(bounds.union(*c.bounds()), *bounds);
                    check(c, prims, boxes, depth + 1, max_depth);
                }
            }
        }
    }

    fn boxes_of(points: &[Vec3]) -> (Vec<Aabb>, Vec<Vec3>) {
        let boxes: Vec<Aabb> = points
            .iter()
            .map(|&p| Aabb::of_triangle(&[p, p + Vec3::X * 0.01, p + Vec3::Y * 0.01]))
            .collect();
        let centroids = boxes.iter().map(Aabb::center).collect();
        (boxes, centroids)
    }

    #[test]
    fn equal_centroids_split_by_index() {
        let (boxes, centroids) = boxes_of(&vec![Vec3::ONE; 1000]);
        let bvh = build(&boxes, &centroids, (0..1000).collect());
        let mut depth = 0;
        check(
            bvh.root.as_ref().unwrap(),
            &bvh.prims,
            &boxes,
            0,
            &mut depth,
        );
        assert!(depth <= 10, "{depth}");
        let mut sorted = bvh.prims.clone();
        sorted.sort();
        assert_eq!(sorted, (0..1000).collect::<Vec<_>>());
    }

    #[test]
    fn exponential_spacing_stays_shallow() {
        let pts: Vec<Vec3> = (0..3000)
            .map(|i| Vec3::new(1.02f32.powi(i), 0.0, 0.0))
            .collect();
        let (boxes, centroids) = boxes_of(&pts);
        let bvh = build(&boxes, &centroids, (0..3000).collect());
        let mut depth = 0;
        check(
            bvh.root.as_ref().unwrap(),
            &bvh.prims,
            &boxes,
            0,
            &mut depth,
        );
        assert!(depth <= SAH_MAX_DEPTH + 32, "{depth}");
    }

    #[test]
    fn deterministic_across_thread_counts() {
        let pts: Vec<Vec3> = (0..50_000u32)
            .map(|i| {
                let h = i.wrapping_mul(2654435761);
                Vec3::new(
                    (h % 1000) as f32,
                    ((h >> 10) % 1000) as f32,
                    (i % 97) as f32,
                )
            })
            .collect();
        let (boxes, centroids) = boxes_of(&pts);
        let run = |threads| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| build(&boxes, &centroids, (0..50_000).collect()))
        };
        let a = run(1);
        let b = run(4);
        assert_eq!(a.prims, b.prims);
        assert_eq!(format!("{:?}", a.root), format!("{:?}", b.root));
    }
}
