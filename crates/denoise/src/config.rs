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
//!   BENCHMARKS.md "Seed 001": at 32 spp 0.68-2.9x the unfiltered CIELUV MSE, against
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
//!   `experiments/001-still.toml` 1.30x and 0.92x; BENCHMARKS.md, "Seed 001").
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

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FilterConfig {
    pub method: Method,
    /// Data-driven: the window's width in pixels (odd).
    pub kernel: u32,
    /// Data-driven: every other pixel of the window in each direction ("with holes").
    pub holes: bool,
    /// SVGF: a-trous iterations.
    pub atrous_iterations: u32,
    /// SVGF: the a-trous kernel's width, 5 (the paper's B3 spline) or 3 (the linear
    /// B-spline: a third of the taps; not in the paper). 3 by default: along camera paths as
    /// good or better on every scene measured, in 0.6x the time (BENCHMARKS.md, "Seed 001").
    pub atrous_kernel: u32,
    /// SVGF: integrate and filter direct and indirect light apart (the paper's two signals);
    /// false filters their sum as one signal (not in the paper: about 40% fewer operations
    /// per tap).
    pub svgf_split: bool,
    /// SVGF: the reprojection's normal test. `k > 0` (16 by default) keeps a previous pixel
    /// whose normal lies within `k (w + 0.01)` of this one's, `w` this pixel's normal width
    /// (over its four neighbours, the smaller of each axis's two differences), as the paper's
    /// authors' implementation tests against the normal's screen-space width: normal-mapped
    /// foliage, whose normals change from pixel to pixel, keeps its history, a flat surface
    /// is tested more tightly than by a cosine of 0.9. 0 keeps a previous pixel whose normal's
    /// cosine with this one's is at least 0.9 (this filter's first test; not in the paper).
    pub svgf_normal_width: f32,
    /// SVGF: temporal antialiasing of the output (the paper applies it after the filter;
    /// [`crate::taa`]): each pixel blended with its reprojected previous output (weight 0.7),
    /// clamped to this frame's 3x3 neighbourhood's mean plus and minus half a standard
    /// deviation (in YCoCg of light compressed by its luminance). On by default (the paper's
    /// last stage): along every orbit measured 15-45% less CIELUV error and 2.4-5x less
    /// flicker, for 3-5 ms at 640x360.
    pub svgf_taa: bool,
    /// Temporal antialiasing (SVGF's last stage, and `method = "taa"`): this frame's weight in
    /// the blend with the clamped history (0.3, chosen for SVGF's output; higher trails less
    /// behind a moving camera and smooths less).
    pub taa_alpha: f32,
    /// Temporal antialiasing: the half-width of the box the history is clamped to, in standard
    /// deviations of this frame's 3x3 neighbourhood (0.5, chosen for SVGF's output; wider
    /// keeps more of the history: smoother, and slower to follow a change).
    pub taa_gamma: f32,
    /// SVGF: converge while the camera is still (not in the paper): a pixel whose motion
    /// vector is 0 takes each frame into a plain mean of its history instead of at a weight of
    /// 0.2, and its luminance test narrows with the mean's noise, so a still view converges
    /// to the path tracer's image; a pixel that moves is filtered as the paper does
    /// ([`crate::svgf`]). On by default: better at 32 and 128 still frames on every scene
    /// measured, and a moving camera's frames are the same bit for bit.
    pub svgf_converge: bool,
    /// SVGF: once the camera has been still for this many frames, the data-driven filter of
    /// the accumulated image (with this configuration's data-driven parameters) takes over
    /// until it moves again; 0 never (not in the paper). Needs `frame.accumulate`: the frame
    /// gathers the features' statistics of every frame of a still camera (from each epoch's
    /// first on, as the data-driven filter does: its silhouettes against the sky need every
    /// sample's; the first is gathered by the second frame, so a camera that moves at every
    /// frame gathers none), and
    /// SVGF's history, which stops while the data-driven filter runs, is the still view's
    /// when the camera moves on.
    pub svgf_still_handover: u32,
    /// Data-driven: sigma of the direct light's colour test, in `colour_units` (standard
    /// errors of the difference by default; the thesis's 0.75 is in radiance).
    pub sigma_direct: f32,
    /// Data-driven: sigma of the indirect light's colour test (the thesis's 0.5).
    pub sigma_indirect: f32,
    pub sigma_depth: f32,
    pub sigma_normal: f32,
    pub sigma_texture: f32,
    pub sigma_texture2: f32,
    /// Data-driven: the indirect light's test on texture2, the albedo at the second hit
    /// (the thesis's; off by default: over a few samples the mean of a random bounce's
    /// albedo is noise, and the test refuses neighbours at random).
    pub texture2_test: bool,
    /// Variance scales `s_f` of depth, normal, texture, direction and texture2: a feature's
    /// variance times its scale (clamped to 1) lowers its coefficient (more blur where the
    /// feature itself is noisy). 0 ignores the variance.
    pub variance_scale: [f32; 5],
    pub depth_units: DepthUnits,
    pub colour_units: ColourUnits,
    /// Data-driven: how the colour test weighs the channels of a difference (not in the
    /// thesis).
    pub colour_weights: ColourWeights,
    /// Data-driven: filter the light divided by the albedo (the illumination), then multiply
    /// it back (not in the thesis).
    pub demodulate: bool,
    /// Data-driven, variance units: each pixel's standard error taken over its 3x3
    /// neighbourhood (the root of the mean of the squares), as SVGF blurs its variance: a few
    /// samples' variance is itself noisy (not in the thesis).
    pub error_blur: bool,
    /// Data-driven, variance units: how the two pixels' standard errors combine (not in the
    /// thesis).
    pub error_pair: ErrorPair,
    /// Data-driven: at a metallic pixel, whose light is a glossy reflection that turns with
    /// the normal, the normal test's sigma is at most this times the lobe's GGX alpha
    /// (roughness squared, at least 0.01), blended by the metallic factor; 0 keeps
    /// `sigma_normal` everywhere, the thesis's test (not in the thesis).
    pub sigma_normal_lobe: f32,
    /// Data-driven, in the frame: a pixel only some of whose samples hit a surface (a
    /// silhouette against the sky) is filtered as its hits alone (the sky's light taken out,
    /// the rest divided by the hits' share; the filtered light scaled back and the sky's
    /// added) where the frame knows every sample's sky (one sample per frame); off, or where
    /// it does not, the mixture is filtered with its hits' features (not in the thesis).
    pub sky_coverage: bool,
    /// Data-driven, variance units: each pixel's filtered light is blended with its own by
    /// their squared errors, estimated with Stein's unbiased risk estimate (SURE) and averaged
    /// over the pixel's `(2 sure_radius + 1)^2` neighbourhood, direct and indirect apart: where
    /// the filter moved the pixel further than its noise explains, its own light takes over
    /// (not in the thesis).
    pub sure: bool,
    /// Data-driven, `sure`: the radius of the neighbourhood the risk estimates are averaged
    /// over (0: the pixel's own).
    pub sure_radius: u32,
    /// Data-driven, on the accumulated image of a still camera (and SVGF's handover to it):
    /// the image is filtered again only once the epoch's accumulated frames have grown by this
    /// factor since it was last filtered, and shown as it was meanwhile, as offline renderers
    /// denoise every so many passes (not in the thesis), but for the light a pixel showed as
    /// its own (where it passed through, and its share of its own light in the `sure` blend),
    /// which follows the accumulated light. The filter's cost then grows with the logarithm of
    /// the frames instead of with them: at 1.25 a still view of 300 frames is filtered 22
    /// times. At most 1 (0 by default) filters every frame. A change of the filter's
    /// configuration filters at once.
    pub refresh_growth: f32,
    /// RPF: the passes' box widths, largest first (the paper's 55, 35, 17, 7).
    pub rpf_boxes: Vec<u32>,
    /// RPF: `sigma_8^2`, the noise level at 8 samples per pixel (0.02 for indoor scenes, the
    /// paper's 0.002 for outdoor ones).
    pub rpf_noise: f32,
    /// RPF: the technical report's outlier step after each pass, the pixel's mean kept.
    pub rpf_outliers: bool,
    /// RPF: filter each sample's colour divided by its base colour, then multiply it back
    /// (not in the paper).
    pub rpf_demodulate: bool,
    /// RPF: samples of the sky (camera rays that left the scene) pass through unfiltered and
    /// are no pixel's neighbours (not in the paper).
    pub rpf_sky: bool,
}

impl Default for FilterConfig {
    fn default() -> Self {
        Self {
            method: Method::None,
            kernel: 21,
            holes: false,
            atrous_iterations: 5,
            atrous_kernel: 3,
            svgf_split: true,
            svgf_normal_width: 16.0,
            svgf_taa: true,
            taa_alpha: crate::taa::ALPHA,
            taa_gamma: crate::taa::GAMMA,
            svgf_converge: true,
            svgf_still_handover: 0,
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
            rpf_boxes: vec![55, 35, 17, 7],
            rpf_noise: 0.02,
            rpf_outliers: true,
            rpf_demodulate: false,
            rpf_sky: true,
        }
    }
}

/// Widest window accepted (the thesis tried up to 55).
pub const MAX_KERNEL: u32 = 127;

/// Widest neighbourhood the SURE blend averages its estimates over (`sure_radius`).
pub const MAX_SURE_RADIUS: u32 = 32;

impl FilterConfig {
    /// Checks the parameters: an odd kernel of 1..=[`MAX_KERNEL`], positive finite sigmas,
    /// finite non-negative variance scales, a method that is built.
    pub fn validate(&self) -> Result<(), FilterError> {
        if self.kernel.is_multiple_of(2) || self.kernel > MAX_KERNEL {
            return FilterError::parameter(
                "frame.filter.kernel",
                self.kernel,
                format!("an odd width from 1 to {MAX_KERNEL}"),
            );
        }
        if !(1..=crate::svgf::MAX_ITERATIONS).contains(&self.atrous_iterations) {
            return FilterError::parameter(
                "frame.filter.atrous_iterations",
                self.atrous_iterations,
                format!("from 1 to {}", crate::svgf::MAX_ITERATIONS),
            );
        }
        for (field, v) in [
            ("frame.filter.sigma_direct", self.sigma_direct),
            ("frame.filter.sigma_indirect", self.sigma_indirect),
            ("frame.filter.sigma_depth", self.sigma_depth),
            ("frame.filter.sigma_normal", self.sigma_normal),
            ("frame.filter.sigma_texture", self.sigma_texture),
            ("frame.filter.sigma_texture2", self.sigma_texture2),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return FilterError::parameter(field, v, "a positive number");
            }
        }
        if !(self.taa_alpha > 0.0 && self.taa_alpha <= 1.0) {
            return FilterError::parameter("frame.filter.taa_alpha", self.taa_alpha, "in (0, 1]");
        }
        if !(self.taa_gamma > 0.0 && self.taa_gamma <= 100.0) {
            return FilterError::parameter("frame.filter.taa_gamma", self.taa_gamma, "in (0, 100]");
        }
        if !(self.sigma_normal_lobe.is_finite() && self.sigma_normal_lobe >= 0.0) {
            return FilterError::parameter(
                "frame.filter.sigma_normal_lobe",
                self.sigma_normal_lobe,
                "finite and at least 0",
            );
        }
        if !(self.refresh_growth.is_finite() && self.refresh_growth >= 0.0) {
            return FilterError::parameter(
                "frame.filter.refresh_growth",
                self.refresh_growth,
                "finite and at least 0",
            );
        }
        if self.sure_radius > MAX_SURE_RADIUS {
            return FilterError::parameter(
                "frame.filter.sure_radius",
                self.sure_radius,
                format!("at most {MAX_SURE_RADIUS}"),
            );
        }
        if self.sure && self.colour_units != ColourUnits::Variance {
            return FilterError::parameter(
                "frame.filter.sure",
                self.sure,
                "colour_units = \"variance\" (the risk needs the pixels' standard errors)",
            );
        }
        if let Some(s) = self
            .variance_scale
            .iter()
            .find(|s| !(s.is_finite() && **s >= 0.0))
        {
            return FilterError::parameter(
                "frame.filter.variance_scale",
                s,
                "finite and at least 0",
            );
        }
        self.svgf_params().validate()?;
        self.rpf_params(0).validate()
    }

    /// The filter a frame runs after `still` frames of a still camera (the frames accumulated
    /// in the epoch, this one included): `method`, or the data-driven filter once SVGF hands
    /// over (`svgf_still_handover`).
    pub fn method_after(&self, still: u32) -> Method {
        match self.method {
            Method::Svgf if self.svgf_still_handover > 0 && still >= self.svgf_still_handover => {
                Method::DataDriven
            }
            m => m,
        }
    }

    /// The frame gathers the features' statistics for the data-driven filter: it may run
    /// in this epoch.
    pub fn gathers_features(&self) -> bool {
        self.method == Method::DataDriven
            || (self.method == Method::Svgf && self.svgf_still_handover > 0)
    }

    /// SVGF's parameters.
    pub fn svgf_params(&self) -> crate::SvgfParams {
        crate::SvgfParams {
            iterations: self.atrous_iterations,
            kernel: self.atrous_kernel,
            split: self.svgf_split,
            normal_width: self.svgf_normal_width,
            taa: self.svgf_taa,
            taa_alpha: self.taa_alpha,
            taa_gamma: self.taa_gamma,
            converge: self.svgf_converge,
        }
    }

    /// RPF's parameters, with the seed of its random draws.
    pub fn rpf_params(&self, seed: u64) -> crate::rpf::RpfParams {
        crate::rpf::RpfParams {
            boxes: self.rpf_boxes.clone(),
            noise: self.rpf_noise,
            outliers: self.rpf_outliers,
            demodulate: self.rpf_demodulate,
            sky: self.rpf_sky,
            seed,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_issue_fields_parse_and_bad_values_are_refused() {
        let c: FilterConfig = toml::from_str(
            "method = \"data-driven\"\nkernel = 21\nholes = true\natrous_iterations = 5\n",
        )
        .unwrap();
        assert_eq!(c.method, Method::DataDriven);
        assert!(c.holes);
        assert_eq!(c.validate(), Ok(()));
        for (field, value) in [
            ("kernel", "20"),
            ("kernel", "0"),
            ("sigma_depth", "-1.0"),
            ("sigma_direct", "0.0"),
            ("sigma_normal", "nan"),
            ("variance_scale", "[1.0, -1.0, 1.0, 1.0, 1.0]"),
            ("sigma_normal_lobe", "-1.0"),
            ("sigma_normal_lobe", "inf"),
            ("svgf_normal_width", "-16.0"),
            ("svgf_normal_width", "nan"),
            ("atrous_iterations", "0"),
            ("atrous_kernel", "4"),
            ("rpf_boxes", "[55, 34]"),
            ("rpf_noise", "0.0"),
            ("taa_alpha", "0.0"),
            ("taa_gamma", "0.0"),
            ("taa_gamma", "nan"),
            ("taa_gamma", "inf"),
        ] {
            let c: FilterConfig = toml::from_str(&format!("{field} = {value}")).unwrap();
            let e = c.validate().unwrap_err().to_string();
            assert!(e.contains(field), "{field}: {e}");
        }
        assert!(toml::from_str::<FilterConfig>("kernal = 3").is_err());
    }

    #[test]
    fn svgf_hands_over_to_the_data_driven_filter_after_the_still_frames() {
        let mut c = FilterConfig {
            method: Method::Svgf,
            ..FilterConfig::default()
        };
        assert!(!c.gathers_features());
        assert_eq!(c.method_after(1000), Method::Svgf);
        c.svgf_still_handover = 8;
        assert!(c.gathers_features());
        assert_eq!(c.method_after(7), Method::Svgf);
        assert_eq!(c.method_after(8), Method::DataDriven);
        c.method = Method::None;
        assert_eq!(c.method_after(8), Method::None);
        assert!(!c.gathers_features());
    }
}
