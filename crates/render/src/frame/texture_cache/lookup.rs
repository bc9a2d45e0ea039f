//! The lookup: a pixel's first hit and its footprint -> its texel's light. A pixel sample
//! whose first hit is diffuse enough picks its cell (the level from its footprint, the cell from
//! its barycentrics), reads the filtered texels around it from the texel cache
//! ([`super::texels`]), and adds its own terms (emission, the sun or its direct light); the
//! others, and every sample of a surface that bypasses the cache, trace their whole path.

use std::sync::Mutex;
use std::time::Instant;

use glam::{UVec2, Vec3};

use crate::bsdf::Bsdf;
use crate::camera::Camera;
use crate::light::sun::Part;
use crate::path::{PathSettings, PathTracer, Vertex, CAMERA_DIMENSIONS};

use super::super::accumulation::PixelStats;
use super::super::gbuffer::{GBuffer, PrimaryHit};
use super::super::lighting::{self, LightSample};
use super::super::state::Times;
use super::super::trace::{FirstHitLight, Run, RUN};
use super::footprint::Footprint;
use super::samples::{Status, Work};
use super::settings::{CacheFilter, CachedTerms, LodMeasure, TextureCacheConfig, CHANNELS};
use super::surface_grid::Cell;
use super::table::{Block, CELLS, SQUARES};
use super::texels::TexelFrame;

/// The first sample index of the edges' own samples (a frame's pixel takes `EDGE_SAMPLES +
/// index * edge_spp + k`: apart from the frames' own indices, at most 2^24, and from each
/// other's, as long as `index * edge_spp` stays below 2^30).
const EDGE_SAMPLES: u32 = 1 << 30;

/// What the cache did at one pixel (the stage's views).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct CachePixel {
    /// The key of the texel the first sample looked up (0: none).
    pub key: u64,
    /// Its level.
    pub level: u8,
    pub status: Status,
    /// Cells this pixel's lookups shaded.
    pub shaded: u32,
    /// The cached light the pixel used (times its albedo).
    pub light: Vec3,
}

/// The cache as one frame's lighting pass reads it.
pub(super) struct CacheFrame<'a> {
    /// The texel cache over the sample cache, this frame.
    texels: TexelFrame<'a>,
    /// The path tracer for the pixels' own terms at a cached first hit (no continuation).
    short: PathSettings,
    camera: &'a Camera,
}

impl<'a> CacheFrame<'a> {
    /// The frame's caches (`texels` over its sample cache), the pixels' own terms traced with
    /// `short`, their footprints from `camera`.
    pub(super) fn new(texels: TexelFrame<'a>, short: PathSettings, camera: &'a Camera) -> Self {
        Self {
            texels,
            short,
            camera,
        }
    }

    fn cfg(&self) -> &'a TextureCacheConfig {
        self.texels.samples.cfg
    }

    /// After the frame's lighting pass: its young cells brought up to `fresh_spp`
    /// ([`super::samples::SampleFrame::top_up`]).
    pub(super) fn top_up(&self, tracer: &PathTracer, pixels: usize, times: &mut Times) -> u64 {
        self.texels.samples.top_up(tracer, pixels, times)
    }

    /// The lighting of one pixel (as [`lighting::light`]): samples whose first hit is cached
    /// take their own terms and the texel's light; the others trace their whole path.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn light(
        &self,
        tracer: &PathTracer,
        x: u32,
        y: u32,
        hit: &PrimaryHit,
        (index, spp): (u32, u32),
        gbuffer: &GBuffer,
        along: bool,
        direct: Option<Vec3>,
        record: &mut CachePixel,
    ) -> (LightSample, u64) {
        if spp == 0 {
            return (LightSample::default(), 0);
        }
        let film_lens = tracer.film_lens(x, y, index);
        // The first sample through the cache, or (it bypasses) the plain lighting's.
        let (mut stats, bounce, mut rays) =
            match self.sample(tracer, film_lens, hit, direct, record) {
                Some((d, i, r, bounce)) => (PixelStats::one(d, i), bounce, r),
                None => {
                    let (l, r) = lighting::light(tracer, x, y, hit, index, 1, along, direct);
                    (l.stats, l.bounce, r)
                }
            };
        // The frame's samples, then on an edge the others (numbered apart from every frame's:
        // the frames' own go on from `index + spp`).
        let edge = self.cfg().edge_spp > spp && gbuffer.on_edge(x, y);
        let all = if edge { self.cfg().edge_spp } else { spp };
        for k in 1..all {
            let i = match k < spp {
                true => index + k,
                false => EDGE_SAMPLES
                    .wrapping_add(index.wrapping_mul(self.cfg().edge_spp))
                    .wrapping_add(k),
            };
            let (d, i, r) = self.another(tracer, x, y, i);
            stats.add(d, i);
            rays += r;
        }
        (LightSample { stats, bounce }, rays)
    }

    /// Sample `index` of pixel (`x`, `y`) traced from the camera: through the cache where its
    /// first hit is cached, its whole path otherwise. Returns its direct and indirect light and
    /// the rays traced.
    fn another(&self, tracer: &PathTracer, x: u32, y: u32, index: u32) -> (Vec3, Vec3, u64) {
        let c = tracer.camera_sample(x, y, index);
        let (mut rng, mut rays) = (c.rng.clone(), 0u32);
        let first = tracer.intersect(c.ray, &mut rng, &mut rays);
        let hit = PrimaryHit {
            ray: c.ray,
            first,
            sampler: c.sampler,
            rng,
        };
        let mut scratch = CachePixel::default();
        match self.sample(tracer, (c.film, c.lens), &hit, None, &mut scratch) {
            Some((d, i, r, _)) => (d, i, r + rays as u64),
            None => {
                let s =
                    tracer.trace_from::<false>(hit.ray, hit.first.as_ref(), hit.sampler, hit.rng);
                (s.direct, s.indirect, (s.rays + rays) as u64)
            }
        }
    }

    /// One camera sample (its film and lens point, its first hit) through the cache: `None`
    /// when it bypasses it. Returns its direct and indirect light, the rays traced, and its
    /// first bounce (its direction left zero).
    fn sample(
        &self,
        tracer: &PathTracer,
        (film, lens): (glam::Vec2, glam::Vec2),
        hit: &PrimaryHit,
        direct: Option<Vec3>,
        record: &mut CachePixel,
    ) -> Option<(Vec3, Vec3, u64, crate::path::Bounce)> {
        let v = hit.first.as_ref()?;
        let world = tracer.world;
        let params = &v.shading.params;
        let bsdf = world.bsdf(v.surface.material, params);
        if bsdf.has_delta_lobe()
            || params.metallic > 0.5
            || params.transmission > 0.0
            || params.roughness < self.cfg().min_roughness
        {
            record.status = Status::Bypass;
            return None;
        }
        // The pixel's own terms: emission, and next event estimation (or the reservoir's)
        // unless the cache holds the direct light.
        let s = match self.short.max_bounces {
            // Emission alone (the path tracer's first vertex at a bounce limit of 0, without
            // building its BSDF again).
            Some(0) => crate::path::PathSample {
                direct: world.lights.emitted(
                    &world.scene,
                    v.surface.instance,
                    v.surface.triangle,
                    v.surface.bary,
                    -hit.ray.direction,
                ),
                ..Default::default()
            },
            _ => PathTracer {
                world,
                camera: tracer.camera,
                settings: self.short,
            }
            .trace_lit::<false>(
                hit.ray,
                Some(v),
                hit.sampler.clone(),
                hit.rng.clone(),
                direct,
            ),
        };
        let footprint = Footprint::at(world, &self.camera.ray(film, lens), &v.surface);
        let cell = self.texels.samples.grids.cell(
            &v.surface,
            footprint.as_ref(),
            self.cfg().lod_bias,
            self.cfg().lod == LodMeasure::Area,
        );
        let mut work = Work {
            rays: s.rays as u64,
            cells: record.shaded,
        };
        let mut light = [0.0f32; CHANNELS];
        let (status, key) = match self.cfg().interpolate && self.cfg().filter != CacheFilter::None {
            true => self.interpolated(tracer, &cell, v.surface.bary, &mut light, &mut work),
            false => self.lookup(tracer, &cell, &mut light, &mut work),
        };
        let albedo = directional_albedo(&bsdf, v.surface.to_local(-hit.ray.direction));
        let indirect = albedo * Vec3::from_slice(&light[self.cfg().channels() - 3..]);
        // The direct light: the pixel's own (`indirect`: traced above), the reservoir's
        // (seed 004: every light's, the cache's unused), or the cache's (and the pixel's sun
        // with `sky`).
        let cached = match (self.cfg().terms, direct) {
            (CachedTerms::Indirect, _) | (_, Some(_)) => Vec3::ZERO,
            (CachedTerms::All | CachedTerms::Sky, None) => albedo * Vec3::from_slice(&light[..3]),
        };
        let own = match (self.cfg().terms, direct) {
            (CachedTerms::Indirect, _) => Vec3::ZERO,
            (_, Some(reservoir)) => reservoir,
            (CachedTerms::All, None) => Vec3::ZERO,
            (CachedTerms::Sky, None) => self.sunlight(tracer, v, &bsdf, hit, &mut work.rays),
        };
        let d = s.direct + own + cached;
        *record = CachePixel {
            key,
            level: cell.level,
            status,
            shaded: work.cells,
            light: indirect + cached,
        };
        let bounce = crate::path::Bounce {
            radiance: Vec3::from_slice(&light[self.cfg().channels() - 3..]),
            ..s.bounce
        };
        Some((d, indirect, work.rays, bounce))
    }

    /// With `terms = "sky"`: the direct light of the environment's sun at first hit `v` (BSDF
    /// `bsdf`) of camera sample `hit`, one sample by next event estimation from the
    /// dimensions the path's first vertex would have taken for its light's point; its shadow
    /// ray counted in `rays`.
    fn sunlight(
        &self,
        tracer: &PathTracer,
        v: &Vertex,
        bsdf: &Bsdf,
        hit: &PrimaryHit,
        rays: &mut u64,
    ) -> Vec3 {
        let mut sampler = hit.sampler.clone();
        sampler.set_dimension(CAMERA_DIMENSIONS + 1);
        let Some(ls) =
            self.texels
                .samples
                .sun
                .sample(&tracer.world.lights, Part::Sun, sampler.next_2d())
        else {
            return Vec3::ZERO;
        };
        let mut r = 0;
        let wo = -hit.ray.direction;
        let l = match self.cfg().sun_ratio {
            false => tracer.light_alone(v, bsdf, wo, &ls, &mut r),
            true => {
                // The ratio estimator: the sun's exact unshadowed irradiance of the side of
                // the surface the sample lights, times the BSDF (without its cosine, which the
                // irradiance holds) and the visibility toward the sample.
                let toward = (&v.surface, &v.shading, bsdf, wo, v.surface.to_local(wo));
                tracer
                    .toward_light(toward, &ls, &mut r)
                    .map_or(Vec3::ZERO, |(f_cos, tr, _)| {
                        let cos = ls.wi.dot(v.surface.ns);
                        let n = v.surface.ns * cos.signum();
                        self.texels.samples.sun.sun_irradiance(n) * f_cos * (tr / cos.abs())
                    })
            }
        };
        *rays += r as u64;
        l
    }

    /// The light at barycentrics `bary` of `cell`'s triangle and level into `out`: the
    /// filtered texels of the four squares around it, weighted bilinearly (those past the
    /// triangle's edge left out, the others renormalised), so that texels do not show as
    /// blocks. Returns the worst of the four lookups' statuses and `cell`'s texel key.
    fn interpolated(
        &self,
        tracer: &PathTracer,
        cell: &Cell,
        bary: glam::Vec2,
        out: &mut [f32; CHANNELS],
        work: &mut Work,
    ) -> (Status, u64) {
        let ch = self.cfg().channels();
        let r = self.texels.samples.grids.resolution(cell);
        let u = bary.clamp(glam::Vec2::ZERO, glam::Vec2::ONE) * r as f32 - 0.5;
        let base = u.floor();
        let f = u - base;
        let (mut sum, mut total) = ([0.0f32; CHANNELS], 0.0f32);
        let mut status = Status::Hit;
        // The blocks read so far (the four squares lie in one to four of them), each read once.
        let mut blocks: [(Block, [f32; SQUARES * CHANNELS]); 4] =
            [(Block::of(cell, r).0, [0.0; SQUARES * CHANNELS]); 4];
        let mut read = 0;
        for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
            let (i, j) = (base.x as i64 + dx, base.y as i64 + dy);
            if i < 0 || j < 0 || i + j >= r as i64 {
                continue;
            }
            let w =
                (if dx == 1 { f.x } else { 1.0 - f.x }) * (if dy == 1 { f.y } else { 1.0 - f.y });
            if w <= 0.0 {
                continue;
            }
            let corner = Cell {
                square: UVec2::new(i as u32, j as u32),
                upper: false,
                ..*cell
            };
            let (block, k) = Block::of(&corner, r);
            let b = match blocks[..read].iter().position(|(b, _)| *b == block) {
                Some(b) => b,
                None => {
                    blocks[read].0 = block;
                    let st = self
                        .texels
                        .texel_block(tracer, &block, &mut blocks[read].1, work);
                    if st != Status::Hit {
                        status = st;
                    }
                    read += 1;
                    read - 1
                }
            };
            let light = &blocks[b].1[k / 2 * ch..][..ch];
            for c in 0..ch {
                sum[c] += w * light[c];
            }
            total += w;
        }
        if total <= 0.0 {
            return self.lookup(tracer, cell, out, work);
        }
        for c in 0..ch {
            out[c] = sum[c] / total;
        }
        // (The square's key: both halves share its texel.)
        let (block, k) = Block::of(
            &Cell {
                upper: false,
                ..*cell
            },
            r,
        );
        (status, block.texel_key(k))
    }

    /// The light of `cell` into `out` (its channels): its texel, filtered this frame, or with
    /// no filter its own samples. Returns how it was found and the texel's key.
    fn lookup(
        &self,
        tracer: &PathTracer,
        cell: &Cell,
        out: &mut [f32; CHANNELS],
        work: &mut Work,
    ) -> (Status, u64) {
        let ch = self.cfg().channels();
        let (block, k) = Block::of(cell, self.texels.samples.grids.resolution(cell));
        let key = block.texel_key(k);
        if self.cfg().filter == CacheFilter::None {
            let mut cells = [0.0f32; CELLS * (1 + CHANNELS)];
            let t = Instant::now();
            let status = self
                .texels
                .samples
                .sample_block(tracer, &block, &mut cells, work);
            self.texels.samples.counters.time(t);
            let stride = 1 + ch;
            out[..ch].copy_from_slice(&cells[k * stride + 1..(k + 1) * stride]);
            return (status, key);
        }
        let square = k / 2;
        let mut texels = [0.0f32; SQUARES * CHANNELS];
        let status = self.texels.texel_block(tracer, &block, &mut texels, work);
        out[..ch].copy_from_slice(&texels[square * ch..(square + 1) * ch]);
        (status, key)
    }
}

/// The texture cache as the light at the first hits ([`FirstHitLight`]): each pixel's light
/// looked up through the cache ([`CacheFrame::light`]), its first sample's direct light from
/// the light beneath (next event estimation, or ReSTIR's reservoir), what it met recorded for
/// the stage's views.
pub(super) struct CacheLight<'a> {
    frame: CacheFrame<'a>,
    /// The pixels' records by runs of [`RUN`] pixels, each run's taken by the thread that
    /// lights it.
    records: Vec<Mutex<&'a mut [CachePixel]>>,
    beneath: &'a mut dyn FirstHitLight,
}

impl<'a> CacheLight<'a> {
    pub(super) fn new(
        frame: CacheFrame<'a>,
        records: &'a mut [CachePixel],
        beneath: &'a mut dyn FirstHitLight,
    ) -> Self {
        Self {
            frame,
            records: records.chunks_mut(RUN).map(Mutex::new).collect(),
            beneath,
        }
    }
}

impl FirstHitLight for CacheLight<'_> {
    fn prepare(
        &mut self,
        tracer: &PathTracer,
        gbuffer: &GBuffer,
        hits: &[Vec<Option<PrimaryHit>>],
        times: &mut Times,
    ) -> u64 {
        self.beneath.prepare(tracer, gbuffer, hits, times)
    }

    fn direct(&self, tracer: &PathTracer, pixel: usize, rays: &mut u32) -> Option<Vec3> {
        self.beneath.direct(tracer, pixel, rays)
    }

    /// Down columns: a run's cells are then mostly those the runs above it needed.
    fn by_columns(&self) -> bool {
        true
    }

    fn light_run(&self, tracer: &PathTracer, run: &Run, out: &mut [LightSample]) -> u64 {
        let mut records = self.records[run.start / RUN].lock().expect("not poisoned");
        run.each(
            out,
            |p, r| self.beneath.direct(tracer, p, r),
            |px, hit, d| {
                let (x, y, samples) = (px.x, px.y, (px.index, px.spp));
                let record = &mut records[px.k];
                let g = run.gbuffer;
                self.frame
                    .light(tracer, x, y, hit, samples, g, run.along, d, record)
            },
        )
    }

    fn finish(&mut self, gbuffer: &GBuffer) {
        self.beneath.finish(gbuffer)
    }
}

/// The BSDF's directional albedo at `wo`, what the pixel multiplies the cached light by: its
/// rough specular layer from the precomputed table ([`crate::bsdf::specular_albedo`], within
/// 0.006 of the BSDF's own sampling), elsewhere as [`crate::bsdf::Bsdf::directional_albedo`]
/// with two samples at fixed places. [`crate::bsdf::Bsdf::albedo`], Fresnel at the macro
/// normal without masking, overestimates rough specular layers at grazing angles (by 12% on
/// the interior's walls); a Monte Carlo estimate per pixel is noisy, and its noise is the
/// cached pixel's (random places per pixel and frame made the walls flicker at a still view:
/// in sRGB a standard deviation of 0.0048 per frame against 0.0018 with fixed places); the
/// two fixed places' error was a bias varying smoothly with `wo` (BENCHMARKS.md, "Seed 002").
fn directional_albedo(bsdf: &crate::bsdf::Bsdf, wo: Vec3) -> Vec3 {
    const FIXED: [glam::Vec2; 2] = [glam::Vec2::splat(0.25), glam::Vec2::splat(0.75)];
    bsdf.directional_albedo_tabulated(wo, &FIXED)
}
