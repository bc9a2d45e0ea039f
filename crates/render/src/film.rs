//! Per-pixel accumulation of path samples: running means and variances (Welford, n - 1
//! estimator) of radiance, direct and indirect light, and the first-hit features.

use glam::Vec3;

use crate::path::PathSample;

/// Floats per pixel in [`Pixel::to_array`].
pub const PIXEL_FLOATS: usize = 23;

/// The running statistics of one pixel.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Pixel {
    /// Samples taken.
    pub n: u32,
    /// Mean radiance.
    pub mean: Vec3,
    /// Sum of squared deviations of radiance from the mean (Welford's M2).
    pub m2: Vec3,
    pub direct: Vec3,
    pub indirect: Vec3,
    pub albedo: Vec3,
    pub normal: Vec3,
    pub depth: f32,
}

impl Pixel {
    /// Adds one sample.
    #[inline]
    pub fn add(&mut self, s: &PathSample) {
        self.n += 1;
        let inv = 1.0 / self.n as f32;
        let l = s.radiance();
        let delta = l - self.mean;
        self.mean += delta * inv;
        self.m2 += delta * (l - self.mean);
        self.direct += (s.direct - self.direct) * inv;
        self.indirect += (s.indirect - self.indirect) * inv;
        self.albedo += (s.albedo - self.albedo) * inv;
        self.normal += (s.normal - self.normal) * inv;
        self.depth += (s.depth - self.depth) * inv;
    }

    /// Adds the statistics of `other`, a disjoint set of samples of the same pixel (Chan,
    /// Golub and LeVeque's parallel Welford update: means weighted by the counts, M2 plus the
    /// spread of the two means).
    pub fn merge(&mut self, other: &Pixel) {
        if other.n == 0 {
            return;
        }
        if self.n == 0 {
            *self = *other;
            return;
        }
        let (na, nb) = (self.n as f64, other.n as f64);
        let n = na + nb;
        let (wa, wb) = ((na / n) as f32, (nb / n) as f32);
        let delta = other.mean - self.mean;
        self.m2 += other.m2 + delta * delta * (na * nb / n) as f32;
        let mix = |a: Vec3, b: Vec3| a * wa + b * wb;
        self.mean = mix(self.mean, other.mean);
        self.direct = mix(self.direct, other.direct);
        self.indirect = mix(self.indirect, other.indirect);
        self.albedo = mix(self.albedo, other.albedo);
        self.normal = mix(self.normal, other.normal);
        self.depth = self.depth * wa + other.depth * wb;
        self.n += other.n;
    }

    /// The sample variance of radiance per channel (n - 1 estimator; zero below 2 samples).
    /// Divide by `n` for the variance of the pixel's mean.
    pub fn variance(&self) -> Vec3 {
        if self.n < 2 {
            Vec3::ZERO
        } else {
            self.m2 / (self.n - 1) as f32
        }
    }

    pub fn to_array(&self) -> [f32; PIXEL_FLOATS] {
        let mut a = [0.0; PIXEL_FLOATS];
        a[0] = f32::from_bits(self.n);
        for (i, v) in [
            self.mean,
            self.m2,
            self.direct,
            self.indirect,
            self.albedo,
            self.normal,
        ]
        .iter()
        .enumerate()
        {
            a[1 + 3 * i..4 + 3 * i].copy_from_slice(&v.to_array());
        }
        a[19] = self.depth;
        a
    }

    pub fn from_array(a: &[f32; PIXEL_FLOATS]) -> Self {
        let v = |i: usize| Vec3::new(a[1 + 3 * i], a[2 + 3 * i], a[3 + 3 * i]);
        Self {
            n: a[0].to_bits(),
            mean: v(0),
            m2: v(1),
            direct: v(2),
            indirect: v(3),
            albedo: v(4),
            normal: v(5),
            depth: a[19],
        }
    }
}

/// An image of pixel statistics, row-major, row 0 at the top.
#[derive(Debug, Clone, PartialEq)]
pub struct Film {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<Pixel>,
}

impl Film {
    pub fn new(width: u32, height: u32) -> Self {
        Self {
            width,
            height,
            pixels: vec![Pixel::default(); width as usize * height as usize],
        }
    }

    /// Samples taken over the whole image.
    pub fn samples(&self) -> u64 {
        self.pixels.iter().map(|p| p.n as u64).sum()
    }

    /// The fewest samples any pixel has.
    pub fn min_samples(&self) -> u32 {
        self.pixels.iter().map(|p| p.n).min().unwrap_or(0)
    }

    /// One value per pixel, e.g. `film.layer(|p| p.mean)`.
    pub fn layer(&self, f: impl Fn(&Pixel) -> Vec3) -> Vec<Vec3> {
        self.pixels.iter().map(f).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn welford_matches_two_pass_statistics() {
        let values = [1.0f32, 4.0, 2.5, 10.0, 0.0, 3.0];
        let mut p = Pixel::default();
        for &v in &values {
            p.add(&PathSample {
                direct: Vec3::splat(v),
                indirect: Vec3::new(0.0, 1.0, 2.0),
                ..Default::default()
            });
        }
        let n = values.len() as f32;
        let mean = values.iter().sum::<f32>() / n;
        let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f32>() / (n - 1.0);
        assert!((p.mean.x - mean).abs() < 1e-5);
        assert!((p.mean.z - (mean + 2.0)).abs() < 1e-5);
        assert!((p.variance().x - var).abs() < 1e-4);
        assert_eq!(p.variance().x, p.variance().z);
        assert_eq!(Pixel::from_array(&p.to_array()), p);
    }
}
