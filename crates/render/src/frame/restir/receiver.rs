//! A first hit as the reservoirs see it ([`Receiver`]): its target function over light
//! samples (one by one or in lanes), their visibility and its shading by a reservoir.

use glam::Vec3;
use pathlight_core::color::luminance;
use pathlight_core::rng::Rng;

use crate::bsdf::{Bsdf, BsdfAt};
use crate::light::{LightPoint, LightSample, Lights};
use crate::path::{PathTracer, Vertex};
use crate::surface::Surface;

use super::pool::{Block, LightPool, LANES};
use super::reservoir::Reservoir;

/// A first-hit surface as the reservoirs see it: where light is received and how it is
/// reflected toward the camera.
#[derive(Debug, Clone, Copy)]
pub struct Receiver {
    pub surface: Surface,
    pub bsdf: Bsdf,
    /// The BSDF seen from `wo` (its per-`wo` terms, computed once).
    pub at: BsdfAt,
    /// Unit direction toward the camera.
    pub wo: Vec3,
    /// Light from behind the surface counts (transmission).
    pub transmits: bool,
}

/// A light sample as a receiver sees it.
#[derive(Debug, Clone, Copy)]
pub struct Received {
    /// `f cos L`: the unshadowed integrand in solid angle.
    pub radiance: Vec3,
    /// The target function in the light point's measure (`lum(f cos L) G`).
    pub target: f32,
    pub light: LightSample,
}

impl Receiver {
    /// The receiver of first hit `v`, seen along `ray_dir`; `None` for surfaces next event
    /// estimation does not light (delta BSDFs).
    pub fn new(tracer: &PathTracer, v: &Vertex, ray_dir: Vec3) -> Option<Self> {
        let bsdf = tracer.world.bsdf(v.surface.material, &v.shading.params);
        (!bsdf.is_delta()).then(|| {
            Self::with(
                v.surface,
                bsdf,
                -ray_dir,
                v.shading.params.transmission > 0.0,
            )
        })
    }

    /// The receiver at `surface` with `bsdf`, seen from `wo` (unit, toward the viewer).
    pub fn with(surface: Surface, bsdf: Bsdf, wo: Vec3, transmits: bool) -> Self {
        Self {
            at: bsdf.at(surface.to_local(wo)),
            surface,
            bsdf,
            wo,
            transmits,
        }
    }

    /// Light point `point` as this receiver sees it (unshadowed); `None` where it brings
    /// nothing.
    #[inline]
    pub fn receive(&self, lights: &Lights, point: &LightPoint) -> Option<Received> {
        let s = &self.surface;
        let (ls, g) = lights.evaluate_geometry(s.p, point)?;
        let same_side = ls.wi.dot(s.ng) * self.wo.dot(s.ng) > 0.0;
        if !(same_side || self.transmits) {
            return None;
        }
        let wi_local = s.to_local(ls.wi);
        let f = self.bsdf.eval_at(&self.at, wi_local);
        let radiance = f * wi_local.z.abs() * ls.radiance;
        let target = luminance(radiance) * g;
        (target > 0.0 && target.is_finite()).then_some(Received {
            radiance,
            target,
            light: ls,
        })
    }

    /// Resampled importance sampling of `count` candidates from the frame's `pool` (whole
    /// blocks of it, see [`pool`]) by their target here, in SIMD lanes compiled
    /// for AVX-512 or AVX2 where the processor has them.
    pub fn candidates(
        &self,
        pool: &LightPool,
        lights: &Lights,
        count: u32,
        rng: &mut Rng,
    ) -> Reservoir {
        if !self.bsdf.has_lanes() {
            return self.candidates_one_by_one(pool, lights, count, rng);
        }
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx512f") {
                // SAFETY: the processor has AVX-512, checked just above.
                return unsafe { self.candidates_avx512(pool, lights, count, rng) };
            }
            if std::arch::is_x86_feature_detected!("avx2") {
                // SAFETY: the processor has AVX2, checked just above.
                return unsafe { self.candidates_avx2(pool, lights, count, rng) };
            }
        }
        self.candidates_in_lanes(pool, lights, count, rng)
    }

    /// [`candidates`](Self::candidates) with each target computed by [`target`](Self::target):
    /// the reference, and the path for BSDFs without lanes.
    pub fn candidates_one_by_one(
        &self,
        pool: &LightPool,
        lights: &Lights,
        count: u32,
        rng: &mut Rng,
    ) -> Reservoir {
        self.resample_blocks::<false>(pool, lights, count, rng)
    }

    /// [`candidates`](Self::candidates) with the targets of a block's point lights,
    /// triangles and distant lights computed together in a loop without branches, which the compiler turns into
    /// SIMD lanes (`block_targets`), the other lights one by one; for
    /// the build's baseline instructions.
    pub fn candidates_in_lanes(
        &self,
        pool: &LightPool,
        lights: &Lights,
        count: u32,
        rng: &mut Rng,
    ) -> Reservoir {
        self.resample_blocks::<true>(pool, lights, count, rng)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f")]
    pub(super) fn candidates_avx512(
        &self,
        pool: &LightPool,
        lights: &Lights,
        count: u32,
        rng: &mut Rng,
    ) -> Reservoir {
        self.resample_blocks::<true>(pool, lights, count, rng)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    pub(super) fn candidates_avx2(
        &self,
        pool: &LightPool,
        lights: &Lights,
        count: u32,
        rng: &mut Rng,
    ) -> Reservoir {
        self.resample_blocks::<true>(pool, lights, count, rng)
    }

    /// The target function here of the first `n` of `points` (0 for the others), in lanes as
    /// [`candidates`](Self::candidates) computes them. Not inlined: inlined into the
    /// combination, it made the temporal pass, which never calls it, 1.7 ms slower.
    #[inline(never)]
    pub fn point_targets<const N: usize>(
        &self,
        lights: &Lights,
        points: &[LightPoint; N],
        n: usize,
    ) -> [f32; N] {
        let block = Block::of(lights, points, n);
        if !self.bsdf.has_lanes() {
            return self.targets::<false, N>(lights, &block, points);
        }
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx512f") {
                // SAFETY: the processor has AVX-512, checked just above.
                return unsafe { self.point_targets_avx512(lights, &block, points) };
            }
            if std::arch::is_x86_feature_detected!("avx2") {
                // SAFETY: the processor has AVX2, checked just above.
                return unsafe { self.point_targets_avx2(lights, &block, points) };
            }
        }
        self.targets::<true, N>(lights, &block, points)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f")]
    pub(super) fn point_targets_avx512<const N: usize>(
        &self,
        lights: &Lights,
        block: &Block<N>,
        points: &[LightPoint; N],
    ) -> [f32; N] {
        self.targets::<true, N>(lights, block, points)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    pub(super) fn point_targets_avx2<const N: usize>(
        &self,
        lights: &Lights,
        block: &Block<N>,
        points: &[LightPoint; N],
    ) -> [f32; N] {
        self.targets::<true, N>(lights, block, points)
    }

    /// The targets of a block's lanes here: in SIMD lanes (`LANES_ON`) with the lights the
    /// lanes do not compute one by one, or all one by one.
    #[inline(always)]
    pub(super) fn targets<const LANES_ON: bool, const N: usize>(
        &self,
        lights: &Lights,
        block: &Block<N>,
        points: &[LightPoint; N],
    ) -> [f32; N] {
        let one = |k: usize| {
            if block.inv_density[k] > 0.0 {
                self.target(lights, &points[k])
            } else {
                0.0
            }
        };
        if !LANES_ON {
            return std::array::from_fn(one);
        }
        let mut targets = self.block_targets(block);
        let mut scalar = block.scalar;
        while scalar != 0 {
            let k = scalar.trailing_zeros() as usize;
            scalar &= scalar - 1;
            targets[k] = one(k);
        }
        targets
    }

    /// Streams `count` candidates, whole blocks of [`LANES`] picked at random from `pool`
    /// (the last block's first lanes only), through a reservoir ([`targets`](Self::targets)
    /// computing their target functions): each block is resampled on its own (one lane chosen in
    /// proportion to its weight), then merged into the reservoir with the block's weight sum,
    /// which picks every candidate with probability `w / w_sum` as streaming them one by
    /// one would, with three random numbers per block instead of one per candidate.
    #[inline(always)]
    pub(super) fn resample_blocks<const LANES_ON: bool>(
        &self,
        pool: &LightPool,
        lights: &Lights,
        count: u32,
        rng: &mut Rng,
    ) -> Reservoir {
        let mut r = Reservoir::default();
        if pool.is_empty() {
            r.m = count as f32;
            return r;
        }
        let mut left = count;
        while left > 0 {
            let n = left.min(LANES as u32) as usize;
            left -= n as u32;
            let (block, points) = pool.pick(rng.next_u32());
            let t = self.targets::<LANES_ON, LANES>(lights, block, points);
            // The weights' running sums (a weight that is not positive and finite counts 0).
            let mut prefix = [0.0f32; LANES];
            let mut sum = 0.0f32;
            let mut last = 0;
            for k in 0..LANES {
                let w = t[k] * block.inv_density[k];
                let valid = k < n && w > 0.0 && w.is_finite();
                sum += if valid { w } else { 0.0 };
                last = if valid { k } else { last };
                prefix[k] = sum;
            }
            // The first lane whose running sum exceeds u * sum (the last valid one if
            // rounding leaves none).
            let x = rng.next_f32() * sum;
            let below = prefix.iter().filter(|&&p| p <= x).count();
            let pick = below.min(last);
            if r.admit(sum, t[pick], n as f32, rng.next_f32()) {
                r.sample = points[pick];
            }
        }
        r.finish(r.m);
        r
    }

    /// The target function of a block's point lights, triangles and distant lights here, as
    /// [`target`](Self::target) computes it for each, in one loop without branches on the
    /// lanes: `lum(f e) |cos| a / d^2` to rounding, with `a` the range window of a point light
    /// or the cosine at a triangle; `lum(f |cos| e)` bit for bit for a distant light (the
    /// environment's direction, a directional light: the same arithmetic as `target`). Lanes
    /// of other lights get garbage (the caller replaces them).
    #[inline(always)]
    pub(super) fn block_targets<const N: usize>(&self, b: &Block<N>) -> [f32; N] {
        // Blocks without distant lights skip their arithmetic.
        if b.distant == 0 {
            self.block_targets_with::<false, N>(b)
        } else {
            self.block_targets_with::<true, N>(b)
        }
    }

    #[inline(always)]
    fn block_targets_with<const DISTANT: bool, const N: usize>(&self, b: &Block<N>) -> [f32; N] {
        let s = &self.surface;
        let wo_ng = self.wo.dot(s.ng);
        let mut out = [0.0; N];
        for (k, out) in out.iter_mut().enumerate() {
            let q = Vec3::new(b.q[0][k], b.q[1][k], b.q[2][k]);
            let e = Vec3::new(b.e[0][k], b.e[1][k], b.e[2][k]);
            let n = Vec3::new(b.n[0][k], b.n[1][k], b.n[2][k]);
            let distant = DISTANT && b.distant & (1 << k) != 0;
            let to = q - s.p;
            let d2 = to.length_squared();
            let d = d2.sqrt();
            let inv_d = 1.0 / d;
            let wi = if distant { q } else { to * inv_d };
            let cos = -n.dot(wi);
            let cos = if b.two_sided[k] { cos.abs() } else { cos };
            let window = crate::light::range_window(d, b.inv_range[k]);
            let a = if b.triangle[k] { cos } else { window };
            let facing = wi.dot(s.ng) * wo_ng > 0.0 || self.transmits;
            let wi_local = s.to_local(wi);
            let f = self.bsdf.eval_lane(&self.at, wi_local);
            let cos_i = wi_local.z.abs();
            let mut target = luminance(f * e) * (cos_i * a * (inv_d * inv_d));
            let mut valid = d2 > 0.0 && d2.is_finite() && a > 0.0 && facing;
            if DISTANT {
                // As `receive` has it: `f |cos| L`, then its luminance times a geometry of 1.
                target = if distant {
                    luminance(f * cos_i * e)
                } else {
                    target
                };
                valid = if distant { facing } else { valid };
            }
            *out = if valid && target > 0.0 && target.is_finite() {
                target
            } else {
                0.0
            };
        }
        out
    }

    /// The target function of `point` here (0 where it brings nothing).
    #[inline]
    pub fn target(&self, lights: &Lights, point: &LightPoint) -> f32 {
        self.receive(lights, point).map_or(0.0, |r| r.target)
    }

    /// The shadow ray toward a received sample: the fraction of its light that arrives.
    #[inline]
    pub(super) fn visibility(&self, tracer: &PathTracer, r: &Received, rays: &mut u32) -> f32 {
        tracer.transmittance(&self.surface, r.light.wi, r.light.distance, rays)
    }

    /// `point` is visible (and lit) from here.
    #[inline]
    pub(super) fn sees(&self, tracer: &PathTracer, point: &LightPoint, rays: &mut u32) -> bool {
        self.receive(&tracer.world.lights, point)
            .is_some_and(|r| self.visibility(tracer, &r, rays) > 0.0)
    }

    /// The direct light the reservoir's sample brings here, shadow ray included.
    pub fn shade(&self, tracer: &PathTracer, r: &Reservoir, rays: &mut u32) -> Vec3 {
        if r.weight <= 0.0 {
            return Vec3::ZERO;
        }
        let lights = &tracer.world.lights;
        let Some(rec) = self.receive(lights, &r.sample) else {
            return Vec3::ZERO;
        };
        let tr = self.visibility(tracer, &rec, rays);
        if tr <= 0.0 {
            return Vec3::ZERO;
        }
        let g = rec.target / luminance(rec.radiance);
        rec.radiance * (g * r.weight * tr)
    }
}
