//! Isotropic microfacet normal distributions: GGX (Trowbridge-Reitz) and Beckmann.
//!
//! Microfacet normals `m` always live in the upper hemisphere (`m.z > 0`); directions passed
//! to [`Ndf::sample_m`] / [`Ndf::pdf_m`] must already be flipped into the upper hemisphere.

use super::Microfacet;
use glam::{Vec2, Vec3};
use std::f32::consts::{FRAC_1_PI, TAU};

#[derive(Debug, Clone, Copy)]
pub(crate) struct Ndf {
    pub kind: Microfacet,
    pub alpha: f32,
    a2: f32,
}

impl Ndf {
    #[inline]
    pub fn new(kind: Microfacet, alpha: f32) -> Self {
        Self {
            kind,
            alpha,
            a2: alpha * alpha,
        }
    }

    /// GGX's [`d`](Self::d) without a branch (the same value, bit for bit).
    #[inline(always)]
    pub fn d_ggx_lane(&self, m: Vec3) -> f32 {
        let z2 = m.z * m.z;
        let s2 = m.x * m.x + m.y * m.y;
        let t = s2 / self.a2 + z2;
        let d = FRAC_1_PI / (self.a2 * t * t);
        if m.z <= 0.0 {
            0.0
        } else {
            d
        }
    }

    /// GGX's [`lambda`](Self::lambda) (the same value, bit for bit), inlined into lanes.
    #[inline(always)]
    pub fn lambda_ggx_lane(&self, w: Vec3) -> f32 {
        let az = w.z.abs();
        let s2 = w.x * w.x + w.y * w.y;
        let t = self.a2 * s2;
        t / (2.0 * az * ((az * az + t).sqrt() + az))
    }

    /// D(m), the microfacet normal density (normalised so that the integral of D(m) m.z over
    /// the hemisphere is 1). Zero for `m.z <= 0`.
    #[inline]
    pub fn d(&self, m: Vec3) -> f32 {
        if m.z <= 0.0 {
            return 0.0;
        }
        let z2 = m.z * m.z;
        let s2 = m.x * m.x + m.y * m.y;
        match self.kind {
            Microfacet::Ggx => {
                // 1 / (pi a^2 (sin^2/a^2 + cos^2)^2), stable for tiny alpha.
                let t = s2 / self.a2 + z2;
                FRAC_1_PI / (self.a2 * t * t)
            }
            Microfacet::Beckmann => {
                let e = s2 / (z2 * self.a2);
                if e > 100.0 {
                    return 0.0;
                }
                (-e).exp() * FRAC_1_PI / (self.a2 * z2 * z2)
            }
        }
    }

    /// Smith's Lambda(w) (only |w.z| matters). Infinite at grazing.
    #[inline]
    pub fn lambda(&self, w: Vec3) -> f32 {
        let az = w.z.abs();
        let s2 = w.x * w.x + w.y * w.y;
        match self.kind {
            Microfacet::Ggx => {
                // (sqrt(1 + a^2 tan^2) - 1) / 2 without cancellation.
                let t = self.a2 * s2;
                t / (2.0 * az * ((az * az + t).sqrt() + az))
            }
            Microfacet::Beckmann => {
                // Walter et al. 2007's rational approximation, as Lambda (Heitz 2014).
                if s2 <= 0.0 {
                    return 0.0;
                }
                let a = az / (self.alpha * s2.sqrt());
                if a >= 1.6 {
                    0.0
                } else {
                    (1.0 - 1.259 * a + 0.396 * a * a) / (3.535 * a + 2.181 * a * a)
                }
            }
        }
    }

    /// Smith masking G1(w).
    #[cfg(test)]
    pub fn g1(&self, w: Vec3) -> f32 {
        1.0 / (1.0 + self.lambda(w))
    }

    /// Height-correlated masking-shadowing G2(wo, wi) = 1 / (1 + Lambda(wo) + Lambda(wi)).
    #[cfg(test)]
    pub fn g2(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.g2_with(self.lambda(wo), wi)
    }

    /// [`g2`](Self::g2) given `lambda_o` = Lambda(wo).
    #[inline]
    pub fn g2_with(&self, lambda_o: f32, wi: Vec3) -> f32 {
        1.0 / (1.0 + lambda_o + self.lambda(wi))
    }

    /// The density of [`sample_m`](Self::sample_m) over microfacet normals (`wo.z > 0`),
    /// given `lambda_o` = Lambda(wo): visible normals G1(wo) max(0, wo.m) D(m) / wo.z for
    /// GGX, D(m) m.z for Beckmann.
    #[inline]
    pub fn pdf_m_with(&self, wo: Vec3, lambda_o: f32, m: Vec3) -> f32 {
        match self.kind {
            Microfacet::Ggx => {
                let dot = wo.dot(m);
                if dot <= 0.0 {
                    return 0.0;
                }
                dot * self.d(m) / ((1.0 + lambda_o) * wo.z)
            }
            Microfacet::Beckmann => self.d(m) * m.z.max(0.0),
        }
    }

    /// Samples a microfacet normal (`m.z >= 0`; a zero vector in degenerate cases, which
    /// callers reject through `m.z <= 0`). GGX: visible normals by the spherical-cap method
    /// of Dupuy & Benyoub 2023. Beckmann: D(m) m.z (Walter et al. 2007, Eq. 28-29).
    #[inline]
    pub fn sample_m(&self, wo: Vec3, u: Vec2) -> Vec3 {
        match self.kind {
            Microfacet::Ggx => {
                let v = Vec3::new(wo.x * self.alpha, wo.y * self.alpha, wo.z).normalize();
                let z = (1.0 - u.y).mul_add(1.0 + v.z, -v.z);
                let st = (1.0 - z * z).max(0.0).sqrt();
                let (s, c) = (TAU * u.x).sin_cos();
                let h = Vec3::new(st * c + v.x, st * s + v.y, z + v.z);
                Vec3::new(h.x * self.alpha, h.y * self.alpha, h.z).normalize_or_zero()
            }
            Microfacet::Beckmann => {
                let tan2 = -self.a2 * (1.0 - u.x).ln();
                let cos = 1.0 / (1.0 + tan2).sqrt();
                let sin = tan2.sqrt() * cos;
                let (s, c) = (TAU * u.y).sin_cos();
                Vec3::new(sin * c, sin * s, cos)
            }
        }
    }
}

/// Mirror reflection of `wo` about the unit normal `m`.
#[inline]
pub(crate) fn reflect(wo: Vec3, m: Vec3) -> Vec3 {
    2.0 * wo.dot(m) * m - wo
}

/// Refraction of `wo` through the unit normal `n` (`wo.n > 0`, on `wo`'s side), with
/// `etap` = eta_transmitted / eta_incident. `None` on total internal reflection.
#[inline]
pub(crate) fn refract(wo: Vec3, n: Vec3, etap: f32) -> Option<Vec3> {
    let cos_i = wo.dot(n);
    let sin2_t = (1.0 - cos_i * cos_i).max(0.0) / (etap * etap);
    if sin2_t >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    Some((-wo / etap + (cos_i / etap - cos_t) * n).normalize())
}
