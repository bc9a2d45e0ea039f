//! The data-driven filter's blend of each pixel's filtered light with its own by their
//! estimated errors (`sure`, not in the thesis).
//!
//! A filter that averages a pixel with neighbours whose light differs by less than their noise
//! trades the pixel's variance for a bias, and past some number of samples the bias is the
//! larger: the filtered image's error then falls more slowly than the unfiltered one's, and
//! a true highlight that looks like a firefly at a few samples lends its light to the dark
//! pixels around it. Stein's unbiased risk estimate (SURE) measures both from the image: for
//! a pixel's light `y` with noise variance `s^2` and a filter `f = sum(w_q y_q) / W`, whose
//! weights are taken as fixed,
//!
//! ```text
//! SURE(f) = (f - y)^2 - s^2 + 2 s^2 df/dy = (f - y)^2 - s^2 + 2 s^2 w_p / W
//! SURE(y) = s^2
//! ```
//!
//! are unbiased estimates of the two squared errors (`w_p` is the centre's own weight: 1 in
//! the data-driven filter, whose window always holds it). A single pixel's estimates are
//! noise, so each is averaged over the valid pixels of the pixel's `(2r + 1)^2` neighbourhood
//! (as Li, Wu and Chuang do with theirs, "SURE-based Optimization for Adaptive Sampling and
//! Reconstruction", SIGGRAPH Asia 2012, who choose among filter scales by them), and the
//! pixel's light is `f + b (y - f)` with `b = E_f / (E_f + E_y)`, the two estimates'
//! inverse-error weights.
//! `E_f` is the neighbourhood's mean of SURE(f) less its standard error there (at least 0):
//! at a few samples the estimates' own noise would otherwise hand back a share of the
//! pixel's noise where the filter is right (measured: the refractive box's CIELUV MSE at 8 spp
//! 0.10x the unfiltered image's with the plain mean, 0.09x with the margin, 0.08x without the
//! blend; BENCHMARKS.md, "Seed 001"). Each signal (the direct and the indirect light,
//! demodulated) is blended apart, on its luminance (the errors the filter has are the
//! luminance's).
//!
//! Choices, written down:
//! - The weights' own dependence on `y` (the colour test) is left out of the derivative, as
//!   it is in a fixed-weight filter's; with it the estimate would need three more sums per
//!   tap.
//! - The estimates are averaged with equal weights over the neighbourhood's valid pixels (the
//!   sky and bad pixels count for nothing), rows then columns. Averaged relative to each
//!   pixel's noise instead (up to 10x the error on the interior at 8 spp), or used to choose
//!   one light or the other (as Li et al. choose a scale), the blend was worse from 1 to 32
//!   spp on most scenes.

use glam::Vec3;
use pathlight_core::color::luminance;
use rayon::prelude::*;

/// A pixel's two signals as the window left them: the filtered light (demodulated) and the
/// squared errors' estimates, direct and indirect (its own light is the filter's input).
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Risk {
    pub filtered: [Vec3; 2],
    /// SURE of the filtered light of each signal, then of its own light of each.
    pub estimates: [f32; 4],
    /// The pixel passes through (the sky, a bad pixel): it is nobody's neighbour and keeps its
    /// light.
    pub passes: bool,
}

impl Risk {
    /// The risks of a filtered pixel: `filtered` from sums of weight `weight` (the centre's
    /// own `centre`), its own light `own` of noise variance `variance`, each signal apart.
    /// The squared errors are the luminance's, or with the colour test's channel weights
    /// (`channels`, [`crate::config::ColourWeights::Albedo`]) the mean over the channels of
    /// each one's squared error times its weight, the measure of `variance` then.
    pub fn new(
        filtered: [Vec3; 2],
        own: [Vec3; 2],
        weight: [f32; 2],
        variance: [f32; 2],
        centre: f32,
        channels: Option<Vec3>,
    ) -> Self {
        let mut estimates = [0.0; 4];
        for s in 0..2 {
            let d = filtered[s] - own[s];
            let d2 = match channels {
                None => luminance(d) * luminance(d),
                Some(w) => (w * d * d).element_sum() / 3.0,
            };
            let v = variance[s];
            estimates[s] = d2 - v + 2.0 * v * centre / weight[s];
            estimates[2 + s] = v;
        }
        Self {
            filtered,
            estimates,
            passes: false,
        }
    }

    /// A pixel that passes through.
    pub fn none() -> Self {
        Self {
            passes: true,
            ..Default::default()
        }
    }

    /// The pixel counts in its neighbours' means: it does not pass through, and its estimates
    /// are numbers (a light so large that its square overflows counts for nothing).
    fn counts(&self) -> bool {
        !self.passes && self.estimates.iter().all(|e| e.is_finite())
    }

    /// The blended light (demodulated) of a pixel whose own light is `own` from the
    /// neighbourhood's mean estimates `mean`, and each signal's share of its own light in it.
    fn blend(&self, own: [Vec3; 2], mean: [f32; 4]) -> (Vec3, [f32; 2]) {
        let share = std::array::from_fn(|s| {
            let (f, y) = (mean[s].max(0.0), mean[2 + s]);
            let b = f / (f + y);
            // 0 where both are 0 (or not numbers): the filtered light.
            if b.is_nan() {
                0.0
            } else {
                b
            }
        });
        let light = (0..2)
            .map(|s| self.filtered[s] + share[s] * (own[s] - self.filtered[s]))
            .sum();
        (light, share)
    }
}

/// Per pixel, what its neighbourhood sums: the four estimates, the squares of the two
/// filtered ones, and 1 (the count); zeros for a pixel that does not count
/// ([`Risk::counts`]).
const TERMS: usize = 7;
const COUNT: usize = 6;

/// The blend's scratch: the terms in rows padded with `radius` pixels of zeros on either side,
/// and their sums along the rows.
#[derive(Default)]
pub(crate) struct Scratch {
    terms: Vec<f32>,
    rows: Vec<f32>,
}

/// `acc += add`, element by element.
#[inline(always)]
fn add(acc: &mut [f32], add: &[f32]) {
    for (a, b) in acc.iter_mut().zip(add) {
        *a += b;
    }
}

/// Blends every valid pixel of a `width`-wide image of `risks` (sky and bad pixels pass
/// through: left alone in `out`) by the mean estimates over its `(2 radius + 1)^2`
/// neighbourhood, with its own light `own(i)` (demodulated): `out[i]` becomes `finish(i,
/// light)` of its blended light, and `shares[i]` each signal's share of its own light (NaN for
/// the others). The sums run over whole rows of terms (rows, then columns), in the same order
/// whatever the thread count.
#[allow(clippy::too_many_arguments)]
pub(crate) fn blend(
    risks: &[Risk],
    width: usize,
    radius: usize,
    scratch: &mut Scratch,
    out: &mut [Vec3],
    shares: &mut Vec<[f32; 2]>,
    own: impl Fn(usize) -> [Vec3; 2] + Sync,
    finish: impl Fn(usize, Vec3) -> Vec3 + Sync,
) {
    shares.clear();
    shares.resize(risks.len(), [f32::NAN; 2]);
    if width == 0 {
        return;
    }
    let height = risks.len() / width;
    let (pitch, row) = ((width + 2 * radius) * TERMS, width * TERMS);
    let Scratch { terms, rows } = scratch;
    terms.resize(pitch * height, 0.0);
    terms
        .par_chunks_mut(pitch)
        .zip(risks.par_chunks(width))
        .for_each(|(terms, risks)| {
            let (pad, rest) = terms.split_at_mut(radius * TERMS);
            pad.fill(0.0);
            let (body, pad) = rest.split_at_mut(row);
            pad.fill(0.0);
            for (t, r) in body.chunks_exact_mut(TERMS).zip(risks) {
                let e = r.estimates;
                *<&mut [f32; TERMS]>::try_from(t).expect("a pixel's terms") = if r.counts() {
                    [e[0], e[1], e[2], e[3], e[0] * e[0], e[1] * e[1], 1.0]
                } else {
                    [0.0; TERMS]
                };
            }
        });
    // Each pixel's sums over its row's neighbours.
    rows.resize(row * height, 0.0);
    rows.par_chunks_mut(row)
        .zip(terms.par_chunks(pitch))
        .for_each(|(sums, terms)| {
            sums.copy_from_slice(&terms[..row]);
            for dx in 1..=2 * radius {
                add(sums, &terms[dx * TERMS..dx * TERMS + row]);
            }
        });
    let rows = &rows[..];
    // Each row's sums over its columns, in a buffer of each worker's.
    out.par_chunks_mut(width)
        .zip(shares.par_chunks_mut(width))
        .enumerate()
        .for_each_init(Vec::new, |sums, (y, (out, shares))| {
            let (y0, y1) = (y.saturating_sub(radius), (y + radius + 1).min(height));
            sums.clear();
            sums.extend_from_slice(&rows[y0 * row..(y0 + 1) * row]);
            for r in y0 + 1..y1 {
                add(sums, &rows[r * row..(r + 1) * row]);
            }
            let risks = &risks[y * width..(y + 1) * width];
            for (x, ((o, share), s)) in out
                .iter_mut()
                .zip(shares)
                .zip(sums.chunks_exact(TERMS))
                .enumerate()
            {
                let r = &risks[x];
                if r.passes {
                    continue;
                }
                // Where no pixel of the neighbourhood counts (n = 0), the means are not
                // numbers, and the pixel keeps its filtered light (`Risk::blend`).
                let n = s[COUNT];
                let mut mean: [f32; 4] = std::array::from_fn(|k| s[k] / n);
                // The filtered light's estimates less their standard error over the
                // neighbourhood: the pixel's own light comes back only where the filter's
                // error stands out of the estimates' noise.
                for k in 0..2 {
                    let var = ((s[4 + k] - s[k] * mean[k]) / (n - 1.0).max(1.0)).max(0.0);
                    mean[k] -= (var / n).sqrt();
                }
                let i = y * width + x;
                let light;
                (light, *share) = r.blend(own(i), mean);
                *o = finish(i, light);
            }
        });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_filter_that_moves_a_pixel_within_its_noise_is_kept_and_one_far_outside_is_not() {
        // A pixel's own light 0.5 of noise variance 0.01, filtered to `f` by a window of
        // weight 100.
        let moved = |f: f32| {
            Risk::new(
                [Vec3::splat(f), Vec3::ZERO],
                [Vec3::splat(0.5), Vec3::ZERO],
                [100.0, 1.0],
                [0.01, 0.0],
                1.0,
                None,
            )
        };
        // Moved by one standard error: SURE(f) = 0.01 - 0.01 + 0.0002, far below SURE(y) =
        // 0.01.
        let near = moved(0.6);
        let own = [Vec3::splat(0.5), Vec3::ZERO];
        let (light, _) = near.blend(own, near.estimates);
        assert!((light.x - 0.6).abs() < 0.005, "{light}");
        // Moved by ten standard errors: SURE(f) = 1 - 0.01 + 0.0002, 99 times SURE(y).
        let far = moved(1.5);
        let (light, share) = far.blend(own, far.estimates);
        assert!((share[0] - 0.99).abs() < 0.001, "{share:?}");
        assert!((light.x - 0.51).abs() < 0.001, "{light}");
        // With the colour test's channel weights, the squared error is the channels' mean of
        // the weighted squares: moved by 1 in red alone, weighed 6 (then 1 and 0.5):
        // 6 / 3 - 0.01 + 0.0002.
        let red = Risk::new(
            [Vec3::new(1.5, 0.5, 0.5), Vec3::ZERO],
            [Vec3::splat(0.5), Vec3::ZERO],
            [100.0, 1.0],
            [0.01, 0.0],
            1.0,
            Some(Vec3::new(6.0, 1.0, 0.5)),
        );
        assert!(
            (red.estimates[0] - 1.9902).abs() < 1e-5,
            "{:?}",
            red.estimates
        );
    }

    #[test]
    fn the_estimates_are_averaged_over_the_valid_neighbours() {
        // A row of four pixels: three whose filter moved them by 1, 1.2 and 0.8 (their own
        // light 0, noise variance 0.1, the window's weight 10), then sky.
        let moved = |f: f32| {
            Risk::new(
                [Vec3::splat(f), Vec3::ZERO],
                [Vec3::ZERO, Vec3::ZERO],
                [10.0, 10.0],
                [0.1, 0.1],
                1.0,
                None,
            )
        };
        let risks = [moved(1.0), moved(1.2), moved(0.8), Risk::none()];
        let sky = Vec3::splat(7.0);
        // The blend of a row of `risks` whose own light is 0, over a sky of 7.
        let run = |risks: &[Risk], radius: usize| {
            let mut out = vec![sky; risks.len()];
            let mut shares = Vec::new();
            let own = |_| [Vec3::ZERO; 2];
            let n = risks.len();
            let mut scratch = Scratch::default();
            blend(
                risks,
                n,
                radius,
                &mut scratch,
                &mut out,
                &mut shares,
                own,
                |_, l| l,
            );
            (out, shares)
        };
        let (out, shares) = run(&risks, 1);
        assert_eq!(out[3], sky, "the sky is left alone");
        assert!(shares[3][0].is_nan());
        // The second pixel's direct light: the mean of the three SURE(f) = d^2 - 0.1 + 2 0.1
        // / 10, less its standard error over them, against SURE(y) = 0.1.
        let e: Vec<f64> = [1.0f64, 1.2, 0.8].iter().map(|d| d * d - 0.08).collect();
        let mean = e.iter().sum::<f64>() / 3.0;
        let var = e.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / 2.0;
        let f = mean - (var / 3.0).sqrt();
        let b = f / (f + 0.1);
        assert!(
            (shares[1][0] as f64 - b).abs() < 1e-5,
            "{:?} {b}",
            shares[1]
        );
        let expect = 1.2 * (1.0 - b);
        assert!((out[1].x as f64 - expect).abs() < 1e-5, "{}", out[1]);
        // The indirect light was not moved: its estimates are under their noise, and the
        // filtered light stays.
        assert_eq!(shares[1][1], 0.0);
        // A pixel whose estimates are not numbers counts for nothing and keeps its filtered
        // light; so does one without any neighbour that counts.
        let mut huge = moved(1.0);
        huge.estimates[0] = f32::INFINITY;
        let (out, shares) = run(&[huge, moved(1.2)], 0);
        assert_eq!(out[0], Vec3::new(1.0, 1.0, 1.0), "{}", out[0]);
        assert_eq!(shares[0], [0.0, 0.0]);
    }
}
