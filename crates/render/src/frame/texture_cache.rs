//! Seed 002's texture-space shading cache as a stage of the frame: light shaded on grids
//! attached to the surfaces ([`crate::surface_grid`]), filtered there, and looked up by every
//! pixel, primary sample and frame that sees the same texel.
//!
//! ```text
//! texture-cache  (in the lighting pass)  a pixel's first hit, its footprint  -> the texel's
//!                                        sample and texel caches               filtered light
//!                                                                              (demodulated)
//! ```
//!
//! Per pixel sample whose first hit is diffuse enough ([`TextureCacheConfig::min_roughness`]):
//!
//! 1. its footprint (ray differentials of its camera sample, [`crate::footprint`]) picks the
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
//! A pixel on a silhouette or a crease (`edge_spp`, [`GBuffer::on_edge`]) takes more camera
//! samples, each looking its light up: a single sample's coverage of an edge is what the
//! cache leaves of a moving camera's error.
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
//! window instead of a choice among several; its slopes damped by [`RIDGE`]): a gradient's
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

use std::sync::atomic::{AtomicBool, AtomicU32, AtomicU64, Ordering};
use std::time::Instant;

use glam::{UVec2, Vec3};
use pathlight_core::rng::{hash, Rng};
use serde::{Deserialize, Serialize};

use crate::bsdf::{Bsdf, BsdfParams, Microfacet};
use crate::camera::Camera;
use crate::error::ConfigError;
use crate::footprint::Footprint;
use crate::light::sun::{Part, SunAndSky};
use crate::path::{PathSettings, PathTracer, Vertex, CAMERA_DIMENSIONS};
use crate::sampler::PixelSampler;
use crate::surface_grid::{Cell, SurfaceGrids};
use crate::world::World;

use super::accumulation::PixelStats;
use super::display::{viridis, View, ViewKind, NONE};
use super::gbuffer::{GBuffer, PrimaryHit};
use super::lighting::{self, LightSample};
use super::stage::Stage;
use super::state::{Change, FrameState, Times};

/// The stage's name (its views' heading, its pass's time).
pub const TEXTURE_CACHE: &str = "texture-cache";

/// Squares along a block's side.
const BLOCK: u32 = 2;
/// Squares in a block.
const SQUARES: usize = (BLOCK * BLOCK) as usize;
/// Cells in a block (each square's two halves).
const CELLS: usize = 2 * SQUARES;
/// Light channels per cell at most (direct and indirect, [`TextureCacheConfig::channels`]).
const CHANNELS: usize = 6;
/// Ways per set.
const WAYS: usize = 8;
/// Largest filter window.
pub const MAX_KERNEL: u32 = 41;
/// Most camera samples per frame of a pixel on an edge ([`TextureCacheConfig::edge_spp`]).
pub const MAX_EDGE_SPP: u32 = 64;
/// Most samples young cells are brought up to ([`TextureCacheConfig::fresh_spp`]).
pub const MAX_FRESH_SPP: u32 = 256;
/// Most paths per pixel per frame for young cells ([`TextureCacheConfig::fresh_budget`]).
pub const MAX_FRESH_BUDGET: f32 = 64.0;
/// The first sample index of the edges' own samples (a frame's pixel takes `EDGE_SAMPLES +
/// index * edge_spp + k`: apart from the frames' own indices, at most 2^24, and from each
/// other's, as long as `index * edge_spp` stays below 2^30).
const EDGE_SAMPLES: u32 = 1 << 30;
/// Largest budget, in MB: the tables are allocated whole when the cache is switched on, and a
/// larger one buys nothing at the resolutions the pipeline runs (256 bytes per pixel already
/// evict nothing at 320x180; 4 GB is 2,000 bytes per pixel at 1920x1080).
pub const MAX_BUDGET_MB: f32 = 4096.0;
/// The settings' accepted ranges, which [`TextureCacheConfig::validate`] checks and the
/// viewer's sliders span.
pub mod ranges {
    use std::ops::RangeInclusive;
    pub const BUDGET_MB: RangeInclusive<f32> = 0.01..=crate::frame::texture_cache::MAX_BUDGET_MB;
    pub const LOD_BIAS: RangeInclusive<f32> = -8.0..=16.0;
    pub const SHRINK: RangeInclusive<f32> = 0.0..=2.0;
    pub const MIN_ROUGHNESS: RangeInclusive<f32> = 0.0..=1.0;
    pub const EDGE_SPP: RangeInclusive<u32> = 1..=crate::frame::texture_cache::MAX_EDGE_SPP;
    pub const FRESH_SPP: RangeInclusive<u32> = 1..=crate::frame::texture_cache::MAX_FRESH_SPP;
    pub const FRESH_BUDGET: RangeInclusive<f32> =
        0.0..=crate::frame::texture_cache::MAX_FRESH_BUDGET;
}

/// The reconstruction filter over the sample cells, in texture space.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum CacheFilter {
    /// Each cell's own samples.
    None,
    /// The mean over a `kernel` x `kernel` window of squares.
    Box,
    /// A Gaussian over the window, standard deviation a quarter of its width.
    Gaussian,
    /// A linear regression over the squares' places, weighted by the Gaussian: a gradient's
    /// texels unbiased to first order, at the window's edges too (seed 002's regression in
    /// texture space, over the place alone).
    Linear,
}

/// Which light the cache holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum CachedTerms {
    /// The light arriving through at least one more bounce.
    Indirect,
    /// Direct light too.
    All,
    /// All but the environment's sun ([`SunAndSky`]): each pixel adds the sun's direct light
    /// by next event estimation at its own first hit (sharp shadows where they fall, not
    /// spread over texels). Without an environment or without a sun, as `all`.
    Sky,
}

/// How a cell's samples of successive frames combine.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Temporal {
    /// The mean of all its samples, up to `max_count` of them.
    Mean,
    /// Eq. 6: an exponential history of weight `temporal_alpha`.
    Exponential,
    /// This frame's sample alone.
    None,
}

/// How a footprint picks a grid's level.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum LodMeasure {
    /// A cell about a pixel's area ([`Footprint::area_level`]).
    Area,
    /// Eq. 1: the finer of the footprint's two directions ([`Footprint::level`]).
    Finer,
}

/// Seed 002's texture-space cache (`[frame.texture_cache]`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TextureCacheConfig {
    pub enabled: bool,
    /// Both caches' memory, in MB (70% samples, 30% texels; fractions allowed).
    pub budget_mb: f32,
    /// Levels added to Eq. 1's (coarser texels: fewer cells shaded).
    pub lod_bias: f32,
    pub filter: CacheFilter,
    /// The filter's window, in squares of the grid (odd).
    pub kernel: u32,
    /// Eq. 6's history weight (with `temporal = "exponential"`).
    pub temporal_alpha: f32,
    pub terms: CachedTerms,
    pub temporal: Temporal,
    /// With `temporal = "mean"`: a cell stops being shaded once it has this many samples.
    pub max_count: u32,
    /// With `temporal = "mean"`: a block whose cells hold `n` samples on average is shaded
    /// again at a frame with probability `reshade / n` (decided by a hash of the block and
    /// the frame; 0: at every frame it is needed, as the paper): new cells converge at once,
    /// cells seen for a while take fewer samples as their error falls, and a camera that moves
    /// slowly pays for what it newly sees.
    pub reshade: f32,
    /// The filter narrows as its texels' cells gather samples: its width (the Gaussian's
    /// deviation, the box's radius) times `n^-shrink` for cells of `n` samples on average (0:
    /// the paper's fixed window; its bias stays as the noise goes).
    pub shrink: f32,
    /// How a footprint picks the level: `"area"`, cells about a pixel's area (the default:
    /// fewer cells on long thin triangles), or `"finer"`, Eq. 1's finer direction.
    pub lod: LodMeasure,
    /// A pixel's light interpolated bilinearly between the four filtered texels around it
    /// (with a filter; without one, its cell's own light).
    pub interpolate: bool,
    /// Pixels on surfaces smoother than this (perceptual roughness), metallic above 0.5,
    /// transmissive or with a mirror-like lobe trace their whole path instead.
    pub min_roughness: f32,
    /// Camera samples a pixel on a silhouette or a crease takes per frame, if more than the
    /// frame's ([`crate::frame::gbuffer::GBuffer::on_edge`]): the cache makes a sample cheap
    /// (its light is looked up), and a single sample's coverage of an edge is what is left of
    /// a moving camera's error. 1: as every pixel (not in the paper).
    pub edge_spp: u32,
    /// With `temporal = "mean"`: the samples a young cell is brought up to after the frame's
    /// lighting pass (16; 1: none, as the paper; not in the paper). The blocks shaded this frame
    /// whose cells hold fewer are shaded again up to this count, the youngest first, within
    /// `fresh_budget`; the frames that follow read them: a camera's first frames and the
    /// surfaces it turns toward are not a single path's noise for long, and a cell seen once
    /// costs its samples once.
    pub fresh_spp: u32,
    /// Paths per pixel of the frame that bringing young cells up to `fresh_spp` may take per
    /// frame (the rest wait for the next frame they are seen in): a camera that turns toward
    /// new rooms pays for them over several frames instead of in one. A stereo pair's second
    /// eye (the same instant) spends what the first eye's frame left of it.
    pub fresh_budget: f32,
    /// As `fresh_budget`, at the first frame of an empty cache (a scene loaded, settings
    /// changed): that frame has no young cells left from earlier frames to pay for, and takes
    /// more of its own (bounded: the first frame costs a few later ones, not a stall).
    pub cold_budget: f32,
    /// A cell's sample of indirect light is clamped (its luminance, keeping its colour) to
    /// this multiple of the most a white Lambertian surface lit directly by the scene's lights
    /// can reflect ([`crate::light::Lights::reflected_bound`]): with two bounces, what exceeds
    /// it came off a glossy surface (a caustic), a rare path that a cell would keep for many
    /// frames and its filter spread (1; 0: no clamp, as the paper; not in the paper).
    pub clamp: f32,
    /// With `terms = "sky"`: each pixel's sun by a ratio estimator (Heitz et al. 2018): the
    /// sun's unshadowed irradiance of its normal, worked out over the sun's texels
    /// ([`SunAndSky::sun_irradiance`]), times the BSDF and the visibility toward its one
    /// sample, so that the sample no longer decides the sun's colour or its cosine, only its
    /// shadow (true; false: the sample's own estimate, as before; not in the paper).
    pub sun_ratio: bool,
}

impl Default for TextureCacheConfig {
    fn default() -> Self {
        Self {
            enabled: false,
            budget_mb: 64.0,
            lod_bias: 1.0,
            filter: CacheFilter::Gaussian,
            kernel: 9,
            temporal_alpha: 0.7,
            terms: CachedTerms::Sky,
            temporal: Temporal::Mean,
            max_count: 256,
            reshade: 2.0,
            shrink: 0.5,
            lod: LodMeasure::Area,
            interpolate: true,
            min_roughness: 0.3,
            edge_spp: 1,
            fresh_spp: 16,
            fresh_budget: 0.5,
            cold_budget: 2.0,
            clamp: 1.0,
            sun_ratio: true,
        }
    }
}

impl TextureCacheConfig {
    pub fn validate(&self) -> Result<(), ConfigError> {
        /// `Ok` when `ok`, else the error for `field`'s `value`, which must be `requirement`.
        /// "between A and B" of a range.
        fn between<T: std::fmt::Display>(r: std::ops::RangeInclusive<T>) -> String {
            format!("between {} and {}", r.start(), r.end())
        }
        fn require(
            ok: bool,
            field: &'static str,
            value: impl std::fmt::Display,
            requirement: &str,
        ) -> Result<(), ConfigError> {
            match ok {
                true => Ok(()),
                false => Err(ConfigError::new(field, value, requirement)),
            }
        }
        require(
            ranges::BUDGET_MB.contains(&self.budget_mb),
            "frame.texture_cache.budget_mb",
            self.budget_mb,
            &between(ranges::BUDGET_MB),
        )?;
        require(
            ranges::LOD_BIAS.contains(&self.lod_bias),
            "frame.texture_cache.lod_bias",
            self.lod_bias,
            &between(ranges::LOD_BIAS),
        )?;
        require(
            !self.kernel.is_multiple_of(2) && self.kernel <= MAX_KERNEL,
            "frame.texture_cache.kernel",
            self.kernel,
            &format!("odd, at most {MAX_KERNEL}"),
        )?;
        require(
            (0.0..1.0).contains(&self.temporal_alpha),
            "frame.texture_cache.temporal_alpha",
            self.temporal_alpha,
            "in [0, 1)",
        )?;
        require(
            ranges::SHRINK.contains(&self.shrink),
            "frame.texture_cache.shrink",
            self.shrink,
            &between(ranges::SHRINK),
        )?;
        require(
            self.reshade.is_finite() && self.reshade >= 0.0,
            "frame.texture_cache.reshade",
            self.reshade,
            "finite and at least 0",
        )?;
        require(
            self.max_count > 0,
            "frame.texture_cache.max_count",
            self.max_count,
            "at least 1",
        )?;
        require(
            ranges::MIN_ROUGHNESS.contains(&self.min_roughness),
            "frame.texture_cache.min_roughness",
            self.min_roughness,
            &between(ranges::MIN_ROUGHNESS),
        )?;
        require(
            ranges::EDGE_SPP.contains(&self.edge_spp),
            "frame.texture_cache.edge_spp",
            self.edge_spp,
            &between(ranges::EDGE_SPP),
        )?;
        require(
            ranges::FRESH_SPP.contains(&self.fresh_spp),
            "frame.texture_cache.fresh_spp",
            self.fresh_spp,
            &between(ranges::FRESH_SPP),
        )?;
        require(
            ranges::FRESH_BUDGET.contains(&self.fresh_budget),
            "frame.texture_cache.fresh_budget",
            self.fresh_budget,
            &between(ranges::FRESH_BUDGET),
        )?;
        require(
            ranges::FRESH_BUDGET.contains(&self.cold_budget),
            "frame.texture_cache.cold_budget",
            self.cold_budget,
            &between(ranges::FRESH_BUDGET),
        )?;
        require(
            self.clamp.is_finite() && self.clamp >= 0.0,
            "frame.texture_cache.clamp",
            self.clamp,
            "finite and at least 0",
        )
    }

    /// Light channels per cell: indirect, or direct and indirect.
    fn channels(&self) -> usize {
        match self.terms {
            CachedTerms::Indirect => 3,
            CachedTerms::All | CachedTerms::Sky => CHANNELS,
        }
    }
}

/// A slot's state, in the low two bits of its state word (the rest is the key).
const EMPTY: u64 = 0;
const BUSY: u64 = 1;
const READY: u64 = 2;
const STATE: u64 = 3;

/// A block of [`BLOCK`] x [`BLOCK`] squares of one side of one triangle's grid at one level.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Block {
    instance: u32,
    triangle: u32,
    back: bool,
    level: u8,
    /// The block's place among the grid's blocks.
    at: UVec2,
    /// Squares along the triangle's edge at this level.
    resolution: u32,
}

impl Block {
    /// The block of `cell` (of a grid `resolution` squares along), and the cell's index in it.
    fn of(cell: &Cell, resolution: u32) -> (Block, usize) {
        let at = cell.square / BLOCK;
        let local = cell.square % BLOCK;
        let square = (local.y * BLOCK + local.x) as usize;
        (
            Block {
                instance: cell.instance,
                triangle: cell.triangle,
                back: cell.back,
                level: cell.level,
                at,
                resolution,
            },
            2 * square + cell.upper as usize,
        )
    }

    /// The table key: a hash of everything that names the block (Eq. 3 over blocks), never
    /// zero, its state bits clear.
    fn key(&self) -> u64 {
        let c = Cell {
            instance: self.instance,
            triangle: self.triangle,
            back: self.back,
            level: self.level,
            square: self.at,
            upper: false,
        };
        (c.key() | 4) & !STATE
    }

    /// The key of the texel of cell `k` of the block (its place, Eq. 3 over texels).
    fn texel_key(&self, k: usize) -> u64 {
        hash(&[self.key(), k as u64])
    }

    /// The neighbouring block `d` blocks away, if it holds any square of the triangle.
    fn beside(&self, dx: i32, dy: i32) -> Option<Block> {
        let (x, y) = (self.at.x as i32 + dx, self.at.y as i32 + dy);
        let r = self.resolution as i32;
        (x >= 0 && y >= 0 && (x + y) * (BLOCK as i32) < r).then_some(Block {
            at: UVec2::new(x as u32, y as u32),
            ..*self
        })
    }

    /// The cell with index `k` in the block, if it lies in the triangle.
    fn cell(&self, k: usize) -> Option<Cell> {
        let square = (k / 2) as u32;
        let upper = k % 2 == 1;
        let s = self.at * BLOCK + UVec2::new(square % BLOCK, square / BLOCK);
        let r = self.resolution;
        let inside = if upper {
            s.x + s.y + 1 < r
        } else {
            s.x + s.y < r
        };
        inside.then_some(Cell {
            instance: self.instance,
            triangle: self.triangle,
            back: self.back,
            level: self.level,
            square: s,
            upper,
        })
    }
}

/// A fixed table of slots in sets of [`WAYS`], each slot a state word (key and state), the
/// frame it was shaded at, and `stride` words of data.
#[derive(Default)]
struct Table {
    states: Vec<AtomicU64>,
    frames: Vec<AtomicU32>,
    /// Per set: a thread is putting a new key in it.
    inserting: Vec<AtomicBool>,
    /// Per set (under its insertion flag): the way after the last of this frame's blocks it
    /// gave up, where it looks first for the next (first in, first out).
    turn: Vec<AtomicU32>,
    data: Vec<AtomicU32>,
    stride: usize,
}

/// What a thread found for a key.
enum Claim {
    /// Shaded this frame, at this slot.
    /// (With its state word, to check after reading that the slot still holds it:
    /// [`Table::still`].)
    Ready(usize, u64),
    /// Claimed by this thread, to be shaded (`fresh`: a new key, its data to be cleared).
    Mine(usize, bool),
    /// Being shaded by another thread.
    Busy,
    /// Its set is full of this frame's keys.
    Full,
}

impl Table {
    /// A table of `bytes` bytes of slots of `stride` data words.
    fn new(bytes: usize, stride: usize) -> Self {
        let slot = 12 + 4 * stride;
        let sets = (bytes / (slot * WAYS)).max(1);
        let n = sets * WAYS;
        Self {
            states: (0..n).map(|_| AtomicU64::new(EMPTY)).collect(),
            frames: (0..n).map(|_| AtomicU32::new(0)).collect(),
            inserting: (0..sets).map(|_| AtomicBool::new(false)).collect(),
            turn: (0..sets).map(|_| AtomicU32::new(0)).collect(),
            data: (0..n * stride).map(|_| AtomicU32::new(0)).collect(),
            stride,
        }
    }

    fn slots(&self) -> usize {
        self.states.len()
    }

    fn bytes(&self) -> usize {
        self.slots() * 12 + self.inserting.len() * 5 + self.data.len() * 4
    }

    /// Every slot empty.
    fn clear(&self) {
        for s in &self.states {
            s.store(EMPTY, Ordering::Relaxed);
        }
    }

    /// The first slot of `key`'s set.
    fn set(&self, key: u64) -> usize {
        let sets = self.inserting.len() as u64;
        ((key >> 2).wrapping_mul(0x9e37_79b9_7f4a_7c15) >> 32) as usize % sets as usize * WAYS
    }

    /// The slot of `key` in its set and its state word, if there.
    fn find(&self, key: u64, base: usize) -> Option<(usize, u64)> {
        (base..base + WAYS).find_map(|i| {
            let s = self.states[i].load(Ordering::Acquire);
            (s & !STATE == key).then_some((i, s))
        })
    }

    /// Finds or claims `key` for frame `frame` (the three-state protocol).
    fn claim(&self, key: u64, frame: u32) -> Claim {
        let base = self.set(key);
        loop {
            if let Some((i, s)) = self.find(key, base) {
                match s & STATE {
                    BUSY => return Claim::Busy,
                    // (The state re-read: the slot was not taken by another key meanwhile.)
                    READY
                        if self.frames[i].load(Ordering::Acquire) == frame
                            && self.states[i].load(Ordering::Acquire) == s =>
                    {
                        return Claim::Ready(i, s)
                    }
                    // Shaded at an earlier frame: re-shade it on its history. (The state word
                    // is the same before and after another thread re-shades it: having taken
                    // it, check that this frame did not.)
                    _ => match self.states[i].compare_exchange(
                        s,
                        key | BUSY,
                        Ordering::AcqRel,
                        Ordering::Acquire,
                    ) {
                        Ok(_) if self.frames[i].load(Ordering::Acquire) == frame => {
                            self.states[i].store(s, Ordering::Release);
                            continue;
                        }
                        Ok(_) => return Claim::Mine(i, false),
                        Err(_) => continue,
                    },
                }
            }
            // A new key: under the set's insertion flag, so that two threads never put the
            // same key in two ways.
            let flag = &self.inserting[base / WAYS];
            if flag
                .compare_exchange(false, true, Ordering::Acquire, Ordering::Relaxed)
                .is_err()
            {
                std::hint::spin_loop();
                continue;
            }
            if self.find(key, base).is_some() {
                flag.store(false, Ordering::Release);
                continue;
            }
            // An empty way, else the way shaded longest ago, else (the set full of this
            // frame's blocks: a table too small for the frame) the one of this frame's that
            // came in first, whose readers see it go (`still`) and look again: a block shaded
            // once is then reused by the lookups that follow it instead of every lookup
            // shading it again, and the lighting pass's order (down columns of the image)
            // gives up the blocks it has gone past.
            let turn = &self.turn[base / WAYS];
            let first = turn.load(Ordering::Relaxed) as usize;
            let victim = (base..base + WAYS)
                .filter_map(|i| {
                    let s = self.states[i].load(Ordering::Acquire);
                    match s & STATE {
                        EMPTY => Some((i, s, (false, 0, 0))),
                        READY => {
                            // (This frame's last, from the set's turn on; then the smaller
                            // `f - frame`, wrapping: the older.)
                            let f = self.frames[i].load(Ordering::Acquire);
                            let order = (i - base + WAYS - first) % WAYS;
                            Some((i, s, (f == frame, f.wrapping_sub(frame), order)))
                        }
                        _ => None,
                    }
                })
                .min_by_key(|&(_, _, age)| age);
            if let Some((i, _, (true, _, _))) = victim {
                turn.store(((i - base + 1) % WAYS) as u32, Ordering::Relaxed);
            }
            let claim = match victim {
                None => Claim::Full,
                Some((i, s, (current, _, _))) => {
                    match self.states[i].compare_exchange(
                        s,
                        key | BUSY,
                        Ordering::AcqRel,
                        Ordering::Acquire,
                    ) {
                        // A stale way that its key re-shaded this frame meanwhile: keep it.
                        Ok(_) if !current && self.frames[i].load(Ordering::Acquire) == frame => {
                            self.states[i].store(s, Ordering::Release);
                            flag.store(false, Ordering::Release);
                            continue;
                        }
                        Ok(_) => Claim::Mine(i, true),
                        // Re-shaded meanwhile by its own key's thread: look again.
                        Err(_) => {
                            flag.store(false, Ordering::Release);
                            continue;
                        }
                    }
                }
            };
            flag.store(false, Ordering::Release);
            return claim;
        }
    }

    /// After reading slot `i`, found shaded at `frame` with state word `s`: it still is (no
    /// other key took it while it was read; a seqlock's second check).
    fn still(&self, i: usize, s: u64, frame: u32) -> bool {
        std::sync::atomic::fence(Ordering::Acquire);
        self.states[i].load(Ordering::Relaxed) == s
            && self.frames[i].load(Ordering::Relaxed) == frame
    }

    /// Publishes slot `i`, claimed for `key`, as shaded at `frame`.
    fn publish(&self, i: usize, key: u64, frame: u32) {
        self.frames[i].store(frame, Ordering::Release);
        self.states[i].store(key | READY, Ordering::Release);
    }

    fn word(&self, i: usize, k: usize) -> f32 {
        f32::from_bits(self.data[i * self.stride + k].load(Ordering::Relaxed))
    }

    fn set_word(&self, i: usize, k: usize, v: f32) {
        self.data[i * self.stride + k].store(v.to_bits(), Ordering::Relaxed)
    }

    /// Slot `i`'s data.
    fn read(&self, i: usize, out: &mut [f32]) {
        for (k, o) in out.iter_mut().enumerate() {
            *o = self.word(i, k);
        }
    }

    /// Writes slot `i`'s data.
    fn write(&self, i: usize, values: &[f32]) {
        for (k, &v) in values.iter().enumerate() {
            self.set_word(i, k, v);
        }
    }
}

/// What a camera sample's lookups cost: rays traced (its own and its cells'), cells shaded.
struct Work {
    rays: u64,
    cells: u32,
}

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

/// How a pixel's first sample met the cache.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum Status {
    /// Not traced, or the sky.
    #[default]
    None,
    /// Its surface bypasses the cache (glossy, metallic, transmissive).
    Bypass,
    /// Its texel was filtered already this frame.
    Hit,
    /// It filtered its texel (or, without a filter, shaded its cell's block).
    Miss,
    /// Its block's set was full: shaded without the cache.
    Uncached,
}

/// The frame's counts, summed over threads.
#[derive(Debug, Default)]
struct Counters {
    cells: AtomicU64,
    topped_up: AtomicU64,
    blocks: AtomicU64,
    texels: AtomicU64,
    uncached: AtomicU64,
    nanos: AtomicU64,
}

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

/// The two tables, the frame they serve and its counts: what the lighting pass's threads
/// share.
#[derive(Default)]
struct Caches {
    samples: Table,
    texels: Table,
    /// Frames the cache has served (its slots' frame stamps; 0: never).
    frame: u32,
    counters: Counters,
    /// The blocks shaded this frame whose cells hold fewer than `fresh_spp` samples, with
    /// their slots (brought up to it after the lighting pass: [`CacheFrame::top_up`]).
    young: std::sync::Mutex<Vec<(Block, usize)>>,
    /// What the texel table holds this frame, unique over every cache of the process and
    /// frame ([`GENERATIONS`]): the tag of the threads' [`TexelMemo`] entries.
    generation: u64,
    /// The tables were emptied since the last frame: the top-up takes `cold_budget`.
    cold: bool,
    /// The young cells' paths this instant may still take, set by its first frame's top-up
    /// (`u64::MAX`: not yet): a stereo pair's second eye (the same instant) spends what the
    /// first left, so that the pair tops up what one frame would.
    instant_budget: AtomicU64,
}

/// The source of [`Caches::generation`] (0: no table).
static GENERATIONS: AtomicU64 = AtomicU64::new(1);

/// Entries of a thread's [`TexelMemo`].
const MEMO: usize = 64;

/// A thread's last texel blocks read this frame, direct-mapped by key: a pixel's four
/// texels, and the next pixels' (a block covers a few pixels each way), are found without
/// the table's hash, probe and checks. An entry is the table's data for its block at its
/// generation, so what it gives is what the table would.
struct TexelMemo([(u64, u64, [f32; SQUARES * CHANNELS]); MEMO]);

thread_local! {
    static TEXEL_MEMO: std::cell::RefCell<TexelMemo> =
        const { std::cell::RefCell::new(TexelMemo([(0, 0, [0.0; SQUARES * CHANNELS]); MEMO])) };
}

/// Seed 002's stage: the grids, the two tables, and what each pixel met.
#[derive(Default)]
pub struct TextureCache {
    /// The grids of the world they were made for (its address and triangle count).
    grids: Option<(usize, usize, SurfaceGrids)>,
    /// The environment's sun and sky, of the same world as the grids (`terms = "sky"`).
    sun: SunAndSky,
    /// The same world's [`crate::light::Lights::reflected_bound`] (the clamp's unit).
    bound: f32,
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

/// The cache as one frame's lighting pass reads it.
pub struct CacheFrame<'a> {
    cache: &'a Caches,
    grids: &'a SurfaceGrids,
    sun: &'a SunAndSky,
    cfg: &'a TextureCacheConfig,
    /// The largest luminance of a cell's sample of indirect light (`clamp`; infinite: none).
    clamp: f32,
    /// The path tracer for the pixels' own terms at a cached first hit (no continuation).
    short: PathSettings,
    camera: &'a Camera,
    /// The sample streams' seed.
    seed: u64,
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

    /// At a new epoch: any change but a camera move (or a repeat) empties the cache.
    pub fn start_epoch(&mut self, change: Change) {
        if change == Change::Settings {
            self.clear = true;
        }
    }

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
        if self.layout != layout || self.cache.samples.slots() == 0 {
            let bytes = (cfg.budget_mb as f64 * (1 << 20) as f64) as usize;
            self.cache.samples = Table::new(bytes * 7 / 10, CELLS * (1 + layout.1));
            self.cache.texels = Table::new(bytes * 3 / 10, SQUARES * layout.1);
            self.layout = layout;
            self.clear = true;
        }
        let cleared = std::mem::take(&mut self.clear);
        self.cache.cold = cleared || self.cache.frame == 0;
        if cleared {
            self.cache.samples.clear();
            self.cache.texels.clear();
        }
        let same_instant = std::mem::take(&mut self.same_instant);
        let new_instant = !same_instant || self.cache.frame == 0;
        if new_instant {
            self.cache.frame = self.cache.frame.wrapping_add(1).max(1);
            *self.cache.instant_budget.get_mut() = u64::MAX;
        }
        if !same_instant || cleared || self.cache.generation == 0 {
            self.cache.generation = GENERATIONS.fetch_add(1, Ordering::Relaxed);
        }
        self.cache.counters = Counters::default();
        self.cache.young.get_mut().expect("not poisoned").clear();
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
        if self.grids.as_ref().map(|g| (g.0, g.1)) != Some(id) {
            self.grids = Some((id.0, id.1, SurfaceGrids::new(world)));
            self.sun = SunAndSky::new(&world.lights);
            self.bound = world.lights.reflected_bound();
            self.clear = true;
            crate::bsdf::specular_albedo::prepare(microfacet);
        }
    }

    /// What the frame's lighting pass reads (after [`prepare`](Self::prepare)), and the
    /// pixels' records it fills.
    fn frame<'a>(
        &'a mut self,
        cfg: &'a TextureCacheConfig,
        settings: PathSettings,
        camera: &'a Camera,
    ) -> (CacheFrame<'a>, &'a mut [CachePixel]) {
        let frame = CacheFrame {
            cache: &self.cache,
            grids: &self.grids.as_ref().expect("made above").2,
            sun: &self.sun,
            cfg,
            clamp: match cfg.clamp > 0.0 {
                true => cfg.clamp * self.bound,
                false => f32::INFINITY,
            },
            short: PathSettings {
                max_bounces: Some(match cfg.terms {
                    CachedTerms::Indirect => 1,
                    CachedTerms::All | CachedTerms::Sky => 0,
                }),
                mis_at_last: true,
                ..settings
            },
            camera,
            seed: hash(&[settings.seed, 0x002]),
        };
        (frame, &mut self.pixels)
    }

    /// Before the frame's lighting pass: [`prepare`](Self::prepare) for `world`, `cfg` and
    /// `pixels` pixels, then [`frame`](Self::frame).
    pub fn begin<'a>(
        &'a mut self,
        world: &World,
        cfg: &'a TextureCacheConfig,
        settings: PathSettings,
        camera: &'a Camera,
        pixels: usize,
    ) -> (CacheFrame<'a>, &'a mut [CachePixel]) {
        self.prepare(world, cfg, settings.microfacet, pixels);
        self.frame(cfg, settings, camera)
    }

    /// After the frame's lighting pass (`lighting`, the pass's name) and top-up: what the
    /// cache did, its lookups' thread time (spread over the threads) moved in `times` from
    /// the lighting pass to the stage's.
    pub fn end(&self, times: &mut Times, lighting: &'static str) -> CacheReport {
        let (report, ms) = self.report();
        let ms = ms / rayon::current_num_threads() as f64;
        times.add(TEXTURE_CACHE, ms);
        times.add(lighting, -ms);
        report
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
                bytes: (self.cache.samples.bytes() + self.cache.texels.bytes()) as u64,
            },
            load(&c.nanos) as f64 * 1e-6,
        )
    }

    /// Sample blocks shaded at the current frame, counted over the table (with no eviction,
    /// each block shaded once: equal to the report's `blocks_shaded`).
    pub fn blocks_at_current_frame(&self) -> usize {
        (0..self.cache.samples.slots())
            .filter(|&i| {
                self.cache.samples.states[i].load(Ordering::Relaxed) & STATE == READY
                    && self.cache.samples.frames[i].load(Ordering::Relaxed) == self.cache.frame
            })
            .count()
    }
}

impl CacheFrame<'_> {
    /// The lighting of one pixel (as [`lighting::light`]): samples whose first hit is cached
    /// take their own terms and the texel's light; the others trace their whole path.
    #[allow(clippy::too_many_arguments)]
    pub fn light(
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
        let edge = self.cfg.edge_spp > spp && gbuffer.on_edge(x, y);
        let all = if edge { self.cfg.edge_spp } else { spp };
        for k in 1..all {
            let i = match k < spp {
                true => index + k,
                false => EDGE_SAMPLES
                    .wrapping_add(index.wrapping_mul(self.cfg.edge_spp))
                    .wrapping_add(k),
            };
            let (d, i, r) = self.another(tracer, x, y, i);
            stats.add(d, i);
            rays += r;
        }
        (LightSample { stats, bounce }, rays)
    }

    fn time(&self, t: Instant) {
        let ns = t.elapsed().as_nanos() as u64;
        self.cache.counters.nanos.fetch_add(ns, Ordering::Relaxed);
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
            || params.roughness < self.cfg.min_roughness
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
        let cell = self.grids.cell(
            &v.surface,
            footprint.as_ref(),
            self.cfg.lod_bias,
            self.cfg.lod == LodMeasure::Area,
        );
        let mut work = Work {
            rays: s.rays as u64,
            cells: record.shaded,
        };
        let mut light = [0.0f32; CHANNELS];
        let (status, key) = match self.cfg.interpolate && self.cfg.filter != CacheFilter::None {
            true => self.interpolated(tracer, &cell, v.surface.bary, &mut light, &mut work),
            false => self.lookup(tracer, &cell, &mut light, &mut work),
        };
        let albedo = directional_albedo(&bsdf, v.surface.to_local(-hit.ray.direction));
        let indirect = albedo * Vec3::from_slice(&light[self.cfg.channels() - 3..]);
        // The direct light: the pixel's own (`indirect`: traced above), the reservoir's
        // (seed 004: every light's, the cache's unused), or the cache's (and the pixel's sun
        // with `sky`).
        let cached = match (self.cfg.terms, direct) {
            (CachedTerms::Indirect, _) | (_, Some(_)) => Vec3::ZERO,
            (CachedTerms::All | CachedTerms::Sky, None) => albedo * Vec3::from_slice(&light[..3]),
        };
        let own = match (self.cfg.terms, direct) {
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
            radiance: Vec3::from_slice(&light[self.cfg.channels() - 3..]),
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
        let Some(ls) = self
            .sun
            .sample(&tracer.world.lights, Part::Sun, sampler.next_2d())
        else {
            return Vec3::ZERO;
        };
        let mut r = 0;
        let wo = -hit.ray.direction;
        let l = match self.cfg.sun_ratio {
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
                        self.sun.sun_irradiance(n) * f_cos * (tr / cos.abs())
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
        let ch = self.cfg.channels();
        let r = self.grids.resolution(cell);
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
                    let st = self.texel_block(tracer, &block, &mut blocks[read].1, work);
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
        let ch = self.cfg.channels();
        let (block, k) = Block::of(cell, self.grids.resolution(cell));
        let key = block.texel_key(k);
        if self.cfg.filter == CacheFilter::None {
            let mut cells = [0.0f32; CELLS * (1 + CHANNELS)];
            let t = Instant::now();
            let status = self.sample_block(tracer, &block, &mut cells, work);
            self.time(t);
            let stride = 1 + ch;
            out[..ch].copy_from_slice(&cells[k * stride + 1..(k + 1) * stride]);
            return (status, key);
        }
        let square = k / 2;
        let mut texels = [0.0f32; SQUARES * CHANNELS];
        let status = self.texel_block(tracer, &block, &mut texels, work);
        out[..ch].copy_from_slice(&texels[square * ch..(square + 1) * ch]);
        (status, key)
    }

    /// The filtered texels of `block`'s squares into `out` (channels per square): found
    /// filtered this frame, or filtered here (into the slot claimed, or without the cache when
    /// its set is full).
    fn texel_block(
        &self,
        tracer: &PathTracer,
        block: &Block,
        out: &mut [f32; SQUARES * CHANNELS],
        work: &mut Work,
    ) -> Status {
        let (bkey, frame) = (block.key(), self.cache.frame);
        let generation = self.cache.generation;
        let slot = (bkey.wrapping_mul(0x9e37_79b9_7f4a_7c15) >> 58) as usize % MEMO;
        let remembered = TEXEL_MEMO.with_borrow(|m| {
            let (g, k, data) = &m.0[slot];
            let found = *g == generation && *k == bkey;
            if found {
                *out = *data;
            }
            found
        });
        if remembered {
            return Status::Hit;
        }
        let remember = |out: &[f32; SQUARES * CHANNELS]| {
            TEXEL_MEMO.with_borrow_mut(|m| m.0[slot] = (generation, bkey, *out));
        };
        let texels = &mut out[..SQUARES * self.cfg.channels()];
        let table = &self.cache.texels;
        loop {
            match table.claim(bkey, frame) {
                Claim::Ready(i, s) => {
                    table.read(i, texels);
                    if table.still(i, s, frame) {
                        remember(out);
                        return Status::Hit;
                    }
                }
                Claim::Busy => std::thread::yield_now(),
                claim => {
                    let t = Instant::now();
                    self.filter(tracer, block, texels, work);
                    self.time(t);
                    let Claim::Mine(i, _) = claim else {
                        return Status::Uncached;
                    };
                    table.write(i, texels);
                    table.publish(i, bkey, frame);
                    self.cache.counters.texels.fetch_add(1, Ordering::Relaxed);
                    remember(out);
                    return Status::Miss;
                }
            }
        }
    }

    /// Sample block `block` shaded this frame, its cells' data (count, channels) into `out`:
    /// found, shaded here, waited for, or shaded without the cache.
    fn sample_block(
        &self,
        tracer: &PathTracer,
        block: &Block,
        out: &mut [f32],
        work: &mut Work,
    ) -> Status {
        loop {
            if let Some(status) = self.try_sample_block(tracer, block, out, work) {
                return status;
            }
            std::thread::yield_now();
        }
    }

    /// As [`sample_block`](Self::sample_block) without waiting: `None` while another thread
    /// shades the block (or replaced it as it was read).
    fn try_sample_block(
        &self,
        tracer: &PathTracer,
        block: &Block,
        out: &mut [f32],
        work: &mut Work,
    ) -> Option<Status> {
        let table = &self.cache.samples;
        let frame = self.cache.frame;
        let out = &mut out[..table.stride];
        match table.claim(block.key(), frame) {
            Claim::Ready(i, s) => {
                table.read(i, out);
                table.still(i, s, frame).then_some(Status::Hit)
            }
            Claim::Busy => None,
            Claim::Mine(i, fresh) => {
                self.shade_slot(tracer, block, i, fresh, out, work);
                Some(Status::Miss)
            }
            Claim::Full => {
                out.fill(0.0);
                self.shade(tracer, block, out, work, None);
                self.cache.counters.uncached.fetch_add(1, Ordering::Relaxed);
                Some(Status::Uncached)
            }
        }
    }

    /// Shades sample block `block` into slot `i` of the sample cache, claimed for it (`fresh`:
    /// a new key, no history), its cells' data into `out`, and publishes it as shaded this
    /// frame.
    #[allow(clippy::too_many_arguments)]
    fn shade_slot(
        &self,
        tracer: &PathTracer,
        block: &Block,
        i: usize,
        fresh: bool,
        out: &mut [f32],
        work: &mut Work,
    ) {
        let table = &self.cache.samples;
        if fresh {
            out.fill(0.0);
        } else {
            table.read(i, out);
        }
        self.shade(tracer, block, out, work, None);
        table.write(i, out);
        table.publish(i, block.key(), self.cache.frame);
        self.cache.counters.blocks.fetch_add(1, Ordering::Relaxed);
        if self.cfg.fresh_spp > 1
            && self.cfg.temporal == Temporal::Mean
            && block_mean(block, out, 1 + self.cfg.channels()) < self.cfg.fresh_spp as f32
        {
            self.cache
                .young
                .lock()
                .expect("not poisoned")
                .push((*block, i));
        }
    }

    /// After the frame's lighting pass: the young blocks it shaded (cells of fewer than
    /// `fresh_spp` samples) shaded again toward `fresh_spp` within `fresh_budget` paths per
    /// pixel of the frame (`pixels`), at a cold cache's first frame as at any other: every
    /// young cell up to the same level, the highest the budget pays for, then the youngest
    /// blocks (then by key: the same blocks whatever the thread count) one sample further.
    /// The rest wait for a frame that sees them again. Returns the rays traced.
    pub fn top_up(&self, tracer: &PathTracer, pixels: usize, times: &mut Times) -> u64 {
        use rayon::prelude::*;
        let start = Instant::now();
        let mut young = std::mem::take(&mut *self.cache.young.lock().expect("not poisoned"));
        let (table, frame) = (&self.cache.samples, self.cache.frame);
        // (A block's words, a cell's.)
        let (words, stride) = (table.stride, 1 + self.cfg.channels());
        // Each block's data, read once, while its slot still holds it as shaded this frame
        // (nothing else writes the table until the next frame).
        let mut order: Vec<(f32, u64, usize, [f32; CELLS * (1 + CHANNELS)])> = (young.iter())
            .enumerate()
            .filter(|(_, &(b, i))| {
                table.states[i].load(Ordering::Acquire) == b.key() | READY
                    && table.frames[i].load(Ordering::Acquire) == frame
            })
            .map(|(k, &(b, i))| {
                let mut d = [0.0f32; CELLS * (1 + CHANNELS)];
                table.read(i, &mut d[..words]);
                (block_mean(&b, &d, stride), b.key(), k, d)
            })
            .collect();
        order.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let per_pixel = match self.cache.cold {
            true => self.cfg.cold_budget,
            false => self.cfg.fresh_budget,
        };
        // The frame's budget, or at a second frame of the same instant what the first left.
        let own = (per_pixel as f64 * pixels as f64) as u64;
        let left = &self.cache.instant_budget;
        let budget = match left.load(Ordering::Relaxed) {
            u64::MAX => own,
            remaining => remaining,
        };
        let fresh = self.cfg.fresh_spp.min(self.cfg.max_count);
        // The samples that bring block `k`'s cells (data `d`) up to `t` each.
        let cost = |t: u32, k: usize, d: &[f32]| -> u64 {
            (0..CELLS)
                .filter(|&c| young[k].0.cell(c).is_some())
                .map(|c| t.saturating_sub(d[c * stride] as u32) as u64)
                .sum()
        };
        let total = |t: u32| -> u64 { order.iter().map(|(_, _, k, d)| cost(t, *k, d)).sum() };
        // Water-filling: every young cell up to the highest level the budget pays for (the
        // error of cells of n samples falls as 1/n: spread evenly, a budget's paths lower the
        // frame's error more than on a few cells brought all the way), then the youngest
        // blocks one sample further while the budget lasts.
        let (mut level, mut high) = (0, fresh);
        while level < high {
            let mid = (level + high).div_ceil(2);
            match total(mid) <= budget {
                true => level = mid,
                false => high = mid - 1,
            }
        }
        let mut spent = total(level);
        let mut targets: Vec<(u32, usize)> = Vec::with_capacity(order.len());
        for (i, (_, _, k, d)) in order.iter().enumerate() {
            let mut t = level;
            if level < fresh {
                let more = cost(level + 1, *k, d) - cost(level, *k, d);
                if spent + more <= budget {
                    spent += more;
                    t += 1;
                }
            }
            if cost(t, *k, d) > 0 {
                targets.push((t, i));
            }
        }
        left.store(budget - spent.min(budget), Ordering::Relaxed);
        let rays = targets
            .into_par_iter()
            .map(|(t, i)| {
                let (block, slot) = young[order[i].2];
                let mut d = order[i].3;
                let mut work = Work { rays: 0, cells: 0 };
                self.shade(tracer, &block, &mut d[..words], &mut work, Some(t));
                table.write(slot, &d[..words]);
                let topped = &self.cache.counters.topped_up;
                topped.fetch_add(work.cells as u64, Ordering::Relaxed);
                work.rays
            })
            .sum();
        young.clear();
        *self.cache.young.lock().expect("not poisoned") = young;
        times.since(TEXTURE_CACHE, start);
        rays
    }

    /// Shades `block`'s cells into their data `data` (count, channels per cell) by the
    /// temporal rule, or (`target`) each cell up to that many samples.
    fn shade(
        &self,
        tracer: &PathTracer,
        block: &Block,
        data: &mut [f32],
        work: &mut Work,
        target: Option<u32>,
    ) {
        let ch = self.cfg.channels();
        let stride = 1 + ch;
        let world = tracer.world;
        let mut cells = 0;
        if target.is_none() && self.cfg.temporal == Temporal::Mean && self.cfg.reshade > 0.0 {
            let mean = block_mean(block, data, stride);
            let u = (hash(&[block.key(), self.cache.frame as u64, self.seed]) >> 40) as f32
                / (1u64 << 24) as f32;
            if mean > 0.0 && u * mean >= self.cfg.reshade {
                return;
            }
        }
        // Each cell once, or (`target`) as many times as it lacks.
        let rounds = target.unwrap_or(1);
        for k in (0..rounds).flat_map(|_| 0..CELLS) {
            let Some(cell) = block.cell(k) else { continue };
            let d = &mut data[k * stride..(k + 1) * stride];
            let count = d[0] as u32;
            let limit = target.map_or(self.cfg.max_count, |t| t.min(self.cfg.max_count));
            if (self.cfg.temporal == Temporal::Mean || target.is_some()) && count >= limit {
                continue;
            }
            let (ray, hit) = self.grids.probe(world, &cell);
            let (surface, mut shading) = world.shaded(&ray, &hit, tracer.settings.microfacet);
            shading.params = BsdfParams::lambertian(Vec3::ONE);
            shading.alpha = 1.0;
            shading.volume = false;
            let vertex = Vertex {
                hit,
                surface,
                shading,
            };
            let key = cell.key();
            let sampler = PixelSampler::with_kind(
                tracer.settings.sampler,
                self.seed,
                key as u32,
                (key >> 32) as u32,
                count,
            );
            let rng = Rng::new(hash(&[self.seed, key]), count as u64);
            // Every light but the sun (`sky`) by next event estimation alone, from the
            // dimensions the path's would have taken; then no next event estimation at the
            // cell (with `indirect` its direct light is the pixel's own).
            let sky = (self.cfg.terms == CachedTerms::Sky).then(|| {
                let mut s = sampler.clone();
                s.set_dimension(CAMERA_DIMENSIONS);
                let (u_select, u) = (s.next_1d(), s.next_2d());
                let ls =
                    self.sun
                        .sample_with(&world.lights, Part::Sky, vertex.surface.p, u_select, u);
                let bsdf = world.bsdf(vertex.surface.material, &vertex.shading.params);
                let mut r = 0;
                let l = ls.map_or(Vec3::ZERO, |ls| {
                    tracer.light_alone(&vertex, &bsdf, -ray.direction, &ls, &mut r)
                });
                work.rays += r as u64;
                l
            });
            let direct = (self.cfg.terms != CachedTerms::All).then_some(Vec3::ZERO);
            let s = tracer.trace_lit::<false>(ray, Some(&vertex), sampler, rng, direct);
            work.rays += s.rays as u64;
            cells += 1;
            let mut v = [0.0f32; CHANNELS];
            let lum = pathlight_core::color::luminance(s.indirect);
            let indirect = match lum > self.clamp {
                true => s.indirect * (self.clamp / lum),
                false => s.indirect,
            };
            v[ch - 3..ch].copy_from_slice(&indirect.to_array());
            if let Some(sky) = sky {
                v[..3].copy_from_slice(&sky.to_array());
            } else if ch == 6 {
                let le = world.lights.emitted(
                    &world.scene,
                    cell.instance,
                    cell.triangle,
                    surface.bary,
                    -ray.direction,
                );
                v[..3].copy_from_slice(&(s.direct - le).max(Vec3::ZERO).to_array());
            }
            let w = match self.cfg.temporal {
                _ if count == 0 => 1.0,
                Temporal::Mean => 1.0 / (count + 1) as f32,
                Temporal::Exponential => 1.0 - self.cfg.temporal_alpha,
                Temporal::None => 1.0,
            };
            for c in 0..ch {
                d[1 + c] += (v[c] - d[1 + c]) * w;
            }
            d[0] = (count + 1) as f32;
        }
        work.cells += cells;
        self.cache
            .counters
            .cells
            .fetch_add(cells as u64, Ordering::Relaxed);
    }

    /// The filtered texels of `block`'s squares into `out` (channels per square): the
    /// separable window over the squares of the blocks around it, each square the mean of its
    /// shaded halves, clipped to the triangle and renormalised. The window narrows with the
    /// block's own cells' samples (`shrink`), and only the blocks it reaches are read.
    /// Neighbouring blocks being shaded by other threads are deferred and read last.
    fn filter(&self, tracer: &PathTracer, block: &Block, out: &mut [f32], work: &mut Work) {
        let ch = self.cfg.channels();
        let stride = 1 + ch;
        // The block's own cells first: their mean sample count narrows the window.
        let mut own = [0.0f32; CELLS * (1 + CHANNELS)];
        self.sample_block(tracer, block, &mut own, work);
        let mut weights = [0.0f32; MAX_KERNEL as usize];
        let weights = self.weights(block_mean(block, &own, stride), &mut weights);
        let radius = (weights.len() / 2) as i32;
        let reach = (radius + BLOCK as i32 - 1) / BLOCK as i32;
        let side = (2 * reach + 1) as usize;
        // The squares of the (2 reach + 1)^2 blocks around: per square, channel sums and the
        // weight (halves shaded).
        let w = side * BLOCK as usize;
        // Per-thread scratch (the filter runs once per texel block and frame).
        let (mut grid, mut rows) = SCRATCH.with_borrow_mut(std::mem::take);
        grid.clear();
        grid.resize(w * w * (ch + 1), 0.0);
        let mut cells = [0.0f32; CELLS * (1 + CHANNELS)];
        let mut deferred = Vec::new();
        let gather = |b: &Block, cells: &[f32], grid: &mut [f32]| {
            let ox = (b.at.x as i32 - block.at.x as i32 + reach) as usize * BLOCK as usize;
            let oy = (b.at.y as i32 - block.at.y as i32 + reach) as usize * BLOCK as usize;
            for k in 0..CELLS {
                if b.cell(k).is_none() {
                    continue;
                }
                let d = &cells[k * stride..(k + 1) * stride];
                if d[0] <= 0.0 {
                    continue;
                }
                let sq = (k / 2) as u32;
                let (sx, sy) = ((sq % BLOCK) as usize, (sq / BLOCK) as usize);
                let g = &mut grid[((oy + sy) * w + ox + sx) * (ch + 1)..][..ch + 1];
                for c in 0..ch {
                    g[c] += d[1 + c];
                }
                g[ch] += 1.0;
            }
        };
        gather(block, &own, &mut grid);
        for dy in -reach..=reach {
            for dx in -reach..=reach {
                let Some(b) = block.beside(dx, dy).filter(|_| (dx, dy) != (0, 0)) else {
                    continue;
                };
                match self.try_sample_block(tracer, &b, &mut cells, work) {
                    Some(_) => gather(&b, &cells, &mut grid),
                    None => deferred.push(b),
                }
            }
        }
        for b in deferred {
            self.sample_block(tracer, &b, &mut cells, work);
            gather(&b, &cells, &mut grid);
        }
        let lo = reach as usize * BLOCK as usize;
        let order = match self.cfg.filter {
            CacheFilter::Linear => 2,
            _ => 0,
        };
        convolve(&grid, w, lo, weights, ch, order, &mut rows, out);
        SCRATCH.with_borrow_mut(|s| *s = (grid, rows));
    }
}

/// The filter's window applied to `grid` (`w` x `w` squares, each its channels' sums and its
/// weight: `ch + 1` values) at the block's squares (`lo` squares from the grid's corner), into
/// `out` (`ch` values per square), separably: along x over the rows the block's squares need
/// (into `rows`), then along y. `order` 0: the window's weighted mean; 2: a weighted linear
/// regression over the squares' places, read at the square's own (the window's first and
/// second moments along each axis: a gradient across the window, or the window cut short by
/// its triangle's edge, no longer biases the texel toward the side that has more squares).
#[allow(clippy::too_many_arguments)]
fn convolve(
    grid: &[f32],
    w: usize,
    lo: usize,
    weights: &[f32],
    ch: usize,
    order: usize,
    rows: &mut Vec<f32>,
    out: &mut [f32],
) {
    let b = BLOCK as usize;
    let radius = (weights.len() / 2) as i32;
    let g1 = ch + 1;
    // Per row and square: sum over x of weight * d^p * value, p = 0..=order.
    let record = (order + 1) * g1;
    rows.clear();
    rows.resize(w * b * record, 0.0);
    for y in 0..w {
        for x in 0..b {
            let o = &mut rows[(y * b + x) * record..][..record];
            for (t, &wt) in weights.iter().enumerate() {
                let sx = (lo + x) as i32 + t as i32 - radius;
                if sx < 0 || sx >= w as i32 {
                    continue;
                }
                let g = &grid[(y * w + sx as usize) * g1..][..g1];
                let d = (t as i32 - radius) as f32;
                let mut wd = wt;
                for p in 0..=order {
                    for c in 0..g1 {
                        o[p * g1 + c] += wd * g[c];
                    }
                    wd *= d;
                }
            }
        }
    }
    for sy in 0..b {
        for sx in 0..b {
            // m[q][p]: sum of weight * dx^p * dy^q * value, p + q <= order.
            let mut m = [[[0.0f32; 1 + CHANNELS]; 3]; 3];
            for (t, &wt) in weights.iter().enumerate() {
                let y = (lo + sy) as i32 + t as i32 - radius;
                if y < 0 || y >= w as i32 {
                    continue;
                }
                let r = &rows[(y as usize * b + sx) * record..][..record];
                let e = (t as i32 - radius) as f32;
                let mut we = wt;
                for (q, mq) in m.iter_mut().enumerate().take(order + 1) {
                    for (p, mp) in mq.iter_mut().enumerate().take(order + 1 - q) {
                        for (v, x) in mp.iter_mut().zip(&r[p * g1..(p + 1) * g1]) {
                            *v += we * x;
                        }
                    }
                    we *= e;
                }
            }
            let o = &mut out[(sy * b + sx) * ch..][..ch];
            let n = m[0][0][ch];
            if n <= 0.0 {
                o.fill(0.0);
                continue;
            }
            // The linear model's intercept by the first row of the normal equations' inverse
            // (cofactors), the slopes damped (ridge) so that a window of few squares, or of
            // squares along a line, falls back toward the mean.
            let solve = |m: &[[[f32; 1 + CHANNELS]; 3]; 3]| {
                let (a, bb, cc) = (n, m[0][1][ch], m[1][0][ch]);
                let (d, e, f) = (
                    m[0][2][ch] + RIDGE * n,
                    m[1][1][ch],
                    m[2][0][ch] + RIDGE * n,
                );
                let (c0, c1, c2) = (d * f - e * e, cc * e - bb * f, bb * e - cc * d);
                let det = a * c0 + bb * c1 + cc * c2;
                (det > 1e-6 * a * d * f).then(|| [c0 / det, c1 / det, c2 / det])
            };
            match (order == 2).then(|| solve(&m)).flatten() {
                Some(k) => {
                    for c in 0..ch {
                        o[c] = (k[0] * m[0][0][c] + k[1] * m[0][1][c] + k[2] * m[1][0][c]).max(0.0);
                    }
                }
                _ => {
                    let norm = 1.0 / n;
                    for c in 0..ch {
                        o[c] = m[0][0][c] * norm;
                    }
                }
            }
        }
    }
}

/// The linear regression's damping of its slopes: added to the window's second moments, in
/// squares squared times its weight.
const RIDGE: f32 = 0.25;

thread_local! {
    /// The filter's scratch, per thread: the window's squares, and its rows filtered along x.
    static SCRATCH: std::cell::RefCell<(Vec<f32>, Vec<f32>)> =
        const { std::cell::RefCell::new((Vec::new(), Vec::new())) };
}

/// The mean sample count of `block`'s cells (those in its triangle) in its data `data`
/// (`stride` values per cell, the count first).
fn block_mean(block: &Block, data: &[f32], stride: usize) -> f32 {
    let (mut sum, mut n) = (0.0f32, 0u32);
    for k in (0..CELLS).filter(|&k| block.cell(k).is_some()) {
        sum += data[k * stride];
        n += 1;
    }
    sum / n.max(1) as f32
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

impl CacheFrame<'_> {
    /// The filter's 1D weights over its window for cells of `n` samples on average: a box of
    /// radius `radius n^-shrink` or a Gaussian of deviation `kernel / 4 n^-shrink` (at least a
    /// tenth of a square) over two deviations each side; at most `kernel` wide.
    fn weights<'w>(&self, n: f32, out: &'w mut [f32; MAX_KERNEL as usize]) -> &'w [f32] {
        let radius = (self.cfg.kernel / 2) as i32;
        let narrow = n.max(1.0).powf(-self.cfg.shrink);
        let sigma = (self.cfg.kernel as f32 / 4.0 * narrow).max(0.1);
        let reach = radius as f32 * narrow + 0.5;
        // The window's half-width narrows with it (the Gaussian's stays two deviations; the
        // box's is its reach), so that the blocks past it are not read.
        let half = match self.cfg.filter {
            CacheFilter::Gaussian | CacheFilter::Linear => (2.0 * sigma).ceil() as i32,
            _ => (reach.max(1.0) - 1e-3).floor() as i32,
        }
        .clamp(0, radius);
        let out = &mut out[..(2 * half + 1) as usize];
        for (o, d) in out.iter_mut().zip(-half..=half) {
            *o = match self.cfg.filter {
                CacheFilter::Gaussian | CacheFilter::Linear => {
                    (-(d * d) as f32 / (2.0 * sigma * sigma)).exp()
                }
                _ => f32::from((d.abs() as f32) < reach.max(1.0)),
            };
        }
        out
    }
}

impl Stage for TextureCache {
    fn name(&self) -> &'static str {
        TEXTURE_CACHE
    }

    fn views(&self) -> &'static [View] {
        Self::VIEWS
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
        self.cache.samples.bytes()
            + self.cache.texels.bytes()
            + self.pixels.capacity() * std::mem::size_of::<CachePixel>()
            + self.grids.as_ref().map_or(0, |g| g.2.bytes())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Keys that land in one set (a table of one set).
    fn keys(n: u64) -> Vec<u64> {
        (1..=n).map(|k| (hash(&[k]) | 4) & !STATE).collect()
    }

    fn publish_all(t: &Table, keys: &[u64], frame: u32) -> Vec<usize> {
        keys.iter()
            .map(|&k| match t.claim(k, frame) {
                Claim::Mine(i, _) => {
                    t.write(i, &[k as f32]);
                    t.publish(i, k, frame);
                    i
                }
                _ => panic!("{k:x} not claimed"),
            })
            .collect()
    }

    /// The window's filters on a grid of squares holding a linear ramp (one channel, each
    /// square weight 1 or, past a triangle's edge, empty): the weighted mean is the ramp's
    /// value where the window is whole and biased where an edge cuts it (toward the side that
    /// has squares); the linear regression gives the ramp's value exactly in both.
    #[test]
    fn the_regression_follows_a_gradient_to_the_window_s_edge() {
        let (w, lo, ch) = (10usize, 4usize, 1usize);
        let ramp = |x: usize, y: usize| 1.0 + 0.25 * x as f32 + 0.125 * y as f32;
        let weights: Vec<f32> = (-3i32..=3)
            .map(|d| (-(d * d) as f32 / (2.0 * 1.75f32.powi(2))).exp())
            .collect();
        // Whole, then cut: no squares left of column 4 (the block's left squares on the edge).
        for cut in [0usize, lo] {
            let mut grid = vec![0.0f32; w * w * (ch + 1)];
            for y in 0..w {
                for x in cut..w {
                    grid[(y * w + x) * 2] = ramp(x, y);
                    grid[(y * w + x) * 2 + 1] = 1.0;
                }
            }
            let mut rows = Vec::new();
            let (mut mean, mut linear) = ([0.0f32; SQUARES], [0.0f32; SQUARES]);
            convolve(&grid, w, lo, &weights, ch, 0, &mut rows, &mut mean);
            convolve(&grid, w, lo, &weights, ch, 2, &mut rows, &mut linear);
            for s in 0..SQUARES {
                let exact = ramp(lo + s % 2, lo + s / 2);
                let (bias, error) = ((mean[s] - exact).abs(), (linear[s] - exact).abs());
                if cut == 0 {
                    assert!(bias < 1e-4 * exact, "whole window, square {s}: {}", mean[s]);
                    assert!(
                        error < 1e-4 * exact,
                        "whole window, square {s}: {}",
                        linear[s]
                    );
                } else if s % 2 == 0 {
                    // (The regression's slopes are damped a little: not exact at the edge.)
                    assert!(
                        bias > 0.05 * exact,
                        "cut, square {s}: {} (no bias)",
                        mean[s]
                    );
                    assert!(
                        error < bias / 4.0,
                        "cut, square {s}: {} against {exact} (the mean's {})",
                        linear[s],
                        mean[s]
                    );
                }
            }
        }
    }

    /// Colliding keys are told apart by their tags: each reads its own data; at the next
    /// frame a new key takes the way shaded longest ago while the others keep their data; a
    /// set full of this frame's keys gives one of their ways to a new key (a table too small
    /// for its frame), and its readers see it go; a set whose ways are all being shaded turns
    /// a new key away.
    #[test]
    fn tags_catch_colliding_keys() {
        let t = Table::new(1, 1);
        assert_eq!(t.slots(), WAYS);
        let k = keys(WAYS as u64 + 2);
        let slots = publish_all(&t, &k[..WAYS], 1);
        for (&key, &i) in k.iter().zip(&slots) {
            match t.claim(key, 1) {
                Claim::Ready(j, s) => {
                    assert_eq!(j, i);
                    assert_eq!(t.word(j, 0), key as f32);
                    assert!(t.still(j, s, 1));
                }
                _ => panic!("{key:x} not ready"),
            }
        }
        // Frame 2: k[0] shaded again on its history; the new key takes the oldest way.
        match t.claim(k[0], 2) {
            Claim::Mine(i, fresh) => {
                assert!(!fresh);
                assert_eq!(t.word(i, 0), k[0] as f32, "its history kept");
                t.publish(i, k[0], 2)
            }
            _ => panic!("not claimed again"),
        }
        let taken = match t.claim(k[WAYS], 2) {
            Claim::Mine(i, fresh) => {
                assert!(fresh);
                assert_ne!(i, slots[0], "not the way shaded this frame");
                t.publish(i, k[WAYS], 2);
                i
            }
            _ => panic!("not claimed"),
        };
        assert!(matches!(t.claim(k[2], 2), Claim::Mine(_, false)) || slots[2] == taken);
        // Frame 3: every way shaded this frame, then one more key.
        let t = Table::new(1, 1);
        let slots = publish_all(&t, &k[..WAYS], 3);
        let (i0, s0) = match t.claim(k[0], 3) {
            Claim::Ready(i, s) => (i, s),
            _ => panic!("not ready"),
        };
        match t.claim(k[WAYS], 3) {
            Claim::Mine(i, true) => {
                t.write(i, &[1.5]);
                t.publish(i, k[WAYS], 3);
                let gone = slots.iter().position(|&j| j == i).unwrap();
                if i == i0 {
                    assert!(
                        !t.still(i0, s0, 3),
                        "the reader of the replaced key sees it go"
                    );
                }
                assert!(matches!(t.claim(k[gone], 3), Claim::Mine(_, true)));
            }
            _ => panic!("the new key found no way"),
        }
        // Every way being shaded: a new key is turned away.
        let busy = Table::new(1, 1);
        for &key in &k[..WAYS] {
            assert!(matches!(busy.claim(key, 1), Claim::Mine(..)));
        }
        assert!(matches!(busy.claim(k[WAYS + 1], 1), Claim::Full));
    }

    /// A set full of this frame's keys gives its ways up first in, first out: each new key
    /// takes the way filled longest ago, and the keys just put in stay (a set that gave up
    /// the same way every time would drop each new key at the next).
    #[test]
    fn a_full_set_gives_up_its_oldest_keys_first() {
        let t = Table::new(1, 1);
        let k = keys(WAYS as u64 + 3);
        let slots = publish_all(&t, &k[..WAYS], 1);
        for (n, &key) in k[WAYS..].iter().enumerate() {
            match t.claim(key, 1) {
                Claim::Mine(i, true) => {
                    assert_eq!(i, slots[n], "key {n} past the set's ways");
                    t.publish(i, key, 1);
                }
                _ => panic!("no way for key {n} past the set's ways"),
            }
        }
        // (The newest first: claiming a key that went puts it back, giving up another.)
        for (n, &key) in k.iter().enumerate().rev() {
            let ready = matches!(t.claim(key, 1), Claim::Ready(..));
            assert_eq!(ready, n >= 3, "key {n}");
        }
    }

    /// Two threads claiming the same keys of one frame: each key is claimed once, and ends in
    /// exactly one way.
    #[test]
    fn each_key_is_claimed_once_per_frame_by_two_threads() {
        // A table large enough for the frame (no set overflows).
        let t = Table::new(1 << 20, 1);
        let k = keys(2000);
        for frame in 1..4 {
            let claimed: Vec<AtomicU32> = k.iter().map(|_| AtomicU32::new(0)).collect();
            std::thread::scope(|s| {
                for _ in 0..2 {
                    s.spawn(|| {
                        for (n, &key) in k.iter().enumerate() {
                            loop {
                                match t.claim(key, frame) {
                                    Claim::Mine(i, _) => {
                                        claimed[n].fetch_add(1, Ordering::Relaxed);
                                        t.publish(i, key, frame);
                                        break;
                                    }
                                    Claim::Ready(..) | Claim::Full => break,
                                    Claim::Busy => std::hint::spin_loop(),
                                }
                            }
                        }
                    });
                }
            });
            let full = claimed
                .iter()
                .filter(|c| c.load(Ordering::Relaxed) == 0)
                .count();
            assert!(claimed.iter().all(|c| c.load(Ordering::Relaxed) <= 1));
            let ways = (0..t.slots())
                .filter(|&i| t.states[i].load(Ordering::Relaxed) & STATE == READY)
                .filter(|&i| t.frames[i].load(Ordering::Relaxed) == frame)
                .count();
            assert_eq!(ways + full, k.len(), "frame {frame}");
        }
    }

    /// A block's cells lie in the triangle, and its neighbours beyond the triangle are none.
    #[test]
    fn blocks_hold_the_triangles_cells() {
        let b = Block {
            instance: 0,
            triangle: 0,
            back: false,
            level: 0,
            at: UVec2::ZERO,
            resolution: 3,
        };
        let inside = (0..CELLS).filter(|&k| b.cell(k).is_some()).count();
        // A grid of 3: 9 cells, of which those in the block's first BLOCK x BLOCK squares.
        let want = (0..3u32)
            .flat_map(|y| (0..3u32).map(move |x| (x, y)))
            .filter(|&(x, y)| x < BLOCK && y < BLOCK)
            .map(|(x, y)| u32::from(x + y < 3) + u32::from(x + y + 1 < 3))
            .sum::<u32>();
        assert_eq!(inside as u32, want);
        assert!(b.beside(-1, 0).is_none());
        assert!(b.beside(3, 0).is_none());
    }
}
