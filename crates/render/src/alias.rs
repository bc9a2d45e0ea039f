//! Walker / Vose alias tables: O(1) sampling of a discrete distribution.
//!
//! The table is built with Vose's algorithm (O(n), numerically stable) in f64, so the implied
//! probabilities match the weights to f32 precision even with millions of entries. Sampling
//! takes one uniform number: its integer part (after scaling by `n`) picks the column, its
//! fractional part is the biased coin between the column's own entry and its alias.
//!
//! Resolution: a `u` in [0, 1) carries 24 bits (f32), so entries whose probability is below
//! ~2^-24 are sampled with a frequency correct only to about 2^-24 in absolute terms (as with
//! any sampling from one f32 uniform, CDF inversion included).

/// One column of the table: keep the column's own index when the coin is below `threshold`,
/// otherwise take `alias`.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Bin {
    threshold: f32,
    alias: u32,
}

/// A discrete distribution over `0..len` proportional to the weights it was built from.
#[derive(Debug, Clone)]
pub struct AliasTable {
    pmf: Vec<f32>,
    bins: Vec<Bin>,
}

/// The largest f32 below 1.
pub(crate) const ONE_MINUS_EPSILON: f32 = 1.0 - f32::EPSILON / 2.0;

impl AliasTable {
    /// `None` when no weight is positive. Negative and non-finite weights count as 0.
    ///
    /// # Panics
    /// With `u32::MAX` or more weights.
    pub fn new(weights: &[f32]) -> Option<Self> {
        let n = weights.len();
        assert!(n < u32::MAX as usize, "alias table of {n} entries");
        let clean = |w: f32| {
            if w.is_finite() && w > 0.0 {
                w as f64
            } else {
                0.0
            }
        };
        let sum: f64 = weights.iter().map(|&w| clean(w)).sum();
        if sum <= 0.0 {
            return None;
        }
        let pmf: Vec<f32> = weights.iter().map(|&w| (clean(w) / sum) as f32).collect();

        // Vose: scaled probabilities n * p; columns under 1 ("small") are topped up by an alias
        // taken from a column over 1 ("large").
        let scale = n as f64 / sum;
        let mut scaled: Vec<f64> = weights.iter().map(|&w| clean(w) * scale).collect();
        let mut bins = vec![
            Bin {
                threshold: 1.0,
                alias: 0
            };
            n
        ];
        let mut small: Vec<u32> = Vec::with_capacity(n);
        let mut large: Vec<u32> = Vec::with_capacity(n);
        for (i, &s) in scaled.iter().enumerate() {
            if s < 1.0 {
                small.push(i as u32);
            } else {
                large.push(i as u32);
            }
        }
        while let (Some(&s), Some(&l)) = (small.last(), large.last()) {
            small.pop();
            large.pop();
            let (s, l) = (s as usize, l as usize);
            bins[s] = Bin {
                threshold: scaled[s] as f32,
                alias: l as u32,
            };
            // pbrt-v4's form: less cancellation than (scaled[l] + scaled[s]) - 1.
            scaled[l] -= 1.0 - scaled[s];
            if scaled[l] < 1.0 {
                small.push(l as u32);
            } else {
                large.push(l as u32);
            }
        }
        // What is left is 1 up to rounding: keep the column. A zero-weight entry left over (only
        // possible through rounding) must never be returned: it sends everything to the entry
        // of largest weight instead.
        let heaviest = pmf
            .iter()
            .enumerate()
            .fold(0, |best, (i, &p)| if p > pmf[best] { i } else { best });
        for i in large.into_iter().chain(small) {
            let i = i as usize;
            bins[i] = if pmf[i] > 0.0 {
                Bin {
                    threshold: 1.0,
                    alias: i as u32,
                }
            } else {
                Bin {
                    threshold: 0.0,
                    alias: heaviest as u32,
                }
            };
        }
        Some(Self { pmf, bins })
    }

    /// The index chosen by `u` in [0, 1) and its probability. Values outside [0, 1) (and NaN)
    /// are clamped into it.
    #[inline]
    pub fn sample(&self, u: f32) -> (usize, f32) {
        let n = self.bins.len();
        let x = u * n as f32;
        // `as` saturates: negative and NaN give 0.
        let column = (x as usize).min(n - 1);
        let coin = (x - column as f32).clamp(0.0, ONE_MINUS_EPSILON);
        let bin = self.bins[column];
        // NaN coins (u NaN) fail the comparison and take the alias, which has positive weight.
        let index = if coin < bin.threshold {
            column
        } else {
            bin.alias as usize
        };
        (index, self.pmf[index])
    }

    pub fn pmf(&self, index: usize) -> f32 {
        self.pmf[index]
    }

    pub fn len(&self) -> usize {
        self.pmf.len()
    }

    pub fn is_empty(&self) -> bool {
        self.pmf.is_empty()
    }
}

/// The (1 - alpha) quantile of the chi-square distribution with `dof` degrees of freedom, by the
/// Wilson-Hilferty approximation (good to a few percent from dof = 3 up); `z` is the standard
/// normal quantile (3.09 for alpha = 0.001).
#[cfg(test)]
pub(crate) fn chi2_critical(dof: usize, z: f64) -> f64 {
    let k = dof as f64;
    let a = 2.0 / (9.0 * k);
    k * (1.0 - a + z * a.sqrt()).powi(3)
}

/// Pearson's chi-square statistic of `counts` against `expected` counts, pooling bins whose
/// expected count is under 5 into one; returns (statistic, degrees of freedom). Panics if a bin
/// of expected count 0 was hit.
#[cfg(test)]
pub(crate) fn chi2(counts: &[u64], expected: &[f64]) -> (f64, usize) {
    let mut stat = 0.0;
    let mut bins = 0;
    let (mut pooled_c, mut pooled_e) = (0.0, 0.0);
    for (&c, &e) in counts.iter().zip(expected) {
        if e == 0.0 {
            assert_eq!(c, 0, "a bin of probability 0 was sampled");
            continue;
        }
        if e < 5.0 {
            pooled_c += c as f64;
            pooled_e += e;
            continue;
        }
        stat += (c as f64 - e).powi(2) / e;
        bins += 1;
    }
    if pooled_e > 0.0 {
        stat += (pooled_c - pooled_e).powi(2) / pooled_e;
        bins += 1;
    }
    (stat, bins.max(2) - 1)
}

#[cfg(test)]
mod tests {
    use super::*;
    use pathlight_core::rng::Rng;

    /// The probability of each index implied by the table itself (column share plus aliases).
    fn implied(t: &AliasTable) -> Vec<f64> {
        let n = t.bins.len() as f64;
        let mut p = vec![0.0; t.bins.len()];
        for (i, b) in t.bins.iter().enumerate() {
            p[i] += b.threshold as f64 / n;
            p[b.alias as usize] += (1.0 - b.threshold as f64) / n;
        }
        p
    }

    fn check_frequencies(weights: &[f32], samples: usize, seed: u64) {
        let t = AliasTable::new(weights).unwrap();
        let sum: f64 = weights.iter().map(|&w| w.max(0.0) as f64).sum();
        for (i, &w) in weights.iter().enumerate() {
            let p = w.max(0.0) as f64 / sum;
            assert!((t.pmf(i) as f64 - p).abs() <= 1e-6 * p.max(1e-30), "{i}");
        }
        let mut rng = Rng::new(seed, 3);
        let mut counts = vec![0u64; weights.len()];
        for _ in 0..samples {
            let (i, pmf) = t.sample(rng.next_f32());
            assert_eq!(pmf, t.pmf(i));
            counts[i] += 1;
        }
        let expected: Vec<f64> = (0..weights.len())
            .map(|i| t.pmf(i) as f64 * samples as f64)
            .collect();
        let (stat, dof) = chi2(&counts, &expected);
        assert!(
            stat < chi2_critical(dof, 3.09),
            "chi2 {stat} dof {dof} {counts:?}"
        );
    }

    #[test]
    fn frequencies_match_weights_with_zeros() {
        check_frequencies(&[1.0, 2.0, 0.0, 3.0, 4.0, 0.0, 10.0, 0.5], 200_000, 1);
        check_frequencies(&[0.0, 0.0, 5.0], 10_000, 2);
    }

    #[test]
    fn frequencies_match_random_weights() {
        let mut rng = Rng::new(7, 1);
        let w: Vec<f32> = (0..300).map(|_| rng.next_f32().powi(3)).collect();
        check_frequencies(&w, 300_000, 4);
    }

    #[test]
    fn one_huge_weight_among_tiny_ones() {
        let mut w = vec![1.0f32; 100];
        w[37] = 1e6;
        check_frequencies(&w, 100_000, 5);
        // Stratified u: the frequencies are exact up to one sample per column the entry uses.
        let t = AliasTable::new(&w).unwrap();
        let n = 1usize << 22;
        let mut counts = vec![0u64; w.len()];
        for k in 0..n {
            counts[t.sample((k as f32 + 0.5) / n as f32).0] += 1;
        }
        for (i, &c) in counts.iter().enumerate() {
            let e = t.pmf(i) as f64 * n as f64;
            let columns = 1 + t.bins.iter().filter(|b| b.alias as usize == i).count();
            assert!((c as f64 - e).abs() <= columns as f64, "{i}: {c} vs {e}");
        }
    }

    #[test]
    fn single_entry() {
        let t = AliasTable::new(&[3.5]).unwrap();
        assert_eq!(t.len(), 1);
        for u in [0.0, 0.3, ONE_MINUS_EPSILON, 1.0, -1.0, f32::NAN] {
            assert_eq!(t.sample(u), (0, 1.0));
        }
    }

    #[test]
    fn nothing_positive_gives_none() {
        assert!(AliasTable::new(&[]).is_none());
        assert!(AliasTable::new(&[0.0, 0.0]).is_none());
        assert!(AliasTable::new(&[f32::NAN, -1.0, f32::NEG_INFINITY]).is_none());
        // Non-finite and negative weights count as zero among positive ones.
        let t = AliasTable::new(&[f32::NAN, 2.0, f32::INFINITY, -3.0, 2.0]).unwrap();
        assert_eq!(
            (0..5).map(|i| t.pmf(i)).collect::<Vec<_>>(),
            [0.0, 0.5, 0.0, 0.0, 0.5]
        );
    }

    #[test]
    fn out_of_range_u_gives_valid_indices() {
        let t = AliasTable::new(&[0.0, 1.0, 0.0, 2.0, 0.0]).unwrap();
        for u in [
            0.0,
            1.0,
            1.5,
            -0.5,
            f32::NAN,
            f32::INFINITY,
            ONE_MINUS_EPSILON,
        ] {
            let (i, p) = t.sample(u);
            assert!(p > 0.0 && (i == 1 || i == 3), "{u}: {i}");
        }
    }

    #[test]
    fn million_entries_table_is_exact() {
        let mut rng = Rng::new(11, 2);
        let w: Vec<f32> = (0..1_000_000)
            .map(|i| {
                let x = rng.next_f32();
                match i % 10 {
                    0 => 0.0,
                    1 => x * 1e-6,
                    _ => x * x * 1e3,
                }
            })
            .collect();
        let t = AliasTable::new(&w).unwrap();
        let total: f64 = (0..t.len()).map(|i| t.pmf(i) as f64).sum();
        assert!((total - 1.0).abs() < 1e-5, "{total}");
        let p = implied(&t);
        for (i, &p) in p.iter().enumerate() {
            let e = t.pmf(i) as f64;
            if e == 0.0 {
                assert_eq!(p, 0.0, "{i}");
            } else {
                // f32 thresholds: relative error ~1e-7 of a column's 1/n share.
                assert!((p - e).abs() <= 1e-6 / t.len() as f64, "{i}: {p} vs {e}");
            }
        }
    }
}
