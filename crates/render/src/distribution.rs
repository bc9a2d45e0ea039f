//! Piecewise-constant 2D distributions over `[0,1]^2` (environment map importance sampling).
//!
//! Sampling inverts CDFs: the marginal CDF over rows picks a row and a continuous offset in it,
//! then that row's conditional CDF picks a column and an offset. The map from [0,1)^2 to the
//! point is monotone in each coordinate and continuous inside every cell, so stratified and
//! low-discrepancy inputs stay well spread.
//!
//! The density is defined by the stored (f32) CDFs themselves: a cell's density is
//! `(cdf[x+1] - cdf[x]) * width * (marginal[y+1] - marginal[y]) * height`. This is the weight's
//! share to f32 precision, and it is exactly the frequency with which sampling lands in the
//! cell, so a cell rounded away to nothing has density 0 rather than a density it never gets
//! sampled with. Exactly-zero weights give exactly-zero density.

use glam::Vec2;

use crate::alias::ONE_MINUS_EPSILON;

/// A density over `[0,1]^2`, constant on each cell of a `width` x `height` grid and proportional
/// to the cell weights (row-major, row 0 at v = 0).
#[derive(Debug, Clone)]
pub struct Distribution2D {
    width: usize,
    height: usize,
    /// `height` rows of `width + 1` entries: each row's CDF over its columns, from 0 to 1.
    conditional: Vec<f32>,
    /// `height + 1` entries: the CDF over rows, from 0 to 1.
    marginal: Vec<f32>,
    /// Guide tables (see [`build_guide`]): one per row, then the marginal's.
    conditional_guide: Vec<u32>,
    marginal_guide: Vec<u32>,
}

/// Normalised running sums of `weights` into `cdf` (`weights.len() + 1` entries, from 0 to
/// exactly 1); returns the total (0: `cdf` is left uniform).
fn build_cdf(weights: impl Iterator<Item = f64> + Clone, cdf: &mut [f32]) -> f64 {
    let total: f64 = weights.clone().sum();
    let n = cdf.len() - 1;
    cdf[0] = 0.0;
    if total > 0.0 {
        let mut running = 0.0;
        for (c, w) in cdf[1..].iter_mut().zip(weights) {
            running += w;
            *c = (running / total) as f32;
        }
    } else {
        for (i, c) in cdf.iter_mut().enumerate().skip(1) {
            *c = i as f32 / n as f32;
        }
    }
    // The same summation order: exactly `total / total`, but say it.
    cdf[n] = 1.0;
    total
}

/// Cells of a CDF per entry of its guide table.
const GUIDE_STRIDE: usize = 4;

/// The guide table of `cdf` (n + 1 entries): for each of `ceil(n / GUIDE_STRIDE)` equal
/// buckets of [0, 1), the cell where inversion of the bucket's lower end lands (Chen and Asau's
/// cutpoint method). Inversion then starts there and scans a few cells instead of a binary
/// search over the whole CDF, which for an environment map is a chain of cache misses.
fn build_guide(cdf: &[f32], guide: &mut [u32]) {
    let n = cdf.len() - 1;
    let k = guide.len();
    for (b, g) in guide.iter_mut().enumerate() {
        let t = b as f32 / k as f32;
        *g = cdf[1..n].partition_point(|&c| c <= t) as u32;
    }
}

fn guide_len(n: usize) -> usize {
    n.div_ceil(GUIDE_STRIDE).max(1)
}

/// Inverts `cdf` (n + 1 entries from 0 to 1) at `u`: the cell i with cdf[i] <= u < cdf[i+1]
/// (never one of zero probability), its probability and the offset in [0, 1) within it.
/// `guide` is `cdf`'s guide table: the result is exactly that of a binary search.
#[inline]
fn invert(cdf: &[f32], guide: &[u32], u: f32) -> (usize, f32, f32) {
    let n = cdf.len() - 1;
    let u = if u.is_nan() {
        0.0
    } else {
        u.clamp(0.0, ONE_MINUS_EPSILON)
    };
    // The number of entries of cdf[1..n] that are <= u, found from the bucket's start (which
    // rounding may have put one cell too far either way).
    let bucket = ((u * guide.len() as f32) as usize).min(guide.len() - 1);
    let mut i = guide[bucket] as usize;
    while i > 0 && cdf[i] > u {
        i -= 1;
    }
    while i < n - 1 && cdf[i + 1] <= u {
        i += 1;
    }
    let (lo, hi) = (cdf[i], cdf[i + 1]);
    let p = hi - lo;
    let offset = ((u - lo) / p).clamp(0.0, ONE_MINUS_EPSILON);
    (i, p, offset)
}

/// The coordinate `(cell + offset) / n`, kept inside the cell as `cell_of` computes it and
/// below 1.
#[inline]
fn place(cell: usize, offset: f32, n: usize) -> f32 {
    let nf = n as f32;
    let mut x = ((cell as f32 + offset) / nf).min(ONE_MINUS_EPSILON);
    while x > 0.0 && cell_of(x, n) > cell {
        x = x.next_down();
    }
    while cell_of(x, n) < cell {
        x = x.next_up();
    }
    x
}

/// The cell of coordinate `x` on a grid of `n` cells over [0, 1]: the same rounding as
/// `Environment::radiance`'s nearest-texel lookup.
#[inline]
fn cell_of(x: f32, n: usize) -> usize {
    ((x * n as f32) as usize).min(n - 1)
}

impl Distribution2D {
    /// `None` when no weight is positive. Negative and non-finite weights count as 0.
    ///
    /// # Panics
    /// If `weights.len() != width * height`.
    pub fn new(weights: &[f32], width: usize, height: usize) -> Option<Self> {
        assert_eq!(weights.len(), width * height, "{width}x{height} weights");
        if width == 0 || height == 0 {
            return None;
        }
        let clean = |w: &f32| {
            if w.is_finite() && *w > 0.0 {
                *w as f64
            } else {
                0.0
            }
        };
        let mut conditional = vec![0.0f32; height * (width + 1)];
        let mut row_totals = Vec::with_capacity(height);
        for (row, cdf) in weights
            .chunks_exact(width)
            .zip(conditional.chunks_exact_mut(width + 1))
        {
            row_totals.push(build_cdf(row.iter().map(clean), cdf));
        }
        let mut marginal = vec![0.0f32; height + 1];
        let total = build_cdf(row_totals.iter().copied(), &mut marginal);
        if !(total > 0.0 && total.is_finite()) {
            return None;
        }
        let row_guide = guide_len(width);
        let mut conditional_guide = vec![0u32; height * row_guide];
        for (cdf, guide) in conditional
            .chunks_exact(width + 1)
            .zip(conditional_guide.chunks_exact_mut(row_guide))
        {
            build_guide(cdf, guide);
        }
        let mut marginal_guide = vec![0u32; guide_len(height)];
        build_guide(&marginal, &mut marginal_guide);
        Some(Self {
            width,
            height,
            conditional,
            marginal,
            conditional_guide,
            marginal_guide,
        })
    }

    pub fn width(&self) -> usize {
        self.width
    }

    pub fn height(&self) -> usize {
        self.height
    }

    /// Heap bytes.
    pub fn bytes(&self) -> usize {
        4 * (self.conditional.len()
            + self.marginal.len()
            + self.conditional_guide.len()
            + self.marginal_guide.len())
    }

    #[inline]
    fn row(&self, y: usize) -> &[f32] {
        &self.conditional[y * (self.width + 1)..(y + 1) * (self.width + 1)]
    }

    /// A point and its density with respect to area on `[0,1]^2`. The point lies in the cell whose
    /// density is returned (as [`pdf`](Self::pdf) finds cells), and that density is positive.
    /// Inputs outside [0, 1) are clamped into it.
    #[inline]
    pub fn sample(&self, u: Vec2) -> (Vec2, f32) {
        let ((x, y), offset, probability) = self.sample_cell(u);
        let p = Vec2::new(
            place(x, offset.x, self.width),
            place(y, offset.y, self.height),
        );
        (p, probability * (self.width * self.height) as f32)
    }

    /// A cell (column, row), the offset in [0, 1)^2 within it at which the inversion landed,
    /// and the probability of the cell (positive): what [`sample`](Self::sample) places as a
    /// point. Inputs outside [0, 1) are clamped into it.
    #[inline]
    pub fn sample_cell(&self, u: Vec2) -> ((usize, usize), Vec2, f32) {
        let (y, py, oy) = invert(&self.marginal, &self.marginal_guide, u.y);
        let g = guide_len(self.width);
        let (x, px, ox) = invert(
            self.row(y),
            &self.conditional_guide[y * g..(y + 1) * g],
            u.x,
        );
        ((x, y), Vec2::new(ox, oy), px * py)
    }

    /// The probability of cell (`x`, `y`): its density over the number of cells.
    #[inline]
    pub fn cell_probability(&self, x: usize, y: usize) -> f32 {
        let row = self.row(y);
        (row[x + 1] - row[x]) * (self.marginal[y + 1] - self.marginal[y])
    }

    /// The density at `p` with respect to area on `[0,1]^2` (points outside are clamped onto the
    /// square's cells).
    #[inline]
    pub fn pdf(&self, p: Vec2) -> f32 {
        let x = cell_of(p.x.max(0.0), self.width);
        let y = cell_of(p.y.max(0.0), self.height);
        let row = self.row(y);
        (row[x + 1] - row[x])
            * (self.marginal[y + 1] - self.marginal[y])
            * (self.width * self.height) as f32
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::alias::{chi2, chi2_critical};
    use pathlight_core::rng::Rng;

    /// The guide table finds exactly the cell a binary search finds, zero cells included.
    #[test]
    fn guided_inversion_equals_binary_search() {
        let mut rng = Rng::new(11, 3);
        for n in [1usize, 2, 3, 7, 64, 1000] {
            let weights = random_weights(n, 1, n as u64);
            let mut cdf = vec![0.0f32; n + 1];
            build_cdf(weights.iter().map(|&w| w as f64), &mut cdf);
            let mut guide = vec![0u32; guide_len(n)];
            build_guide(&cdf, &mut guide);
            let mut us: Vec<f32> = (0..5000).map(|_| rng.next_f32()).collect();
            us.extend(cdf.iter().copied());
            us.extend(cdf.iter().map(|c| c.next_down().max(0.0)));
            us.extend([0.0, ONE_MINUS_EPSILON, 1.0, f32::NAN]);
            for u in us {
                let got = invert(&cdf, &guide, u);
                let uc = if u.is_nan() {
                    0.0
                } else {
                    u.clamp(0.0, ONE_MINUS_EPSILON)
                };
                let want = cdf[1..n].partition_point(|&c| c <= uc);
                assert_eq!(got.0, want, "n {n} u {u}");
            }
        }
    }

    fn random_weights(w: usize, h: usize, seed: u64) -> Vec<f32> {
        let mut rng = Rng::new(seed, 9);
        (0..w * h)
            .map(|i| {
                let x = rng.next_f32();
                if i % 7 == 3 {
                    0.0
                } else {
                    x * x * 10.0
                }
            })
            .collect()
    }

    #[test]
    fn density_is_proportional_to_weights_and_integrates_to_one() {
        let (w, h) = (7, 5);
        let weights = random_weights(w, h, 1);
        let d = Distribution2D::new(&weights, w, h).unwrap();
        let mean = weights.iter().sum::<f32>() / (w * h) as f32;
        // Midpoint quadrature, 10 x 10 points per cell.
        let n = 10;
        let mut integral = 0.0f64;
        for j in 0..h * n {
            for i in 0..w * n {
                let p = Vec2::new(
                    (i as f32 + 0.5) / (w * n) as f32,
                    (j as f32 + 0.5) / (h * n) as f32,
                );
                let pdf = d.pdf(p);
                let cell = weights[(j / n) * w + i / n];
                assert!((pdf - cell / mean).abs() <= 1e-5 * (cell / mean).max(1.0));
                integral += pdf as f64;
            }
        }
        integral /= (w * h * n * n) as f64;
        assert!((integral - 1.0).abs() < 1e-5, "{integral}");
    }

    #[test]
    fn histogram_matches_density_and_pdf_matches_sample() {
        let (w, h) = (9, 6);
        let weights = random_weights(w, h, 2);
        let d = Distribution2D::new(&weights, w, h).unwrap();
        let mut rng = Rng::new(5, 1);
        let samples = 200_000;
        let mut counts = vec![0u64; w * h];
        for _ in 0..samples {
            let (p, pdf) = d.sample(Vec2::new(rng.next_f32(), rng.next_f32()));
            assert!(p.x >= 0.0 && p.x < 1.0 && p.y >= 0.0 && p.y < 1.0, "{p}");
            assert!(pdf > 0.0);
            assert_eq!(d.pdf(p), pdf, "{p}");
            counts[cell_of(p.y, h) * w + cell_of(p.x, w)] += 1;
        }
        let expected: Vec<f64> = (0..w * h)
            .map(|c| {
                let p = Vec2::new(
                    ((c % w) as f32 + 0.5) / w as f32,
                    ((c / w) as f32 + 0.5) / h as f32,
                );
                d.pdf(p) as f64 / (w * h) as f64 * samples as f64
            })
            .collect();
        let (stat, dof) = chi2(&counts, &expected);
        assert!(stat < chi2_critical(dof, 3.09), "chi2 {stat} dof {dof}");
    }

    #[test]
    fn sampling_inverts_the_cdf_continuously() {
        // One row [1, 3]: the CDF is 0, 1/4, 1.
        let d = Distribution2D::new(&[1.0, 3.0], 2, 1).unwrap();
        let x = |u: f32| d.sample(Vec2::new(u, 0.5)).0.x;
        assert_eq!(x(0.0), 0.0);
        assert!((x(0.125) - 0.25).abs() < 1e-6);
        assert!((x(0.25) - 0.5).abs() < 1e-6);
        assert!((x(0.625) - 0.75).abs() < 1e-6);
        assert_eq!(d.sample(Vec2::new(0.1, 0.5)).1, 0.5);
        assert_eq!(d.sample(Vec2::new(0.9, 0.5)).1, 1.5);
        // Monotone in v, and within [0, 1) even at the ends.
        let d = Distribution2D::new(&random_weights(13, 4, 3), 13, 4).unwrap();
        let mut last = Vec2::splat(-1.0);
        for k in 0..=4096 {
            let u = k as f32 / 4096.0;
            let p = d.sample(Vec2::new(u, u)).0;
            assert!(p.x < 1.0 && p.y < 1.0);
            assert!(p.y >= last.y, "{u}");
            last = p;
        }
        for u in [f32::NAN, -1.0, 2.0, ONE_MINUS_EPSILON] {
            let (p, pdf) = d.sample(Vec2::splat(u));
            assert!(pdf > 0.0 && d.pdf(p) == pdf, "{u}");
        }
    }

    #[test]
    fn within_a_row_x_is_monotone() {
        let d = Distribution2D::new(&random_weights(31, 3, 4), 31, 3).unwrap();
        let mut last = -1.0;
        for k in 0..10_000 {
            let p = d.sample(Vec2::new(k as f32 / 10_000.0, 0.4)).0;
            assert!(p.x >= last);
            last = p.x;
        }
    }

    #[test]
    fn nothing_positive_gives_none() {
        assert!(Distribution2D::new(&[0.0; 6], 3, 2).is_none());
        assert!(Distribution2D::new(&[f32::NAN, -1.0], 2, 1).is_none());
        assert!(Distribution2D::new(&[], 0, 0).is_none());
        // A single positive cell takes everything.
        let d = Distribution2D::new(&[0.0, 0.0, 0.0, 4.0, 0.0, 0.0], 3, 2).unwrap();
        let mut rng = Rng::new(1, 1);
        for _ in 0..1000 {
            let (p, pdf) = d.sample(Vec2::new(rng.next_f32(), rng.next_f32()));
            assert_eq!(pdf, 6.0);
            assert!(p.x >= 0.0 && p.x < 1.0 / 3.0 && p.y >= 0.5, "{p}");
        }
        assert_eq!(d.pdf(Vec2::new(0.5, 0.2)), 0.0);
    }
}
