//! `[frame.filter]`: which reconstruction filter runs on the frame, and its parameters.
//!
//! The data-driven filter's defaults are the thesis's final parameters (Table 7.2: kernel 21,
//! sigma depth 1.75, normal 0.25, texture 0.1, direction 0.75, texture2 0.1, colour direct 0.75
//! and indirect 0.5), except where the thesis's units do not carry across scenes or samples:
//! - **Depth** is compared relative to the centre pixel's own depth (`depth_units =
//!   "relative"`): `(d_q - d_p) / d_p`, so the test means the same in a room and a city.
//!   The thesis compares scene units with sigma 1.75; its scenes (a Cornell box seen from about
//!   3.5 units) make that about 0.5 of the depth, the default here. `depth_units = "scene"`
//!   with `sigma_depth = 1.75` is the thesis's test.
//! - **Colour** differences squared are divided by the sum of the squares of the centre's and
//!   the neighbour's standard errors of the mean, the variance of their difference
//!   (`colour_units = "variance"`, `error_pair = "sum"`, sigma 1.25 for the direct light and
//!   4 for the indirect; `error_pair = "product"`, their product, was the first form, with
//!   sigma 4): the test follows the noise, as SVGF's luminance test does, so the filter
//!   smooths noise and keeps what the samples agree on, and fades as they accumulate. The
//!   indirect light, smooth where it is not noise, takes a loose test (sigma 1.5 for both
//!   until 2026-11-27; 4 and 1.25 measured better at 1, 8 and 32 spp on every scene of
//!   `experiments/001-quality.toml` but the helmet, 1-2% worse there; BENCHMARKS.md, "Seed
//!   001").
//!   The thesis's test on radiance as it is (`colour_units = "linear"`, sigmas 0.75 and 0.5)
//!   never converges: its error stops falling while the unfiltered image's goes on (measured,
//!   at c8a57f1, 2026-11-25: at 32 spp 0.68-2.9x the unfiltered CIELUV MSE, against
//!   0.12-1.2x in variance units). `colour_units = "relative"` divides by
//!   `(1 + L_p)(1 + L_q)`, the luminances of the two pixels' light (dividing by the centre's
//!   alone blurred the Cornell box's light into its ceiling).
//! - **Texture2** (`texture2_test`, off): the indirect light's test on the albedo at the
//!   second hit is not made. Its value at a pixel is the mean of a few random bounces'
//!   albedos, noise at the sample counts the filter runs at, and with sigma 0.1 the test
//!   refused neighbours at random (measured: with it the interior's CIELUV MSE at 8 spp is
//!   0.30x the unfiltered image's, without 0.14x; BENCHMARKS.md, "Seed 001"). On, it is the
//!   thesis's, with `sigma_texture2`.
//! - **Colour weights** (`colour_weights`, `albedo`): a difference of light is tested on the
//!   channels the centre's albedo shows, not on each alike ([`ColourWeights`]; `equal` is the
//!   thesis's). Demodulated, a saturated surface's dim channels carry noise divided by their
//!   small albedo, and tested alike they hide a change in the channel the surface shows
//!   (measured on `experiments/001-quality.toml`: at 8 spp the interior's CIELUV MSE 0.08x
//!   the unfiltered image's with `equal`, 0.06x with `albedo`; the garden's at 128 frames of
//!   `experiments/001-still.toml` 1.30x and 0.92x; eb0b101, 2026-11-28).
//! - **Demodulation** (`demodulate`, on): the light is filtered divided by the albedo.
//! - **The two pixels' errors** (`error_pair`, `sum`): added in squares or multiplied
//!   ([`crate::data_driven`]).
//! - **Blurred standard errors** (`error_blur`, off): in variance units, each pixel's
//!   standard error taken over its 3x3 neighbourhood's ([`crate::data_driven`]).
//! - **Glossy normals** (`sigma_normal_lobe`, 1): a metallic pixel's normal test is as tight
//!   as its reflection lobe ([`crate::data_driven`]).
//! - **Silhouettes against the sky** (`sky_coverage`, on): filtered as their hits alone
//!   (the frame pipeline's `filter` pass).
//! - **The SURE blend** (`sure`, off; `sure_radius`, 3): in variance units, each pixel's
//!   filtered light blended with its own by their estimated errors ([`crate::sure`]).
//! - **Variance scales** `s_f` (depth, normal, texture, direction, texture2) are not published;
//!   1 each by choice.

use serde::{Deserialize, Serialize};

use crate::FilterError;

/// The reconstruction filter of the frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Method {
    /// The accumulated image as it is.
    #[default]
    None,
    /// Seed 001's data-driven feature-guided filter ([`crate::data_driven`]).
    DataDriven,
    /// A spatio-temporal variance-guided filter in the manner of SVGF ([`crate::svgf`]): it
    /// filters each frame's own samples with its temporal history.
    Svgf,
    /// Random Parameter Filtering ([`crate::rpf`]), the offline baseline: it filters every
    /// sample apart, so it runs on the reference path tracer's samples (`pathlight render
    /// --filter rpf`, or an `eval` configuration), not in the real-time frame.
    Rpf,
    /// Temporal antialiasing alone ([`crate::taa`], SVGF's last stage without the filter) of
    /// the accumulated image: for frames whose light is already smooth (seed 002's texture
    /// cache), their single sample's edges averaged over frames as the jitter moves them.
    Taa,
}

impl Method {
    /// True for the filters the real-time frame runs.
    pub fn in_frame(self) -> bool {
        matches!(self, Self::DataDriven | Self::Svgf | Self::Taa)
    }
}

/// How depth differences are measured.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum DepthUnits {
    /// Relative to the centre pixel's depth.
    #[default]
    Relative,
    /// In scene units (the thesis).
    Scene,
}

/// How colour differences are measured.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ColourUnits {
    /// Squared differences over (1 + the centre's luminance)(1 + the neighbour's).
    Relative,
    /// Radiance as it is (the thesis).
    Linear,
    /// Squared differences over the centre's and the neighbour's standard errors of the mean
    /// ([`crate::Features::light_variance`], or the 3x3 neighbourhood's
    /// where unknown), combined as [`ErrorPair`] says: the test follows the noise, so the
    /// filter fades as samples accumulate (SVGF's luminance test in this filter's form;
    /// sigmas of 1.5 to 2 suit the sum, 2 to 4 the product).
    #[default]
    Variance,
}

/// How the colour test weighs the three channels of a difference of light (demodulated).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ColourWeights {
    /// Each channel alike, `|dF|^2` (the thesis's).
    Equal,
    /// Channel `c` by `(a_c / L(a))^2`, `a` the centre's albedo (its demodulator) and `L` its
    /// luminance: the difference as the centre pixel shows it, relative to its albedo's
    /// brightness, so a saturated surface is tested on the channels it shows. In variance
    /// units the standard errors are then the mean over the channels of each channel's
    /// variance of the mean (relative to `L(a)^2`), which makes the test's noise the same
    /// as on a grey surface (not in the thesis).
    #[default]
    Albedo,
}

/// How the centre's and the neighbour's standard errors of the mean, `e_p` and `e_q`, scale a
/// squared colour difference (`colour_units = "variance"`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ErrorPair {
    /// Over `e_p^2 + e_q^2`, the variance of the difference of the two means: a pixel whose
    /// samples hold a firefly (a large error) takes its neighbours' light and lends them its
    /// own.
    #[default]
    Sum,
    /// Over `e_p e_q` (this filter's first form): a pixel whose samples agree is a wall to a
    /// noisy neighbour, and a firefly stays where it fell.
    Product,
}

/// `[frame.filter]`: the method, and each method's settings in its own table.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(default, try_from = "FilterFile")]
pub struct FilterConfig {
    pub method: Method,
    /// `[frame.filter.data_driven]`: seed 001's filter (and SVGF's handover to it).
    pub data_driven: DataDrivenConfig,
    /// `[frame.filter.svgf]`: the spatio-temporal filter.
    pub svgf: SvgfConfig,
    /// `[frame.filter.taa]`: temporal antialiasing (SVGF's last stage, and `method = "taa"`).
    pub taa: TaaConfig,
    /// `[frame.filter.rpf]`: Random Parameter Filtering, the offline baseline.
    pub rpf: crate::rpf::RpfParams,
}

/// `[frame.filter.data_driven]`: the data-driven filter (seed 001; module docs for its
/// departures from the thesis).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DataDrivenConfig {
    /// The window's width in pixels (odd).
    pub kernel: u32,
    /// Every other pixel of the window in each direction ("with holes").
    pub holes: bool,
    /// Sigma of the direct light's colour test, in `colour_units` (standard
    /// errors of the difference by default; the thesis's 0.75 is in radiance).
    pub sigma_direct: f32,
    /// Sigma of the indirect light's colour test (the thesis's 0.5).
    pub sigma_indirect: f32,
    pub sigma_depth: f32,
    pub sigma_normal: f32,
    pub sigma_texture: f32,
    pub sigma_texture2: f32,
    /// The indirect light's test on texture2, the albedo at the second hit
    /// (the thesis's; off by default: over a few samples the mean of a random bounce's
    /// albedo is noise, and the test refuses neighbours at random).
    pub texture2_test: bool,
    /// Variance scales `s_f` of depth, normal, texture, direction and texture2: a feature's
    /// variance times its scale (clamped to 1) lowers its coefficient (more blur where the
    /// feature itself is noisy). 0 ignores the variance.
    pub variance_scale: [f32; 5],
    pub depth_units: DepthUnits,
    pub colour_units: ColourUnits,
    /// How the colour test weighs the channels of a difference (not in the
    /// thesis).
    pub colour_weights: ColourWeights,
    /// Filter the light divided by the albedo (the illumination), then multiply
    /// it back (not in the thesis).
    pub demodulate: bool,
    /// Variance units: each pixel's standard error taken over its 3x3
    /// neighbourhood (the root of the mean of the squares), as SVGF blurs its variance: a few
    /// samples' variance is itself noisy (not in the thesis).
    pub error_blur: bool,
    /// Variance units: how the two pixels' standard errors combine (not in the
    /// thesis).
    pub error_pair: ErrorPair,
    /// At a metallic pixel, whose light is a glossy reflection that turns with
    /// the normal, the normal test's sigma is at most this times the lobe's GGX alpha
    /// (roughness squared, at least 0.01), blended by the metallic factor; 0 keeps
    /// `sigma_normal` everywhere, the thesis's test (not in the thesis).
    pub sigma_normal_lobe: f32,
    /// In the frame: a pixel only some of whose samples hit a surface (a
    /// silhouette against the sky) is filtered as its hits alone (the sky's light taken out,
    /// the rest divided by the hits' share; the filtered light scaled back and the sky's
    /// added) where the frame knows every sample's sky (one sample per frame); off, or where
    /// it does not, the mixture is filtered with its hits' features (not in the thesis).
    pub sky_coverage: bool,
    /// Variance units: each pixel's filtered light is blended with its own by
    /// their squared errors, estimated with Stein's unbiased risk estimate (SURE) and averaged
    /// over the pixel's `(2 sure_radius + 1)^2` neighbourhood, direct and indirect apart: where
    /// the filter moved the pixel further than its noise explains, its own light takes over
    /// (not in the thesis).
    pub sure: bool,
    /// `sure`: the radius of the neighbourhood the risk estimates are averaged
    /// over (0: the pixel's own).
    pub sure_radius: u32,
    /// On the accumulated image of a still camera (and SVGF's handover to it):
    /// the image is filtered again only once the epoch's accumulated frames have grown by this
    /// factor since it was last filtered, and shown as it was meanwhile, as offline renderers
    /// denoise every so many passes (not in the thesis), but for the light a pixel showed as
    /// its own (where it passed through, and its share of its own light in the `sure` blend),
    /// which follows the accumulated light. The filter's cost then grows with the logarithm of
    /// the frames instead of with them: at 1.25 a still view of 300 frames is filtered 22
    /// times. At most 1 (0 by default) filters every frame. A change of the filter's
    /// configuration filters at once.
    pub refresh_growth: f32,
}

impl Default for DataDrivenConfig {
    fn default() -> Self {
        Self {
            kernel: 21,
            holes: false,
            sigma_direct: 1.25,
            sigma_indirect: 4.0,
            sigma_depth: 0.5,
            sigma_normal: 0.25,
            sigma_texture: 0.1,
            sigma_texture2: 0.1,
            texture2_test: false,
            variance_scale: [1.0; 5],
            depth_units: DepthUnits::Relative,
            colour_units: ColourUnits::Variance,
            colour_weights: ColourWeights::Albedo,
            demodulate: true,
            error_blur: false,
            error_pair: ErrorPair::Sum,
            sigma_normal_lobe: 1.0,
            sky_coverage: true,
            sure: false,
            sure_radius: 3,
            refresh_growth: 0.0,
        }
    }
}

/// `[frame.filter.svgf]`: SVGF, the spatio-temporal filter.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SvgfConfig {
    /// A-trous iterations.
    pub atrous_iterations: u32,
    /// The a-trous kernel's width, 5 (the paper's B3 spline) or 3 (the linear
    /// B-spline: a third of the taps; not in the paper). 3 by default: along camera paths as
    /// good or better on every scene measured, in 0.6x the time (BENCHMARKS.md, "Seed 001").
    pub atrous_kernel: u32,
    /// Integrate and filter direct and indirect light apart (the paper's two signals);
    /// false filters their sum as one signal (not in the paper: about 40% fewer operations
    /// per tap).
    pub split: bool,
    /// The reprojection's normal test. `k > 0` (16 by default) keeps a previous pixel
    /// whose normal lies within `k (w + 0.01)` of this one's, `w` this pixel's normal width
    /// (over its four neighbours, the smaller of each axis's two differences), as the paper's
    /// authors' implementation tests against the normal's screen-space width: normal-mapped
    /// foliage, whose normals change from pixel to pixel, keeps its history, a flat surface
    /// is tested more tightly than by a cosine of 0.9. 0 keeps a previous pixel whose normal's
    /// cosine with this one's is at least 0.9 (this filter's first test; not in the paper).
    pub normal_width: f32,
    /// Temporal antialiasing of the output (the paper applies it after the filter;
    /// [`crate::taa`]): each pixel blended with its reprojected previous output (weight 0.7),
    /// clamped to this frame's 3x3 neighbourhood's mean plus and minus half a standard
    /// deviation (in YCoCg of light compressed by its luminance). On by default (the paper's
    /// last stage): along every orbit measured 15-45% less CIELUV error and 2.4-5x less
    /// flicker, for 3-5 ms at 640x360.
    pub taa: bool,
    /// Converge while the camera is still (not in the paper): a pixel whose motion
    /// vector is 0 takes each frame into a plain mean of its history instead of at a weight of
    /// 0.2, and its luminance test narrows with the mean's noise, so a still view converges
    /// to the path tracer's image; a pixel that moves is filtered as the paper does
    /// ([`crate::svgf`]). On by default: better at 32 and 128 still frames on every scene
    /// measured, and a moving camera's frames are the same bit for bit.
    pub converge: bool,
    /// Once the camera has been still for this many frames, the data-driven filter of
    /// the accumulated image (with this configuration's data-driven parameters) takes over
    /// until it moves again; 0 never (not in the paper). Needs `frame.accumulate`: the frame
    /// gathers the features' statistics of every frame of a still camera (from each epoch's
    /// first on, as the data-driven filter does: its silhouettes against the sky need every
    /// sample's; the first is gathered by the second frame, so a camera that moves at every
    /// frame gathers none), and
    /// SVGF's history, which stops while the data-driven filter runs, is the still view's
    /// when the camera moves on.
    pub still_handover: u32,
}

impl Default for SvgfConfig {
    fn default() -> Self {
        Self {
            atrous_iterations: 5,
            atrous_kernel: 3,
            split: true,
            normal_width: 16.0,
            taa: true,
            converge: true,
            still_handover: 0,
        }
    }
}

/// `[frame.filter.taa]`: temporal antialiasing.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TaaConfig {
    /// Temporal antialiasing (SVGF's last stage, and `method = "taa"`): this frame's weight in
    /// the blend with the clamped history (0.3, chosen for SVGF's output; higher trails less
    /// behind a moving camera and smooths less).
    pub alpha: f32,
    /// Temporal antialiasing: the half-width of the box the history is clamped to, in standard
    /// deviations of this frame's 3x3 neighbourhood (0.5, chosen for SVGF's output; wider
    /// keeps more of the history: smoother, and slower to follow a change).
    pub gamma: f32,
}

impl Default for TaaConfig {
    fn default() -> Self {
        Self {
            alpha: crate::taa::ALPHA,
            gamma: crate::taa::GAMMA,
        }
    }
}

/// The flat keys `[frame.filter]` had before each method's settings got their own table, and
/// where each is now: a file that sets one is refused, naming its new key.
pub const MOVED: [(&str, &str); 35] = [
    ("kernel", "data_driven.kernel"),
    ("holes", "data_driven.holes"),
    ("sigma_direct", "data_driven.sigma_direct"),
    ("sigma_indirect", "data_driven.sigma_indirect"),
    ("sigma_depth", "data_driven.sigma_depth"),
    ("sigma_normal", "data_driven.sigma_normal"),
    ("sigma_texture", "data_driven.sigma_texture"),
    ("sigma_texture2", "data_driven.sigma_texture2"),
    ("texture2_test", "data_driven.texture2_test"),
    ("variance_scale", "data_driven.variance_scale"),
    ("depth_units", "data_driven.depth_units"),
    ("colour_units", "data_driven.colour_units"),
    ("colour_weights", "data_driven.colour_weights"),
    ("demodulate", "data_driven.demodulate"),
    ("error_blur", "data_driven.error_blur"),
    ("error_pair", "data_driven.error_pair"),
    ("sigma_normal_lobe", "data_driven.sigma_normal_lobe"),
    ("sky_coverage", "data_driven.sky_coverage"),
    ("sure", "data_driven.sure"),
    ("sure_radius", "data_driven.sure_radius"),
    ("refresh_growth", "data_driven.refresh_growth"),
    ("atrous_iterations", "svgf.atrous_iterations"),
    ("atrous_kernel", "svgf.atrous_kernel"),
    ("svgf_split", "svgf.split"),
    ("svgf_normal_width", "svgf.normal_width"),
    ("svgf_taa", "svgf.taa"),
    ("svgf_converge", "svgf.converge"),
    ("svgf_still_handover", "svgf.still_handover"),
    ("taa_alpha", "taa.alpha"),
    ("taa_gamma", "taa.gamma"),
    ("rpf_boxes", "rpf.boxes"),
    ("rpf_noise", "rpf.noise"),
    ("rpf_outliers", "rpf.outliers"),
    ("rpf_demodulate", "rpf.demodulate"),
    ("rpf_sky", "rpf.sky"),
];

/// `[frame.filter]` as a file writes it: the tables, and any old flat key (refused).
#[derive(Default, Deserialize)]
#[serde(default)]
struct FilterFile {
    method: Method,
    data_driven: DataDrivenConfig,
    svgf: SvgfConfig,
    taa: TaaConfig,
    rpf: crate::rpf::RpfParams,
    #[serde(flatten)]
    moved: std::collections::BTreeMap<String, serde::de::IgnoredAny>,
}

impl TryFrom<FilterFile> for FilterConfig {
    type Error = String;

    fn try_from(f: FilterFile) -> Result<Self, String> {
        if let Some(key) = f.moved.keys().next() {
            return Err(match MOVED.iter().find(|(old, _)| old == key) {
                Some((old, new)) => format!(
                    "`frame.filter.{old}` has moved: it is `{new}` in `[frame.filter.{}]` now",
                    new.split('.').next().unwrap_or_default()
                ),
                None => format!("unknown field `{key}` in `[frame.filter]`"),
            });
        }
        Ok(Self {
            method: f.method,
            data_driven: f.data_driven,
            svgf: f.svgf,
            taa: f.taa,
            rpf: f.rpf,
        })
    }
}

/// Widest window accepted (the thesis tried up to 55).
pub const MAX_KERNEL: u32 = 127;

/// Widest neighbourhood the SURE blend averages its estimates over (`sure_radius`).
pub const MAX_SURE_RADIUS: u32 = 32;

/// The accepted range of each numeric setting: what `validate()` checks and what the viewer's
/// sliders span (one source for both).
pub mod ranges {
    use std::ops::RangeInclusive;

    pub const KERNEL: RangeInclusive<u32> = 1..=super::MAX_KERNEL;
    /// Every colour and feature sigma.
    pub const SIGMA: RangeInclusive<f32> = 0.001..=1.0e6;
    pub const SIGMA_NORMAL_LOBE: RangeInclusive<f32> = 0.0..=16.0;
    pub const VARIANCE_SCALE: RangeInclusive<f32> = 0.0..=1000.0;
    pub const SURE_RADIUS: RangeInclusive<u32> = 0..=super::MAX_SURE_RADIUS;
    pub const REFRESH_GROWTH: RangeInclusive<f32> = 0.0..=16.0;
    pub const ATROUS_ITERATIONS: RangeInclusive<u32> = 1..=crate::svgf::MAX_ITERATIONS;
    pub const NORMAL_WIDTH: RangeInclusive<f32> = 0.0..=64.0;
    pub const STILL_HANDOVER: RangeInclusive<u32> = 0..=1024;
    pub const TAA_ALPHA: RangeInclusive<f32> = 0.01..=1.0;
    pub const TAA_GAMMA: RangeInclusive<f32> = 0.05..=100.0;
}

/// `value` of `field` within `range` (NaN is not).
fn within<T: PartialOrd + std::fmt::Display>(
    field: &'static str,
    value: T,
    range: &std::ops::RangeInclusive<T>,
) -> Result<(), FilterError> {
    if range.contains(&value) {
        Ok(())
    } else {
        FilterError::parameter(
            field,
            value,
            format!("from {} to {}", range.start(), range.end()),
        )
    }
}

impl DataDrivenConfig {
    /// Checks the parameters against [`ranges`] (the kernel odd too; the SURE blend in
    /// variance units).
    pub fn validate(&self) -> Result<(), FilterError> {
        if self.kernel.is_multiple_of(2) {
            return FilterError::parameter(
                "frame.filter.data_driven.kernel",
                self.kernel,
                format!("an odd width from 1 to {MAX_KERNEL}"),
            );
        }
        within(
            "frame.filter.data_driven.kernel",
            self.kernel,
            &ranges::KERNEL,
        )?;
        for (field, v) in [
            ("frame.filter.data_driven.sigma_direct", self.sigma_direct),
            (
                "frame.filter.data_driven.sigma_indirect",
                self.sigma_indirect,
            ),
            ("frame.filter.data_driven.sigma_depth", self.sigma_depth),
            ("frame.filter.data_driven.sigma_normal", self.sigma_normal),
            ("frame.filter.data_driven.sigma_texture", self.sigma_texture),
            (
                "frame.filter.data_driven.sigma_texture2",
                self.sigma_texture2,
            ),
        ] {
            within(field, v, &ranges::SIGMA)?;
        }
        within(
            "frame.filter.data_driven.sigma_normal_lobe",
            self.sigma_normal_lobe,
            &ranges::SIGMA_NORMAL_LOBE,
        )?;
        within(
            "frame.filter.data_driven.refresh_growth",
            self.refresh_growth,
            &ranges::REFRESH_GROWTH,
        )?;
        within(
            "frame.filter.data_driven.sure_radius",
            self.sure_radius,
            &ranges::SURE_RADIUS,
        )?;
        if self.sure && self.colour_units != ColourUnits::Variance {
            return FilterError::parameter(
                "frame.filter.data_driven.sure",
                self.sure,
                "colour_units = \"variance\" (the risk needs the pixels' standard errors)",
            );
        }
        for s in self.variance_scale {
            within(
                "frame.filter.data_driven.variance_scale",
                s,
                &ranges::VARIANCE_SCALE,
            )?;
        }
        Ok(())
    }
}

impl FilterConfig {
    /// Checks each method's parameters (the data-driven filter's, SVGF's, the temporal
    /// antialiasing's, RPF's) against [`ranges`].
    pub fn validate(&self) -> Result<(), FilterError> {
        self.data_driven.validate()?;
        within(
            "frame.filter.svgf.atrous_iterations",
            self.svgf.atrous_iterations,
            &ranges::ATROUS_ITERATIONS,
        )?;
        within(
            "frame.filter.svgf.normal_width",
            self.svgf.normal_width,
            &ranges::NORMAL_WIDTH,
        )?;
        within(
            "frame.filter.svgf.still_handover",
            self.svgf.still_handover,
            &ranges::STILL_HANDOVER,
        )?;
        within("frame.filter.taa.alpha", self.taa.alpha, &ranges::TAA_ALPHA)?;
        within("frame.filter.taa.gamma", self.taa.gamma, &ranges::TAA_GAMMA)?;
        self.svgf_params().validate()?;
        self.rpf_params(0).validate()
    }

    /// The filter a frame runs after `still` frames of a still camera (the frames accumulated
    /// in the epoch, this one included): `method`, or the data-driven filter once SVGF hands
    /// over (`svgf.still_handover`).
    pub fn method_after(&self, still: u32) -> Method {
        match self.method {
            Method::Svgf if self.svgf.still_handover > 0 && still >= self.svgf.still_handover => {
                Method::DataDriven
            }
            m => m,
        }
    }

    /// The frame gathers the features' statistics for the data-driven filter: it may run
    /// in this epoch.
    pub fn gathers_features(&self) -> bool {
        self.method == Method::DataDriven
            || (self.method == Method::Svgf && self.svgf.still_handover > 0)
    }

    /// SVGF's parameters.
    pub fn svgf_params(&self) -> crate::SvgfParams {
        crate::SvgfParams {
            iterations: self.svgf.atrous_iterations,
            kernel: self.svgf.atrous_kernel,
            split: self.svgf.split,
            normal_width: self.svgf.normal_width,
            taa: self.svgf.taa,
            taa_alpha: self.taa.alpha,
            taa_gamma: self.taa.gamma,
            converge: self.svgf.converge,
        }
    }

    /// RPF's parameters, with the seed of its random draws.
    pub fn rpf_params(&self, seed: u64) -> crate::rpf::RpfParams {
        crate::rpf::RpfParams {
            seed,
            ..self.rpf.clone()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_issue_fields_parse_and_bad_values_are_refused() {
        let c: FilterConfig = toml::from_str(
            "method = \"data-driven\"\n[data_driven]\nkernel = 21\nholes = true\n\
             [svgf]\natrous_iterations = 5\n",
        )
        .unwrap();
        assert_eq!(c.method, Method::DataDriven);
        assert!(c.data_driven.holes);
        assert_eq!(c.validate(), Ok(()));
        for (table, field, value) in [
            ("data_driven", "kernel", "20"),
            ("data_driven", "kernel", "0"),
            ("data_driven", "sigma_depth", "-1.0"),
            ("data_driven", "sigma_direct", "0.0"),
            ("data_driven", "sigma_normal", "nan"),
            (
                "data_driven",
                "variance_scale",
                "[1.0, -1.0, 1.0, 1.0, 1.0]",
            ),
            ("data_driven", "sigma_normal_lobe", "-1.0"),
            ("data_driven", "sigma_normal_lobe", "inf"),
            ("svgf", "normal_width", "-16.0"),
            ("svgf", "normal_width", "nan"),
            ("svgf", "atrous_iterations", "0"),
            ("svgf", "atrous_kernel", "4"),
            ("rpf", "boxes", "[55, 34]"),
            ("rpf", "noise", "0.0"),
            ("taa", "alpha", "0.0"),
            ("taa", "gamma", "0.0"),
            ("taa", "gamma", "nan"),
            ("taa", "gamma", "inf"),
        ] {
            let c: FilterConfig = toml::from_str(&format!("[{table}]\n{field} = {value}")).unwrap();
            let e = c.validate().unwrap_err().to_string();
            assert!(
                e.contains(&format!("frame.filter.{table}.{field}")),
                "{field}: {e}"
            );
        }
        assert!(toml::from_str::<FilterConfig>("[data_driven]\nkernal = 3").is_err());
        let e = toml::from_str::<FilterConfig>("kernal = 3")
            .unwrap_err()
            .to_string();
        assert!(e.contains("kernal"), "{e}");
    }

    /// Each flat key of before the tables is refused with a message naming its new key, and
    /// the new key takes the value.
    #[test]
    fn an_old_flat_key_is_refused_naming_its_new_one() {
        for (old, new) in MOVED {
            let e = toml::from_str::<FilterConfig>(&format!("{old} = 1"))
                .unwrap_err()
                .to_string();
            assert!(e.contains(old) && e.contains(new), "{old}: {e}");
            let (table, key) = new.split_once('.').unwrap();
            let value = match key {
                "boxes" => "[7]",
                "variance_scale" => "[2.0, 1.0, 1.0, 1.0, 1.0]",
                "depth_units" => "\"scene\"",
                "colour_units" => "\"linear\"",
                "colour_weights" => "\"equal\"",
                "error_pair" => "\"product\"",
                _ => {
                    let default = toml::to_string(&FilterConfig::default()).unwrap();
                    let table_text = default.split(&format!("[{table}]")).nth(1).unwrap();
                    let line = table_text
                        .lines()
                        .find(|l| l.starts_with(&format!("{key} = ")))
                        .unwrap();
                    match line.split(" = ").nth(1).unwrap() {
                        "true" => "false",
                        "false" => "true",
                        v if v.contains('.') => "0.375",
                        _ => "7",
                    }
                }
            };
            let c: FilterConfig = toml::from_str(&format!("[{table}]\n{key} = {value}")).unwrap();
            assert_ne!(
                c,
                FilterConfig::default(),
                "{new} = {value} changed nothing"
            );
        }
    }

    #[test]
    fn svgf_hands_over_to_the_data_driven_filter_after_the_still_frames() {
        let mut c = FilterConfig {
            method: Method::Svgf,
            ..FilterConfig::default()
        };
        assert!(!c.gathers_features());
        assert_eq!(c.method_after(1000), Method::Svgf);
        c.svgf.still_handover = 8;
        assert!(c.gathers_features());
        assert_eq!(c.method_after(7), Method::Svgf);
        assert_eq!(c.method_after(8), Method::DataDriven);
        c.method = Method::None;
        assert_eq!(c.method_after(8), Method::None);
        assert!(!c.gathers_features());
    }
}
