//! Statistics of a pixel's 3x3 neighbourhood for two signals (the data-driven filter's
//! single-sample standard errors and their blur): the count, sum and sum of squares of the
//! finite values, in lanes ([`crate::simd`]) over two planes with a border of NaN, so that a
//! neighbourhood cut by the image's border and one with pixels that count for nothing (NaN: the
//! sky, bad pixels) are the same case. The sums run row by row, left to right, as a pixel's
//! loop over its neighbours would.

use rayon::prelude::*;

use crate::simd::{dispatch, finite, ByGroups, F32xN, Groups, Isa, LANES};

/// What a neighbourhood's sums become.
#[derive(Clone, Copy, PartialEq, Eq)]
pub enum Statistic {
    /// The root of the values' sample variance (n - 1; 0 under two values).
    Deviation,
    /// The root of the values' mean (0 without values).
    RootMean,
}

/// Two signals' values in padded planes.
#[derive(Default)]
pub struct Neighbourhoods {
    planes: Vec<f32>,
    width: usize,
}

impl Neighbourhoods {
    /// Floats per padded row of one plane: a border pixel on either side, and the lanes of a
    /// group that reach past the row's last pixel.
    fn pitch(&self) -> usize {
        self.width + 2 + LANES
    }

    /// Index of pixel (x, y) of signal `k` (x and y from -1, the border).
    fn at(&self, x: isize, y: isize, k: usize) -> usize {
        let pitch = self.pitch();
        ((y + 1) as usize * 2 + k) * pitch + (x + 1) as usize
    }

    /// Lays out a `width x height` image's values: `value(i)` of pixel `i` (NaN: not counted).
    pub fn fill(&mut self, width: usize, height: usize, value: impl Fn(usize) -> [f32; 2] + Sync) {
        self.width = width;
        let row = 2 * self.pitch();
        // Every float is written: the border NaN, the image's pixels their values.
        self.planes.resize(row * (height + 2), f32::NAN);
        let pitch = self.pitch();
        self.planes
            .par_chunks_mut(row)
            .enumerate()
            .for_each(|(py, planes)| {
                planes.fill(f32::NAN);
                if (1..=height).contains(&py) {
                    let y = py - 1;
                    for x in 0..width {
                        let v = value(y * width + x);
                        planes[1 + x] = v[0];
                        planes[pitch + 1 + x] = v[1];
                    }
                }
            });
    }

    /// Each pixel's `statistic` of both signals into `out` (one entry per pixel), but where
    /// `skip(i)` says a signal's is not wanted (left alone there).
    pub fn compute(
        &self,
        statistic: Statistic,
        isa: Isa,
        out: &mut [[f32; 2]],
        skip: impl Fn(usize, usize) -> bool + Sync,
    ) {
        let w = self.width;
        out.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
            dispatch(
                isa,
                ByGroups(Row {
                    n: self,
                    y,
                    statistic,
                    row,
                    skip: &skip,
                }),
            );
        });
    }
}

/// One row of [`Neighbourhoods::compute`].
struct Row<'a, F> {
    n: &'a Neighbourhoods,
    y: usize,
    statistic: Statistic,
    row: &'a mut [[f32; 2]],
    skip: &'a F,
}

impl<F: Fn(usize, usize) -> bool> Groups for Row<'_, F> {
    fn width(&self) -> usize {
        self.n.width
    }

    #[inline(always)]
    fn group<V: F32xN>(&mut self, x0: usize) -> bool {
        let n = V::N.min(self.n.width - x0);
        let (zero, one) = (V::splat(0.0), V::splat(1.0));
        for k in 0..2 {
            let (mut count, mut sum, mut sq) = (zero, zero, zero);
            for dy in -1..=1 {
                let at = self.n.at(x0 as isize - 1, self.y as isize + dy, k);
                for dx in 0..3 {
                    // SAFETY: a row of a plane has `width + 2 + LANES` floats, and the
                    // group's taps start at most at column `width + 1` of the padded row.
                    debug_assert!(at + dx + LANES <= self.n.planes.len());
                    let v: V = unsafe { V::load(self.n.planes.as_ptr().add(at + dx)) };
                    let m = finite(v);
                    count = count + V::select(m, one, zero);
                    sum = sum + V::select(m, v, zero);
                    sq = sq + V::select(m, v * v, zero);
                }
            }
            let value = match self.statistic {
                Statistic::Deviation => {
                    let variance = (sq - sum * sum / count) / (count - one);
                    let variance = V::select(variance.ge(zero), variance, zero);
                    V::select(count.gt(one), variance, zero).sqrt()
                }
                Statistic::RootMean => V::select(count.gt(zero), (sum / count).sqrt(), zero),
            }
            .to_array();
            let first = self.y * self.n.width + x0;
            for (j, out) in self.row[x0..x0 + n].iter_mut().enumerate() {
                if !(self.skip)(first + j, k) {
                    out[k] = value[j];
                }
            }
        }
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Both statistics, on every kind of lanes, against a plain loop over each pixel's
    /// neighbours: on an image narrower and wider than a group, with NaN and infinite values
    /// (not counted) and the borders.
    #[test]
    fn the_lanes_agree_with_a_loop_over_the_neighbours() {
        for (w, h) in [(1, 1), (5, 3), (37, 6)] {
            let value = |i: usize| -> [f32; 2] {
                let v = ((i * 7919) % 101) as f32 * 0.37 - 4.0;
                match i % 11 {
                    3 => [f32::NAN, v],
                    7 => [v, f32::INFINITY],
                    _ => [v, 0.5 * v * v],
                }
            };
            let mut n = Neighbourhoods::default();
            n.fill(w, h, value);
            for statistic in [Statistic::Deviation, Statistic::RootMean] {
                for isa in [Isa::Portable, Isa::Avx2, Isa::Avx512] {
                    let mut out = vec![[-1.0f32; 2]; w * h];
                    // Pixel 4's second signal is not wanted: left alone.
                    n.compute(statistic, isa, &mut out, |i, k| i == 4 && k == 1);
                    for (i, got) in out.iter().enumerate() {
                        let (x, y) = ((i % w) as i64, (i / w) as i64);
                        for (k, got) in got.iter().enumerate() {
                            if i == 4 && k == 1 {
                                assert_eq!(*got, -1.0);
                                continue;
                            }
                            let (mut count, mut sum, mut sq) = (0.0f64, 0.0f64, 0.0f64);
                            for (qx, qy) in (y - 1..=y + 1)
                                .flat_map(|qy| (x - 1..=x + 1).map(move |qx| (qx, qy)))
                            {
                                if qx < 0 || qy < 0 || qx >= w as i64 || qy >= h as i64 {
                                    continue;
                                }
                                let v = value((qy * w as i64 + qx) as usize)[k] as f64;
                                if v.is_finite() {
                                    (count, sum, sq) = (count + 1.0, sum + v, sq + v * v);
                                }
                            }
                            let want = match statistic {
                                Statistic::Deviation if count > 1.0 => {
                                    ((sq - sum * sum / count) / (count - 1.0)).max(0.0).sqrt()
                                }
                                Statistic::RootMean if count > 0.0 => (sum / count).sqrt(),
                                _ => 0.0,
                            };
                            // (A negative mean's root is NaN, as `f32::sqrt` gives.)
                            assert!(
                                (*got as f64 - want).abs() <= 1e-4 * (1.0 + want)
                                    || (got.is_nan() && want.is_nan()),
                                "{w}x{h} pixel ({x}, {y}) signal {k}: {got} against {want}"
                            );
                        }
                    }
                }
            }
        }
    }
}
