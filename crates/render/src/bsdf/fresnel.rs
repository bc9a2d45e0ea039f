//! Schlick's Fresnel approximation, as glTF uses it.

use glam::Vec3;

/// (1 - cos)^5, clamped to [0, 1].
#[inline]
pub(crate) fn schlick_weight(cos: f32) -> f32 {
    let m = (1.0 - cos).clamp(0.0, 1.0);
    let m2 = m * m;
    m2 * m2 * m
}

/// Schlick's F = f0 + (f90 - f0) (1 - cos)^5, per channel.
#[inline]
pub(crate) fn schlick(f0: Vec3, f90: f32, cos: f32) -> Vec3 {
    f0 + (Vec3::splat(f90) - f0) * schlick_weight(cos)
}

/// Reflectance at normal incidence of an interface with relative index `ior`:
/// ((ior - 1) / (ior + 1))^2, and 1 for `ior` = 0 or infinity (glTF's specular-glossiness
/// conversion).
#[inline]
pub(crate) fn f0_from_ior(ior: f32) -> f32 {
    if ior.is_infinite() {
        return 1.0;
    }
    let r = (ior - 1.0) / (ior + 1.0);
    if r.is_finite() {
        r * r
    } else {
        1.0
    }
}

/// The cosine to feed Schlick's approximation at a dielectric interface seen from the side
/// with relative index `etap` = eta_other / eta_this. From the denser side (`etap` < 1)
/// Schlick's formula is evaluated at the transmitted angle (it is accurate from the lighter
/// side only); 0 beyond the critical angle, where Schlick then gives F = f90 (1 for
/// `specular` = 1: total internal reflection).
#[inline]
pub(crate) fn schlick_cos(cos: f32, etap: f32) -> f32 {
    if etap >= 1.0 {
        return cos;
    }
    let sin2_t = (1.0 - cos * cos).max(0.0) / (etap * etap);
    if sin2_t >= 1.0 {
        0.0
    } else {
        (1.0 - sin2_t).sqrt()
    }
}
