//! Seed 002's texture-space shading cache as a stage of the frame: light shaded on grids
//! attached to the surfaces ([`surface_grid`]), filtered there, and looked up by every
//! pixel, primary sample and frame that sees the same texel.
//!
//! ```text
//! texture-cache  (in the lighting pass)  a pixel's first hit, its footprint  -> the texel's
//!                                        sample and texel caches               filtered light
//!                                                                              (demodulated)
//! ```
//!
//! **How it plugs in.** [`TextureCache::begin`] returns the cache's frame as the light at the
//! first hits that the lighting pass asks ([`FirstHitLight`]): it lights each run of pixels
//! itself (down columns of the image, see the tables below), taking each pixel's direct light
//! at its first hit from the light it was given beneath it (next event estimation, or ReSTIR's
//! reservoirs), and records what each pixel met for the stage's views.
//! [`TextureCache::end`] then brings the young cells up to `fresh_spp` and reports.
//!
//! Per pixel sample whose first hit is diffuse enough ([`TextureCacheConfig::min_roughness`]):
//!
//! 1. its footprint (ray differentials of its camera sample, [`footprint`]) picks the
//!    level of its triangle's grid (by default from the footprint's area, or Eq. 1's finer
//!    direction; plus `lod_bias`), its barycentrics the cell (Eq. 2);
//! 2. the **texel cache** holds the cell's filtered light for this frame; on a miss, the
//!    filter's footprint is walked in the **sample cache**, whose cells not yet shaded this
//!    frame are shaded (one path each from the cell's centroid, white Lambertian there: the
//!    light is demodulated), the filter is applied and the result stored;
//! 3. the pixel adds its own terms: its emission, and with `terms = "indirect"` its direct
//!    light at the first hit (next event estimation and the BSDF's ray, by multiple importance
//!    sampling, or ReSTIR's reservoir), and the texel's light times its BSDF's directional
//!    albedo ([`crate::bsdf::Bsdf::directional_albedo`]).
//!
//! What is cached (`terms`): `"all"`, the direct light too (next event estimation at the
//! cell), and the pixel traces no shadow ray; `"indirect"`, the light arriving at the cell
//! through at least one more bounce (what the path tracer's split calls indirect); `"sky"`
//! (the default), all but the environment's sun ([`crate::light::sun`]: next event
//! estimation at the cell with the sky in the environment's place), while each pixel lights
//! itself by the sun (next event estimation at its own first hit, one shadow ray): the sun's
//! shadows stay sharp where a texel would spread them over its neighbours (the error that
//! dominated `"all"` along the interior's orbit: bright texels leaking into shade, which
//! relMSE weighs most), for a shadow ray per pixel; without a sun, as `"all"`. The pixel's
//! sun is a ratio estimator (`sun_ratio`): the sun's unshadowed irradiance of its normal,
//! summed over the sun's texels, times the BSDF and the visibility toward the one sample, so
//! that a fully lit surface's sun does not change from frame to frame. With ReSTIR
//! (seed 004), a cached pixel's direct light is its reservoir's whatever the cache holds.
//! A pixel on a silhouette or a crease (`edge_spp`,
//! [`GBuffer::on_edge`](crate::frame::gbuffer::GBuffer::on_edge)) takes more camera samples,
//! each looking its light up: a single sample's coverage of an edge is what the cache leaves
//! of a moving camera's error.
//! Pixels on glossy (`min_roughness`), metallic, transmissive or mirror-like surfaces bypass
//! the cache: their whole path is traced per pixel, as without it. The cached
//! light is the cosine-weighted mean of the incoming light (a white Lambertian's reflected
//! light); the pixel's BSDF albedo makes it exact for Lambertian surfaces and an approximation
//! for the rough specular layer of the surfaces that do not bypass (their specular lobe sees
//! the cosine-weighted mean instead of its own lobe's).
//!
//! **Blocks.** A cache slot holds a block of 2 x 2 squares of one triangle's grid at one level
//! (8 cells: each square's two halves): one key and one state per block, so that the filter
//! reads a few blocks instead of scattered cells, and runs separably over the squares. A cell's
//! key (Eq. 3) is its block's key and its place in the block. Blocks are shaded whole: cells
//! next to visible ones are shaded too, which the filter mostly reads anyway (blocks of 4 x 4
//! shaded a third more cells for no gain).
//!
//! **Tables.** Each cache is a fixed table of slots (the budget, `budget_mb`, split 70 / 30
//! between samples and texels) in sets of eight ways (their state words one cache line): a
//! key's set is fixed (direct-mapped by the key's hash) and its slot keeps the whole key as the
//! tag, so colliding keys never read each other's light. Eight ways instead of one: with a direct-mapped table two blocks the same frame
//! needs collide in proportion to the square of the blocks in use (with four ways, a 256 MB
//! table still overflowed a few sets a frame at 62,000 blocks), and the one that loses is
//! shaded without a history each frame.
//!
//! **Protocol** (the paper's three states): a slot is empty, being shaded (by one thread), or
//! shaded at a frame. A thread that needs a block this frame finds it shaded (reads it),
//! being shaded (defers it and comes back after the rest of the filter's footprint), or claims
//! it by compare-and-swap and shades it. Taking an empty or stale way for a new key happens
//! under the set's insertion flag (a miss path, once per block and frame); reads and re-shading
//! take no lock. A slot shaded this frame is evicted this frame only when its set holds
//! nothing older (a table too small for the frame: its readers check after reading, as a
//! seqlock's, and look again), first in, first out; the lighting pass goes down columns of
//! the image (an eighth of its width) so that the blocks given up are those it has gone past
//! (at 1920x1080 a table of one byte per pixel, the paper's budget, shades 25% more cells
//! than an unbounded one). A block whose set is all being shaded is shaded without the cache
//! (counted as `uncached`). So with a table large enough, every block needed is shaded
//! exactly once per frame, and the image does not depend on the thread count: a cell's
//! random stream is keyed by the cell, its sample count and the epoch (the frame pipeline's
//! seed), not by the pixel, the frame or the thread.
//!
//! **Temporal reuse** (`temporal`): the cache persists across frames and camera moves, and is
//! emptied by any other change. `"mean"` (the default): each cell keeps the mean of all its
//! samples, a cell with `max_count` samples is not shaded again, and with `reshade` a block
//! of `n` samples is shaded again at a frame with probability `reshade / n` (a still scene's
//! view-independent light converges whatever the camera does, and cells seen for a while cost
//! less and less). Young cells (`fresh_spp`): after the lighting pass, the blocks it shaded
//! whose cells hold fewer than `fresh_spp` samples are shaded again toward that count within
//! `fresh_budget` paths per pixel (`cold_budget` at an empty cache's first frame: no frame
//! stalls, the blocks left wait for the next frame that sees them), every young cell up to the
//! same level first (the error of a cell of `n` samples falls as `1/n`: spread evenly, the
//! paths lower the frame's error more than on a few cells brought all the way; along the
//! interior's orbit relMSE 0.104 -> 0.101), for the frames that follow: a cell newly seen costs
//! its samples once, where the reshading rate would have spread fewer over many frames (a
//! cell's samples grow as the square root of the frames it is seen in), and a camera turning
//! toward new rooms pays for them over a few frames. A sample's indirect light is clamped (`clamp`) to a multiple of
//! what a white Lambertian surface lit directly can reflect ([`crate::light::Lights::
//! reflected_bound`]): beyond it the path came off a glossy surface, a caustic too rare for
//! one cell's samples, that a cell would keep for many frames and its filter spread (the
//! garden's relMSE was dominated by a few such cells once cells took 16 samples).
//! `"exponential"`: Eq. 6, `c = (1 - alpha) c_new + alpha c_old` with `alpha =
//! temporal_alpha`; `"none"`: each frame's sample alone. The filter (box or Gaussian over a
//! `kernel`-wide window of squares) narrows as `n^-shrink` as the cells gather samples (the
//! paper notes its fixed kernels are not consistent). `filter = "linear"`: a linear
//! regression over the window's squares' places, weighted by the Gaussian, read at the
//! texel's own place (the paper's regression in texture space over the place alone, one
//! window instead of a choice among several; its slopes damped by `RIDGE`): a gradient's
//! texels, and those whose window a triangle's edge cuts short, are no longer pulled toward
//! the side with more squares (along the interior's orbit the crease pixels' error fell by
//! a tenth; BENCHMARKS.md).
//!
//! Departures from the paper: per-triangle grids instead of Ptex faces; the filter stays
//! inside its triangle (its window is clipped and renormalised at the triangle's edges) and so
//! needs no normal test; both halves of a square share one filtered texel; eight-way sets; the
//! level from the footprint's area by default; direct light cached too by default; the
//! narrowing filter (whose window reads only the blocks its narrowed width reaches), the
//! reshading rate, the young cells' samples and the clamp. The measurements behind the
//! defaults: BENCHMARKS.md, "Seed 002".
//!
//! **Layers** (each module uses only those above it in this list):
//!
//! ```text
//! footprint, surface_grid  a camera ray's footprint at its hit; the triangles' grids of cells
//! settings                 [frame.texture_cache], its ranges, the stage's name
//! table                    slots in sets of eight ways, blocks, the claim/ready protocol
//! samples                  the sample cache: cells shaded by the temporal rule, the top-up
//! texels                   the texel cache: blocks of texels filtered from the cells around
//! lookup                   a pixel's first hit and footprint -> its texel's light
//! (this module)            the stage: its state across frames, begin/end, views, report
//! ```

pub mod footprint;
mod lookup;
mod samples;
mod settings;
pub mod surface_grid;
mod table;
#[cfg(test)]
mod tests;
mod texels;

use std::sync::atomic::{AtomicU64, Ordering};

use glam::Vec3;
use pathlight_core::rng::hash;
use serde::Serialize;

use crate::bsdf::Microfacet;
use crate::camera::Camera;
use crate::light::sun::SunAndSky;
use crate::path::{PathSettings, PathTracer};
use crate::world::World;

use super::display::{viridis, View, ViewKind, NONE};
use super::stage::Stage;
use super::state::{Change, FrameState, Times};
use super::trace::FirstHitLight;

pub use lookup::CachePixel;
pub use samples::Status;
pub use settings::{
    ranges, CacheFilter, CachedTerms, LodMeasure, Temporal, TextureCacheConfig, MAX_BUDGET_MB,
    MAX_EDGE_SPP, MAX_FRESH_BUDGET, MAX_FRESH_SPP, MAX_KERNEL, TEXTURE_CACHE,
};

use lookup::{CacheFrame, CacheLight};
use samples::{Counters, SampleCache, SampleFrame};
use surface_grid::SurfaceGrids;
use table::{Table, CELLS, READY, SQUARES, STATE};
use texels::{TexelCache, TexelFrame, GENERATIONS};

/// What the cache did in one frame (`FrameReport::texture_cache`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct CacheReport {
    /// Cells shaded (paths traced from cells).
    pub cells_shaded: u64,
    /// Sample blocks shaded (claimed and shaded once each).
    pub blocks_shaded: u64,
    /// Texel blocks filtered.
    pub texel_blocks: u64,
    /// Blocks shaded without the cache (their set full of this frame's blocks).
    pub uncached: u64,
    /// Of the cells shaded, those brought up to `fresh_spp` after the lighting pass.
    pub topped_up: u64,
    /// Pixels whose first sample looked up a texel.
    pub cached_pixels: u64,
    /// Bytes of the two tables.
    pub bytes: u64,
}

/// The two caches, the frame they serve and its counts, and what they keep per world: what
/// the lighting pass's threads share.
#[derive(Default)]
struct Caches {
    /// The grids of the world they were made for (its address and triangle count).
    grids: Option<(usize, usize, SurfaceGrids)>,
    /// The environment's sun and sky, of the same world as the grids (`terms = "sky"`).
    sun: SunAndSky,
    /// The same world's [`crate::light::Lights::reflected_bound`] (the clamp's unit).
    bound: f32,
    samples: SampleCache,
    texels: TexelCache,
    /// Frames the cache has served (its slots' frame stamps; 0: never).
    frame: u32,
    counters: Counters,
}

impl Caches {
    /// What a frame's lighting pass reads (after [`TextureCache::prepare`]) with `cfg`, the
    /// frame's path `settings` and `camera`.
    fn frame<'a>(
        &'a self,
        cfg: &'a TextureCacheConfig,
        settings: PathSettings,
        camera: &'a Camera,
    ) -> CacheFrame<'a> {
        let samples = SampleFrame {
            cache: &self.samples,
            frame: self.frame,
            counters: &self.counters,
            grids: &self.grids.as_ref().expect("made by prepare_world").2,
            sun: &self.sun,
            cfg,
            clamp: match cfg.clamp > 0.0 {
                true => cfg.clamp * self.bound,
                false => f32::INFINITY,
            },
            seed: hash(&[settings.seed, 0x002]),
        };
        let short = PathSettings {
            max_bounces: Some(match cfg.terms {
                CachedTerms::Indirect => 1,
                CachedTerms::All | CachedTerms::Sky => 0,
            }),
            mis_at_last: true,
            ..settings
        };
        let texels = TexelFrame {
            samples,
            cache: &self.texels,
        };
        CacheFrame::new(texels, short, camera)
    }
}

/// Seed 002's stage: the grids, the two tables, and what each pixel met.
#[derive(Default)]
pub struct TextureCache {
    cache: Caches,
    /// The tables' configuration (budget's bits, channels): a change reallocates them.
    layout: (u32, usize),
    clear: bool,
    /// Per pixel: what its first sample met.
    pixels: Vec<CachePixel>,
    /// The next frame belongs to the same instant as the last (a stereo pair's second eye):
    /// it finds the cells and texels the last one shaded this frame instead of shading them
    /// again.
    pub same_instant: bool,
}

impl TextureCache {
    pub const VIEWS: &'static [View] = &[
        View {
            name: "cache-light",
            about: "texture cache: the cached light each pixel used (times its albedo)",
            kind: ViewKind::Radiance,
        },
        View {
            name: "cache-texels",
            about: "texture cache: each texel a colour of its own (the grid's cells)",
            kind: ViewKind::Painted,
        },
        View {
            name: "cache-level",
            about: "texture cache: the grid level each pixel looked up (0 finest, dark; \
                    15 bright)",
            kind: ViewKind::Painted,
        },
        View {
            name: "cache-hits",
            about: "texture cache: green the texel was ready, red this pixel filtered it, \
                    yellow shaded without the cache, blue the surface bypasses it, black none",
            kind: ViewKind::Painted,
        },
        View {
            name: "cache-shaded",
            about: "texture cache: cells each pixel's lookups shaded",
            kind: ViewKind::HeatOfLargest,
        },
    ];

    /// Before the frame's lighting pass: the grids for `world`, the tables for `cfg`, the
    /// frame's counters, and the pixels' records (`pixels` of them, for the lighting pass to
    /// fill).
    fn prepare(
        &mut self,
        world: &World,
        cfg: &TextureCacheConfig,
        microfacet: Microfacet,
        pixels: usize,
    ) {
        self.prepare_world(world, microfacet);
        let layout = (cfg.budget_mb.to_bits(), cfg.channels());
        if self.layout != layout || self.cache.samples.table.slots() == 0 {
            let bytes = (cfg.budget_mb as f64 * (1 << 20) as f64) as usize;
            self.cache.samples.table = Table::new(bytes * 7 / 10, CELLS * (1 + layout.1));
            self.cache.texels.table = Table::new(bytes * 3 / 10, SQUARES * layout.1);
            self.layout = layout;
            self.clear = true;
        }
        let cleared = std::mem::take(&mut self.clear);
        self.cache.samples.cold = cleared || self.cache.frame == 0;
        if cleared {
            self.cache.samples.table.clear();
            self.cache.texels.table.clear();
        }
        let same_instant = std::mem::take(&mut self.same_instant);
        let new_instant = !same_instant || self.cache.frame == 0;
        if new_instant {
            self.cache.frame = self.cache.frame.wrapping_add(1).max(1);
            *self.cache.samples.instant_budget.get_mut() = u64::MAX;
        }
        if !same_instant || cleared || self.cache.texels.generation == 0 {
            self.cache.texels.generation = GENERATIONS.fetch_add(1, Ordering::Relaxed);
        }
        self.cache.counters = Counters::default();
        self.cache
            .samples
            .young
            .get_mut()
            .expect("not poisoned")
            .clear();
        self.pixels.clear();
        self.pixels.resize(pixels, CachePixel::default());
    }

    /// What the cache keeps per world, made for `world` unless it was made for it: the
    /// triangles' grids, the environment's sun and sky, the clamp's unit (a new world empties
    /// the cache), and the rough specular albedo's table of `microfacet` (once per run).
    pub fn prepare_world(&mut self, world: &World, microfacet: Microfacet) {
        let id = (
            world as *const World as usize,
            world.scene.triangle_count() as usize,
        );
        let c = &mut self.cache;
        if c.grids.as_ref().map(|g| (g.0, g.1)) != Some(id) {
            c.grids = Some((id.0, id.1, SurfaceGrids::new(world)));
            c.sun = SunAndSky::new(&world.lights);
            c.bound = world.lights.reflected_bound();
            self.clear = true;
            crate::bsdf::specular_albedo::prepare(microfacet);
        }
    }

    /// Before the frame's lighting pass: [`prepare`](Self::prepare) for `tracer`'s world, `cfg`
    /// and `pixels` pixels. Returns the light at the first hits that the lighting pass asks
    /// ([`FirstHitLight`]): each pixel's light looked up through the cache, its first sample's
    /// direct light from `beneath` (next event estimation, or ReSTIR's reservoirs), what it
    /// met kept for the stage's views.
    pub fn begin<'a>(
        &'a mut self,
        tracer: &PathTracer<'a>,
        cfg: &'a TextureCacheConfig,
        pixels: usize,
        beneath: &'a mut dyn FirstHitLight,
    ) -> impl FirstHitLight + 'a {
        self.prepare(tracer.world, cfg, tracer.settings.microfacet, pixels);
        let frame = self.cache.frame(cfg, tracer.settings, tracer.camera);
        CacheLight::new(frame, &mut self.pixels, beneath)
    }

    /// After the frame's lighting pass (`lighting`, the pass's name, with `cfg`): the young
    /// cells it shaded brought up to `fresh_spp` ([`CacheFrame::top_up`]), then what the cache
    /// did, its lookups' thread time (spread over the threads) moved in `times` from the
    /// lighting pass to the stage's. Returns the top-up's rays and the report.
    pub fn end(
        &self,
        tracer: &PathTracer,
        cfg: &TextureCacheConfig,
        times: &mut Times,
        lighting: &'static str,
    ) -> (u64, CacheReport) {
        let frame = self.cache.frame(cfg, tracer.settings, tracer.camera);
        let rays = frame.top_up(tracer, self.pixels.len(), times);
        let (report, ms) = self.report();
        let ms = ms / rayon::current_num_threads() as f64;
        times.add(TEXTURE_CACHE, ms);
        times.add(lighting, -ms);
        (rays, report)
    }

    /// What the cache did this frame, and the thread time its lookups took (ms).
    fn report(&self) -> (CacheReport, f64) {
        let c = &self.cache.counters;
        let load = |a: &AtomicU64| a.load(Ordering::Relaxed);
        (
            CacheReport {
                cells_shaded: load(&c.cells),
                blocks_shaded: load(&c.blocks),
                texel_blocks: load(&c.texels),
                uncached: load(&c.uncached),
                topped_up: load(&c.topped_up),
                cached_pixels: self
                    .pixels
                    .iter()
                    .filter(|p| matches!(p.status, Status::Hit | Status::Miss | Status::Uncached))
                    .count() as u64,
                bytes: (self.cache.samples.table.bytes() + self.cache.texels.table.bytes()) as u64,
            },
            load(&c.nanos) as f64 * 1e-6,
        )
    }

    /// Sample blocks shaded at the current frame, counted over the table (with no eviction,
    /// each block shaded once: equal to the report's `blocks_shaded`).
    pub fn blocks_at_current_frame(&self) -> usize {
        (0..self.cache.samples.table.slots())
            .filter(|&i| {
                self.cache.samples.table.states[i].load(Ordering::Relaxed) & STATE == READY
                    && self.cache.samples.table.frames[i].load(Ordering::Relaxed)
                        == self.cache.frame
            })
            .count()
    }
}

impl Stage for TextureCache {
    fn name(&self) -> &'static str {
        TEXTURE_CACHE
    }

    fn views(&self) -> &'static [View] {
        Self::VIEWS
    }

    /// At a new epoch: any change but a camera move (or a repeat) empties the cache.
    fn start_epoch(&mut self, change: Change) {
        if change == Change::Settings {
            self.clear = true;
        }
    }

    /// The cached light used (`cache-light`), the level, the cells shaded; zero where the
    /// cache was not used.
    fn value(&self, _: &FrameState, view: usize, i: usize) -> Vec3 {
        let p = self.pixels.get(i).copied().unwrap_or_default();
        match view {
            0 => p.light,
            2 => Vec3::splat(p.level as f32),
            4 => Vec3::splat(p.shaded as f32),
            _ => Vec3::ZERO,
        }
    }

    fn paint(&self, _: &FrameState, view: usize, i: usize) -> [u8; 3] {
        let p = self.pixels.get(i).copied().unwrap_or_default();
        match view {
            1 if p.key != 0 => {
                let h = hash(&[p.key]);
                [
                    h as u8 | 0x30,
                    (h >> 8) as u8 | 0x30,
                    (h >> 16) as u8 | 0x30,
                ]
            }
            2 if p.key != 0 => viridis(p.level as f32 / 15.0),
            3 => match p.status {
                Status::None => [0, 0, 0],
                Status::Bypass => [40, 70, 200],
                Status::Hit => [40, 190, 60],
                Status::Miss => [220, 50, 40],
                Status::Uncached => [230, 210, 40],
            },
            _ => NONE,
        }
    }

    fn bytes(&self) -> usize {
        self.cache.samples.table.bytes()
            + self.cache.texels.table.bytes()
            + self.pixels.capacity() * std::mem::size_of::<CachePixel>()
            + self.cache.grids.as_ref().map_or(0, |g| g.2.bytes())
    }
}
