//! [`NativeBvh`]: pathlight's own ray tracing backend.

use std::time::Instant;

use glam::DVec3;
use rayon::prelude::*;

use crate::bvh::aabb::Aabb;
use crate::bvh::packet;
pub use crate::bvh::packet::PACKET;
use crate::bvh::wide::{Node, WIDTH};
use crate::bvh::{build, traverse, wide};
use crate::geometry::SceneTriangles;
use crate::ray::{Hit, Ray};
#[cfg(target_arch = "x86_64")]
use crate::simd::{Avx8, Sse4};
use crate::simd::{Pair, Scalar4};
use crate::triangle::TriPacket;
use crate::Accel;

/// The instruction set the traversal runs with, chosen at build time.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Isa {
    /// Portable code on `[f32; 4]` (every target).
    Scalar,
    /// 4-wide SSE (x86_64 baseline): node boxes in two halves, triangles four at a time.
    Sse2,
    /// 8-wide AVX node boxes, 4-wide triangle tests, all compiled with AVX2 enabled (VEX
    /// encoding); x86_64 with AVX2.
    Avx2,
}

impl Isa {
    /// The fastest instruction set this CPU supports.
    pub fn best() -> Isa {
        #[cfg(target_arch = "x86_64")]
        {
            if is_x86_feature_detected!("avx2") {
                return Isa::Avx2;
            }
            Isa::Sse2
        }
        #[cfg(not(target_arch = "x86_64"))]
        Isa::Scalar
    }

    pub fn is_supported(self) -> bool {
        match self {
            Isa::Scalar => true,
            #[cfg(target_arch = "x86_64")]
            Isa::Sse2 => true,
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2 => is_x86_feature_detected!("avx2"),
            #[cfg(not(target_arch = "x86_64"))]
            _ => false,
        }
    }

    /// Every instruction set this CPU supports.
    pub fn supported() -> Vec<Isa> {
        [Isa::Scalar, Isa::Sse2, Isa::Avx2]
            .into_iter()
            .filter(|i| i.is_supported())
            .collect()
    }

    pub fn name(self) -> &'static str {
        match self {
            Isa::Scalar => "scalar",
            Isa::Sse2 => "sse2",
            Isa::Avx2 => "avx2",
        }
    }
}

/// What the build produced and how long it took.
#[derive(Debug, Clone, PartialEq)]
pub struct BuildStats {
    /// Triangles in the structure.
    pub triangles: usize,
    /// Zero-area input triangles left out (no ray can hit them).
    pub degenerate: usize,
    /// Wide nodes (eight children each).
    pub nodes: usize,
    pub leaves: usize,
    /// Packets of four triangles (leaves pad the last one).
    pub packets: usize,
    /// Depth of the wide tree (the root is depth 0).
    pub depth: u32,
    /// Surface area heuristic cost of the tree, in packet tests per ray hitting the root box
    /// (node visits cost 1, packet tests 1).
    pub sah_cost: f64,
    pub build_seconds: f64,
    pub memory_bytes: usize,
    pub isa: Isa,
}

impl std::fmt::Display for BuildStats {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "native BVH{} ({}): {} triangles ({} degenerate left out), {} nodes, {} leaves, \
             {} packets, depth {}, SAH cost {:.2}, {:.1} ms, {:.1} MiB",
            WIDTH,
            self.isa.name(),
            self.triangles,
            self.degenerate,
            self.nodes,
            self.leaves,
            self.packets,
            self.depth,
            self.sah_cost,
            self.build_seconds * 1e3,
            self.memory_bytes as f64 / (1024.0 * 1024.0),
        )
    }
}

/// An 8-wide BVH over a scene's world-space triangles, traversed with SIMD.
pub struct NativeBvh {
    nodes: Vec<Node<WIDTH>>,
    packets: Vec<TriPacket>,
    ids: Vec<(u32, u32)>,
    isa: Isa,
    stats: BuildStats,
}

/// True when the triangle has zero area (its edge vectors are parallel, computed in f64).
fn is_degenerate(t: &[glam::Vec3; 3]) -> bool {
    let [a, b, c] = t.map(|p| p.as_dvec3());
    let n: DVec3 = (b - a).cross(c - a);
    n == DVec3::ZERO || !n.is_finite() || !t.iter().all(|p| p.is_finite())
}

impl NativeBvh {
    /// Builds with the fastest instruction set of this CPU.
    pub fn new(triangles: &SceneTriangles) -> Self {
        Self::with_isa(triangles, Isa::best())
    }

    /// Builds for a given instruction set (the best supported one if `isa` isn't).
    pub fn with_isa(triangles: &SceneTriangles, isa: Isa) -> Self {
        let start = Instant::now();
        let isa = if isa.is_supported() { isa } else { Isa::best() };
        let corners = &triangles.corners;
        let boxes: Vec<Aabb> = corners.par_iter().map(Aabb::of_triangle).collect();
        let centroids: Vec<glam::Vec3> = boxes.par_iter().map(Aabb::center).collect();
        let prims: Vec<u32> = (0..corners.len() as u32)
            .into_par_iter()
            .filter(|&i| !is_degenerate(&corners[i as usize]))
            .collect();
        let kept = prims.len();
        let bvh2 = build::build(&boxes, &centroids, prims);
        let w = wide::collapse::<WIDTH>(&bvh2, corners);
        drop(bvh2);
        let mut bvh = NativeBvh {
            stats: BuildStats {
                triangles: kept,
                degenerate: corners.len() - kept,
                nodes: w.nodes.len(),
                leaves: w.leaves,
                packets: w.packets.len(),
                depth: w.depth,
                sah_cost: w.sah_cost,
                build_seconds: 0.0,
                memory_bytes: 0,
                isa,
            },
            nodes: w.nodes,
            packets: w.packets,
            ids: triangles.ids.clone(),
            isa,
        };
        bvh.stats.memory_bytes = bvh.memory_bytes();
        bvh.stats.build_seconds = start.elapsed().as_secs_f64();
        bvh
    }

    pub fn stats(&self) -> &BuildStats {
        &self.stats
    }

    pub fn isa(&self) -> Isa {
        self.isa
    }

    /// The closest hits of eight rays traced together as one packet: exactly the hits
    /// [`intersect`](Accel::intersect) gives each ray, found with one traversal. `None` when
    /// the rays are not coherent enough to share one: they must share the dominant axis of
    /// their directions and the sign of every direction component (camera rays of
    /// neighbouring pixels nearly always do), and have non-zero, finite directions.
    pub fn intersect_packet(&self, rays: &[Ray; PACKET]) -> Option<[Option<Hit>; PACKET]> {
        let (n, p) = (&self.nodes[..], &self.packets[..]);
        let mut out = [None; PACKET];
        let traced = match self.isa {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `Isa::Avx2` is only chosen when the CPU reports AVX2 (`with_isa`).
            Isa::Avx2 => unsafe { avx2::closest_packet(n, p, rays, &mut out) },
            #[cfg(target_arch = "x86_64")]
            Isa::Sse2 => packet::closest::<Pair<Sse4>, Sse4>(n, p, rays, &mut out),
            _ => packet::closest::<Pair<Scalar4>, Scalar4>(n, p, rays, &mut out),
        };
        traced.then(|| out.map(|r| self.hit(r)))
    }

    #[inline]
    fn hit(&self, r: Option<(u32, f32, f32, f32)>) -> Option<Hit> {
        r.map(|(id, t, u, v)| {
            let (instance, triangle) = self.ids[id as usize];
            Hit {
                t,
                u,
                v,
                instance,
                triangle,
            }
        })
    }
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use super::*;

    // The generic traversal is `#[inline(always)]` all the way down, so it is compiled here
    // with AVX2 enabled.
    #[target_feature(enable = "avx2")]
    pub(super) fn closest(
        nodes: &[Node<WIDTH>],
        packets: &[TriPacket],
        ray: &Ray,
    ) -> Option<(u32, f32, f32, f32)> {
        traverse::closest::<WIDTH, Avx8, Sse4>(nodes, packets, ray)
    }

    #[target_feature(enable = "avx2")]
    pub(super) fn closest_packet(
        nodes: &[Node<WIDTH>],
        packets: &[TriPacket],
        rays: &[Ray; PACKET],
        out: &mut [Option<(u32, f32, f32, f32)>; PACKET],
    ) -> bool {
        packet::closest::<Avx8, Sse4>(nodes, packets, rays, out)
    }

    #[target_feature(enable = "avx2")]
    pub(super) fn occluded(nodes: &[Node<WIDTH>], packets: &[TriPacket], ray: &Ray) -> bool {
        traverse::occluded::<WIDTH, Avx8, Sse4>(nodes, packets, ray)
    }
}

impl Accel for NativeBvh {
    fn name(&self) -> &'static str {
        "native"
    }

    #[inline]
    fn intersect(&self, ray: &Ray) -> Option<Hit> {
        let (n, p) = (&self.nodes[..], &self.packets[..]);
        let r = match self.isa {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `Isa::Avx2` is only chosen when the CPU reports AVX2 (`with_isa`).
            Isa::Avx2 => unsafe { avx2::closest(n, p, ray) },
            #[cfg(target_arch = "x86_64")]
            Isa::Sse2 => traverse::closest::<WIDTH, Pair<Sse4>, Sse4>(n, p, ray),
            _ => traverse::closest::<WIDTH, Pair<Scalar4>, Scalar4>(n, p, ray),
        };
        self.hit(r)
    }

    /// Eight rays at a time as packets where they are coherent enough (see
    /// [`intersect_packet`](NativeBvh::intersect_packet)), one by one elsewhere; the hits are
    /// the same either way.
    fn intersect_batch(&self, rays: &[Ray], hits: &mut [Option<Hit>]) {
        for (rays, hits) in rays.chunks(PACKET).zip(hits.chunks_mut(PACKET)) {
            let packet = <&[Ray; PACKET]>::try_from(rays)
                .ok()
                .and_then(|rays| self.intersect_packet(rays));
            match packet {
                Some(packet) => hits.copy_from_slice(&packet),
                None => {
                    for (r, h) in rays.iter().zip(hits.iter_mut()) {
                        *h = self.intersect(r);
                    }
                }
            }
        }
    }

    #[inline]
    fn occluded(&self, ray: &Ray) -> bool {
        let (n, p) = (&self.nodes[..], &self.packets[..]);
        match self.isa {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `Isa::Avx2` is only chosen when the CPU reports AVX2 (`with_isa`).
            Isa::Avx2 => unsafe { avx2::occluded(n, p, ray) },
            #[cfg(target_arch = "x86_64")]
            Isa::Sse2 => traverse::occluded::<WIDTH, Pair<Sse4>, Sse4>(n, p, ray),
            _ => traverse::occluded::<WIDTH, Pair<Scalar4>, Scalar4>(n, p, ray),
        }
    }

    fn memory_bytes(&self) -> usize {
        self.nodes.len() * std::mem::size_of::<Node<WIDTH>>()
            + self.packets.len() * std::mem::size_of::<TriPacket>()
            + self.ids.len() * std::mem::size_of::<(u32, u32)>()
    }
}
