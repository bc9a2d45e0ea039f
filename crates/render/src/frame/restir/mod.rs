//! Seed 004: ReSTIR direct illumination at the first hit (Bitterli et al. 2020, as the thesis
//! builds it): resampled importance sampling of many light candidates into one reservoir per
//! pixel, reused across frames and neighbouring pixels, then shaded with one shadow ray.
//!
//! ```text
//! receivers   first hits (primary pass)               -> receivers (surface, BSDF, wo)
//! candidates  receivers, lights                       -> reservoirs (RIS over `candidates`
//!                                                        light samples; visibility reuse)
//! temporal    reservoirs, last frame's reservoirs and -> reservoirs
//!             receivers, motion vectors
//! spatial     reservoirs, receivers                   -> reservoirs (`iterations` rounds of
//!                                                        `neighbours` within `radius`)
//! shading     reservoirs, receivers                   -> the first hit's direct light, which
//!             (in the lighting pass)                     replaces next event estimation there
//! ```
//!
//! Choices the sources leave open, written down:
//! - **The domain.** A reservoir's sample is a point on a light ([`LightPoint`]): a point of an
//!   emissive triangle, a punctual light, or an environment direction. The target function
//!   and densities are measured in that point's own measure (area for triangles, counting
//!   for punctual lights, solid angle for the environment), so a sample moves between pixels
//!   without a Jacobian: target `p_hat(y) = lum(f cos L) G` with `G = cos_light / d^2` for
//!   triangles and 1 otherwise (unshadowed), source density [`Lights::point_pdf`] (selection
//!   by power or uniform, as `light_selection` says, then uniform by area).
//! - **Weights.** The reservoir's contribution weight is `W = w_sum / (Z p_hat(y))`. Biased
//!   mode: `Z` is the sum of the combined reservoirs' `M` (the paper's plain combination).
//!   Unbiased mode (the paper's Algorithm 6, "1/Z"): `Z` sums the `M` of only those combined
//!   reservoirs whose own pixel could have produced the sample, i.e. whose target there is
//!   positive and whose shadow ray to it is clear (one more shadow ray per reused reservoir).
//!   That count is exact only if every reservoir holds samples its own pixel sees, so the
//!   unbiased mode keeps that invariant: the candidates' survivor is always shadow-tested
//!   (visibility reuse, whatever `visibility_reuse` says), and a combined reservoir whose
//!   survivor its pixel does not see is emptied (`W = 0`; it would shade nothing there
//!   anyway). Without it, a sample a neighbour or an earlier frame saw but this pixel does not
//!   is counted out of `Z` while its weight stays in `w_sum`, and the temporal chain amplifies
//!   that by up to `m_cap` per frame (measured: weights growing without bound behind a
//!   blocker).
//!   MIS mode (`mis`, the paper's Section 4): each reservoir's sample is weighted by the
//!   generalised balance heuristic over the combined pixels' targets and `W = w_sum / p_hat`;
//!   with `unbiased` the targets include visibility (a shadow ray per pair), without it they
//!   do not (the paper's biased MIS).
//! - **Visibility reuse**: the survivor of the candidates is shadow-tested and its `W` set to
//!   0 when occluded, before any reuse.
//! - **Temporal reuse**: the previous frame's final reservoir at the pixel the motion vector
//!   points to (nearest pixel), kept when the previous surface lies within
//!   `depth_threshold x depth` of this one, the normals' cosine is at least
//!   `normal_threshold` and the albedos differ by at most [`ALBEDO_TOLERANCE`] in every
//!   channel; its `M` is capped at `m_cap` times the current `M` (0: no cap).
//! - **Spatial reuse**: neighbours uniform in a disk of `radius` pixels (the paper's pattern),
//!   taken as consecutive entries, from a random start, of a table of 1,024 offsets that
//!   follow the R2 sequence over the disk (RTXDI's neighbour table: a pixel's neighbours are
//!   spread over the disk instead of independent), the origin left out; a neighbour is
//!   rejected when off screen, on the sky, when their depth differs by more than
//!   `depth_threshold` relative to this pixel's, or their normals' cosine is below
//!   `normal_threshold`. Each iteration reads the previous iteration's reservoirs.
//! - **Which samples**: the frame's first sample of each pixel (the G-buffer's) is lit by its
//!   reservoir; with more samples per frame the others use next event estimation. Later
//!   bounces always use next event estimation. Emission that BSDF sampling reaches from the
//!   first hit through a non-delta lobe is left out (the reservoir has it), except from
//!   emitters the light list does not hold.
//! - **Candidates**: drawn from the frame's pool ([`pool`]): 16,384 light points drawn once
//!   per frame from the source density, in blocks of 16 that a pixel picks at random (the
//!   "light tiles" of Wyman and Panteleev 2021). Each candidate is still distributed as the
//!   source density; pixels that pick the same block share its candidates.
//! - **Randomness**: each pixel's candidates and resampling come from streams mixed from a
//!   hash of the seed and the pass, the pixel and its sample index, its neighbours' start in
//!   the offset table from a hash of the same, and the pool from the seed and the sample
//!   index, so frames do not depend on the thread count.
//! - **Speed**: a block's targets on point lights and emissive triangles are computed in one
//!   branch-free loop over its structure of arrays, which the compiler turns into SIMD lanes
//!   (AVX-512 or AVX2 chosen at run time), and so are the environment's directions and
//!   directional lights (the environment's radiance looked up once per pool entry instead of
//!   once per candidate); spot lights are evaluated one by one. A block is
//!   resampled on its own (one lane chosen by the prefix sums of its weights) and merged into
//!   the reservoir with its weight sum, three random numbers per block. The spatial pass
//!   evaluates a pixel's neighbours' samples together the same way, prefetches the neighbours
//!   of the pixel four ahead, and tests its neighbours on a 16-byte key per pixel (depth and
//!   normal) instead of the G-buffer pixel.
//! - **With seed 000**: the reservoirs are those of the pixels the frame traces (adaptive
//!   sampling's picks; an untraced pixel has none this frame, and its neighbours and the
//!   next frame find it empty); each pixel's first sample of the frame, whatever its own
//!   sample index, is lit by its reservoir, and the repair's extra samples (`fresh_spp`) use
//!   next event estimation. After a camera move a carried pixel draws fresh candidates like
//!   any other: forward reprojection carries its accumulated light (which holds the direct
//!   light its reservoirs gave in earlier frames), while the reservoirs' own temporal reuse
//!   follows the motion vectors as it does without reprojection. The pool and the pixels'
//!   streams are keyed by the frame's sample index in its epoch (`frames * spp`), not by a
//!   pixel's own count.
//! - **History** ([`Stage::start_epoch`]): the reservoirs survive camera moves (temporal
//!   reuse follows the motion vectors) and frames that do not accumulate; any other change of
//!   the settings, a reset or a new resolution forgets them.
//! - **Cost**: the pass costs far more than the GPU implementations' (BENCHMARKS.md, "Seed
//!   004").

use glam::{Vec2, Vec3};
use pathlight_core::prefetch::prefetch;
use pathlight_core::rng::{hash, mix64, Rng};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::error::ConfigError;
use crate::light::LightPoint;
use crate::path::PathTracer;

use super::gbuffer::{GBuffer, PrimaryHit};

use super::display::{View, ViewKind};
use super::gbuffer::GPixel;
use super::ping_pong::PingPong;
use super::stage::Stage;
use super::state::{Change, FrameState, Times};
use super::trace::{FirstHitLight, RUN};

/// Seed 004's passes: the reservoirs' candidates (with visibility reuse), temporal and
/// spatial reuse. The first is the stage's name (the menu's heading of its views).
pub const RESTIR: &str = "restir";
pub const RESTIR_TEMPORAL: &str = "restir temporal";
pub const RESTIR_SPATIAL: &str = "restir spatial";

/// Largest candidate count (the thesis's keys halve and double it within 1..1024).
pub const MAX_CANDIDATES: u32 = 1024;
/// Most neighbours per spatial iteration, and most iterations.
pub const MAX_NEIGHBOURS: u32 = 64;
pub const MAX_ITERATIONS: u32 = 16;
/// Temporal reuse: the largest difference of the albedos (per channel) of a pixel and its
/// previous surface.
pub const ALBEDO_TOLERANCE: f32 = 0.1;

/// Stream tags of the pixels' random numbers (candidates, temporal, spatial iterations).
const CANDIDATES_STREAM: u64 = 0x5e57_1d00;

/// Settings of ReSTIR DI (`[frame.restir]`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RestirConfig {
    pub enabled: bool,
    /// Light samples resampled into each pixel's reservoir (1..=1024).
    pub candidates: u32,
    /// Shadow-test the candidates' survivor before reuse.
    pub visibility_reuse: bool,
    pub temporal: bool,
    pub spatial: bool,
    /// Neighbours per spatial iteration.
    pub neighbours: u32,
    /// Spatial iterations.
    pub iterations: u32,
    /// Spatial radius in pixels.
    pub radius: f32,
    /// Relative depth difference above which a neighbour (or a previous surface) is rejected.
    pub depth_threshold: f32,
    /// Cosine of the normals below which a neighbour (or a previous surface) is rejected.
    pub normal_threshold: f32,
    /// The previous frame's `M` is capped at `m_cap` times the current `M` (0: no cap).
    pub m_cap: u32,
    /// The unbiased combination (1/Z with visibility) instead of the plain one.
    pub unbiased: bool,
    /// Combine with the paper's MIS weights (generalised balance heuristic, Section 4)
    /// instead of 1/M or 1/Z (with `unbiased`, their targets include visibility).
    pub mis: bool,
}

impl Default for RestirConfig {
    fn default() -> Self {
        Self {
            enabled: false,
            candidates: 32,
            visibility_reuse: true,
            temporal: true,
            spatial: true,
            neighbours: 4,
            iterations: 2,
            radius: 30.0,
            depth_threshold: 0.1,
            normal_threshold: 0.9,
            m_cap: 20,
            unbiased: false,
            mis: false,
        }
    }
}

impl RestirConfig {
    pub fn validate(&self) -> Result<(), ConfigError> {
        if !(1..=MAX_CANDIDATES).contains(&self.candidates) {
            return Err(ConfigError::new(
                "frame.restir.candidates",
                self.candidates,
                format!("between 1 and {MAX_CANDIDATES}"),
            ));
        }
        if self.neighbours > MAX_NEIGHBOURS {
            return Err(ConfigError::new(
                "frame.restir.neighbours",
                self.neighbours,
                format!("at most {MAX_NEIGHBOURS}"),
            ));
        }
        if self.iterations > MAX_ITERATIONS {
            return Err(ConfigError::new(
                "frame.restir.iterations",
                self.iterations,
                format!("at most {MAX_ITERATIONS}"),
            ));
        }
        if !(self.radius.is_finite() && self.radius >= 1.0 && self.radius <= 4096.0) {
            return Err(ConfigError::new(
                "frame.restir.radius",
                self.radius,
                "between 1 and 4096 pixels",
            ));
        }
        if !(self.depth_threshold.is_finite() && self.depth_threshold >= 0.0) {
            return Err(ConfigError::new(
                "frame.restir.depth_threshold",
                self.depth_threshold,
                "finite and >= 0",
            ));
        }
        if !(-1.0..=1.0).contains(&self.normal_threshold) {
            return Err(ConfigError::new(
                "frame.restir.normal_threshold",
                self.normal_threshold,
                "a cosine, between -1 and 1",
            ));
        }
        Ok(())
    }
}

/// ReSTIR's per-pixel state across frames.
#[derive(Debug, Default)]
pub struct Restir {
    /// This frame's reservoirs (after the spatial pass: the ones shading uses), and the
    /// previous frame's final ones (temporal reuse).
    pub reservoirs: PingPong<Reservoir>,
    /// Scratch for the spatial iterations.
    scratch: Vec<Reservoir>,
    /// This frame's surfaces as the spatial pass compares them.
    keys: Vec<Key>,
    /// This frame's receivers (`None`: sky or delta surface), and the previous frame's.
    pub receivers: PingPong<Option<Receiver>>,
    /// This frame's light candidates.
    pool: LightPool,
    /// The spatial pass's neighbour offsets ([`disk_offsets`]) and their radius.
    offsets: Vec<(i32, i32)>,
    offsets_radius: f32,
    /// The previous frame's G-buffer, for temporal reuse (a copy: the frame state owns the
    /// frame's).
    previous_gbuffer: Vec<GPixel>,
    /// The previous frame's state is usable (same resolution, same epoch's world).
    valid: bool,
}

/// What the ReSTIR passes did, for the frame report.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct RestirTimes {
    pub candidates_ms: f64,
    pub temporal_ms: f64,
    pub spatial_ms: f64,
    pub rays: u64,
}

/// A pass's hash mixed with a pixel's index: one mix per pixel.
#[derive(Debug, Clone, Copy)]
struct PixelHash(u64);

impl PixelHash {
    #[inline]
    fn of(self, pixel: usize) -> u64 {
        mix64(self.0 ^ pixel as u64)
    }
}

/// The random streams of the pixels in pass `pass` (0 candidates, 1 temporal, 2.. spatial
/// iterations) at sample index `index`, from the pass's hash of the seed.
#[derive(Debug, Clone, Copy)]
struct PixelStreams {
    pass: PixelHash,
    index: u64,
}

impl PixelStreams {
    fn new(seed: u64, pass: u64, index: u32) -> Self {
        Self {
            pass: PixelHash(hash(&[seed, CANDIDATES_STREAM + pass])),
            index: index as u64,
        }
    }

    #[inline]
    fn rng(&self, pixel: usize) -> Rng {
        Rng::new(self.pass.of(pixel), self.index)
    }
}

/// The receiver a reused reservoir from pixel `q` is combined with: `q`'s own where the
/// combination reads it (the unbiased count and the MIS weights; `None` when `q` has none),
/// else `here`, which the plain combination never reads (and `q`'s would be a cache miss).
#[inline]
fn other_receiver<'a>(
    config: &RestirConfig,
    receivers: &'a [Option<Receiver>],
    q: usize,
    here: &'a Receiver,
) -> Option<&'a Receiver> {
    if config.unbiased || config.mis {
        receivers[q].as_ref()
    } else {
        Some(here)
    }
}

/// Reused reservoirs whose targets are computed together (in SIMD lanes).
const NEIGHBOUR_LANES: usize = 8;

/// Stream tag of the spatial pass's neighbour choices.
const NEIGHBOURS_STREAM: u64 = 0x0ff5_e700;
/// The spatial pass prefetches the neighbours of the pixel this many ahead.
const AHEAD: usize = 4;

/// Neighbour offsets in the spatial pass's table ([`disk_offsets`]).
const OFFSETS: usize = 1024;

/// [`OFFSETS`] pixel offsets uniform in the disk of `radius` pixels, the origin left out: the
/// R2 sequence (Roberts 2018) mapped to the disk, so that consecutive entries, which a pixel
/// takes from a random start, are spread over it (as RTXDI's neighbour table does).
fn disk_offsets(radius: f32) -> Vec<(i32, i32)> {
    // 1 / g and 1 / g^2 for g the plastic number, the root of x^3 = x + 1.
    const A: (f64, f64) = (0.754_877_666_246_692_7, 0.569_840_290_998_053_3);
    let mut offsets = Vec::with_capacity(OFFSETS);
    let mut i = 0u64;
    while offsets.len() < OFFSETS {
        i += 1;
        let u = (0.5 + A.0 * i as f64).fract();
        let v = (0.5 + A.1 * i as f64).fract();
        let r = radius as f64 * u.sqrt();
        let phi = std::f64::consts::TAU * v;
        let (dx, dy) = (
            (r * phi.cos()).round() as i32,
            (r * phi.sin()).round() as i32,
        );
        if (dx, dy) != (0, 0) {
            offsets.push((dx, dy));
        }
    }
    offsets
}

/// What the spatial pass compares of a pixel's surface ([`similar`]): its depth (NaN for
/// the sky, which is similar to nothing) and normal, in 16 bytes where a G-buffer pixel takes
/// 64, so that the neighbours' random reads stay in cache.
#[derive(Debug, Clone, Copy, Default)]
struct Key {
    depth: f32,
    normal: Vec3,
}

impl Key {
    #[inline]
    fn of(g: &GPixel) -> Self {
        Self {
            depth: if g.is_sky() { f32::NAN } else { g.depth },
            normal: g.normal,
        }
    }
}

/// Surfaces close enough to share samples: relative depth and normal tests (false where
/// either is the sky: its NaN depth fails the first).
#[inline]
fn similar(a: &Key, b: &Key, config: &RestirConfig) -> bool {
    (a.depth - b.depth).abs() <= config.depth_threshold * a.depth
        && a.normal.dot(b.normal) >= config.normal_threshold
}

impl Restir {
    pub const VIEWS: &'static [View] = &[
        View {
            name: "reservoir-m",
            about: "the candidates behind each pixel's reservoir (M), as a heat map from 0 to \
                    the image's largest (dark grey: no reservoir)",
            kind: ViewKind::HeatOfLargest,
        },
        View {
            name: "reservoir-weight",
            about: "each reservoir's contribution weight W, as a heat map of its logarithm \
                    over the image's range (dark grey: W = 0, no sample or an occluded one)",
            kind: ViewKind::HeatOfLog,
        },
    ];

    /// Forgets the previous frame (a new epoch, or a resize).
    pub fn reset(&mut self) {
        self.valid = false;
    }

    /// The stage for a frame: its passes with `config`, its streams keyed by sample index
    /// `index` (the frame's in its epoch).
    pub fn frame<'a>(&'a mut self, config: &'a RestirConfig, index: u32) -> RestirFrame<'a> {
        RestirFrame {
            restir: self,
            config,
            index,
        }
    }

    /// Bytes held per pixel buffers.
    pub fn bytes(&self) -> usize {
        use std::mem::size_of;
        self.reservoirs.bytes()
            + self.scratch.capacity() * size_of::<Reservoir>()
            + self.receivers.bytes()
            + self.previous_gbuffer.capacity() * size_of::<GPixel>()
            + self.keys.capacity() * size_of::<Key>()
            + self.pool.bytes()
    }

    /// The candidates, temporal and spatial passes for a frame whose first hits (sample
    /// `index` of every pixel, by runs of `run` pixels) are `firsts` and G-buffer `gbuffer`;
    /// leaves the reservoirs to shade with in [`reservoirs`](Self::reservoirs).
    pub fn run(
        &mut self,
        tracer: &PathTracer,
        config: &RestirConfig,
        gbuffer: &GBuffer,
        index: u32,
        firsts: &[Vec<Option<PrimaryHit>>],
        run: usize,
    ) -> RestirTimes {
        let (width, gbuffer) = (gbuffer.width, &gbuffer.pixels[..]);
        let n = gbuffer.len();
        let seed = tracer.settings.seed;
        let lights = &tracer.world.lights;
        let mut times = RestirTimes::default();
        if self.reservoirs.previous.len() != n {
            self.valid = false;
        }
        let t = std::time::Instant::now();
        self.receivers.current.resize(n, None);
        self.receivers
            .current
            .par_chunks_mut(run)
            .zip(firsts.par_iter())
            .for_each(|(receivers, hits)| {
                for (r, h) in receivers.iter_mut().zip(hits) {
                    *r = h.as_ref().and_then(|h| {
                        h.first
                            .as_ref()
                            .and_then(|v| Receiver::new(tracer, v, h.ray.direction))
                    });
                }
            });
        self.reservoirs.current.resize(n, Reservoir::default());
        self.pool.build(lights, POOL_BLOCKS, seed, index);
        let pool = &self.pool;
        let candidates = config.candidates;
        let streams = PixelStreams::new(seed, 0, index);
        let visibility = config.visibility_reuse;
        let unbiased = config.unbiased;
        times.rays += self
            .reservoirs
            .current
            .par_iter_mut()
            .zip(self.receivers.current.par_iter())
            .enumerate()
            .map(|(pixel, (r, receiver))| {
                *r = Reservoir::default();
                let Some(receiver) = receiver else {
                    return 0u64;
                };
                let mut rng = streams.rng(pixel);
                *r = receiver.candidates(pool, lights, candidates, &mut rng);
                let mut rays = 0;
                if (visibility || unbiased)
                    && r.weight > 0.0
                    && !receiver.sees(tracer, &r.sample, &mut rays)
                {
                    r.weight = 0.0;
                }
                rays as u64
            })
            .sum::<u64>();
        times.candidates_ms = t.elapsed().as_secs_f64() * 1e3;

        let t = std::time::Instant::now();
        if config.temporal && self.valid {
            times.rays += self.temporal(tracer, config, gbuffer, width, index);
        }
        times.temporal_ms = t.elapsed().as_secs_f64() * 1e3;

        let t = std::time::Instant::now();
        if config.spatial {
            for iteration in 0..config.iterations {
                times.rays += self.spatial(tracer, config, gbuffer, width, index, iteration);
            }
        }
        times.spatial_ms = t.elapsed().as_secs_f64() * 1e3;
        times
    }

    /// The reservoirs the last frame shaded with (after [`keep`](Self::keep); empty after a
    /// reset).
    pub fn shaded(&self) -> &[Reservoir] {
        if self.valid {
            &self.reservoirs.previous
        } else {
            &[]
        }
    }

    /// After shading: this frame's reservoirs, receivers and G-buffer become the previous
    /// frame's.
    pub fn keep(&mut self, gbuffer: &[GPixel]) {
        self.reservoirs.swap();
        self.receivers.swap();
        self.previous_gbuffer.clear();
        self.previous_gbuffer.extend_from_slice(gbuffer);
        self.valid = true;
    }

    /// Combines reservoir `own` of `receiver` with `others` (each with its pixel's receiver),
    /// `W` by the plain, the unbiased (1/Z) or the MIS combination as `config` says; returns
    /// the combined reservoir.
    fn combine(
        tracer: &PathTracer,
        config: &RestirConfig,
        receiver: &Receiver,
        own: &Reservoir,
        others: &[(Reservoir, &Receiver)],
        rng: &mut Rng,
        rays: &mut u32,
    ) -> Reservoir {
        if config.mis {
            return Self::combine_mis(tracer, config.unbiased, receiver, own, others, rng, rays);
        }
        let lights = &tracer.world.lights;
        let mut s = Reservoir::default();
        s.update(
            own.sample,
            own.target * own.weight * own.m,
            own.target,
            own.m,
            rng.next_f32(),
        );
        // The others' samples' targets here, in lanes when there are several.
        for chunk in others.chunks(NEIGHBOUR_LANES) {
            let targets = if let [(q, _)] = chunk {
                let mut one = [0.0; NEIGHBOUR_LANES];
                if q.weight > 0.0 {
                    one[0] = receiver.target(lights, &q.sample);
                }
                one
            } else {
                let points = std::array::from_fn(|k| {
                    chunk
                        .get(k)
                        .map_or_else(LightPoint::default, |(q, _)| q.sample)
                });
                receiver.point_targets(lights, &points, chunk.len())
            };
            for ((q, _), t) in chunk.iter().zip(targets) {
                let t = if q.weight > 0.0 { t } else { 0.0 };
                s.update(q.sample, t * q.weight * q.m, t, q.m, rng.next_f32());
            }
        }
        let z = if config.unbiased && s.target > 0.0 {
            // A reservoir holds only samples its own pixel sees (or none): a survivor hidden
            // from here would shade nothing here, and kept, it would break the count below
            // for the next frame.
            if !receiver.sees(tracer, &s.sample, rays) {
                return Reservoir { weight: 0.0, ..s };
            }
            // The reservoirs whose own pixel could have produced the survivor: those that
            // see it.
            let mut z = own.m;
            for (q, r) in others {
                if q.m > 0.0 && r.sees(tracer, &s.sample, rays) {
                    z += q.m;
                }
            }
            z
        } else {
            s.m
        };
        s.finish(z);
        s
    }

    /// The combination with the paper's MIS weights (the generalised balance heuristic):
    /// reservoir i's sample y_i enters with weight `m_i(y_i) p_hat(y_i) W_i`, where
    /// `m_i(y) = M_i p_hat_i(y) / sum_j M_j p_hat_j(y)` over the combined reservoirs' pixels
    /// (with visibility in the unbiased mode), and `W = w_sum / p_hat(y)`. A sample that is
    /// rare where it was drawn but bright here gets the small weight its own pixel gives it,
    /// instead of the 1/M weights' outlier. Costs `(k + 1)^2` target evaluations for `k`
    /// neighbours.
    fn combine_mis(
        tracer: &PathTracer,
        unbiased: bool,
        receiver: &Receiver,
        own: &Reservoir,
        others: &[(Reservoir, &Receiver)],
        rng: &mut Rng,
        rays: &mut u32,
    ) -> Reservoir {
        let lights = &tracer.world.lights;
        let all = || std::iter::once((own, receiver)).chain(others.iter().map(|(q, r)| (q, *r)));
        let mut s = Reservoir::default();
        for (i, (ri, _)) in all().enumerate() {
            let here = if ri.weight <= 0.0 {
                0.0
            } else if i == 0 {
                own.target
            } else {
                receiver.target(lights, &ri.sample)
            };
            if here <= 0.0 {
                s.m += ri.m;
                continue;
            }
            // The balance heuristic over the pixels' targets (a reservoir's own target is
            // its pixel's; in the unbiased mode its sample is visible there).
            let (mut own_term, mut sum) = (0.0, 0.0);
            for (j, (rj, recj)) in all().enumerate() {
                let t = if j == i {
                    ri.target
                } else if unbiased {
                    recj.receive(lights, &ri.sample)
                        .filter(|r| recj.visibility(tracer, r, rays) > 0.0)
                        .map_or(0.0, |r| r.target)
                } else {
                    recj.target(lights, &ri.sample)
                };
                sum += rj.m * t;
                if j == i {
                    own_term = rj.m * t;
                }
            }
            let m = if sum > 0.0 { own_term / sum } else { 0.0 };
            s.update(ri.sample, m * here * ri.weight, here, ri.m, rng.next_f32());
        }
        if unbiased && s.target > 0.0 && !receiver.sees(tracer, &s.sample, rays) {
            return Reservoir { weight: 0.0, ..s };
        }
        s.finish(1.0);
        s
    }

    /// Temporal reuse: each reservoir combined with the previous frame's at the pixel its
    /// motion vector points to.
    fn temporal(
        &mut self,
        tracer: &PathTracer,
        config: &RestirConfig,
        gbuffer: &[GPixel],
        width: u32,
        index: u32,
    ) -> u64 {
        let (w, h) = (width as i64, (gbuffer.len() / width.max(1) as usize) as i64);
        let streams = PixelStreams::new(tracer.settings.seed, 1, index);
        let previous = &self.reservoirs.previous;
        let previous_receivers = &self.receivers.previous;
        let previous_gbuffer = &self.previous_gbuffer;
        self.reservoirs
            .current
            .par_iter_mut()
            .zip(self.receivers.current.par_iter())
            .enumerate()
            .map(|(pixel, (r, receiver))| {
                let Some(receiver) = receiver else {
                    return 0;
                };
                let g = &gbuffer[pixel];
                let (x, y) = ((pixel as i64 % w) as f32, (pixel as i64 / w) as f32);
                let at = Vec2::new(x, y) + g.motion;
                let (px, py) = (at.x.round() as i64, at.y.round() as i64);
                if px < 0 || py < 0 || px >= w || py >= h {
                    return 0;
                }
                let q = (py * w + px) as usize;
                // A pixel without a receiver kept an empty reservoir (M = 0).
                let (mut prev, pg) = (previous[q], &previous_gbuffer[q]);
                if prev.m == 0.0
                    || pg.position.distance(g.position) > config.depth_threshold * g.depth
                    || pg.normal.dot(g.normal) < config.normal_threshold
                    || (pg.albedo - g.albedo).abs().max_element() > ALBEDO_TOLERANCE
                {
                    return 0;
                }
                let Some(prev_receiver) = other_receiver(config, previous_receivers, q, receiver)
                else {
                    return 0;
                };
                if config.m_cap > 0 {
                    prev.m = prev.m.min(config.m_cap as f32 * r.m.max(1.0));
                }
                let mut rng = streams.rng(pixel);
                let mut rays = 0;
                *r = Self::combine(
                    tracer,
                    config,
                    receiver,
                    r,
                    &[(prev, prev_receiver)],
                    &mut rng,
                    &mut rays,
                );
                rays as u64
            })
            .sum()
    }

    /// One spatial iteration: each reservoir combined with `neighbours` others within
    /// `radius` pixels that pass the depth and normal tests (on the frame's [`Key`]s, which
    /// iteration 0 takes from `gbuffer`).
    fn spatial(
        &mut self,
        tracer: &PathTracer,
        config: &RestirConfig,
        gbuffer: &[GPixel],
        width: u32,
        index: u32,
        iteration: u32,
    ) -> u64 {
        let (w, h) = (width as i64, (gbuffer.len() / width.max(1) as usize) as i64);
        let seed = tracer.settings.seed;
        self.scratch
            .resize(self.reservoirs.current.len(), Reservoir::default());
        if iteration == 0 || self.keys.len() != gbuffer.len() {
            self.keys.resize(gbuffer.len(), Key::default());
            self.keys
                .par_iter_mut()
                .zip(gbuffer.par_iter())
                .for_each(|(k, g)| *k = Key::of(g));
        }
        if self.offsets.len() != OFFSETS || self.offsets_radius != config.radius {
            self.offsets = disk_offsets(config.radius);
            self.offsets_radius = config.radius;
        }
        let offsets = &self.offsets;
        // Pixel `p`'s neighbours (those off screen left out): the offsets that follow one a hash
        // of the pixel picks.
        let starts = PixelHash(hash(&[
            seed,
            index as u64,
            NEIGHBOURS_STREAM + iteration as u64,
        ]));
        let streams = PixelStreams::new(seed, 2 + iteration as u64, index);
        // (The pixel's coordinates and start computed once, not per neighbour: a division and
        // a hash each.)
        let neighbours_of = |p: usize| {
            let start = (starts.of(p) >> 32) as usize;
            let (px, py) = (p as i64 % w, p as i64 / w);
            (start..start + config.neighbours as usize).filter_map(move |i| {
                let (dx, dy) = offsets[i % OFFSETS];
                let (x, y) = (px + dx as i64, py + dy as i64);
                (x >= 0 && y >= 0 && x < w && y < h).then_some((y * w + x) as usize)
            })
        };
        let keys = &self.keys;
        let input = &self.reservoirs.current;
        let receivers = &self.receivers.current;
        let rays = self
            .scratch
            .par_iter_mut()
            .enumerate()
            .map_init(Vec::new, |others, (pixel, out)| {
                *out = input[pixel];
                let Some(receiver) = &receivers[pixel] else {
                    return 0;
                };
                let key = &keys[pixel];
                let mut rng = streams.rng(pixel);
                // The neighbours of a pixel a few ahead on their way to the cache.
                for q in neighbours_of(pixel + AHEAD) {
                    prefetch(&input[q]);
                    prefetch(&keys[q]);
                }
                // The neighbours taken (a vector per thread, kept across pixels).
                others.clear();
                for q in neighbours_of(pixel) {
                    // A pixel without a receiver has an empty reservoir (M = 0).
                    if input[q].m == 0.0 || !similar(key, &keys[q], config) {
                        continue;
                    }
                    if let Some(other) = other_receiver(config, receivers, q, receiver) {
                        others.push((input[q], other));
                    }
                }
                let mut rays = 0;
                *out = Self::combine(
                    tracer,
                    config,
                    receiver,
                    &input[pixel],
                    others,
                    &mut rng,
                    &mut rays,
                );
                rays as u64
            })
            .sum();
        std::mem::swap(&mut self.reservoirs.current, &mut self.scratch);
        rays
    }
}

/// ReSTIR in one frame: the stage that lights the first hits ([`FirstHitLight`]).
pub struct RestirFrame<'a> {
    restir: &'a mut Restir,
    config: &'a RestirConfig,
    index: u32,
}

impl FirstHitLight for RestirFrame<'_> {
    /// The candidates, temporal and spatial passes.
    fn prepare(
        &mut self,
        tracer: &PathTracer,
        gbuffer: &GBuffer,
        hits: &[Vec<Option<PrimaryHit>>],
        times: &mut Times,
    ) -> u64 {
        let t = self
            .restir
            .run(tracer, self.config, gbuffer, self.index, hits, RUN);
        times.add(RESTIR, t.candidates_ms);
        times.add(RESTIR_TEMPORAL, t.temporal_ms);
        times.add(RESTIR_SPATIAL, t.spatial_ms);
        t.rays
    }

    /// The pixel's reservoir shaded (`None`: no receiver there, the sky or a delta surface),
    /// with one shadow ray.
    #[inline]
    fn direct(&self, tracer: &PathTracer, pixel: usize, rays: &mut u32) -> Option<Vec3> {
        let r = &self.restir;
        r.receivers.current[pixel]
            .as_ref()
            .map(|rec| rec.shade(tracer, &r.reservoirs.current[pixel], rays))
    }

    fn finish(&mut self, gbuffer: &GBuffer) {
        self.restir.keep(&gbuffer.pixels);
    }
}

impl Stage for Restir {
    fn name(&self) -> &'static str {
        RESTIR
    }

    fn views(&self) -> &'static [View] {
        Self::VIEWS
    }

    fn passes(&self) -> Vec<&'static str> {
        vec![RESTIR, RESTIR_TEMPORAL, RESTIR_SPATIAL]
    }

    /// At a new epoch: a change of the settings forgets the previous frame's reservoirs; a
    /// camera move, or a frame of a pipeline that does not accumulate, keeps them.
    fn start_epoch(&mut self, change: Change) {
        if matches!(change, Change::Settings | Change::Scale) {
            self.reset();
        }
    }

    /// The last frame's reservoir's `M` (`reservoir-m`) or `W` (`reservoir-weight`); 0 where
    /// there is none.
    fn value(&self, _: &FrameState, view: usize, i: usize) -> Vec3 {
        let r = self.shaded().get(i);
        Vec3::splat(r.map_or(0.0, |r| if view == 0 { r.m } else { r.weight }))
    }

    fn bytes(&self) -> usize {
        Restir::bytes(self)
    }
}

pub mod pool;
mod receiver;
mod reservoir;
#[cfg(test)]
mod tests;

pub use receiver::{Received, Receiver};
pub use reservoir::Reservoir;

use pool::{LightPool, POOL_BLOCKS};
