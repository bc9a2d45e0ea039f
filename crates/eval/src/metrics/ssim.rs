//! Structural similarity (SSIM, Wang et al. 2004) as scikit-image computes it with
//! `gaussian_weights=True, sigma=1.5, use_sample_covariance=False, data_range=1`.
//!
//! Per channel of the clamped sRGB encodings x (image) and y (reference): local means,
//! variances and covariance under a normalised Gaussian window (σ = 1.5, truncated at 3.5σ:
//! radius 5, 11x11, applied separably with mirrored borders, scipy.ndimage's `reflect`
//! mode `dcba|abcd|dcba`), then
//! `S = (2 μx μy + C1)(2 σxy + C2) / ((μx² + μy² + C1)(σx² + σy² + C2))` with
//! C1 = (0.01)², C2 = (0.03)². The SSIM of a channel is the mean of S over the pixels at
//! least 5 (the window radius) from every border; the image's SSIM is the mean over the
//! three channels.

use rayon::prelude::*;

use super::{srgb, Pair};

const SIGMA: f64 = 1.5;
/// Window radius: `int(truncate * sigma + 0.5)` with scikit-image's truncate = 3.5.
const RADIUS: usize = 5;
const TAPS: usize = 2 * RADIUS + 1;
const C1: f64 = 0.01 * 0.01;
const C2: f64 = 0.03 * 0.03;

/// The SSIM map of an image pair, averaged over the three channels.
pub(super) struct SsimMap {
    width: usize,
    height: usize,
    ssim: Vec<f64>,
}

impl SsimMap {
    pub(super) fn new(pair: &Pair) -> Self {
        let (width, height) = (pair.width, pair.height);
        let x: Vec<[f64; 3]> = pair.image.par_iter().map(|&p| srgb(p)).collect();
        let y: Vec<[f64; 3]> = pair.reference.par_iter().map(|&p| srgb(p)).collect();
        let blur = Blur::new(width, height);
        let mut ssim = vec![0.0; width * height];
        for c in 0..3 {
            let plane = |f: &(dyn Fn(f64, f64) -> f64 + Sync)| -> Vec<f64> {
                let values: Vec<f64> = x.par_iter().zip(&y).map(|(a, b)| f(a[c], b[c])).collect();
                blur.apply(&values)
            };
            let ux = plane(&|a, _| a);
            let uy = plane(&|_, b| b);
            let uxx = plane(&|a, _| a * a);
            let uyy = plane(&|_, b| b * b);
            let uxy = plane(&|a, b| a * b);
            ssim.par_iter_mut().enumerate().for_each(|(i, s)| {
                let (mx, my) = (ux[i], uy[i]);
                let vx = uxx[i] - mx * mx;
                let vy = uyy[i] - my * my;
                let vxy = uxy[i] - mx * my;
                let numerator = (2.0 * mx * my + C1) * (2.0 * vxy + C2);
                let denominator = (mx * mx + my * my + C1) * (vx + vy + C2);
                *s += numerator / denominator / 3.0;
            });
        }
        Self {
            width,
            height,
            ssim,
        }
    }

    /// The mean SSIM over the pixels at least [`RADIUS`] from every border, as
    /// scikit-image crops. scikit-image refuses images smaller than the 11-pixel window; for
    /// those the crop along a short axis shrinks so that at least one row or column is left.
    pub(super) fn mean_ssim(&self) -> f64 {
        let pad_x = RADIUS.min((self.width - 1) / 2);
        let pad_y = RADIUS.min((self.height - 1) / 2);
        let (x0, x1) = (pad_x, self.width - pad_x);
        let rows: Vec<f64> = self
            .ssim
            .par_chunks(self.width)
            .skip(pad_y)
            .take(self.height - 2 * pad_y)
            .map(|row| row[x0..x1].iter().sum())
            .collect();
        rows.iter().sum::<f64>() / (rows.len() * (x1 - x0)) as f64
    }

    /// `1 - SSIM` for every pixel, borders included.
    pub(super) fn one_minus_ssim(&self) -> Vec<f64> {
        self.ssim.iter().map(|s| 1.0 - s).collect()
    }
}

/// Separable Gaussian filter with mirrored borders (scipy.ndimage `reflect`).
struct Blur {
    width: usize,
    height: usize,
    kernel: [f64; TAPS],
}

impl Blur {
    fn new(width: usize, height: usize) -> Self {
        // scipy.ndimage._gaussian_kernel1d: exp(-x² / 2σ²), normalised to sum 1.
        let mut kernel: [f64; TAPS] = std::array::from_fn(|i| {
            let x = i as f64 - RADIUS as f64;
            (-0.5 / (SIGMA * SIGMA) * x * x).exp()
        });
        let sum: f64 = kernel.iter().sum();
        kernel.iter_mut().for_each(|k| *k /= sum);
        Self {
            width,
            height,
            kernel,
        }
    }

    /// Filters along columns, then along rows (scipy's axis order).
    fn apply(&self, plane: &[f64]) -> Vec<f64> {
        let (w, h) = (self.width, self.height);
        let mut vertical = vec![0.0; w * h];
        vertical.par_chunks_mut(w).enumerate().for_each(|(y, out)| {
            for (j, &k) in self.kernel.iter().enumerate() {
                let src = reflect(y as isize + j as isize - RADIUS as isize, h);
                let row = &plane[src * w..(src + 1) * w];
                out.iter_mut().zip(row).for_each(|(o, &v)| *o += k * v);
            }
        });
        let mut result = vec![0.0; w * h];
        result
            .par_chunks_mut(w)
            .zip(vertical.par_chunks(w))
            .for_each(|(out, row)| {
                let padded: Vec<f64> = (0..w + 2 * RADIUS)
                    .map(|i| row[reflect(i as isize - RADIUS as isize, w)])
                    .collect();
                for (x, o) in out.iter_mut().enumerate() {
                    *o = self
                        .kernel
                        .iter()
                        .zip(&padded[x..x + TAPS])
                        .map(|(k, v)| k * v)
                        .sum();
                }
            });
        result
    }
}

/// scipy.ndimage's `reflect` boundary (half-sample symmetric, `dcba|abcd|dcba`), repeated
/// as often as needed for lines shorter than the window.
fn reflect(i: isize, n: usize) -> usize {
    let period = 2 * n as isize;
    let m = i.rem_euclid(period) as usize;
    if m < n {
        m
    } else {
        2 * n - 1 - m
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reflect_mirrors_half_sample() {
        let n = 4;
        let got: Vec<usize> = (-5..9).map(|i| reflect(i, n)).collect();
        assert_eq!(got, [3, 3, 2, 1, 0, 0, 1, 2, 3, 3, 2, 1, 0, 0]);
        assert_eq!(reflect(-3, 1), 0);
    }

    #[test]
    fn kernel_is_normalised_and_symmetric() {
        let k = Blur::new(1, 1).kernel;
        assert!((k.iter().sum::<f64>() - 1.0).abs() < 1e-15);
        for i in 0..TAPS {
            assert_eq!(k[i], k[TAPS - 1 - i]);
        }
        // scipy.ndimage._gaussian_kernel1d(1.5, 0, 5)[5] (centre tap).
        assert!(
            (k[RADIUS] - 0.266_011_724_861_794_4).abs() < 1e-12,
            "{}",
            k[RADIUS]
        );
    }

    #[test]
    fn blur_keeps_constants() {
        let blur = Blur::new(7, 3);
        let out = blur.apply(&[0.25; 21]);
        assert!(out.iter().all(|v| (v - 0.25).abs() < 1e-15));
    }
}
