//! Seed 001's data-driven filter (thesis chapter 6, Eqs. 6.8-6.21): a cross-bilateral filter
//! over a `kernel x kernel` window, without a spatial Gaussian, guided by the pixel's features
//! and their variances, with direct and indirect light filtered apart.
//!
//! ```text
//! errors   light, its variances            -> standard errors of the means (variance units)
//! planes   features (F0..F5, variances),  -> padded feature planes (validity, depth, normal,
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
//! where `s = s_p s_q` scales the colour differences as [`crate::config`] says: 1 in the
//! thesis (`linear`), `1 / ((1 + L_p)(1 + L_q))` (`relative`), or `1 / (e_p e_q)` with `e` the
//! standard error of the pixel's mean light, direct and indirect apart (`variance`, the
//! default).
//!
//! Choices the thesis leaves open, written down:
//! - **Demodulation** (`demodulate`, not in the thesis; on by default): the direct and indirect
//!   light are divided by the pixel's albedo (each channel at least 0.01) before filtering and
//!   multiplied by it after, as SVGF does, so that the filter smooths the illumination and not
//!   the texture. Off, the thesis's filter blurs texture detail its texture test lets through
//!   (measured on textured scenes: BENCHMARKS.md, "Seed 001").
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
//! - **Sky and bad pixels.** A pixel whose depth is not finite (the sky) or any of whose inputs
//!   is not finite (a NaN or infinite sample) is passed through unfiltered and is nobody's
//!   neighbour, so one bad sample stays in its own pixel. Pixels outside the image are not
//!   neighbours either (the window is cut at the borders, not clamped).
//! - Windows are laid over the padded planes 16 centre pixels at a time, one row of them: each
//!   tap is then 16 neighbours next to each other in memory, which the compiler turns into
//!   SIMD (AVX-512 or AVX2 with fused multiply-adds where the processor has them, chosen at run
//!   time;
//!   without, the results differ by float rounding). Rows run in parallel; every pixel's
//!   result depends on the inputs alone, not on the thread count.

use glam::Vec3;
use pathlight_core::color::luminance;
use rayon::prelude::*;

use crate::config::{ColourUnits, DepthUnits, FilterConfig};
use crate::exp::{exp_neg, Fused, MulAdd, Plain};

use crate::features::{demodulator, Features, DEPTH, NORMAL, TEXTURE, TEXTURE2};
use crate::FilterError;

/// Centre pixels filtered together: one SIMD register of f32 with AVX-512, two with AVX2.
const LANES: usize = 16;
type Lanes = [f32; LANES];

/// The padded planes, one row of each after another: `VALID` (1 or 0), depth, normal, texture,
/// texture2, direct and indirect light, and the colour difference's scale.
const VALID: usize = 0;
const D: usize = 1;
const N: usize = 2;
const T: usize = 5;
const T2: usize = 8;
const F0: usize = 11;
const F1: usize = 14;
/// The colour differences' scales of the direct and indirect light at the pixel (each a test
/// multiplies the centre's and the neighbour's): `1 / (1 + luminance)` of the pixel's light
/// (relative units), `1 / standard error` of its mean (variance units), or 1.
const SCALE_D: usize = 17;
const SCALE_I: usize = 18;
const PLANES: usize = 19;

/// The data-driven filter with its buffers (kept across frames).
#[derive(Default)]
pub struct DataDriven {
    planes: Vec<f32>,
    /// Variance units: each pixel's demodulated luminance of direct and indirect light, and
    /// the standard errors of their means.
    luminance: Vec<[f32; 2]>,
    errors: Vec<[f32; 2]>,
    /// The planes' layout and the image's height (the padding is zero for these).
    layout: Option<(Layout, usize)>,
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

    /// Filters `features` with `config`'s data-driven parameters into `out` (one value per
    /// pixel: filtered direct plus filtered indirect light).
    pub fn filter(
        &mut self,
        features: &Features,
        config: &FilterConfig,
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
        self.fill_planes(features, layout, config.colour_units, config.demodulate);
        let step = if config.holes { 2 } else { 1 };
        let offsets: Vec<usize> = (0..=2 * radius)
            .step_by(step)
            .flat_map(|dy| (0..=2 * radius).step_by(step).map(move |dx| (dy, dx)))
            .map(|(dy, dx)| dy * layout.row + dx)
            .collect();
        let scales = Scales::new(config);
        let planes = &self.planes;
        out.par_chunks_mut(features.width)
            .enumerate()
            .for_each(|(y, row)| {
                let job = Row {
                    planes,
                    layout,
                    offsets: &offsets,
                    scales: &scales,
                    features,
                    y,
                };
                job.run(row);
            });
        Ok(())
    }

    /// Writes the padded planes: the features of valid pixels, zeros (and validity 0) for
    /// the sky and bad pixels. The padding is zeroed when the layout changes and never
    /// written after.
    fn fill_planes(&mut self, f: &Features, layout: Layout, units: ColourUnits, demodulate: bool) {
        let rows = f.height + 2 * layout.radius;
        if self.layout != Some((layout, f.height)) {
            self.planes.clear();
            self.planes.resize(rows * layout.row, 0.0);
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
        if units == ColourUnits::Variance {
            self.neighbourhood_errors(f, &albedo, &valid);
        }
        let fill = FillRows {
            f,
            errors: &self.errors,
            layout,
            units,
            demodulate,
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
    /// when every variance is known).
    fn neighbourhood_errors(
        &mut self,
        f: &Features,
        albedo: &(dyn Fn(usize) -> Vec3 + Sync),
        valid: &(dyn Fn(usize) -> bool + Sync),
    ) {
        let unknown = f
            .light_variance
            .par_iter()
            .any(|v| !(known(v[0]) && known(v[1])));
        if !unknown {
            return;
        }
        let n = f.len();
        self.luminance.resize(n, [0.0; 2]);
        self.luminance
            .par_iter_mut()
            .enumerate()
            .for_each(|(i, l)| {
                let a = luminance(albedo(i));
                *l = if valid(i) {
                    [luminance(f.direct[i]) / a, luminance(f.indirect[i]) / a]
                } else {
                    [f32::NAN; 2]
                };
            });
        let lum = &self.luminance;
        let (w, h) = (f.width, f.height);
        self.errors.par_iter_mut().enumerate().for_each(|(i, e)| {
            for k in 0..2 {
                if known(f.light_variance[i][k]) {
                    continue;
                }
                let (x, y) = (i % w, i / w);
                let (mut count, mut sum, mut sq) = (0.0f32, 0.0f32, 0.0f32);
                for yy in y.saturating_sub(1)..(y + 2).min(h) {
                    for xx in x.saturating_sub(1)..(x + 2).min(w) {
                        let v = lum[yy * w + xx][k];
                        if v.is_finite() {
                            count += 1.0;
                            sum += v;
                            sq += v * v;
                        }
                    }
                }
                let variance = if count > 1.0 {
                    ((sq - sum * sum / count) / (count - 1.0)).max(0.0)
                } else {
                    0.0
                };
                e[k] = variance.sqrt();
            }
        });
    }
}

/// One row of the padded planes from the features ([`DataDriven::fill_planes`]): the
/// features of valid pixels, zeros (and validity 0) for the sky and bad pixels. Written over
/// the row's slices without branches, so that the compiler vectorises it (AVX-512 or AVX2
/// chosen at run time).
struct FillRows<'a> {
    f: &'a Features<'a>,
    /// The neighbourhoods' standard errors, for the pixels whose variance is not known.
    errors: &'a [[f32; 2]],
    layout: Layout,
    units: ColourUnits,
    demodulate: bool,
}

impl FillRows<'_> {
    fn row(&self, y: usize, row: &mut [f32]) {
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx512f") {
                // SAFETY: the processor has AVX-512 (checked just above).
                return unsafe { self.row_avx512(y, row) };
            }
            if std::arch::is_x86_feature_detected!("avx2") {
                // SAFETY: the processor has AVX2 (checked just above).
                return unsafe { self.row_avx2(y, row) };
            }
        }
        self.row_lanes(y, row);
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f")]
    fn row_avx512(&self, y: usize, row: &mut [f32]) {
        self.row_lanes(y, row);
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn row_avx2(&self, y: usize, row: &mut [f32]) {
        self.row_lanes(y, row);
    }

    #[inline(always)]
    fn row_lanes(&self, y: usize, row: &mut [f32]) {
        let (f, w, l) = (self.f, self.f.width, self.layout);
        let span = y * w..(y + 1) * w;
        let (direct, indirect) = (&f.direct[span.clone()], &f.indirect[span.clone()]);
        let (depth, normal) = (&f.depth[span.clone()], &f.normal[span.clone()]);
        let (albedo, texture2) = (&f.albedo[span.clone()], &f.texture2[span.clone()]);
        let (variance, errors) = (&f.light_variance[span.clone()], &self.errors[span]);
        let (row, pitch) = (&mut row[..PLANES * l.pitch], l.pitch);
        for x in 0..w {
            let a = divisor(albedo[x], self.demodulate);
            let inv = a.recip();
            let values = [
                normal[x],
                albedo[x],
                texture2[x],
                direct[x] * inv,
                indirect[x] * inv,
            ];
            let valid = valid_pixel(
                depth[x],
                [normal[x], albedo[x], texture2[x], direct[x], indirect[x]],
            );
            let zero_if_invalid = |v: f32| if valid { v } else { 0.0 };
            let at = x + l.radius;
            row[VALID * pitch + at] = zero_if_invalid(1.0);
            row[D * pitch + at] = zero_if_invalid(depth[x]);
            for (plane, v) in [N, T, T2, F0, F1].into_iter().zip(values) {
                for c in 0..3 {
                    row[(plane + c) * pitch + at] = zero_if_invalid(v[c]);
                }
            }
            let lum = luminance(values[3] + values[4]).max(0.0);
            let [sd, si] = match self.units {
                ColourUnits::Linear => [1.0; 2],
                ColourUnits::Relative => [1.0 / (1.0 + lum); 2],
                ColourUnits::Variance => {
                    // The standard error of the mean of the direct and indirect light's
                    // luminance (demodulated): from the pixel's own variance where the caller
                    // knows it, else from its neighbourhood's (`neighbourhood_errors`). At most
                    // 100 / (1 + L): a pixel without noise is not a wall.
                    let la = luminance(a);
                    let floor = 0.01 * (1.0 + lum);
                    [0, 1].map(|k| {
                        let v = variance[x][k];
                        let e = if known(v) {
                            (v / (la * la)).sqrt()
                        } else {
                            errors[x][k]
                        };
                        1.0 / e.max(floor)
                    })
                }
            };
            row[SCALE_D * pitch + at] = zero_if_invalid(sd);
            row[SCALE_I * pitch + at] = zero_if_invalid(si);
        }
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
    variance.is_finite() && variance >= 0.0
}

/// `1 / (2 sigma^2)` of each test.
struct Scales {
    direct: f32,
    indirect: f32,
    depth: f32,
    normal: f32,
    texture: f32,
    texture2: f32,
    variance: [f32; 5],
    relative_depth: bool,
    demodulate: bool,
}

impl Scales {
    fn new(c: &FilterConfig) -> Self {
        let k = |s: f32| 1.0 / (2.0 * s * s);
        Self {
            direct: k(c.sigma_direct),
            indirect: k(c.sigma_indirect),
            depth: k(c.sigma_depth),
            normal: k(c.sigma_normal),
            texture: k(c.sigma_texture),
            texture2: k(c.sigma_texture2),
            variance: c.variance_scale,
            relative_depth: c.depth_units == DepthUnits::Relative,
            demodulate: c.demodulate,
        }
    }
}

/// One row of the image.
struct Row<'a> {
    planes: &'a [f32],
    layout: Layout,
    offsets: &'a [usize],
    scales: &'a Scales,
    features: &'a Features<'a>,
    y: usize,
}

/// A centre pixel's values and coefficients, lane by lane.
#[derive(Default)]
struct Centre {
    depth: Lanes,
    normal: [Lanes; 3],
    texture: [Lanes; 3],
    texture2: [Lanes; 3],
    direct: [Lanes; 3],
    indirect: [Lanes; 3],
    scale_direct: Lanes,
    scale_indirect: Lanes,
    c_direct: Lanes,
    c_indirect: Lanes,
    c_depth: Lanes,
    c_normal: Lanes,
    c_texture: Lanes,
    c_texture2: Lanes,
}

/// The weighted sums of one block of centres.
#[derive(Default)]
struct Sums {
    direct_w: Lanes,
    direct: [Lanes; 3],
    indirect_w: Lanes,
    indirect: [Lanes; 3],
}

impl Row<'_> {
    fn run(&self, out: &mut [Vec3]) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("fma") {
            if std::arch::is_x86_feature_detected!("avx512f") {
                // SAFETY: the processor has AVX-512 and FMA (checked just above).
                unsafe { self.run_avx512(out) };
                return;
            }
            if std::arch::is_x86_feature_detected!("avx2") {
                // SAFETY: the processor has AVX2 and FMA (checked just above).
                unsafe { self.run_avx2(out) };
                return;
            }
        }
        self.run_blocks::<Plain>(out);
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    fn run_avx2(&self, out: &mut [Vec3]) {
        self.run_blocks::<Fused>(out);
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,fma")]
    fn run_avx512(&self, out: &mut [Vec3]) {
        self.run_blocks::<Fused>(out);
    }

    #[inline(always)]
    fn run_blocks<M: MulAdd>(&self, out: &mut [Vec3]) {
        let width = self.layout.width;
        for x0 in (0..width).step_by(LANES) {
            let centre = self.centre(x0);
            let sums = self.sums::<M>(x0, &centre);
            // The weighted means, in lanes.
            let light: [Lanes; 3] = std::array::from_fn(|c| {
                std::array::from_fn(|j| {
                    sums.direct[c][j] / sums.direct_w[j] + sums.indirect[c][j] / sums.indirect_w[j]
                })
            });
            // The block's pixels, as slices of their length (no bounds checks in the loop).
            let n = LANES.min(width - x0);
            let (f, i0) = (self.features, self.y * width + x0);
            let (direct, indirect) = (&f.direct[i0..i0 + n], &f.indirect[i0..i0 + n]);
            let albedo = &f.albedo[i0..i0 + n];
            let at = self.layout.at(x0, self.y) + VALID * self.layout.pitch;
            let valid = &self.planes[at..at + n];
            for (j, o) in out[x0..x0 + n].iter_mut().enumerate() {
                *o = if valid[j] == 0.0 {
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

    /// The block's centre values and coefficients (lanes past the row's end are padding).
    #[inline(always)]
    fn centre(&self, x0: usize) -> Centre {
        let s = self.scales;
        let l = &self.layout;
        let base = l.at(x0, self.y);
        let load = |plane: usize| -> Lanes {
            let at = base + plane * l.pitch;
            self.planes[at..at + LANES]
                .try_into()
                .expect("a block of lanes")
        };
        let mut c = Centre {
            depth: load(D),
            scale_direct: load(SCALE_D),
            scale_indirect: load(SCALE_I),
            ..Default::default()
        };
        for k in 0..3 {
            c.normal[k] = load(N + k);
            c.texture[k] = load(T + k);
            c.texture2[k] = load(T2 + k);
            c.direct[k] = load(F0 + k);
            c.indirect[k] = load(F1 + k);
        }
        let width = l.width;
        // The feature variances of the block's pixels (zeros past the row's end).
        let row = &self.features.variance[self.y * width..(self.y + 1) * width];
        let variances: [[f32; 5]; LANES] =
            std::array::from_fn(|j| row.get(x0 + j).copied().unwrap_or([0.0; 5]));
        for (j, variance) in variances.into_iter().enumerate() {
            let depth_scale = if s.relative_depth {
                1.0 / c.depth[j].max(1e-6)
            } else {
                1.0
            };
            // A variance that is not a number trusts the feature not at all.
            let lowered = |k: f32, i: usize, v: f32| {
                let t = v * s.variance[i];
                k * (1.0 - if t.is_nan() { 1.0 } else { t.clamp(0.0, 1.0) })
            };
            // The depth scale folded into the coefficient: c (dD / d)^2 = (c / d^2) dD^2.
            let depth_variance = variance[DEPTH] * depth_scale * depth_scale;
            c.c_depth[j] = lowered(s.depth, DEPTH, depth_variance) * depth_scale * depth_scale;
            c.c_normal[j] = lowered(s.normal, NORMAL, variance[NORMAL]);
            c.c_texture[j] = lowered(s.texture, TEXTURE, variance[TEXTURE]);
            c.c_texture2[j] = lowered(s.texture2, TEXTURE2, variance[TEXTURE2]);
            // The centre's half of the colour scales (the neighbour's is its plane).
            c.c_direct[j] = s.direct * c.scale_direct[j];
            c.c_indirect[j] = s.indirect * c.scale_indirect[j];
        }
        c
    }

    /// The weighted sums over the window of each centre of the block.
    #[inline(always)]
    fn sums<M: MulAdd>(&self, x0: usize, c: &Centre) -> Sums {
        let l = &self.layout;
        // The window's top-left corner of the first centre.
        let corner = l.at(x0, self.y) - l.radius * l.row - l.radius;
        let mut s = Sums::default();
        let last = self.offsets.last().map_or(0, |o| corner + o) + (PLANES - 1) * l.pitch;
        assert!(
            last + LANES <= self.planes.len(),
            "the window stays in the planes"
        );
        for &offset in self.offsets {
            let base = corner + offset;
            let load = |plane: usize| -> Lanes {
                let at = base + plane * l.pitch;
                // SAFETY: `offsets` grow, so `at + LANES <= last + LANES`, which is in bounds
                // (asserted above).
                unsafe { *(self.planes.as_ptr().add(at) as *const Lanes) }
            };
            let valid = load(VALID);
            let (scale_d, scale_i) = (load(SCALE_D), load(SCALE_I));
            let depth = load(D);
            let (n, t, t2, f0, f1) = (
                [load(N), load(N + 1), load(N + 2)],
                [load(T), load(T + 1), load(T + 2)],
                [load(T2), load(T2 + 1), load(T2 + 2)],
                [load(F0), load(F0 + 1), load(F0 + 2)],
                [load(F1), load(F1 + 1), load(F1 + 2)],
            );
            for j in 0..LANES {
                // k |a - b|^2 + plus.
                let term = |a: &[Lanes; 3], b: &[Lanes; 3], k: f32, plus: f32| {
                    let (x, y, z) = (a[0][j] - b[0][j], a[1][j] - b[1][j], a[2][j] - b[2][j]);
                    M::mul_add(k, M::mul_add(x, x, M::mul_add(y, y, z * z)), plus)
                };
                let dd = depth[j] - c.depth[j];
                let features = term(&n, &c.normal, c.c_normal[j], c.c_depth[j] * (dd * dd));
                let features = term(&t, &c.texture, c.c_texture[j], features);
                let wd = valid[j]
                    * exp_neg::<M>(-term(&f0, &c.direct, c.c_direct[j] * scale_d[j], features));
                let indirect = term(&t2, &c.texture2, c.c_texture2[j], features);
                let wi = valid[j]
                    * exp_neg::<M>(-term(
                        &f1,
                        &c.indirect,
                        c.c_indirect[j] * scale_i[j],
                        indirect,
                    ));
                s.direct_w[j] += wd;
                s.indirect_w[j] += wi;
                for k in 0..3 {
                    s.direct[k][j] = M::mul_add(wd, f0[k][j], s.direct[k][j]);
                    s.indirect[k][j] = M::mul_add(wi, f1[k][j], s.indirect[k][j]);
                }
            }
        }
        s
    }
}
