//! A spatio-temporal variance-guided filter in the manner of SVGF (Schied et al., "Spatiotemporal
//! Variance-Guided Filtering", HPG 2017), beyond the thesis, which has no temporal part: the
//! one-sample-per-pixel answer while the camera moves.
//!
//! ```text
//! temporal  this frame's light (demodulated by    -> integrated light, moments, history
//!           the albedo), motion, depth, normal;      length (reverse reprojection through
//!           last frame's integrated light            the motion vectors, 2x2 bilinear taps
//!                                                    each kept by depth and normal tests)
//! variance  moments, history length                -> luminance variance (temporal; a 7x7
//!                                                    spatial estimate below 4 frames)
//! a-trous   light, variance, depth, normal         -> filtered light (`iterations` 5x5
//!                                                    B3-spline passes, or 3x3 linear ones,
//!                                                    with holes of 1, 2, 4..;
//!                                                    the first one's output is the next
//!                                                    frame's history, as in the paper)
//! remodulate filtered light, albedo                -> image
//! taa       image, motion, last image              -> image (with `taa`: [`crate::taa`], the
//!                                                    paper's last stage, not the filter's)
//! ```
//!
//! Direct and indirect light are integrated and filtered apart (two signals, each with its
//! luminance moments), as in the paper; with [`SvgfParams::split`] off, their sum is integrated
//! and filtered as one signal (not in the paper: a tap's two luminance tests, exponentials and
//! sums become one). Choices the paper leaves open or that differ, written down:
//! - Edge-stopping: luminance `exp(-|l_p - l_q| / (sigma_l sqrt(g(var_p)) + eps))` with g a 3x3
//!   Gaussian of the variance, sigma_l 4; depth `exp(-|z_p - z_q| / (sigma_z |grad z_p| |p - q|
//!   + eps))` with the depth gradient from central differences, sigma_z 1; normal
//!   `max(0, n_p . n_q)^128` (the paper's values).
//! - Reprojection tests: a previous pixel is kept when its depth is within 10% of this pixel's
//!   (the paper compares depth with its gradient and mesh ids; there are no mesh ids here) and
//!   the two normals lie within `k (w + 0.01)` of each other, `k` 16, `w` this pixel's normal
//!   width (`normal_width`): the test of the authors' implementation, whose width is the
//!   raster's `|(|dn/dx| + |dn/dy|)|`; here each axis takes the smaller of its two one-sided
//!   differences, so the edge between two flat surfaces has a width of 0 where the raster's is
//!   wide. Foliage, whose normals change from pixel to pixel, keeps its history; a flat
//!   surface is tested more tightly than by the first test here, a cosine of at least 0.9
//!   ([`SvgfParams::normal_width`] 0).
//! - Blending: `alpha = max(1 / n, 0.2)` for the light and the moments, n the history length
//!   (capped at 32), as the paper.
//! - **Converging while still** (`converge`, [`SvgfParams::converge`]; not in the paper, off
//!   by default): the paper's history never converges (each frame weighs 0.2, and the
//!   history holds the first a-trous pass's output, so a still view's detail that the first
//!   pass blurs never comes back). With the option a pixel whose motion vector is 0 blends
//!   each frame into a plain mean of its history (`alpha = 1 / (1 / W + 1)`, W the sum of the
//!   squared weights of the frames the history holds, kept per pixel; at most the paper's
//!   alpha), its history keeps the integrated light instead of the first pass's (once it has
//!   taken a previous frame's: a new history, as on a camera path's first frame, whose motion
//!   vectors are 0, is the paper's), and its luminance test narrows with the mean's noise
//!   ([`narrowing`]). A pixel that moves is filtered as the paper does, so a moving camera's
//!   frames are the paper's bit for bit. The sky and light sources still pass through with
//!   one frame's light.
//! - The sky and light sources (`emitter`) pass through with this frame's light and are not
//!   filtered with their neighbours.
//! - A tap's weight under 1e-10 (the centre's is at least 9/64) is 0, and so is a luminance
//!   variance under 1e-16 and the normal weight under a cosine of 0.8: no product is then a
//!   subnormal number, whose arithmetic is slow on Intel's cores (the images are the same to
//!   rounding).
//!
//! The a-trous passes run vectorised over padded planes ([`crate::atrous`]) up to six passes
//! (holes of 32 pixels), the other stages worked out as the planes are laid out: the features
//! with the depth gradient (`Features`) and the temporal pass (`Temporal`, the previous frame's
//! taps loaded from the history's planes, `crate::history`) in lanes, the spatial variance in
//! lanes too in the rows with a short history (`SpatialVariance`; the groups whose 7x7 window
//! would leave the row pixel by pixel, `spatial_variance`), the output in lanes (`Output`).
//! The scalar passes here, with their own buffers (`integrate`, `depth_gradient`, `remodulate`
//! of one pixel), are the reference they are tested against and run beyond that (and for
//! images of 2^24 pixels or more, whose indices an `f32` lane does not hold exactly).

use glam::{Vec2, Vec3};
use pathlight_core::color::luminance;
use rayon::prelude::*;

use crate::atrous::{
    flush_variance, flush_variance_lanes, normal_weight, normal_weight_lanes, radius, spline,
    LightRow, LightView, Planes, StaticRow, StaticsView, BLUR, MAX_PAD, MIN_WEIGHT,
};
use crate::exp::exp_neg;
use crate::features::{demodulator, demodulator_lanes};
use crate::history::{History, State, DEPTH, FIELDS, LENGTH, LIGHT, MOMENTS, NORMAL, WEIGHTS2};
use crate::simd::{
    channels, dispatch, exp_neg_in_range, gather3, iota, load_first, luminance_lanes, max, min,
    store_first, stream_first, ByGroups, F32xN, Fetch, Floats, Groups, LANES,
};
use crate::taa::Taa;
use crate::{simd, FilterError};

/// One frame's inputs, per pixel in row-major order.
#[derive(Debug, Clone, Copy)]
pub struct SvgfFrame<'a> {
    pub width: usize,
    pub height: usize,
    /// This frame's direct and indirect light (the frame's own samples, not accumulated).
    pub direct: &'a [Vec3],
    pub indirect: &'a [Vec3],
    pub albedo: &'a [Vec3],
    pub normal: &'a [Vec3],
    /// Depth along the view axis; not finite on the sky.
    pub depth: &'a [f32],
    /// Where the pixel's surface was on the previous frame minus where it is, in pixels.
    pub motion: &'a [Vec2],
    /// The pixel shows a light source.
    pub emitter: &'a [bool],
}

/// The filter's parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SvgfParams {
    /// A-trous passes.
    pub iterations: u32,
    /// The a-trous kernel's width: 5 (the paper's B3 spline) or 3.
    pub kernel: u32,
    /// Direct and indirect light integrated and filtered apart (the paper); else their sum as
    /// one signal.
    pub split: bool,
    /// The reprojection's normal test: `k > 0` (16 by default) keeps a previous pixel whose
    /// normal lies within `k` times this pixel's normal width ([`normal_width`]) plus 0.01 of
    /// this one's (the authors' implementation's test, with its `k`, on a width that is 0 on
    /// the edge between two flat surfaces); 0 keeps a previous pixel whose normal's cosine
    /// with this one's is at least 0.9.
    pub normal_width: f32,
    /// Temporal antialiasing of the output ([`crate::taa`]), as the paper applies after the
    /// filter.
    pub taa: bool,
    /// This frame's weight in the temporal antialiasing's blend ([`crate::taa::Taa::set_alpha`]).
    pub taa_alpha: f32,
    /// The temporal antialiasing's box half-width ([`crate::taa::Taa::set_gamma`]).
    pub taa_gamma: f32,
    /// Converge while the camera is still (not in the paper): a pixel that has not moved
    /// (its motion vector 0) blends its history as a plain mean of the frames it has seen
    /// instead of at `alpha = 0.2`, and its luminance test narrows as the mean's noise falls
    /// ([`integrate`]); a pixel that moves is filtered as the paper does, bit for bit.
    pub converge: bool,
}

impl SvgfParams {
    /// At most [`MAX_ITERATIONS`] passes (0: the temporal pass alone), a kernel of 3 or 5, a
    /// finite normal width of at least 0; the fields named as pathlight's configuration
    /// names them.
    pub fn validate(&self) -> Result<(), FilterError> {
        if self.iterations > MAX_ITERATIONS {
            return FilterError::parameter(
                "frame.filter.svgf.atrous_iterations",
                self.iterations,
                format!("at most {MAX_ITERATIONS}"),
            );
        }
        if !matches!(self.kernel, 3 | 5) {
            return FilterError::parameter(
                "frame.filter.svgf.atrous_kernel",
                self.kernel,
                "3 or 5",
            );
        }
        if !(self.normal_width.is_finite() && self.normal_width >= 0.0) {
            return FilterError::parameter(
                "frame.filter.svgf.normal_width",
                self.normal_width,
                "finite and at least 0",
            );
        }
        Ok(())
    }
}

/// The most a-trous passes [`Svgf::filter`] runs (holes of 2^15 pixels).
pub const MAX_ITERATIONS: u32 = 16;

impl Default for SvgfParams {
    fn default() -> Self {
        Self {
            iterations: 5,
            kernel: 5,
            split: true,
            normal_width: 16.0,
            taa: false,
            taa_alpha: crate::taa::ALPHA,
            taa_gamma: crate::taa::GAMMA,
            converge: false,
        }
    }
}

/// The filter's history and scratch buffers (kept across frames).
#[derive(Default)]
pub struct Svgf {
    width: usize,
    height: usize,
    /// The history holds direct and indirect light apart (else their sum in the first).
    split: bool,
    /// Last frame's state of each pixel, which the temporal pass reads.
    state: History,
    /// This frame's, written by the temporal pass and the first a-trous pass.
    next: History,
    // Scratch of this frame.
    light: Vec<[Vec3; 2]>,
    variance: Vec<[f32; 2]>,
    next_light: Vec<[Vec3; 2]>,
    next_variance: Vec<[f32; 2]>,
    gradient: Vec<f32>,
    /// The luminance of `light` (per a-trous pass).
    luminance: Vec<[f32; 2]>,
    /// The vectorised a-trous passes' planes.
    planes: Planes,
    /// The output's temporal antialiasing (with [`SvgfParams::taa`]).
    taa: Taa,
    /// Run the scalar a-trous passes (the reference the vectorised ones are tested against).
    scalar: bool,
}

const SIGMA_L: f32 = 4.0;
const SIGMA_Z: f32 = 1.0;
const MIN_ALPHA: f32 = 0.2;
const MAX_LENGTH: f32 = 32.0;
/// The sum of the squared weights of the paper's history (`alpha = 0.2` for ever:
/// `alpha^2 / (1 - (1 - alpha)^2)`), what its luminance test is tuned to.
const PAPER_WEIGHTS2: f32 = MIN_ALPHA * MIN_ALPHA / (1.0 - (1.0 - MIN_ALPHA) * (1.0 - MIN_ALPHA));
/// The smallest sum of squared weights of a converging history: a plain mean of at most 4096
/// frames.
const MIN_WEIGHTS2: f32 = 1.0 / 4096.0;
const DEPTH_TOLERANCE: f32 = 0.1;
const NORMAL_COSINE: f32 = 0.9;
/// Added to the normal width in the reprojection's normal test (the authors' implementation's
/// value): a flat surface keeps normals within `0.01 k`.
const NORMAL_WIDTH_FLOOR: f32 = 0.01;

impl Svgf {
    pub fn new() -> Self {
        Self::default()
    }

    /// Runs the scalar a-trous passes instead of the vectorised ones (same weights and sums;
    /// for tests and benchmarks).
    #[doc(hidden)]
    pub fn set_scalar(&mut self, scalar: bool) {
        self.scalar = scalar;
    }

    /// Caps the vectorised passes' lanes (and its temporal antialiasing's) at AVX2 (`avx2`)
    /// or plain arrays (`portable`) instead of the widest the processor has (for tests on
    /// processors with AVX-512).
    #[doc(hidden)]
    pub fn set_lanes(&mut self, lanes: &str) {
        self.planes.isa = crate::simd::Isa::named(lanes);
        self.taa.set_lanes(lanes);
    }

    /// Forgets the history (a cut: the next frame starts afresh).
    pub fn reset(&mut self) {
        self.state.clear();
        self.taa.reset();
    }

    /// Filters `frame` into `out` with the passes `p` gives, using and updating the history.
    pub fn filter(
        &mut self,
        f: &SvgfFrame,
        p: &SvgfParams,
        out: &mut [Vec3],
    ) -> Result<(), FilterError> {
        let SvgfParams {
            iterations,
            kernel,
            split,
            normal_width,
            taa,
            taa_alpha,
            taa_gamma,
            converge,
        } = *p;
        p.validate()?;
        let n = f.width * f.height;
        for (name, len) in [
            ("direct", f.direct.len()),
            ("indirect", f.indirect.len()),
            ("albedo", f.albedo.len()),
            ("normal", f.normal.len()),
            ("depth", f.depth.len()),
            ("motion", f.motion.len()),
            ("emitter", f.emitter.len()),
            ("output", out.len()),
        ] {
            if len != n {
                return Err(FilterError::Size {
                    name,
                    len,
                    width: f.width,
                    height: f.height,
                });
            }
        }
        if n == 0 {
            return Ok(());
        }
        if (self.width, self.height, self.split) != (f.width, f.height, split)
            || self.state.len() != n
        {
            self.width = f.width;
            self.height = f.height;
            self.split = split;
            self.state.reset(f.width, f.height);
        }
        self.next.fit(f.width, f.height);
        // The padding the passes' taps reach into: the kernel's radius times the widest holes.
        let pad = radius(kernel) << iterations.saturating_sub(1);
        let previous = &self.state;
        // (In lanes the pixels' indices are `f32`s, exact below 2^24.)
        if pad <= MAX_PAD && !self.scalar && n < 1 << 24 {
            // The features, the temporal pass, the variance and the depth gradient worked out
            // in lanes as the planes are laid out: the integrated light straight into them.
            self.planes.layout(f.width, f.height, pad, signals(split));
            let isa = self.planes.isa;
            self.planes.load_statics_rows(|y, row| {
                dispatch(isa, ByGroups(Features { f, y, row }));
            });
            // The rows with pixels whose history is short.
            let rows = self
                .planes
                .load_light_rows(self.next.planes_mut(), |y, next, row| {
                    let t = Temporal {
                        f,
                        previous,
                        split,
                        normal_width,
                        converge,
                        y,
                        row,
                        next,
                    };
                    let short = dispatch(isa, ByGroups(t));
                    // The history's rows were streamed past the caches (the next frame reads
                    // them, after the a-trous passes' tens of megabytes).
                    simd::store_fence();
                    short
                });
            // Where the history is short, the variance from the neighbourhood's moments.
            let next = &self.next;
            self.planes.amend_variance(&rows, |y, mut row, features| {
                let signals = row.signals;
                let out = row.variances();
                dispatch(
                    isa,
                    ByGroups(SpatialVariance {
                        f,
                        next,
                        features,
                        y,
                        out,
                        signals,
                    }),
                );
            });
            for i in 0..iterations {
                self.planes
                    .pass(kernel, 1 << i, SIGMA_L, SIGMA_Z, i + 1 == iterations);
                if i == 0 {
                    self.keep_planes_light(f, converge);
                }
            }
            if iterations == 0 {
                self.keep_planes_light(f, converge);
            }
            self.planes.for_light_rows(out, |y, out, view| {
                dispatch(isa, ByGroups(Output { f, y, view, out }));
            });
        } else {
            // Temporal accumulation into `light` and `next`.
            let (light, states): (Vec<_>, Vec<_>) = (0..n)
                .into_par_iter()
                .map(|i| integrate(f, previous, split, normal_width, converge, i))
                .unzip();
            self.light = light;
            for (i, s) in states.iter().enumerate() {
                self.next.set(i, s);
            }
            self.spatial_variance(f, converge);
            self.depth_gradient(f);
            for i in 0..iterations {
                self.atrous(f, kernel, 1 << i, signals(split));
                std::mem::swap(&mut self.light, &mut self.next_light);
                std::mem::swap(&mut self.variance, &mut self.next_variance);
                if i == 0 {
                    self.keep_light(f, converge);
                }
            }
            if iterations == 0 {
                self.keep_light(f, converge);
            }
            out.par_iter_mut()
                .enumerate()
                .for_each(|(i, o)| *o = remodulate(f, i, self.light[i][0] + self.light[i][1]));
        }
        if taa {
            self.taa.set_alpha(taa_alpha);
            self.taa.set_gamma(taa_gamma);
            self.taa.apply(out, f.motion, f.width, f.height);
        } else {
            self.taa.reset();
        }
        std::mem::swap(&mut self.state, &mut self.next);
        Ok(())
    }

    /// `light` as this frame's history where it does not keep its integrated light (the
    /// scalar passes).
    fn keep_light(&mut self, f: &SvgfFrame, converge: bool) {
        for (i, light) in self.light.iter().enumerate() {
            if !keeps_integrated(f, self.next.field(i, WEIGHTS2), i, converge) {
                self.next.set_light(i, light);
            }
        }
    }

    /// The planes' light as this frame's history where it does not keep its integrated light
    /// (the paper's: the first a-trous pass's output).
    fn keep_planes_light(&mut self, f: &SvgfFrame, converge: bool) {
        let (w, isa) = (f.width, self.planes.isa);
        self.planes
            .for_light_rows(self.next.planes_mut(), |y, next, view| {
                let (light, rest) = next.split_at_mut(NORMAL * w);
                let weights2 = &rest[(WEIGHTS2 - NORMAL) * w..][..w];
                for (p, light) in light[LIGHT * w..][..6 * w].chunks_exact_mut(w).enumerate() {
                    let (s, k) = (p / 3, p % 3);
                    if s >= view.signals {
                        light.fill(0.0);
                    } else if !converge {
                        simd::stream_copy(isa, light, &view.light(s, k)[..w]);
                    } else {
                        let source = &view.light(s, k)[..w];
                        for (x, l) in light.iter_mut().enumerate() {
                            *l = if keeps_integrated(f, weights2[x], y * w + x, converge) {
                                *l
                            } else {
                                source[x]
                            };
                        }
                    }
                }
                simd::store_fence();
            });
    }

    /// The luminance variance of each signal (from the temporal moments, or [`spatial_variance`]
    /// where the history is [`short`]) into `variance`.
    fn spatial_variance(&mut self, f: &SvgfFrame, converge: bool) {
        let n = f.width * f.height;
        self.variance.resize(n, [0.0; 2]);
        let next = &self.next;
        self.variance.par_iter_mut().enumerate().for_each(|(i, v)| {
            *v = if short(f, next, i) {
                spatial_variance(f, next, i)
            } else {
                let k = narrowing(f, next.field(i, WEIGHTS2), i, converge);
                variance(next.moments(i)).map(|v| v * k)
            }
        });
    }

    /// |grad z| per pixel ([`depth_gradient`]) into `gradient`.
    fn depth_gradient(&mut self, f: &SvgfFrame) {
        self.gradient.resize(f.width * f.height, 0.0);
        self.gradient
            .par_iter_mut()
            .enumerate()
            .for_each(|(i, g)| *g = depth_gradient(f, i));
    }

    /// One a-trous pass of a kernel `kernel` pixels wide with holes of `step` pixels over the
    /// first `signals` signals, into `next_light` and `next_variance`.
    fn atrous(&mut self, f: &SvgfFrame, kernel: u32, step: i64, signals: usize) {
        let weights = spline(kernel);
        let r = radius(kernel) as i64;
        let n = f.width * f.height;
        self.next_light.resize(n, [Vec3::ZERO; 2]);
        self.next_variance.resize(n, [0.0; 2]);
        let (w, h) = (f.width as i64, f.height as i64);
        self.luminance.resize(n, [0.0; 2]);
        let light = &self.light;
        self.luminance
            .par_iter_mut()
            .zip(light.par_iter())
            .for_each(|(l, c)| *l = [luminance(c[0]), luminance(c[1])]);
        let (variance, gradient, lum) = (&self.variance, &self.gradient, &self.luminance);
        // The variance's 3x3 Gaussian at a pixel.
        let blurred = |x: i64, y: i64| -> [f32; 2] {
            let mut acc = [0.0f32; 2];
            let mut sum = 0.0;
            for &(dx, dy, k) in &BLUR {
                let (qx, qy) = (x + dx, y + dy);
                if qx < 0 || qy < 0 || qx >= w || qy >= h {
                    continue;
                }
                let v = variance[(qy * w + qx) as usize];
                acc[0] += v[0] * k;
                acc[1] += v[1] * k;
                sum += k;
            }
            acc.map(|a| a / sum)
        };
        (&mut self.next_light, &mut self.next_variance)
            .into_par_iter()
            .enumerate()
            .for_each(|(i, (out_l, out_v))| {
                if passes_through(f, i) {
                    *out_l = light[i];
                    *out_v = variance[i];
                    return;
                }
                let (x, y) = ((i as i64) % w, (i as i64) / w);
                let g = blurred(x, y);
                let lum_p = lum[i];
                let inv_sigma = g.map(|v| 1.0 / (SIGMA_L * v.sqrt() + 1e-4));
                let mut sum_w = [0.0f32; 2];
                let mut acc = [Vec3::ZERO; 2];
                let mut acc_v = [0.0f32; 2];
                for ky in -r..=r {
                    for kx in -r..=r {
                        let (qx, qy) = (x + kx * step, y + ky * step);
                        if qx < 0 || qy < 0 || qx >= w || qy >= h {
                            continue;
                        }
                        let q = (qy * w + qx) as usize;
                        if passes_through(f, q) {
                            continue;
                        }
                        let kernel = weights[kx.unsigned_abs() as usize]
                            * weights[ky.unsigned_abs() as usize];
                        let distance = ((kx * kx + ky * ky) as f32).sqrt() * step as f32;
                        let wz = -(f.depth[q] - f.depth[i]).abs()
                            / (SIGMA_Z * gradient[i] * distance + 1e-4 * f.depth[i]);
                        let wn = normal_weight(f.normal[q].dot(f.normal[i]));
                        for s in 0..signals {
                            let wl = -(lum[q][s] - lum_p[s]).abs() * inv_sigma[s];
                            let e = wz + wl;
                            let wq = if q == i {
                                kernel
                            } else if wn > 0.0 && e > -30.0 {
                                let t = kernel * wn * exp_neg(e);
                                if t < MIN_WEIGHT {
                                    continue;
                                }
                                t
                            } else {
                                // Below e^-30 of the centre's weight: nothing, and no
                                // subnormal arithmetic (which is slow).
                                continue;
                            };
                            sum_w[s] += wq;
                            acc[s] += light[q][s] * wq;
                            acc_v[s] += variance[q][s] * wq * wq;
                        }
                    }
                }
                for s in 0..signals {
                    out_l[s] = acc[s] / sum_w[s];
                    out_v[s] = flush_variance(acc_v[s] / (sum_w[s] * sum_w[s]));
                }
                out_l[signals..].copy_from_slice(&light[i][signals..]);
                out_v[signals..].copy_from_slice(&variance[i][signals..]);
            });
    }
}

/// Pixel `i`'s output for its filtered (demodulated) `light`: the light times the albedo, or
/// this frame's light where the pixel passes through.
fn remodulate(f: &SvgfFrame, i: usize, light: Vec3) -> Vec3 {
    if passes_through(f, i) {
        f.direct[i] + f.indirect[i]
    } else {
        light * demodulator(f.albedo[i])
    }
}

/// The luminance variance of each signal from moments `m`.
fn variance(m: [f32; 4]) -> [f32; 2] {
    [
        flush_variance(m[1] - m[0] * m[0]),
        flush_variance(m[3] - m[2] * m[2]),
    ]
}

/// Temporal accumulation at pixel `i`: this frame's demodulated light (direct and indirect
/// apart if `split`, else their sum) blended with last frame's history (`previous`) at the
/// reprojected position; the integrated light and the pixel's state (its light left for the
/// first a-trous pass to fill in). `normal_width`: [`SvgfParams::normal_width`].
fn integrate(
    f: &SvgfFrame,
    previous: &History,
    split: bool,
    normal_width: f32,
    converge: bool,
    i: usize,
) -> ([Vec3; 2], State) {
    let (w, h) = (f.width, f.height);
    let a = demodulator(f.albedo[i]);
    let current = if split {
        [f.direct[i] / a, f.indirect[i] / a]
    } else {
        [(f.direct[i] + f.indirect[i]) / a, Vec3::ZERO]
    };
    // A sample that is not finite gives its pixel no light, and its moments none either (a
    // NaN moment would take the luminance test's variance from its neighbours).
    let finite = current.iter().all(|c| c.is_finite());
    let current = if finite { current } else { [Vec3::ZERO; 2] };
    let lum = [luminance(current[0]), luminance(current[1])];
    let now = [lum[0], lum[0] * lum[0], lum[1], lum[1] * lum[1]];
    // Where the pixel converges its history keeps the integrated light (else the first
    // a-trous pass's, filled in later: `keeps_integrated`).
    let state = |light: [Vec3; 2], m, length, weights2| {
        let mut s = State {
            light: [Vec3::ZERO; 2],
            m,
            length,
            depth: f.depth[i],
            normal: f.normal[i],
            weights2,
        };
        if keeps_integrated(f, s.weights2, i, converge) {
            s.light = light;
        }
        s
    };
    if passes_through(f, i) || !finite {
        return (current, state(current, now, 0.0, 1.0));
    }
    // The normal test's largest squared distance (with `normal_width`).
    let reach = if normal_width > 0.0 {
        let reach = normal_width * (self::normal_width(f, i) + NORMAL_WIDTH_FLOOR);
        reach * reach
    } else {
        0.0
    };
    // Reverse reprojection: bilinear taps of the previous frame around p + motion.
    let (x, y) = ((i % w) as f32 + 0.5, (i / w) as f32 + 0.5);
    let prev = Vec2::new(x, y) + f.motion[i] - Vec2::splat(0.5);
    let (x0, y0) = (prev.x.floor(), prev.y.floor());
    let (fx, fy) = (prev.x - x0, prev.y - y0);
    let mut sum_w = 0.0;
    let mut old = [Vec3::ZERO; 2];
    let mut old_m = [0.0f32; 4];
    let mut old_len = 0.0;
    let mut old_w2 = 0.0;
    for (dx, dy, bw) in [
        (0, 0, (1.0 - fx) * (1.0 - fy)),
        (1, 0, fx * (1.0 - fy)),
        (0, 1, (1.0 - fx) * fy),
        (1, 1, fx * fy),
    ] {
        let (qx, qy) = (x0 as i64 + dx, y0 as i64 + dy);
        // (A motion that is not finite gives weights that are not: no tap.)
        if qx < 0 || qy < 0 || qx >= w as i64 || qy >= h as i64 || bw.is_nan() || bw <= 0.0 {
            continue;
        }
        let p = &previous.get(qy as usize * w + qx as usize);
        // (A NaN normal agrees with none.)
        let normal_agrees = if normal_width > 0.0 {
            (p.normal - f.normal[i]).length_squared() <= reach
        } else {
            p.normal.dot(f.normal[i]) >= NORMAL_COSINE
        };
        if p.length <= 0.0
            || !p.depth.is_finite()
            || (p.depth - f.depth[i]).abs() > DEPTH_TOLERANCE * f.depth[i]
            || !normal_agrees
        {
            continue;
        }
        sum_w += bw;
        old[0] += p.light[0] * bw;
        old[1] += p.light[1] * bw;
        for (o, m) in old_m.iter_mut().zip(p.m) {
            *o += m * bw;
        }
        old_len += p.length * bw;
        old_w2 += p.weights2 * bw;
    }
    if sum_w < 1e-3 {
        return (current, state(current, now, 1.0, 1.0));
    }
    let inv = 1.0 / sum_w;
    let n_new = (old_len * inv + 1.0).min(MAX_LENGTH);
    let alpha = (1.0 / n_new).max(MIN_ALPHA);
    // With `converge`: a still pixel takes one more frame into a mean of `1 / weights2`
    // frames, if that is slower than the paper's blend (without, `weights2` is not read).
    let (alpha, weights2) = if converge {
        let w2 = (old_w2 * inv).max(MIN_WEIGHTS2);
        let alpha = if converges(f, i, converge) {
            alpha.min(1.0 / (1.0 / w2 + 1.0))
        } else {
            alpha
        };
        (alpha, (1.0 - alpha) * (1.0 - alpha) * w2 + alpha * alpha)
    } else {
        (alpha, 1.0)
    };
    let light = [
        old[0] * inv * (1.0 - alpha) + current[0] * alpha,
        old[1] * inv * (1.0 - alpha) + current[1] * alpha,
    ];
    let m = std::array::from_fn(|k| old_m[k] * inv * (1.0 - alpha) + now[k] * alpha);
    (light, state(light, m, n_new, weights2))
}

/// With `converge`, the pixel has not moved since the previous frame (its motion vector is 0).
fn converges(f: &SvgfFrame, i: usize, converge: bool) -> bool {
    converge && f.motion[i] == Vec2::ZERO
}

/// The pixel's new history `s` keeps its integrated light rather than the first a-trous
/// pass's: with `converge`, where it is still and took a previous frame's history (the sum
/// of its squared weights then below 1; a new history, as on a path's first frame, is the
/// paper's, so a moving camera's frames are the paper's bit for bit).
fn keeps_integrated(f: &SvgfFrame, weights2: f32, i: usize, converge: bool) -> bool {
    converges(f, i, converge) && weights2 < 1.0
}

/// What the luminance test's variance at pixel `i` (whose history is `s`) is multiplied by:
/// with `converge`, where the pixel is still, the square of the ratio of its history's sum of
/// squared weights to the paper's (at most 1); else 1. The test's width, `sigma_l` (4)
/// standard deviations of one frame's light, is 12 standard errors of the paper's history
/// (whose sum of squared weights is 1/9); for a plain mean of `n >= 9` frames it becomes `36 /
/// sqrt(n)` standard errors of that mean, so the filter fades as the frames accumulate and the
/// image converges to their mean. (With the ratio itself, the test a constant 12 standard
/// errors, the still views of `experiments/001-still.toml` converged a little more slowly.)
fn narrowing(f: &SvgfFrame, weights2: f32, i: usize, converge: bool) -> f32 {
    if converges(f, i, converge) {
        let k = (weights2 * (1.0 / PAPER_WEIGHTS2)).min(1.0);
        k * k
    } else {
        1.0
    }
}

/// [`integrate`] in lanes, [`F32xN::N`] pixels of row `y` at a time: the integrated light, its
/// variance and luminance into `row`, the pixels' states into `next` (the row's planes of the
/// history; their light left for the first a-trous pass); whether some pixel's history is
/// [`short`]. The same arithmetic in the same order, so the same numbers; the previous frame's
/// taps are read as [`Fetch`] says (loads where the group's lanes take consecutive pixels of
/// one row; two loads permuted where they lie within `2N` pixels of one row, as most of a
/// rotating camera's do; else gathers of the lanes that pass the tests), and a tap no lane
/// takes (a still camera's three others) is skipped. (No closures here: see
/// `simd::exp2_neg_in_range`.)
struct Temporal<'a, 'f> {
    f: &'a SvgfFrame<'f>,
    previous: &'a History,
    split: bool,
    normal_width: f32,
    converge: bool,
    y: usize,
    row: LightRow<'a>,
    next: &'a mut [f32],
}

impl Temporal<'_, '_> {
    /// Field `k` of the previous frame's history at pixels `(qx, qy)` in the lanes where `m`,
    /// 0 in the others, read as `fetch` says.
    #[inline(always)]
    fn field<V: F32xN>(&self, k: usize, qx: V, qy: V, fetch: Fetch<V>, m: V::Mask) -> V {
        let (planes, w) = (self.previous.planes(), self.f.width);
        // SAFETY: the lanes where `m` are pixels of the previous frame (`qx` in `0..w`, `qy`
        // in `0..h`, whole numbers): their field `k` is within the planes, whose `FIELDS`
        // floats a pixel fit an `i32` (the image has under 2^24 pixels).
        unsafe { fetch.read(planes, k * w, qx, qy, FIELDS * w, m) }
    }
}

impl Groups for Temporal<'_, '_> {
    fn width(&self) -> usize {
        self.f.width
    }

    /// The group of pixels from `x0` on; whether one's history is [`short`].
    #[inline(always)]
    fn group<V: F32xN>(&mut self, x0: usize) -> bool {
        let f = self.f;
        let (w, h) = (f.width, f.height);
        let i0 = self.y * w + x0;
        let n = V::N.min(w - x0);
        let splat = V::splat;
        let (zero, one) = (splat(0.0), splat(1.0));
        let lane = iota::<V>();
        let valid = splat(n as f32).gt(lane);
        let albedo: [V; 3] = channels(f.albedo, i0, n);
        let direct: [V; 3] = channels(f.direct, i0, n);
        let indirect: [V; 3] = channels(f.indirect, i0, n);
        let normal: [V; 3] = channels(f.normal, i0, n);
        let [depth] = channels(f.depth, i0, n);
        let [mx, my] = channels(f.motion, i0, n);
        // Not passed through (`passes_through`).
        let live = V::and(valid, live_lanes(f, i0, n, depth));

        let mut cur = [[zero; 3]; 2];
        for k in 0..3 {
            let a = demodulator_lanes(albedo[k]);
            if self.split {
                cur[0][k] = direct[k] / a;
                cur[1][k] = indirect[k] / a;
            } else {
                cur[0][k] = (direct[k] + indirect[k]) / a;
            }
        }
        let mut finite = valid;
        for c in cur.iter().flatten() {
            finite = V::and(finite, simd::finite(*c));
        }
        // As `integrate`: no light and no moments from a sample that is not finite.
        for c in cur.iter_mut().flatten() {
            *c = V::select(finite, *c, zero);
        }
        let lum = [luminance_lanes(cur[0]), luminance_lanes(cur[1])];
        let now = [lum[0], lum[0] * lum[0], lum[1], lum[1] * lum[1]];

        // Reverse reprojection: bilinear taps of the previous frame around p + motion.
        let px = (splat(x0 as f32) + lane + splat(0.5)) + mx - splat(0.5);
        let py = splat(self.y as f32 + 0.5) + my - splat(0.5);
        let (fx0, fy0) = (px.floor(), py.floor());
        let (fx, fy) = (px - fx0, py - fy0);
        let reprojects = V::and(live, finite);
        let signals = if self.split { 2 } else { 1 };
        // The normal test's largest squared distance (with `normal_width`).
        let reach = if self.normal_width > 0.0 {
            let width = normal_width_lanes(f, x0, self.y, normal, valid);
            let reach = splat(self.normal_width) * (width + splat(NORMAL_WIDTH_FLOOR));
            reach * reach
        } else {
            zero
        };
        let mut sum_w = zero;
        let mut old = [[zero; 3]; 2];
        let mut old_m = [zero; 4];
        let mut old_len = zero;
        let mut old_w2 = zero;
        for (dx, dy) in [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)] {
            let bx = if dx == 0.0 { one - fx } else { fx };
            let by = if dy == 0.0 { one - fy } else { fy };
            let bw = bx * by;
            let (qx, qy) = (fx0 + splat(dx), fy0 + splat(dy));
            let inside = V::and(
                V::and(
                    V::and(qx.ge(zero), qy.ge(zero)),
                    V::and(splat(w as f32).gt(qx), splat(h as f32).gt(qy)),
                ),
                V::and(bw.gt(zero), reprojects),
            );
            if !V::any(inside) {
                continue;
            }
            let run = Fetch::new(
                qx,
                qy,
                inside,
                FIELDS * w,
                (FIELDS - 1) * w,
                self.previous.planes().len(),
            );
            let (length, pdepth) = (
                self.field(LENGTH, qx, qy, run, inside),
                self.field(DEPTH, qx, qy, run, inside),
            );
            let pnormal = [
                self.field(NORMAL, qx, qy, run, inside),
                self.field(NORMAL + 1, qx, qy, run, inside),
                self.field(NORMAL + 2, qx, qy, run, inside),
            ];
            let normal_agrees = if self.normal_width > 0.0 {
                reach.ge(distance2(pnormal, normal))
            } else {
                let dot = pnormal[0] * normal[0] + pnormal[1] * normal[1] + pnormal[2] * normal[2];
                dot.ge(splat(NORMAL_COSINE))
            };
            let keep = V::and(
                V::and(V::and(inside, length.gt(zero)), simd::finite(pdepth)),
                V::and(
                    (splat(DEPTH_TOLERANCE) * depth).ge((pdepth - depth).abs()),
                    normal_agrees,
                ),
            );
            let bw = V::select(keep, bw, zero);
            sum_w = sum_w + bw;
            for (s, old) in old.iter_mut().take(signals).enumerate() {
                for (k, old) in old.iter_mut().enumerate() {
                    let l = self.field(LIGHT + 3 * s + k, qx, qy, run, keep);
                    *old = *old + l * bw;
                }
            }
            for (k, old) in old_m.iter_mut().take(2 * signals).enumerate() {
                *old = *old + self.field(MOMENTS + k, qx, qy, run, keep) * bw;
            }
            old_len = old_len + length * bw;
            if self.converge {
                old_w2 = old_w2 + self.field(WEIGHTS2, qx, qy, run, keep) * bw;
            }
        }
        let blends = V::and(reprojects, sum_w.ge(splat(1e-3)));
        let inv = one / sum_w;
        let n_new = old_len * inv + one;
        let n_new = V::select(n_new.gt(splat(MAX_LENGTH)), splat(MAX_LENGTH), n_new);
        let alpha = one / n_new;
        let alpha = V::select(alpha.ge(splat(MIN_ALPHA)), alpha, splat(MIN_ALPHA));
        // With `converge`, `integrate`'s mean where the pixel is still.
        let still = V::and(zero.ge(mx.abs()), zero.ge(my.abs()));
        let (alpha, weights2) = if self.converge {
            let w2 = (old_w2 * inv).at_least(splat(MIN_WEIGHTS2));
            let mean = one / (one / w2 + one);
            let alpha = V::select(V::and(still, alpha.gt(mean)), mean, alpha);
            let keep = one - alpha;
            let weights2 = keep * keep * w2 + alpha * alpha;
            (alpha, V::select(blends, weights2, one))
        } else {
            (alpha, one)
        };
        let mut light = [[zero; 3]; 2];
        for ((light, old), cur) in light.iter_mut().zip(&old).zip(&cur).take(signals) {
            for ((light, &old), &cur) in light.iter_mut().zip(old).zip(cur) {
                let blend = old * inv * (one - alpha) + cur * alpha;
                *light = V::select(blends, blend, cur);
            }
        }
        let mut m = [zero; 4];
        for ((m, &old), &now) in m.iter_mut().zip(&old_m).zip(&now) {
            *m = V::select(blends, old * inv * (one - alpha) + now * alpha, now);
        }
        let length = V::select(blends, n_new, V::select(reprojects, one, zero));

        // `narrowing`, with `converge` (computed once for both signals).
        let narrow = if self.converge {
            let k = min(weights2 * splat(1.0 / PAPER_WEIGHTS2), one);
            Some(V::select(still, k * k, one))
        } else {
            None
        };
        for (s, light) in light.iter().enumerate().take(signals) {
            for (k, &c) in light.iter().enumerate() {
                store_first(c, n, &mut self.row.light(s, k)[x0..]);
            }
            let l = m[2 * s];
            let var = flush_variance_lanes(m[2 * s + 1] - l * l);
            let var = match narrow {
                Some(k) => var * k,
                None => var,
            };
            store_first(var, n, &mut self.row.variance(s)[x0..]);
            store_first(luminance_lanes(*light), n, &mut self.row.luminance(s)[x0..]);
        }
        // The history's light where the pixel keeps its integrated light (`keeps_integrated`,
        // with `converge`); the rest is the first pass's (`Svgf::keep_planes_light`).
        if self.converge {
            let keeps = V::and(still, one.gt(weights2));
            for (s, light) in light.iter().enumerate().take(signals) {
                for (k, &c) in light.iter().enumerate() {
                    let kept = V::select(keeps, c, zero);
                    stream_first(kept, n, &mut self.next[(LIGHT + 3 * s + k) * w + x0..]);
                }
            }
        }
        let fields = [
            (MOMENTS, m[0]),
            (MOMENTS + 1, m[1]),
            (MOMENTS + 2, m[2]),
            (MOMENTS + 3, m[3]),
            (LENGTH, length),
            (DEPTH, depth),
            (NORMAL, normal[0]),
            (NORMAL + 1, normal[1]),
            (NORMAL + 2, normal[2]),
            (WEIGHTS2, weights2),
        ];
        for (k, value) in fields {
            stream_first(value, n, &mut self.next[k * w + x0..]);
        }
        V::any(V::and(live, splat(4.0).gt(length)))
    }
}

/// The features' planes of row `y` in lanes, [`F32xN::N`] pixels at a time: depth, |grad z|
/// ([`depth_gradient`]), whether the pixel passes through ([`passes_through`]), the normal (0
/// where it does). The same arithmetic, so the same numbers. (No closures here: see
/// `simd::exp2_neg_in_range`.)
struct Features<'a, 'f> {
    f: &'a SvgfFrame<'f>,
    y: usize,
    row: StaticRow<'a>,
}

impl Groups for Features<'_, '_> {
    fn width(&self) -> usize {
        self.f.width
    }

    #[inline(always)]
    fn group<V: F32xN>(&mut self, x0: usize) -> bool {
        let f = self.f;
        let (w, h, y) = (f.width, f.height, self.y);
        let n = V::N.min(w - x0);
        let splat = V::splat;
        let (zero, one) = (splat(0.0), splat(1.0));
        let lane = iota::<V>();
        let valid = splat(n as f32).gt(lane);
        let [[depth], [r], [l], [u], [d]] = neighbours::<V, f32, 1>(f.depth, w, h, x0, y, valid);
        let (dx, dy) = ((r - l) * splat(0.5), (u - d) * splat(0.5));
        let gz = max(dx.abs(), dy.abs());
        let gz = V::select(simd::finite(gz), gz, zero);
        let live = live_lanes(f, y * w + x0, n, depth);
        let normal: [V; 3] = channels(f.normal, y * w + x0, n);
        store_first(depth, n, &mut self.row.depth()[x0..]);
        store_first(gz, n, &mut self.row.gradient()[x0..]);
        store_first(V::select(live, zero, one), n, &mut self.row.through()[x0..]);
        for (k, c) in normal.into_iter().enumerate() {
            store_first(V::select(live, c, zero), n, &mut self.row.normal(k)[x0..]);
        }
        false
    }
}

/// The output of row `y` in lanes, [`F32xN::N`] pixels at a time: the filtered light times
/// the albedo ([`remodulate`]), or this frame's light where the pixel passes through. The same
/// arithmetic, so the same numbers. (No closures here: see `simd::exp2_neg_in_range`.)
struct Output<'a, 'f> {
    f: &'a SvgfFrame<'f>,
    y: usize,
    view: LightView<'a>,
    out: &'a mut [Vec3],
}

impl Groups for Output<'_, '_> {
    fn width(&self) -> usize {
        self.f.width
    }

    #[inline(always)]
    fn group<V: F32xN>(&mut self, x0: usize) -> bool {
        let f = self.f;
        let i0 = self.y * f.width + x0;
        let n = V::N.min(f.width - x0);
        let splat = V::splat;
        let valid = splat(n as f32).gt(iota::<V>());
        let index = splat(i0 as f32) + iota::<V>();
        let mut light = [splat(0.0); 3];
        for (k, light) in light.iter_mut().enumerate() {
            *light = load_first(&self.view.light(0, k)[x0..]);
            if self.view.signals == 2 {
                *light = *light + load_first(&self.view.light(1, k)[x0..]);
            }
        }
        let through = load_first::<V>(&self.view.through()[x0..]).ne(splat(0.0));
        let albedo: [V; 3] = channels(f.albedo, i0, n);
        let mut out = [splat(0.0); 3];
        for ((out, &light), &albedo) in out.iter_mut().zip(&light).zip(&albedo) {
            *out = light * demodulator_lanes(albedo);
        }
        let through = V::and(through, valid);
        if V::any(through) {
            // SAFETY: the lanes where `through` (and `valid`) index this row's pixels.
            let (direct, indirect) = unsafe {
                (
                    gather3(f.direct, index, through),
                    gather3(f.indirect, index, through),
                )
            };
            for ((out, &d), &i) in out.iter_mut().zip(&direct).zip(&indirect) {
                *out = V::select(through, d + i, *out);
            }
        }
        let (r, g, b) = (out[0].to_array(), out[1].to_array(), out[2].to_array());
        for (j, o) in self.out[x0..x0 + n].iter_mut().enumerate() {
            *o = Vec3::new(r[j], g[j], b[j]);
        }
        false
    }
}

/// Whether the `n` pixels from `i0` on (whose depths are `depth`) do not pass through
/// ([`passes_through`]), in lanes (the lanes past `n`: as their depths say).
#[inline(always)]
fn live_lanes<V: F32xN>(f: &SvgfFrame, i0: usize, n: usize, depth: V) -> V::Mask {
    let mut emitter = [0.0f32; LANES];
    for (e, &b) in emitter.iter_mut().zip(&f.emitter[i0..i0 + n]) {
        *e = if b { 1.0 } else { 0.0 };
    }
    // SAFETY: `emitter` has `LANES` lanes.
    let emitter = unsafe { V::load(emitter.as_ptr()) };
    V::and(simd::finite(depth), V::splat(0.5).gt(emitter))
}

/// The luminance variances of row `y`'s pixels whose history is short, from the moments of
/// their 7x7 neighbourhoods ([`spatial_variance`]) in lanes, [`F32xN::N`] pixels at a time,
/// into the first `signals` of `out` (the row's variance planes); the other pixels' left as
/// they are. A group whose window would leave the row (its first three or last three pixels)
/// is worked out pixel by pixel. The depth, normal and the pixels that pass through are the
/// a-trous passes' feature planes (loads; the frame's buffers took a de-interleaving of the
/// normal and a byte at a time of the emitters a tap). The same weights, with
/// [`crate::simd::exp_neg_in_range`]'s exponential and fused multiply-adds: the same numbers to
/// rounding. (No closures here: see `simd::exp2_neg_in_range`.)
struct SpatialVariance<'a, 'f> {
    f: &'a SvgfFrame<'f>,
    next: &'a History,
    /// The frame's depth, normal and the pixels that pass through, as planes.
    features: StaticsView<'a>,
    y: usize,
    out: [&'a mut [f32]; 2],
    signals: usize,
}

impl Groups for SpatialVariance<'_, '_> {
    fn width(&self) -> usize {
        self.f.width
    }

    #[inline(always)]
    fn group<V: F32xN>(&mut self, x0: usize) -> bool {
        let (f, next, y) = (self.f, self.next, self.y);
        let (w, h) = (f.width, f.height);
        let n = V::N.min(w - x0);
        if x0 < 3 || x0 + V::N + 3 > w {
            for x in x0..x0 + n {
                let i = y * w + x;
                if short(f, next, i) {
                    let v = spatial_variance(f, next, i);
                    for (out, v) in self.out.iter_mut().zip(v).take(self.signals) {
                        out[x] = v;
                    }
                }
            }
            return false;
        }
        let splat = V::splat;
        let (zero, one) = (splat(0.0), splat(1.0));
        // The features' planes (what `live_lanes` and the frame's buffers give, as loads; a
        // normal where the pixel passes through is 0 there, and such a neighbour is left out).
        let st = self.features;
        let depth = load_first::<V>(&st.depth(y)[x0..]);
        let length = load_first::<V>(&next.row_field(y, LENGTH)[x0..]);
        let live = one.gt(load_first::<V>(&st.through(y)[x0..]));
        let is_short = V::and(live, splat(4.0).gt(length));
        if !V::any(is_short) {
            return false;
        }
        let normal: [V; 3] = [
            load_first(&st.normal(y, 0)[x0..]),
            load_first(&st.normal(y, 1)[x0..]),
            load_first(&st.normal(y, 2)[x0..]),
        ];
        // The depth test's `-1 / (0.05 z + 1e-6)`.
        let minus_inv = splat(-1.0) / (depth.mul_add(splat(0.05), splat(1e-6)));
        let floor = splat(-30.0);
        let mut sum_w = zero;
        let mut acc = [zero; 4];
        for qy in y.saturating_sub(3)..(y + 4).min(h) {
            let moments: [&[f32]; 4] = [
                next.row_field(qy, MOMENTS),
                next.row_field(qy, MOMENTS + 1),
                next.row_field(qy, MOMENTS + 2),
                next.row_field(qy, MOMENTS + 3),
            ];
            let (zs, through) = (st.depth(qy), st.through(qy));
            let ns = [st.normal(qy, 0), st.normal(qy, 1), st.normal(qy, 2)];
            for qx in x0 - 3..=x0 + 3 {
                let zq = load_first::<V>(&zs[qx..]);
                let nq: [V; 3] = [
                    load_first(&ns[0][qx..]),
                    load_first(&ns[1][qx..]),
                    load_first(&ns[2][qx..]),
                ];
                let live = one.gt(load_first::<V>(&through[qx..]));
                let ez = (zq - depth).abs() * minus_inv;
                let cos = nq[0].mul_add(normal[0], nq[1].mul_add(normal[1], nq[2] * normal[2]));
                let wn = normal_weight_lanes(cos);
                let used = V::and(live, V::and(wn.gt(zero), ez.ge(floor)));
                let wq = V::select(used, exp_neg_in_range(ez.at_least(floor)) * wn, zero);
                sum_w = sum_w + wq;
                for (a, m) in acc.iter_mut().zip(moments) {
                    let m = V::select(used, load_first::<V>(&m[qx..]), zero);
                    *a = m.mul_add(wq, *a);
                }
            }
        }
        let inv = splat(1.0) / max(sum_w, splat(1e-12));
        let mean = [acc[0] * inv, acc[1] * inv, acc[2] * inv, acc[3] * inv];
        // Few frames: the spatial estimate, raised as the paper does.
        let boost = splat(4.0) / min(length + splat(1.0), splat(4.0));
        let variance = [
            flush_variance_lanes(mean[1] - mean[0] * mean[0]) * boost,
            flush_variance_lanes(mean[3] - mean[2] * mean[2]) * boost,
        ];
        for (out, v) in self.out.iter_mut().zip(variance).take(self.signals) {
            let old = load_first::<V>(&out[x0..]);
            store_first(V::select(is_short, v, old), n, &mut out[x0..]);
        }
        false
    }
}

/// Pixel `i`'s history is under 4 frames: its variance comes from its neighbourhood.
fn short(f: &SvgfFrame, state: &History, i: usize) -> bool {
    state.field(i, LENGTH) < 4.0 && !passes_through(f, i)
}

/// Pixel `i`'s luminance variance of each signal from the moments of its 7x7 neighbourhood
/// (weighted by depth and normal), for a short history.
fn spatial_variance(f: &SvgfFrame, state: &History, i: usize) -> [f32; 2] {
    let (w, h) = (f.width as i64, f.height as i64);
    let (x, y) = ((i as i64) % w, (i as i64) / w);
    let mut sum_w = 0.0;
    let mut acc = [0.0f32; 4];
    for qy in (y - 3).max(0)..(y + 4).min(h) {
        // The row's moments' planes (found once a row: a pixel's, by its index, cost four
        // divisions a tap).
        let moments: [&[f32]; 4] =
            std::array::from_fn(|k| state.row_field(qy as usize, MOMENTS + k));
        for qx in (x - 3).max(0)..(x + 4).min(w) {
            let q = (qy * w + qx) as usize;
            if passes_through(f, q) {
                continue;
            }
            let ez = -(f.depth[q] - f.depth[i]).abs() / (f.depth[i] * 0.05 + 1e-6);
            let wn = normal_weight(f.normal[q].dot(f.normal[i]));
            if wn <= 0.0 || ez < -30.0 {
                continue;
            }
            let wq = ez.exp() * wn;
            sum_w += wq;
            for (a, m) in acc.iter_mut().zip(moments) {
                *a += m[qx as usize] * wq;
            }
        }
    }
    let mean = acc.map(|x| x / sum_w.max(1e-12));
    // Few frames: the spatial estimate, raised as the paper does.
    let boost = 4.0 / (state.field(i, LENGTH) + 1.0).min(4.0);
    variance(mean).map(|v| v * boost)
}

/// Pixel `i`'s |grad z| from central differences (for the depth test); 0 where not finite.
fn depth_gradient(f: &SvgfFrame, i: usize) -> f32 {
    let (w, h) = (f.width, f.height);
    let (x, y) = (i % w, i / w);
    let d = |x: usize, y: usize| f.depth[y * w + x];
    let dx = (d((x + 1).min(w - 1), y) - d(x.saturating_sub(1), y)) * 0.5;
    let dy = (d(x, (y + 1).min(h - 1)) - d(x, y.saturating_sub(1))) * 0.5;
    let gz = dx.abs().max(dy.abs());
    if gz.is_finite() {
        gz
    } else {
        0.0
    }
}

/// Pixel `i`'s normal width for the reprojection's normal test: `sqrt(min(|n - n_l|^2, |n -
/// n_r|^2) + min(|n - n_u|^2, |n - n_d|^2))` over its four neighbours (the image's border
/// clamped; 0 where not finite). The smaller of each axis's one-sided differences: a pixel
/// on the edge between two flat surfaces has a neighbour on its own surface along both axes
/// and a width of 0 (its history is tested as tightly as a flat surface's), where the
/// normals change from pixel to pixel (foliage) the width is theirs. (The authors'
/// implementation takes `|(|dn/dx| + |dn/dy|)|` from the raster's derivatives, which is wide
/// on every edge: along a faster orbit of the Cornell box it took history across the walls'
/// corners.)
fn normal_width(f: &SvgfFrame, i: usize) -> f32 {
    let (w, h) = (f.width, f.height);
    let (x, y) = (i % w, i / w);
    let c = f.normal[i];
    let d = |x: usize, y: usize| (f.normal[y * w + x] - c).length_squared();
    let dx = d((x + 1).min(w - 1), y).min(d(x.saturating_sub(1), y));
    let dy = d(x, (y + 1).min(h - 1)).min(d(x, y.saturating_sub(1)));
    let width = (dx + dy).sqrt();
    if width.is_finite() {
        width
    } else {
        0.0
    }
}

/// [`normal_width`] of the pixels of row `y` from `x0` on, whose normals are `normal`, in
/// lanes (the lanes where `valid`).
#[inline(always)]
fn normal_width_lanes<V: F32xN>(
    f: &SvgfFrame,
    x0: usize,
    y: usize,
    normal: [V; 3],
    valid: V::Mask,
) -> V {
    let [_, right, left, up, down] = neighbours(f.normal, f.width, f.height, x0, y, valid);
    let (r, l, u, d) = (
        distance2(right, normal),
        distance2(left, normal),
        distance2(up, normal),
        distance2(down, normal),
    );
    let width = (min(r, l) + min(u, d)).sqrt();
    V::select(simd::finite(width), width, V::splat(0.0))
}

/// The indices of the pixels of row `y` of a `w x h` image from `x0` on and of their
/// neighbours, in lanes: `[centre, right, left, up, down]` (`up` the next row, `down` the
/// previous one), the neighbours clamped to the image: the lanes whose column is in the image
/// index its pixels.
#[inline(always)]
fn cross<V: F32xN>(w: usize, h: usize, x0: usize, y: usize) -> [V; 5] {
    let splat = V::splat;
    let (zero, one) = (splat(0.0), splat(1.0));
    let x = splat(x0 as f32) + iota::<V>();
    let last = splat((w - 1) as f32);
    let right = V::select(x.ge(last), last, x + one);
    let left = V::select(one.gt(x), zero, x - one);
    let at = splat((y * w) as f32);
    let up = splat(((y + 1).min(h - 1) * w) as f32);
    let down = splat((y.saturating_sub(1) * w) as f32);
    [at + x, at + right, at + left, up + x, down + x]
}

/// The entries of `buffer` (a `w x h` image) at the pixels of row `y` from `x0` on and at
/// their neighbours, in the lanes where `valid` (the pixels in the image) and 0 in the
/// others: `[centre, right, left, up, down]`, as [`cross`] (the neighbours clamped to the
/// image). Loads and shuffles ([`channels`]) but for the neighbours beside a group at the
/// image's left or right edge, which are gathered.
#[inline(always)]
fn neighbours<V: F32xN, T: Floats<K>, const K: usize>(
    buffer: &[T],
    w: usize,
    h: usize,
    x0: usize,
    y: usize,
    valid: V::Mask,
) -> [[V; K]; 5] {
    let n = V::N.min(w - x0);
    let i0 = y * w + x0;
    let (up, down) = ((y + 1).min(h - 1) * w + x0, y.saturating_sub(1) * w + x0);
    let [_, right_index, left_index, _, _] = cross::<V>(w, h, x0, y);
    let base = buffer.as_ptr().cast::<f32>();
    // SAFETY (the gathers): the lanes where `valid` index pixels of the image (`cross`), `K`
    // floats each (`Floats`).
    let gathered = |index: V| -> [V; K] {
        std::array::from_fn(|c| unsafe { V::gather(base.add(c), index, K as i32, valid) })
    };
    [
        channels(buffer, i0, n),
        if x0 + V::N < w {
            channels(buffer, i0 + 1, V::N)
        } else {
            gathered(right_index)
        },
        if x0 > 0 && n == V::N {
            channels(buffer, i0 - 1, V::N)
        } else {
            gathered(left_index)
        },
        channels(buffer, up, n),
        channels(buffer, down, n),
    ]
}

/// `|a - b|^2` in lanes.
#[inline(always)]
fn distance2<V: F32xN>(a: [V; 3], b: [V; 3]) -> V {
    let d = [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
}

/// The number of signals the passes filter.
fn signals(split: bool) -> usize {
    if split {
        2
    } else {
        1
    }
}

/// The sky and light sources: passed through, nobody's neighbour.
fn passes_through(f: &SvgfFrame, i: usize) -> bool {
    !f.depth[i].is_finite() || f.emitter[i]
}
