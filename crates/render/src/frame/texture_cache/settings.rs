//! The texture cache's settings (`[frame.texture_cache]`) and their accepted ranges, with the
//! stage's name: what every layer of the cache reads.

use serde::{Deserialize, Serialize};

use crate::error::ConfigError;

/// The stage's name (its views' heading, its pass's time).
pub const TEXTURE_CACHE: &str = "texture-cache";
/// Light channels per cell at most (direct and indirect, [`TextureCacheConfig::channels`]).
pub(super) const CHANNELS: usize = 6;
/// Largest filter window.
pub const MAX_KERNEL: u32 = 41;
/// Most camera samples per frame of a pixel on an edge ([`TextureCacheConfig::edge_spp`]).
pub const MAX_EDGE_SPP: u32 = 64;
/// Most samples young cells are brought up to ([`TextureCacheConfig::fresh_spp`]).
pub const MAX_FRESH_SPP: u32 = 256;
/// Most paths per pixel per frame for young cells ([`TextureCacheConfig::fresh_budget`]).
pub const MAX_FRESH_BUDGET: f32 = 64.0;
/// Largest budget, in MB: the tables are allocated whole when the cache is switched on, and a
/// larger one buys nothing at the resolutions the pipeline runs (256 bytes per pixel already
/// evict nothing at 320x180; 4 GB is 2,000 bytes per pixel at 1920x1080).
pub const MAX_BUDGET_MB: f32 = 4096.0;
/// The settings' accepted ranges, which [`TextureCacheConfig::validate`] checks and the
/// viewer's sliders span.
pub mod ranges {
    use std::ops::RangeInclusive;
    pub const BUDGET_MB: RangeInclusive<f32> =
        0.01..=crate::frame::texture_cache::settings::MAX_BUDGET_MB;
    pub const LOD_BIAS: RangeInclusive<f32> = -8.0..=16.0;
    pub const SHRINK: RangeInclusive<f32> = 0.0..=2.0;
    pub const MIN_ROUGHNESS: RangeInclusive<f32> = 0.0..=1.0;
    pub const EDGE_SPP: RangeInclusive<u32> =
        1..=crate::frame::texture_cache::settings::MAX_EDGE_SPP;
    pub const FRESH_SPP: RangeInclusive<u32> =
        1..=crate::frame::texture_cache::settings::MAX_FRESH_SPP;
    pub const FRESH_BUDGET: RangeInclusive<f32> =
        0.0..=crate::frame::texture_cache::settings::MAX_FRESH_BUDGET;
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
    /// All but the environment's sun ([`SunAndSky`](crate::light::sun::SunAndSky)): each pixel adds the sun's direct light
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
    /// A cell about a pixel's area ([`Footprint::area_level`](super::footprint::Footprint::area_level)).
    Area,
    /// Eq. 1: the finer of the footprint's two directions ([`Footprint::level`](super::footprint::Footprint::level)).
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
    /// ([`SunAndSky::sun_irradiance`](crate::light::sun::SunAndSky::sun_irradiance)), times the BSDF and the visibility toward its one
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
    pub(super) fn channels(&self) -> usize {
        match self.terms {
            CachedTerms::Indirect => 3,
            CachedTerms::All | CachedTerms::Sky => CHANNELS,
        }
    }
}
