//! Per-pixel running statistics of direct and indirect light (Welford; batches merged with
//! Chan et al.'s formula): the lighting pass's output for one frame, and the history that
//! accumulates frames while nothing changes.

use glam::Vec3;

/// Running mean and sum of squared deviations (M2) of an RGB quantity.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Moments {
    pub mean: Vec3,
    pub m2: Vec3,
}

impl Moments {
    /// Merges `b`, the moments of `nb` samples, into these moments of `na` samples.
    #[inline]
    fn merge(&mut self, na: u32, b: &Moments, nb: u32) {
        let n = na + nb;
        let w = nb as f32 / n as f32;
        let delta = b.mean - self.mean;
        self.mean += delta * w;
        self.m2 += b.m2 + delta * delta * (na as f32 * w);
    }
}

/// The statistics of one pixel's samples.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct PixelStats {
    /// Samples taken.
    pub n: u32,
    pub direct: Moments,
    pub indirect: Moments,
    /// M2 of the radiance (direct + indirect) of each sample; its mean is the sum of the two
    /// means.
    pub radiance_m2: Vec3,
}

impl PixelStats {
    /// The statistics of one sample.
    #[inline]
    pub fn one(direct: Vec3, indirect: Vec3) -> Self {
        PixelStats {
            n: 1,
            direct: Moments {
                mean: direct,
                m2: Vec3::ZERO,
            },
            indirect: Moments {
                mean: indirect,
                m2: Vec3::ZERO,
            },
            radiance_m2: Vec3::ZERO,
        }
    }

    /// Adds one sample.
    #[inline]
    pub fn add(&mut self, direct: Vec3, indirect: Vec3) {
        self.merge(&Self::one(direct, indirect));
    }

    /// Merges the statistics of another batch of samples of this pixel.
    #[inline]
    pub fn merge(&mut self, b: &PixelStats) {
        if b.n == 0 {
            return;
        }
        if self.n == 0 {
            // What the general formulas below give for finite values.
            *self = *b;
            return;
        }
        let na = self.n;
        let mut radiance = Moments {
            mean: self.mean(),
            m2: self.radiance_m2,
        };
        radiance.merge(
            na,
            &Moments {
                mean: b.mean(),
                m2: b.radiance_m2,
            },
            b.n,
        );
        self.radiance_m2 = radiance.m2;
        self.direct.merge(na, &b.direct, b.n);
        self.indirect.merge(na, &b.indirect, b.n);
        self.n = na + b.n;
    }

    /// Mean radiance.
    #[inline]
    pub fn mean(&self) -> Vec3 {
        self.direct.mean + self.indirect.mean
    }

    /// Sample variance of radiance per channel (n - 1 estimator; zero below two samples).
    /// Divide by `n` for the variance of the mean.
    pub fn variance(&self) -> Vec3 {
        variance(self.radiance_m2, self.n)
    }

    pub fn direct_variance(&self) -> Vec3 {
        variance(self.direct.m2, self.n)
    }

    pub fn indirect_variance(&self) -> Vec3 {
        variance(self.indirect.m2, self.n)
    }
}

fn variance(m2: Vec3, n: u32) -> Vec3 {
    if n < 2 {
        Vec3::ZERO
    } else {
        m2 / (n - 1) as f32
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two-pass mean and variance (n - 1) of a list.
    fn two_pass(v: &[Vec3]) -> (Vec3, Vec3) {
        let n = v.len() as f32;
        let mean = v.iter().copied().sum::<Vec3>() / n;
        let var = v.iter().map(|x| (*x - mean) * (*x - mean)).sum::<Vec3>() / (n - 1.0);
        (mean, var)
    }

    #[test]
    fn batches_merge_to_the_statistics_of_all_samples() {
        let d: Vec<Vec3> = (0..9)
            .map(|i| Vec3::new(i as f32, (i * i % 5) as f32, 0.5))
            .collect();
        let ind: Vec<Vec3> = (0..9)
            .map(|i| Vec3::new(1.0, (i % 3) as f32 * 2.0, i as f32 * 0.25))
            .collect();
        // One at a time, and as batches of 2, 3 and 4 merged.
        let mut single = PixelStats::default();
        for i in 0..9 {
            single.add(d[i], ind[i]);
        }
        let mut merged = PixelStats::default();
        for range in [0..2, 2..5, 5..9] {
            let mut b = PixelStats::default();
            for i in range {
                b.add(d[i], ind[i]);
            }
            merged.merge(&b);
        }
        let radiance: Vec<Vec3> = d.iter().zip(&ind).map(|(a, b)| *a + *b).collect();
        for s in [single, merged] {
            assert_eq!(s.n, 9);
            let (m, v) = two_pass(&d);
            assert!(s.direct.mean.abs_diff_eq(m, 1e-5));
            assert!(s.direct_variance().abs_diff_eq(v, 1e-4));
            let (m, v) = two_pass(&ind);
            assert!(s.indirect.mean.abs_diff_eq(m, 1e-5));
            assert!(s.indirect_variance().abs_diff_eq(v, 1e-4));
            let (m, v) = two_pass(&radiance);
            assert!(s.mean().abs_diff_eq(m, 1e-5));
            assert!(s.variance().abs_diff_eq(v, 1e-4), "{} {v}", s.variance());
        }
        // Merging nothing changes nothing; one sample has no variance.
        let before = single;
        single.merge(&PixelStats::default());
        assert_eq!(single, before);
        let mut one = PixelStats::default();
        one.add(Vec3::ONE, Vec3::ONE);
        assert_eq!(one.variance(), Vec3::ZERO);
    }
}
