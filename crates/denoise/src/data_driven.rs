//! Seed 001's data-driven filter (thesis chapter 6, Eqs. 6.8-6.21): a cross-bilateral filter
//! over a `kernel x kernel` window, without a spatial Gaussian, guided by the pixel's features
//! and their variances, with direct and indirect light filtered apart.
//!
//! ```text
//! errors   light, its variances            -> standard errors of the means (variance units)
//! planes   features (F0..F5, variances),  -> padded feature planes (depth, normal,
//!          standard errors                   texture, texture2, direct, indirect, colour
//!                                            scales)
//! filter   planes, centre coefficients    -> image = filtered direct + filtered indirect
//! ```
//!
//! For a centre pixel p the coefficients are `c_dc = 1/(2 sigma_direct^2)`, `c_ic =
//! 1/(2 sigma_indirect^2)` and, per feature i, `c_f,i = 1/(2 sigma_i^2) (1 - clamp01(GB_i s_i))`
//! with GB_i the feature's variance at p and s_i its scale: a feature that is itself noisy at p
//! (an edge inside the pixel, depth of field) is trusted less. For each neighbour q:
//!
//! ```text
//! w_f = exp(-c_f,depth dD^2 - c_f,normal |dN|^2 - c_f,texture |dT|^2)
//! w_d = exp(-c_dc s |dF0|^2) w_f                       (direct)
//! w_i = exp(-c_ic s |dF1|^2) w_f exp(-c_f,texture2 |dT2|^2)   (indirect)
//! C   = sum(w_d F0_q) / sum(w_d) + sum(w_i F1_q) / sum(w_i)
//! ```
//!
//! where `s` scales the colour differences as [`crate::config`] says: 1 in the thesis
//! (`linear`), `1 / ((1 + L_p)(1 + L_q))` (`relative`), or, with `e` the standard error of the
//! pixel's mean light, direct and indirect apart (`variance`, the default), `1 / (e_p^2 +
//! e_q^2)` (`error_pair = "sum"`, the default: the variance of the two means' difference) or
//! `1 / (e_p e_q)` (`"product"`).
//!
//! Choices the thesis leaves open, written down:
//! - **Demodulation** (`demodulate`, not in the thesis; on by default): the direct and indirect
//!   light are divided by the pixel's albedo (each channel at least 0.01) before filtering and
//!   multiplied by it after, as SVGF does, so that the filter smooths the illumination and not
//!   the texture. Off, the thesis's filter blurs texture detail its texture test lets through
//!   (measured on textured scenes: BENCHMARKS.md, "Seed 001").
//! - **The texture2 test** (Eq. 6.21's `exp(-c_f,texture2 |dT2|^2)`) is made only with
//!   `texture2_test` (off by default: over a few samples the second hit's albedo is noise;
//!   [`crate::config`]).
//! - **Glossy normals** (`sigma_normal_lobe`, not in the thesis): the light of a metallic
//!   surface is a glossy reflection, which turns with the normal as fast as its lobe is
//!   narrow, so a normal difference the thesis's sigma (0.25) lets through carries another
//!   part of the environment: the pixel's normal test uses a sigma of at most
//!   `sigma_normal_lobe` times the GGX alpha (roughness squared), blended by the metallic
//!   factor (measured on DamagedHelmet, whose light is mostly its metal's reflections: CIELUV
//!   MSE at 8 spp 1.04x the unfiltered image's without, 0.84x with; BENCHMARKS.md, "Seed
//!   001"). A dielectric's light is mostly its diffuse part and keeps the thesis's test.
//! - **Holes** (`holes`): every other pixel of the window from its corner, and its centre,
//!   which a window of odd radius (7x7, 15x15) would skip: a pixel unlike all its taps (a
//!   wire one pixel wide) would take their light.
//! - The direction test (Eq. 6.19) has no neighbour term: it is the same factor for every q
//!   and cancels in the normalisation, so it is not computed.
//! - Depth and colour differences are measured as [`crate::config`] says (the thesis's units
//!   behind `depth_units` and `colour_units`). A depth variance is scaled like the depth
//!   (divided by the centre's depth squared when relative).
//! - **Standard errors** (variance units): from [`Features::light_variance`] where the caller
//!   knows it (two samples or more), divided by the albedo's luminance squared when
//!   demodulating; else the sample variance of the luminance over the pixel's 3x3
//!   neighbourhood (a single sample's: the real-time case of one sample per frame). Each is at
//!   least `0.01 (1 + L)`, so that a pixel whose samples agree exactly is not a wall to all.
//! - **Channel weights** (`colour_weights = "albedo"`, not in the thesis; the default): a
//!   colour difference's channel `c` counts `(a_c / L(a))^2` times, `a` the centre's
//!   demodulator and `L` its luminance, so the test measures the difference as the centre
//!   shows it, relative to its brightness. Demodulated, a saturated surface's dim channels
//!   (a red leaf's green, albedo 0.05) carry the illumination's noise divided by their albedo;
//!   tested alike with the luminance's standard error, that noise hides a change in the
//!   channel the surface shows, and the filter blurs it (the garden's red foliage). The
//!   standard errors follow the same measure: the caller's variance is the channels' mean
//!   ([`Features::light_variance`]), and a single sample's neighbourhood error, the
//!   luminance's, is scaled by the root of the mean weight (exact for illumination whose
//!   noise is the same in each channel), so that on a grey surface the test is the one
//!   with equal weights. The SURE blend's squared errors are then the channels' mean of the
//!   weighted squares. A tap's weighted difference `sqrt(w_c) (a_c - b_c)` is one fused
//!   multiply-add with the centre's light premultiplied, as many operations as the plain
//!   difference (the first form, three multiplications more per tap and signal, cost 5% of
//!   the 21x21 window with holes at 640x360; this one about 1%). Measured on
//!   `experiments/001-quality.toml` and `001-still.toml`: better from 8 spp on (the
//!   interior's CIELUV MSE at 8 spp 0.081x -> 0.058x the unfiltered image's; the garden's at
//!   128 frames 1.30x -> 0.92x), 0.01-0.02 worse at 1 spp, where a saturated pixel's noise
//!   sits in the one channel the test then weighs (BENCHMARKS.md, "Seed 001").
//! - **The two errors added** (`error_pair`, not in the thesis): the colour test asks whether
//!   two pixels' means differ by more than their noise, and the noise of a difference is
//!   `e_p^2 + e_q^2`. A pixel whose few samples held a firefly (a large `e_p`) then takes its
//!   neighbours' light, and lends them a little of its own. Over the product `e_p e_q` (this
//!   filter's first form, `"product"`) a neighbour whose samples agree is a wall to it and
//!   the firefly stays (measured, with the texture2 test: the refractive box's CIELUV MSE at
//!   8 spp 0.52x the unfiltered image's with the product, 0.15x with the sum; the helmet's
//!   visor, whose true highlights look like fireflies at 8 spp, loses: 0.96x to 1.04x;
//!   BENCHMARKS.md, "Seed 001"). The sum costs a division per tap (within the benchmark's
//!   noise).
//! - **Blurred standard errors** (`error_blur`, not in the thesis; off by default): a few
//!   samples' variance is itself noisy, and a pixel whose samples happened to agree (no
//!   firefly among them) has an error near the floor and is a wall to its neighbours. With
//!   the option each pixel's error is the root of the mean of the squared errors of the valid
//!   pixels of its 3x3 neighbourhood, as SVGF blurs its variance (measured: better on the
//!   refractive box and the interior, worse on the helmet and the garden; BENCHMARKS.md,
//!   "Seed 001"; an edge-aware blur and one of relative errors did no better).
//! - **The SURE blend** (`sure`, not in the thesis; off by default): each pixel's filtered
//!   light is blended with its own by the two lights' squared errors, estimated with Stein's
//!   unbiased risk estimate and averaged over the pixel's neighbourhood ([`crate::sure`]). A
//!   filter whose colour test is in standard errors trades variance for a bias of the same
//!   order, and as samples accumulate it falls behind the unfiltered image (measured on
//!   `experiments/001-still.toml`: at 128 spp the default filter's CIELUV MSE is 1.05x the
//!   unfiltered image's on the helmet and 1.30x on the garden); blended, its error stays
//!   nearer the smaller of the two (BENCHMARKS.md, "Seed 001").
//! - **Sky and bad pixels.** A pixel whose depth is not finite (the sky) or any of whose inputs
//!   is not finite (a NaN or infinite sample) is passed through unfiltered and is nobody's
//!   neighbour, so one bad sample stays in its own pixel. Pixels outside the image are not
//!   neighbours either (the window is cut at the borders, not clamped). A block of centres
//!   that are all sky or bad does not run the window (an outdoor frame's sky: the garden's
//!   filter pass took a third of its time after this).
//! - Windows are laid over the padded planes 16 centre pixels at a time, one row of them: each
//!   tap is then 16 neighbours next to each other in memory, one value of [`crate::simd`]'s
//!   lanes (AVX-512, or 8 pixels at a time with AVX2, with fused multiply-adds where the
//!   processor has them, chosen at run time; without, plain arrays, and the results differ by
//!   float rounding). Rows run in parallel; every pixel's result depends on the inputs
//!   alone, not on the thread count.
//! - **A tap's weights** are powers of two: the tests' coefficients are multiplied by
//!   `-log2(e)` once per block, so each exponent comes out negative and in base 2. A
//!   neighbour that is not valid has a NaN depth in the planes (there is no validity plane):
//!   its exponents are NaN, floored to a weight of 1.6e-38 on light of 0, nothing beside a
//!   weight that counts (the centre's own is 1 where the window holds it).

use glam::Vec3;
use pathlight_core::color::luminance;
use rayon::prelude::*;

use crate::config::{ColourUnits, ColourWeights, DataDrivenConfig, DepthUnits, ErrorPair};
use crate::simd::{
    channels, dispatch, exp2_neg_in_range, finite, iota, luminance_lanes, store_first, ByGroups,
    F32xN, Groups, Isa, Kernel, LANES,
};

use crate::features::{demodulator, demodulator_lanes, Features, DEPTH, NORMAL, TEXTURE, TEXTURE2};
use crate::neighbourhood::{Neighbourhoods, Statistic};
use crate::sure::{self, Risk};
use crate::FilterError;

/// Centre pixels filtered together ([`crate::simd`]).
type Lanes = [f32; LANES];

/// The padded planes, one row of each after another: depth, normal, texture, texture2 (written
/// only for the texture2 test), direct and indirect light, and the colour difference's scale.
/// Where a pixel is not valid (the sky, a bad pixel, the padding) its depth is NaN and its other
/// planes 0: the depth is the validity. A NaN depth makes a tap's exponents NaN, floored to a
/// weight of `2^(LOWEST log2 e)` (1.6e-38) on light of 0: nothing beside a weight that counts
/// (the centre's own is 1 where the window holds it).
const D: usize = 0;
const N: usize = 1;
const T: usize = 4;
const T2: usize = 7;
const F0: usize = 10;
const F1: usize = 13;
/// The colour differences' scales of the direct and indirect light at the pixel (each a test
/// multiplies the centre's and the neighbour's): `1 / (1 + luminance)` of the pixel's light
/// (relative units), `1 / standard error` of its mean (variance units), or 1.
const SCALE_D: usize = 16;
const SCALE_I: usize = 17;
const PLANES: usize = 18;

/// The data-driven filter with its buffers (kept across frames).
#[derive(Default)]
pub struct DataDriven {
    planes: Vec<f32>,
    /// Variance units, per pixel and signal (direct, indirect): the neighbourhoods' values
    /// (the demodulated luminance for the single-sample errors, then the squared error for
    /// `error_blur`), and the standard error of the mean.
    neighbourhoods: Neighbourhoods,
    errors: Vec<[f32; 2]>,
    /// `sure`: each pixel's filtered and own light with their estimated errors, and the
    /// blend's scratch.
    risks: Vec<Risk>,
    sure_scratch: sure::Scratch,
    shares: Vec<[f32; 2]>,
    /// The planes' layout and the image's height (the padding is zero for these).
    layout: Option<(Layout, usize)>,
    /// The widest lanes the filter uses (narrower ones for tests).
    isa: Isa,
}

/// The planes' geometry for one frame and window.
#[derive(Clone, Copy, PartialEq, Eq)]
struct Layout {
    width: usize,
    radius: usize,
    /// Floats per padded row of one plane.
    pitch: usize,
    /// Floats per padded row of all planes.
    row: usize,
}

impl Layout {
    fn new(width: usize, radius: usize) -> Self {
        let pitch = width + 2 * radius + LANES;
        Self {
            width,
            radius,
            pitch,
            row: pitch * PLANES,
        }
    }

    /// Index of pixel (x, y) of the image in plane 0.
    fn at(&self, x: usize, y: usize) -> usize {
        (y + self.radius) * self.row + x + self.radius
    }
}

impl DataDriven {
    pub fn new() -> Self {
        Self::default()
    }

    /// Caps the filter's lanes at AVX2 (`avx2`) or plain arrays (`portable`) instead of the
    /// widest the processor has (for tests on processors with AVX-512).
    #[doc(hidden)]
    pub fn set_lanes(&mut self, lanes: &str) {
        self.isa = Isa::named(lanes);
    }

    /// With `sure`, each pixel's share of its own light in the last image filtered, direct and
    /// indirect (NaN where the pixel passed through); empty without.
    pub fn shares(&self) -> &[[f32; 2]] {
        &self.shares
    }

    /// Empties [`shares`](Self::shares) (another filter ran, or none).
    pub fn forget_shares(&mut self) {
        self.shares.clear();
    }

    /// Filters `features` with `config`'s data-driven parameters into `out` (one value per
    /// pixel: filtered direct plus filtered indirect light).
    pub fn filter(
        &mut self,
        features: &Features,
        config: &DataDrivenConfig,
        out: &mut [Vec3],
    ) -> Result<(), FilterError> {
        config.validate()?;
        features.check()?;
        if out.len() != features.len() {
            return Err(FilterError::Size {
                name: "output",
                len: out.len(),
                width: features.width,
                height: features.height,
            });
        }
        if features.is_empty() {
            return Ok(());
        }
        let radius = (config.kernel / 2) as usize;
        let layout = Layout::new(features.width, radius);
        let scales = Scales::new(config);
        self.fill_planes(features, layout, config, scales.sum);
        let step = if config.holes { 2 } else { 1 };
        let mut offsets: Vec<usize> = (0..=2 * radius)
            .step_by(step)
            .flat_map(|dy| (0..=2 * radius).step_by(step).map(move |dx| (dy, dx)))
            .map(|(dy, dx)| dy * layout.row + dx)
            .collect();
        // The holes of a window of odd radius (7x7, 15x15) skip its centre: it is a tap all
        // the same, or a pixel unlike all its taps (a wire one pixel wide, a pixel alone
        // against the sky) would take their light, or none. In order: the taps' bounds are
        // checked at the last.
        if !radius.is_multiple_of(step) {
            let at = radius * layout.row + radius;
            let k = offsets.partition_point(|&o| o < at);
            offsets.insert(k, at);
        }
        let planes = &self.planes;
        // With `sure` the rows leave each valid pixel's light and risks, and the blend writes
        // it.
        let sure = config.sure;
        self.risks
            .resize(if sure { features.len() } else { 0 }, Risk::default());
        let width = features.width;
        let risks = self.risks.par_chunks_mut(width.max(1)).map(Some);
        let rows = out.par_chunks_mut(width).enumerate();
        let run = |((y, row), risks): ((usize, &mut [Vec3]), Option<&mut [Risk]>)| {
            let job = Row {
                planes,
                layout,
                offsets: &offsets,
                scales: &scales,
                features,
                y,
                isa: self.isa,
            };
            job.run(row, risks);
        };
        if sure {
            rows.zip(risks).for_each(run);
            let demodulate = config.demodulate;
            // A pixel's own light, demodulated: its planes' direct and indirect light.
            let own = |i: usize| {
                let at = layout.at(i % width, i / width);
                let light = |p: usize| {
                    let c = |k: usize| planes[at + (p + k) * layout.pitch];
                    Vec3::new(c(0), c(1), c(2))
                };
                [light(F0), light(F1)]
            };
            sure::blend(
                &self.risks,
                width,
                config.sure_radius as usize,
                &mut self.sure_scratch,
                out,
                &mut self.shares,
                own,
                |i, light| light * divisor(features.albedo[i], demodulate),
            );
        } else {
            self.shares.clear();
            rows.map(|row| (row, None)).for_each(run);
        }
        Ok(())
    }

    /// Writes the padded planes: the features of valid pixels, zeros (and depth NaN) for the
    /// sky and bad pixels. The padding (zeros, the depth NaN) is laid out when the layout
    /// changes and never written after.
    /// `sum`: the colour scales are squared errors ([`Scales::sum`]).
    fn fill_planes(&mut self, f: &Features, layout: Layout, config: &DataDrivenConfig, sum: bool) {
        let (units, demodulate) = (config.colour_units, config.demodulate);
        let rows = f.height + 2 * layout.radius;
        if self.layout != Some((layout, f.height)) {
            self.planes.clear();
            self.planes.resize(rows * layout.row, 0.0);
            for row in self.planes.chunks_exact_mut(layout.row) {
                row[D * layout.pitch..(D + 1) * layout.pitch].fill(f32::NAN);
            }
            self.layout = Some((layout, f.height));
        }
        let albedo = |i: usize| divisor(f.albedo[i], demodulate);
        let valid = |i: usize| {
            valid_pixel(
                f.depth[i],
                [
                    f.normal[i],
                    f.albedo[i],
                    f.texture2[i],
                    f.direct[i],
                    f.indirect[i],
                ],
            )
        };
        // Sized for the rows' slices even when every variance is known (then never read).
        self.errors.resize(f.len(), [0.0; 2]);
        let blur = units == ColourUnits::Variance && config.error_blur;
        if units == ColourUnits::Variance {
            let weights = config.colour_weights == ColourWeights::Albedo;
            self.neighbourhood_errors(f, &albedo, &valid, weights);
            if blur {
                self.blur_errors(f, &albedo, &valid);
            }
        }
        let fill = FillRows {
            f,
            errors: &self.errors,
            layout,
            units,
            demodulate,
            all_errors: blur,
            sum,
            texture2: config.texture2_test,
            isa: self.isa,
        };
        let r = layout.radius;
        self.planes[r * layout.row..(r + f.height) * layout.row]
            .par_chunks_mut(layout.row)
            .enumerate()
            .for_each(|(y, row)| fill.row(y, row));
    }

    /// For the pixels whose light's variance the caller does not know (not [`known`]), the
    /// standard error of the mean of the direct and indirect light's luminance (demodulated)
    /// from the 3x3 neighbourhood's variance (a single sample's), into `errors` (left alone
    /// when every variance is known). With the colour test's channel weights (`weights`),
    /// each is scaled to the channels' mean error, as for light whose noise is the same in
    /// every channel: by the root of the mean of the pixel's weights.
    fn neighbourhood_errors(
        &mut self,
        f: &Features,
        albedo: &(impl Fn(usize) -> Vec3 + Sync),
        valid: &(impl Fn(usize) -> bool + Sync),
        weights: bool,
    ) {
        // By blocks, without branches within one (the compiler vectorises them).
        let unknown = f.light_variance.par_chunks(4096).any(|block| {
            block
                .iter()
                .fold(false, |unknown, v| unknown | !(known(v[0]) & known(v[1])))
        });
        if !unknown {
            return;
        }
        self.neighbourhoods.fill(f.width, f.height, |i| {
            let a = luminance(albedo(i));
            if valid(i) {
                [luminance(f.direct[i]) / a, luminance(f.indirect[i]) / a]
            } else {
                [f32::NAN; 2]
            }
        });
        self.neighbourhoods
            .compute(Statistic::Deviation, self.isa, &mut self.errors, |i, k| {
                known(f.light_variance[i][k])
            });
        if weights {
            self.errors.par_iter_mut().enumerate().for_each(|(i, e)| {
                let scale = (channel_weights(albedo(i)).element_sum() / 3.0).sqrt();
                for (k, e) in e.iter_mut().enumerate() {
                    if !known(f.light_variance[i][k]) {
                        *e *= scale;
                    }
                }
            });
        }
    }
}

impl DataDriven {
    /// Every pixel's standard errors (its own where known, else its neighbourhood's from
    /// `errors`), then each replaced by the root of the mean of the squares over the valid
    /// pixels of its 3x3 neighbourhood, into `errors` (`error_blur`).
    fn blur_errors(
        &mut self,
        f: &Features,
        albedo: &(impl Fn(usize) -> Vec3 + Sync),
        valid: &(impl Fn(usize) -> bool + Sync),
    ) {
        // The squared standard errors, NaN where the pixel is not valid.
        let errors = &self.errors;
        self.neighbourhoods.fill(f.width, f.height, |i| {
            let la = luminance(albedo(i));
            std::array::from_fn(|k| {
                let v = f.light_variance[i][k];
                if !valid(i) {
                    f32::NAN
                } else if known(v) {
                    v / (la * la)
                } else {
                    errors[i][k] * errors[i][k]
                }
            })
        });
        self.neighbourhoods
            .compute(Statistic::RootMean, self.isa, &mut self.errors, |_, _| {
                false
            });
    }
}

/// One row of the padded planes from the features ([`DataDriven::fill_planes`]): the
/// features of valid pixels, zeros (and depth NaN) for the sky and bad pixels, in lanes
/// ([`FillRow`]; a per-pixel loop over the row's slices, left to the compiler to vectorise, was
/// left scalar).
struct FillRows<'a> {
    f: &'a Features<'a>,
    /// The neighbourhoods' standard errors, for the pixels whose variance is not known.
    errors: &'a [[f32; 2]],
    layout: Layout,
    units: ColourUnits,
    demodulate: bool,
    /// `errors` holds every pixel's standard errors (blurred), not only the unknown ones'.
    all_errors: bool,
    /// The colour scales are squared errors ([`Scales::sum`]), not their inverses.
    sum: bool,
    /// The texture2 planes are read (the texture2 test).
    texture2: bool,
    isa: Isa,
}

impl FillRows<'_> {
    fn row(&self, y: usize, row: &mut [f32]) {
        dispatch(self.isa, ByGroups(FillRow { fill: self, y, row }));
    }

    /// A signal's colour scale from its luminance variance `v` (where [`known`]) or its
    /// neighbourhood's standard error `error`, the albedo's luminance `la` and the error's
    /// `floor` (`ColourUnits::Variance`), in lanes.
    #[inline(always)]
    fn scale<V: F32xN>(&self, v: V, error: V, la: V, floor: V) -> V {
        let known = V::and(finite(v), v.ge(V::splat(0.0)));
        let own = (v / (la * la)).sqrt();
        let e = if self.all_errors {
            error
        } else {
            V::select(known, own, error)
        };
        // The floor where e is NaN, as `f32::max` gives.
        let e = e.at_least(floor);
        if self.sum {
            e * e
        } else {
            V::splat(1.0) / e
        }
    }
}

/// One row of [`FillRows`] in lanes, [`F32xN::N`] pixels at a time. (No closures here: see
/// `simd::exp2_neg_in_range`.)
struct FillRow<'a, 'b> {
    fill: &'a FillRows<'b>,
    y: usize,
    row: &'a mut [f32],
}

impl Groups for FillRow<'_, '_> {
    fn width(&self) -> usize {
        self.fill.f.width
    }

    #[inline(always)]
    fn group<V: F32xN>(&mut self, x0: usize) -> bool {
        let (s, f) = (self.fill, self.fill.f);
        let w = f.width;
        let n = V::N.min(w - x0);
        let splat = V::splat;
        let (zero, one) = (splat(0.0), splat(1.0));
        let lanes = splat(n as f32).gt(iota::<V>());
        let i0 = self.y * w + x0;
        let [depth] = channels::<V, _, 1>(f.depth, i0, n);
        let vectors: [[V; 3]; 5] = [
            channels(f.normal, i0, n),
            channels(f.albedo, i0, n),
            channels(f.texture2, i0, n),
            channels(f.direct, i0, n),
            channels(f.indirect, i0, n),
        ];
        let variance: [V; 2] = channels(f.light_variance, i0, n);
        let errors: [V; 2] = channels(s.errors, i0, n);
        // `valid_pixel`.
        let mut valid = V::and(lanes, finite(depth));
        for c in vectors.iter().flatten() {
            valid = V::and(valid, finite(*c));
        }
        let [normal, albedo, texture2, direct, indirect] = vectors;
        let mut a = [one; 3];
        if s.demodulate {
            for (a, &albedo) in a.iter_mut().zip(&albedo) {
                *a = demodulator_lanes(albedo);
            }
        }
        let (mut direct, mut indirect) = (direct, indirect);
        for k in 0..3 {
            let inv = one / a[k];
            direct[k] = direct[k] * inv;
            indirect[k] = indirect[k] * inv;
        }
        let put = (x0, n, valid);
        self.put_or(put, D, depth, V::splat(f32::NAN));
        for (plane, v) in [N, T, F0, F1]
            .into_iter()
            .zip([normal, albedo, direct, indirect])
        {
            for (c, v) in v.into_iter().enumerate() {
                self.put(put, plane + c, v);
            }
        }
        if s.texture2 {
            for (c, v) in texture2.into_iter().enumerate() {
                self.put(put, T2 + c, v);
            }
        }
        let sum = [
            direct[0] + indirect[0],
            direct[1] + indirect[1],
            direct[2] + indirect[2],
        ];
        let lum = luminance_lanes(sum);
        let lum = V::select(lum.ge(zero), lum, zero);
        let (sd, si) = match s.units {
            ColourUnits::Linear => (one, one),
            ColourUnits::Relative => {
                let r = one / (one + lum);
                (r, r)
            }
            ColourUnits::Variance => {
                // The standard error of the mean of the direct and indirect light's
                // luminance (demodulated): from the pixel's own variance where the caller
                // knows it, else from its neighbourhood's (`neighbourhood_errors`). At most
                // 100 / (1 + L): a pixel without noise is not a wall.
                let (la, floor) = (luminance_lanes(a), splat(0.01) * (one + lum));
                (
                    s.scale(variance[0], errors[0], la, floor),
                    s.scale(variance[1], errors[1], la, floor),
                )
            }
        };
        self.put(put, SCALE_D, sd);
        self.put(put, SCALE_I, si);
        false
    }
}

impl FillRow<'_, '_> {
    /// Stores `v` (0 where not `valid`) into `plane` at the `n` pixels from `x0` on.
    #[inline(always)]
    fn put<V: F32xN>(&mut self, put: (usize, usize, V::Mask), plane: usize, v: V) {
        self.put_or(put, plane, v, V::splat(0.0));
    }

    /// Stores `v` (`or` where not `valid`) into `plane` at the `n` pixels from `x0` on.
    #[inline(always)]
    fn put_or<V: F32xN>(
        &mut self,
        (x0, n, valid): (usize, usize, V::Mask),
        plane: usize,
        v: V,
        or: V,
    ) {
        let l = self.fill.layout;
        let at = plane * l.pitch + x0 + l.radius;
        store_first(V::select(valid, v, or), n, &mut self.row[at..]);
    }
}

/// What a pixel's light is divided by in the planes: its albedo's demodulator, or 1.
#[inline(always)]
fn divisor(albedo: Vec3, demodulate: bool) -> Vec3 {
    if demodulate {
        demodulator(albedo)
    } else {
        Vec3::ONE
    }
}

/// A pixel whose depth and feature vectors are all finite (the others pass through and are
/// nobody's neighbour); without branches, for the vectorised rows.
#[inline(always)]
fn valid_pixel(depth: f32, vectors: [Vec3; 5]) -> bool {
    vectors
        .iter()
        .fold(depth.is_finite(), |ok, v| ok & v.is_finite())
}

/// A variance the caller gives (finite and not negative; NaN: not known).
#[inline]
fn known(variance: f32) -> bool {
    variance.is_finite() & (variance >= 0.0)
}

/// `1 / (2 sigma^2)` of each test.
struct Scales {
    direct: f32,
    indirect: f32,
    depth: f32,
    /// `sigma_normal` and `sigma_normal_lobe`: the normal test's coefficient depends on the
    /// pixel ([`Scales::normal_lanes`]).
    sigma_normal: f32,
    lobe: f32,
    texture: f32,
    texture2: f32,
    variance: [f32; 5],
    relative_depth: bool,
    demodulate: bool,
    /// The colour scales' planes hold squared standard errors, added in the window
    /// (`ErrorPair::Sum`), instead of factors multiplied.
    sum: bool,
    /// The colour tests weigh the channels by the centre's albedo (`ColourWeights::Albedo`).
    weights: bool,
}

impl Scales {
    fn new(c: &DataDrivenConfig) -> Self {
        Self {
            direct: coefficient(c.sigma_direct),
            indirect: coefficient(c.sigma_indirect),
            depth: coefficient(c.sigma_depth),
            sigma_normal: c.sigma_normal,
            lobe: c.sigma_normal_lobe,
            texture: coefficient(c.sigma_texture),
            texture2: if c.texture2_test {
                coefficient(c.sigma_texture2)
            } else {
                0.0
            },
            variance: c.variance_scale,
            relative_depth: c.depth_units == DepthUnits::Relative,
            demodulate: c.demodulate,
            sum: c.colour_units == ColourUnits::Variance && c.error_pair == ErrorPair::Sum,
            weights: c.colour_weights == ColourWeights::Albedo,
        }
    }

    /// The normal test's coefficient at pixels of these roughnesses and metallic factors, in
    /// lanes: its sigma is `sigma_normal` blended by the metallic factor (clamped to [0, 1],
    /// NaN as 0) toward `sigma_normal_lobe` times the GGX alpha (roughness squared, at least
    /// 0.01; NaN as 0.01) where that is smaller. A pixel that is not metallic gets the
    /// configuration's exactly.
    #[inline(always)]
    fn normal_lanes<V: F32xN>(&self, roughness: V, metallic: V) -> V {
        let (sigma, one) = (V::splat(self.sigma_normal), V::splat(1.0));
        if self.lobe == 0.0 {
            return V::splat(coefficient(self.sigma_normal));
        }
        // `at_least` takes NaN to its floor.
        let m = metallic.at_least(V::splat(0.0));
        let m = V::select(m.gt(one), one, m);
        let alpha = (roughness * roughness).at_least(V::splat(0.01));
        let lobe = V::splat(self.lobe) * alpha;
        let lobe = V::select(lobe.gt(sigma), sigma, lobe);
        // `sigma + 0 (lobe - sigma)` is `sigma` exactly where the pixel is not metallic.
        let sigma = sigma + m * (lobe - sigma);
        one / (V::splat(2.0) * sigma * sigma)
    }
}

/// A test's coefficient `k` lowered by the feature's scaled variance `t` at the pixel, in
/// lanes: `k (1 - clamp01(t))`, a `t` that is not a number trusting the feature not at all.
#[inline(always)]
fn lowered<V: F32xN>(k: V, t: V) -> V {
    let one = V::splat(1.0);
    let clamped = V::select(t.gt(one), one, t.at_least(V::splat(0.0)));
    k * (one - V::select(t.ne(t), one, clamped))
}

/// A test's coefficient `1 / (2 sigma^2)`.
fn coefficient(sigma: f32) -> f32 {
    1.0 / (2.0 * sigma * sigma)
}

/// One row of the image.
struct Row<'a> {
    planes: &'a [f32],
    layout: Layout,
    offsets: &'a [usize],
    scales: &'a Scales,
    features: &'a Features<'a>,
    y: usize,
    /// The widest lanes to use.
    isa: Isa,
}

/// A block's centre pixels' values and the tests' coefficients, in lanes. The coefficients
/// are times `-log2(e)`: a tap's exponents are then powers of two, added up negative, without
/// a negation and a change of base a weight.
struct Centre<T> {
    depth: T,
    normal: [T; 3],
    texture: [T; 3],
    texture2: [T; 3],
    direct: [T; 3],
    indirect: [T; 3],
    scale_direct: T,
    scale_indirect: T,
    c_direct: T,
    c_indirect: T,
    c_depth: T,
    c_normal: T,
    c_texture: T,
    c_texture2: T,
}

/// An array's lanes.
#[inline(always)]
fn lanes<V: F32xN>(a: &Lanes) -> V {
    // SAFETY: the array has `LANES` values.
    unsafe { V::load(a.as_ptr()) }
}

/// The lanes of `planes` from `at` on.
#[inline(always)]
fn plane_lanes<V: F32xN>(planes: &[f32], at: usize) -> V {
    lanes(planes[at..at + LANES].try_into().expect("a block of lanes"))
}

/// The lanes of three planes `pitch` apart from `at` on.
#[inline(always)]
fn three_planes<V: F32xN>(planes: &[f32], at: usize, pitch: usize) -> [V; 3] {
    [
        plane_lanes(planes, at),
        plane_lanes(planes, at + pitch),
        plane_lanes(planes, at + 2 * pitch),
    ]
}

/// The weighted sums of one block of centres.
struct Sums<V> {
    direct_w: V,
    direct: [V; 3],
    indirect_w: V,
    indirect: [V; 3],
}

/// A row's blocks run with lanes `V` ([`crate::simd::dispatch`]).
struct RowJob<'r, 'a> {
    row: &'r Row<'a>,
    out: &'r mut [Vec3],
    risks: Option<&'r mut [Risk]>,
}

impl Kernel<()> for RowJob<'_, '_> {
    #[inline(always)]
    fn run<V: F32xN>(self) {
        self.row.run_blocks::<V>(self.out, self.risks)
    }
}

impl Row<'_> {
    /// The row's filtered pixels into `out`; with `risks` (`sure`), each valid pixel's two
    /// signals and their risks there instead.
    fn run(&self, out: &mut [Vec3], risks: Option<&mut [Risk]>) {
        dispatch(
            self.isa,
            RowJob {
                row: self,
                out,
                risks,
            },
        );
    }

    #[inline(always)]
    fn run_blocks<V: F32xN>(&self, out: &mut [Vec3], mut risks: Option<&mut [Risk]>) {
        let width = self.layout.width;
        for x0 in (0..width).step_by(V::N) {
            // The block's pixels, as slices of their length (no bounds checks in the loop).
            let n = V::N.min(width - x0);
            let (f, i0) = (self.features, self.y * width + x0);
            let (direct, indirect) = (&f.direct[i0..i0 + n], &f.indirect[i0..i0 + n]);
            // The block's depths, its validity: NaN where not valid (lanes past the row's end
            // are its padding: not valid).
            let at = self.layout.at(x0, self.y) + D * self.layout.pitch;
            let block: &Lanes = self.planes[at..at + LANES]
                .try_into()
                .expect("a block of lanes");
            let depth = &block[..n];
            let d = lanes::<V>(block);
            if V::all(d.ne(d)) {
                // Sky or bad pixels only (much of an outdoor frame): as they are, the window
                // not run.
                for (j, o) in out[x0..x0 + n].iter_mut().enumerate() {
                    *o = direct[j] + indirect[j];
                }
                if let Some(risks) = risks.as_deref_mut() {
                    risks[x0..x0 + n].fill(Risk::none());
                }
                continue;
            }
            let centre = self.centre::<V>(x0);
            let s = self.scales;
            let sums = match (s.sum, s.texture2 > 0.0, s.weights) {
                (true, false, false) => self.sums::<V, true, false, false>(x0, &centre),
                (true, true, false) => self.sums::<V, true, true, false>(x0, &centre),
                (false, false, false) => self.sums::<V, false, false, false>(x0, &centre),
                (false, true, false) => self.sums::<V, false, true, false>(x0, &centre),
                (true, false, true) => self.sums::<V, true, false, true>(x0, &centre),
                (true, true, true) => self.sums::<V, true, true, true>(x0, &centre),
                (false, false, true) => self.sums::<V, false, false, true>(x0, &centre),
                (false, true, true) => self.sums::<V, false, true, true>(x0, &centre),
            };
            if let Some(risks) = risks.as_deref_mut() {
                self.risks::<V>(&sums, &centre, depth, &mut risks[x0..x0 + n]);
                for (j, o) in out[x0..x0 + n].iter_mut().enumerate() {
                    if depth[j].is_nan() {
                        *o = direct[j] + indirect[j];
                    }
                }
                continue;
            }
            // The weighted means, in lanes.
            let mut light = [[0.0; LANES]; 3];
            for (c, light) in light.iter_mut().enumerate() {
                *light = (sums.direct[c] / sums.direct_w + sums.indirect[c] / sums.indirect_w)
                    .to_array();
            }
            let albedo = &f.albedo[i0..i0 + n];
            for (j, o) in out[x0..x0 + n].iter_mut().enumerate() {
                *o = if depth[j].is_nan() {
                    // Sky or a bad pixel: as it is.
                    direct[j] + indirect[j]
                } else {
                    let light = Vec3::new(light[0][j], light[1][j], light[2][j]);
                    if self.scales.demodulate {
                        light * demodulator(albedo[j])
                    } else {
                        light
                    }
                };
            }
        }
    }

    /// The risks of the block's pixels (`sure`): the valid ones' (a `depth` that is a number)
    /// filtered light and estimates, the others passing through. (No closures here: see
    /// `simd::exp2_neg_in_range`.)
    #[inline(always)]
    fn risks<V: F32xN>(
        &self,
        sums: &Sums<V>,
        centre: &Centre<V>,
        depth: &[f32],
        risks: &mut [Risk],
    ) {
        let mut direct = [[0.0; LANES]; 3];
        let mut indirect = [[0.0; LANES]; 3];
        for k in 0..3 {
            direct[k] = (sums.direct[k] / sums.direct_w).to_array();
            indirect[k] = (sums.indirect[k] / sums.indirect_w).to_array();
        }
        let (wd, wi) = (sums.direct_w.to_array(), sums.indirect_w.to_array());
        // The centres' values the risks need, as arrays.
        let texture = centre.texture.map(V::to_array);
        let (direct_c, indirect_c) = (
            centre.direct.map(V::to_array),
            centre.indirect.map(V::to_array),
        );
        let (scale_direct, scale_indirect) = (
            centre.scale_direct.to_array(),
            centre.scale_indirect.to_array(),
        );
        for (j, risk) in risks.iter_mut().enumerate() {
            if depth[j].is_nan() {
                *risk = Risk::none();
                continue;
            }
            // The squared standard errors (or their inverses, `product`) of the colour
            // scales.
            let (sd, si) = (scale_direct[j], scale_indirect[j]);
            let variance = if self.scales.sum {
                [sd, si]
            } else {
                [1.0 / (sd * sd), 1.0 / (si * si)]
            };
            *risk = Risk::new(
                [
                    Vec3::new(direct[0][j], direct[1][j], direct[2][j]),
                    Vec3::new(indirect[0][j], indirect[1][j], indirect[2][j]),
                ],
                [
                    Vec3::new(direct_c[0][j], direct_c[1][j], direct_c[2][j]),
                    Vec3::new(indirect_c[0][j], indirect_c[1][j], indirect_c[2][j]),
                ],
                [wd[j], wi[j]],
                variance,
                // The centre's own weight: it is always a tap.
                1.0,
                self.scales.weights.then(|| {
                    let t = Vec3::new(texture[0][j], texture[1][j], texture[2][j]);
                    channel_weights(divisor(t, self.scales.demodulate))
                }),
            );
        }
    }

    /// The block's centre values and coefficients (lanes past the row's end are padding).
    /// (No closures here: see `simd::exp2_neg_in_range`.)
    #[inline(always)]
    fn centre<V: F32xN>(&self, x0: usize) -> Centre<V> {
        let s = self.scales;
        let l = &self.layout;
        let base = l.at(x0, self.y);
        let at = |plane: usize| base + plane * l.pitch;
        let (planes, pitch) = (self.planes, l.pitch);
        let zero = V::splat(0.0);
        let mut c = Centre {
            depth: plane_lanes(planes, at(D)),
            normal: three_planes(planes, at(N), pitch),
            texture: three_planes(planes, at(T), pitch),
            // Not written without the texture2 test.
            texture2: if s.texture2 > 0.0 {
                three_planes(planes, at(T2), pitch)
            } else {
                [zero; 3]
            },
            direct: three_planes(planes, at(F0), pitch),
            indirect: three_planes(planes, at(F1), pitch),
            scale_direct: plane_lanes(planes, at(SCALE_D)),
            scale_indirect: plane_lanes(planes, at(SCALE_I)),
            c_direct: zero,
            c_indirect: zero,
            c_depth: zero,
            c_normal: zero,
            c_texture: zero,
            c_texture2: zero,
        };
        // The feature variances and materials of the block's pixels (zeros past the row's
        // end, whose results are not used), in lanes.
        let (f, width) = (self.features, l.width);
        let (i0, n) = (self.y * width + x0, V::N.min(width - x0));
        let variance: [V; 5] = channels(f.variance, i0, n);
        let [roughness] = channels::<V, _, 1>(f.roughness, i0, n);
        let [metallic] = channels::<V, _, 1>(f.metallic, i0, n);
        let one = V::splat(1.0);
        let depth_scale = if s.relative_depth {
            one / c.depth.at_least(V::splat(1e-6))
        } else {
            one
        };
        // The depth scale folded into the coefficient: c (dD / d)^2 = (c / d^2) dD^2.
        let depth_variance = variance[DEPTH] * depth_scale * depth_scale;
        let c_depth = lowered(
            V::splat(s.depth),
            depth_variance * V::splat(s.variance[DEPTH]),
        );
        let c_depth = c_depth * depth_scale * depth_scale;
        let normal = s.normal_lanes(roughness, metallic);
        let c_normal = lowered(normal, variance[NORMAL] * V::splat(s.variance[NORMAL]));
        let c_texture = lowered(
            V::splat(s.texture),
            variance[TEXTURE] * V::splat(s.variance[TEXTURE]),
        );
        let c_texture2 = lowered(
            V::splat(s.texture2),
            variance[TEXTURE2] * V::splat(s.variance[TEXTURE2]),
        );
        (c.c_depth, c.c_normal) = (c_depth, c_normal);
        (c.c_texture, c.c_texture2) = (c_texture, c_texture2);
        // The centre's half of the colour scales (the neighbour's is its plane); with squared
        // errors the window divides by their sum, and a centre that is not valid (its planes
        // 0: the sky, a bad pixel, past the row's end; its sums unused) gets 1, so that no
        // lane divides 0 by 0.
        for (scale, k, own) in [
            (&mut c.scale_direct, s.direct, &mut c.c_direct),
            (&mut c.scale_indirect, s.indirect, &mut c.c_indirect),
        ] {
            if s.sum {
                *scale = V::select(scale.ne(zero), *scale, one);
                *own = V::splat(k);
            } else {
                *own = V::splat(k) * *scale;
            }
        }
        let base = V::splat(-std::f32::consts::LOG2_E);
        for k in [
            &mut c.c_direct,
            &mut c.c_indirect,
            &mut c.c_depth,
            &mut c.c_normal,
            &mut c.c_texture,
            &mut c.c_texture2,
        ] {
            *k = *k * base;
        }
        c
    }

    /// The weighted sums over the window of each centre of the block. (No closures here:
    /// see `simd::exp2_neg_in_range`.)
    #[inline(always)]
    fn sums<V: F32xN, const SUM: bool, const TEXTURE2: bool, const WEIGHTS: bool>(
        &self,
        x0: usize,
        centre: &Centre<V>,
    ) -> Sums<V> {
        let l = &self.layout;
        // The window's top-left corner of the first centre.
        let corner = l.at(x0, self.y) - l.radius * l.row - l.radius;
        let last = self.offsets.last().map_or(0, |o| corner + o) + (PLANES - 1) * l.pitch;
        assert!(
            last + LANES <= self.planes.len(),
            "the window stays in the planes"
        );
        let c = centre;
        let floor = V::splat(crate::exp::LOWEST * std::f32::consts::LOG2_E);
        let zero = V::splat(0.0);
        let mut s = Sums {
            direct_w: zero,
            direct: [zero; 3],
            indirect_w: zero,
            indirect: [zero; 3],
        };
        // The colour tests' channel weights' roots, and the centre's light times them, negated:
        // a tap's weighted difference is then one fused multiply-add per channel.
        let (root, direct_root, indirect_root) = if WEIGHTS {
            let root = roots(c.texture, self.scales.demodulate);
            (root, negated(root, c.direct), negated(root, c.indirect))
        } else {
            ([zero; 3], [zero; 3], [zero; 3])
        };
        for &offset in self.offsets {
            let base = corner + offset;
            let mut v = [zero; PLANES];
            for (plane, v) in v.iter_mut().enumerate() {
                // SAFETY: `offsets` grow, so every plane's `base + plane * pitch + LANES <=
                // last + LANES`, which is in bounds (asserted above).
                *v = unsafe { V::load(self.planes.as_ptr().add(base + plane * l.pitch)) };
            }
            let three = |p: usize| [v[p], v[p + 1], v[p + 2]];
            let dd = v[D] - c.depth;
            let features = term(three(N), c.normal, c.c_normal, c.c_depth * (dd * dd));
            let features = term(three(T), c.texture, c.c_texture, features);
            // The colour tests' coefficients: `k / (e_p^2 + e_q^2)` or `k s_p s_q`.
            let (kd, ki) = if SUM {
                (
                    c.c_direct / (c.scale_direct + v[SCALE_D]),
                    c.c_indirect / (c.scale_indirect + v[SCALE_I]),
                )
            } else {
                (c.c_direct * v[SCALE_D], c.c_indirect * v[SCALE_I])
            };
            let wd = weight::<V, WEIGHTS>(
                floor,
                three(F0),
                (c.direct, direct_root),
                root,
                kd,
                features,
            );
            // Without the texture2 test its planes are not read (the loads are dead code).
            let indirect = if TEXTURE2 {
                term(three(T2), c.texture2, c.c_texture2, features)
            } else {
                features
            };
            let wi = weight::<V, WEIGHTS>(
                floor,
                three(F1),
                (c.indirect, indirect_root),
                root,
                ki,
                indirect,
            );
            s.direct_w = s.direct_w + wd;
            s.indirect_w = s.indirect_w + wi;
            for k in 0..3 {
                s.direct[k] = wd.mul_add(v[F0 + k], s.direct[k]);
                s.indirect[k] = wi.mul_add(v[F1 + k], s.indirect[k]);
            }
        }
        s
    }
}

/// `k |a - b|^2 + plus` in lanes.
#[inline(always)]
fn term<V: F32xN>(a: [V; 3], b: [V; 3], k: V, plus: V) -> V {
    let (x, y, z) = (a[0] - b[0], a[1] - b[1], a[2] - b[2]);
    k.mul_add(x.mul_add(x, y.mul_add(y, z * z)), plus)
}

/// A colour test's exponent in lanes: [`term`] of `a` and the centre's `b`, or with the
/// channel weights (`WEIGHTS`; `root`, their roots, and `b_root = -root b`) `k sum_c w_c (a_c -
/// b_c)^2 + plus`.
#[inline(always)]
fn colour<V: F32xN, const WEIGHTS: bool>(
    a: [V; 3],
    (b, b_root): ([V; 3], [V; 3]),
    root: [V; 3],
    k: V,
    plus: V,
) -> V {
    if !WEIGHTS {
        return term(a, b, k, plus);
    }
    let x = root[0].mul_add(a[0], b_root[0]);
    let y = root[1].mul_add(a[1], b_root[1]);
    let z = root[2].mul_add(a[2], b_root[2]);
    k.mul_add(x.mul_add(x, y.mul_add(y, z * z)), plus)
}

/// A signal's weight at a neighbour in lanes: its [`colour`] test and the tests in `plus`,
/// with coefficients times `-log2(e)`, `2^exponent`, the exponent at least `floor` (`LOWEST
/// log2(e)`; a NaN exponent, a neighbour that is not valid, is floored too).
#[inline(always)]
fn weight<V: F32xN, const WEIGHTS: bool>(
    floor: V,
    a: [V; 3],
    centre: ([V; 3], [V; 3]),
    root: [V; 3],
    k: V,
    plus: V,
) -> V {
    exp2_neg_in_range(colour::<V, WEIGHTS>(a, centre, root, k, plus).at_least(floor))
}

/// `-root light`, channel by channel, in lanes.
#[inline(always)]
fn negated<V: F32xN>(root: [V; 3], light: [V; 3]) -> [V; 3] {
    let zero = V::splat(0.0);
    [
        zero - root[0] * light[0],
        zero - root[1] * light[1],
        zero - root[2] * light[2],
    ]
}

/// The roots of [`channel_weights`] in lanes, `a / L(a)`, of a pixel of albedo `albedo` (its
/// plane: 0 where not valid).
#[inline(always)]
fn roots<V: F32xN>(albedo: [V; 3], demodulate: bool) -> [V; 3] {
    let a = if demodulate {
        [
            demodulator_lanes(albedo[0]),
            demodulator_lanes(albedo[1]),
            demodulator_lanes(albedo[2]),
        ]
    } else {
        [V::splat(1.0); 3]
    };
    let inv = V::splat(1.0) / luminance_lanes(a);
    [a[0] * inv, a[1] * inv, a[2] * inv]
}

/// The colour test's channel weights at a pixel whose light is divided by `a`
/// (`ColourWeights::Albedo`): `(a_c / L(a))^2`. Their mean is the ratio of the mean channel's
/// variance to the luminance's, for light whose noise is the same in every channel.
pub(crate) fn channel_weights(a: Vec3) -> Vec3 {
    let r = a / luminance(a);
    r * r
}
