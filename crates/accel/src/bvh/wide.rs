//! The wide BVH the traversal runs on, collapsed from the binary one.
//!
//! A [`Node`] holds its `W` children's boxes in structure-of-arrays layout (one `[f32; W]` per
//! bound and axis, ready for one SIMD register, or two SSE ones when `W = 8`) and their codes. A child code is either a
//! node index, or a leaf: bit 31 set, the number of triangle packets in bits 28..31 and the
//! first packet in bits 0..28. Unused child slots hold an inverted (empty) box, which no ray
//! hits, and a leaf code with no packets.

use glam::Vec3;

use super::aabb::Aabb;
use super::build::{blocks, Bvh2, Node2, PACKET_COST, TRAVERSAL_COST};
use crate::triangle::TriPacket;

pub(crate) const LEAF_BIT: u32 = 1 << 31;
const COUNT_SHIFT: u32 = 28;
const FIRST_MASK: u32 = (1 << COUNT_SHIFT) - 1;
/// The code of an unused child slot.
pub(crate) const EMPTY_CHILD: u32 = LEAF_BIT;

/// The branching factor of the native BVH.
pub(crate) const WIDTH: usize = 8;

/// `W` children: `b[2 * axis + 0]` their minima along `axis`, `b[2 * axis + 1]` their maxima.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
pub(crate) struct Node<const W: usize> {
    pub b: [[f32; W]; 6],
    pub child: [u32; W],
}

impl<const W: usize> Node<W> {
    const EMPTY: Self = Node {
        b: [
            [f32::INFINITY; W],
            [f32::NEG_INFINITY; W],
            [f32::INFINITY; W],
            [f32::NEG_INFINITY; W],
            [f32::INFINITY; W],
            [f32::NEG_INFINITY; W],
        ],
        child: [EMPTY_CHILD; W],
    };

    fn set(&mut self, slot: usize, bounds: &Aabb, code: u32) {
        for axis in 0..3 {
            self.b[2 * axis][slot] = bounds.min[axis];
            self.b[2 * axis + 1][slot] = bounds.max[axis];
        }
        self.child[slot] = code;
    }
}

#[inline(always)]
pub(crate) fn leaf_range(code: u32) -> (usize, usize) {
    (
        (code & FIRST_MASK) as usize,
        ((code & !LEAF_BIT) >> COUNT_SHIFT) as usize,
    )
}

fn leaf_code(first: usize, count: usize) -> u32 {
    assert!(
        first <= FIRST_MASK as usize && count < 8,
        "too many triangles for the native BVH (at most 2^30)"
    );
    LEAF_BIT | (count as u32) << COUNT_SHIFT | first as u32
}

/// The wide BVH with its triangles.
pub(crate) struct Wide<const W: usize> {
    /// `nodes[0]` is the root.
    pub nodes: Vec<Node<W>>,
    pub packets: Vec<TriPacket>,
    pub leaves: usize,
    pub depth: u32,
    /// SAH cost of the tree (node visits cost [`TRAVERSAL_COST`], packet tests
    /// [`PACKET_COST`]), for rays hitting the root's box.
    pub sah_cost: f64,
}

struct Collapser<'a, const W: usize> {
    prims: &'a [u32],
    corners: &'a [[Vec3; 3]],
    nodes: Vec<Node<W>>,
    packets: Vec<TriPacket>,
    leaves: usize,
    depth: u32,
    weighted_cost: f64,
}

/// Collapses `bvh` (over indices into `corners`) into a `W`-wide BVH; packet lanes carry the
/// indices.
pub(crate) fn collapse<const W: usize>(bvh: &Bvh2, corners: &[[Vec3; 3]]) -> Wide<W> {
    let mut c = Collapser {
        prims: &bvh.prims,
        corners,
        nodes: Vec::new(),
        packets: Vec::with_capacity(bvh.prims.len().div_ceil(3)),
        leaves: 0,
        depth: 0,
        weighted_cost: 0.0,
    };
    let mut root_area = 0.0;
    match &bvh.root {
        None => c.nodes.push(Node::EMPTY),
        Some(leaf @ Node2::Leaf { bounds, .. }) => {
            root_area = bounds.half_area();
            c.nodes.push(Node::EMPTY);
            c.weighted_cost += TRAVERSAL_COST * root_area;
            let code = c.emit(leaf, 1);
            c.nodes[0].set(0, bounds, code);
        }
        Some(root) => {
            root_area = root.bounds().half_area();
            c.emit(root, 0);
        }
    }
    let sah_cost = if root_area > 0.0 {
        c.weighted_cost / root_area
    } else {
        0.0
    };
    Wide {
        nodes: c.nodes,
        packets: c.packets,
        leaves: c.leaves,
        depth: c.depth,
        sah_cost,
    }
}

impl<const W: usize> Collapser<'_, W> {
    /// Emits `node` and its subtree; returns its child code.
    fn emit(&mut self, node: &Node2, depth: u32) -> u32 {
        self.depth = self.depth.max(depth);
        match node {
            Node2::Leaf {
                bounds,
                first,
                count,
            } => {
                let ids = &self.prims[*first as usize..(*first + *count) as usize];
                let start = self.packets.len();
                for chunk in ids.chunks(4) {
                    let tris: Vec<([Vec3; 3], u32)> = chunk
                        .iter()
                        .map(|&p| (self.corners[p as usize], p))
                        .collect();
                    self.packets.push(TriPacket::new(&tris));
                }
                self.leaves += 1;
                self.weighted_cost += PACKET_COST * blocks(ids.len()) * bounds.half_area();
                leaf_code(start, self.packets.len() - start)
            }
            Node2::Inner { bounds, children } => {
                // Open the largest inner child until there are `W`.
                let mut kids: Vec<&Node2> = vec![&children[0], &children[1]];
                while kids.len() < W {
                    let widest = kids
                        .iter()
                        .enumerate()
                        .filter(|(_, k)| matches!(k, Node2::Inner { .. }))
                        .max_by(|a, b| {
                            a.1.bounds()
                                .half_area()
                                .total_cmp(&b.1.bounds().half_area())
                        })
                        .map(|(i, _)| i);
                    let Some(i) = widest else { break };
                    let Node2::Inner { children, .. } = kids[i] else {
                        unreachable!()
                    };
                    kids[i] = &children[0];
                    kids.insert(i + 1, &children[1]);
                }
                let index = self.nodes.len();
                self.nodes.push(Node::EMPTY);
                self.weighted_cost += TRAVERSAL_COST * bounds.half_area();
                for (slot, kid) in kids.into_iter().enumerate() {
                    let code = self.emit(kid, depth + 1);
                    self.nodes[index].set(slot, kid.bounds(), code);
                }
                index as u32
            }
        }
    }
}
