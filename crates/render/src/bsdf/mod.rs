//! Bidirectional scattering distribution functions.
//!
//! Everything here works in the local shading frame: +Z is the shading normal, `wo` points
//! toward the viewer (or the previous path vertex) and `wi` toward the light (or the next
//! vertex); both are unit vectors. `wo.z < 0` means the path arrives from the back side (for a
//! dielectric: from inside the object). Values returned by `eval` do NOT include the cosine
//! factor |wi.z|; the integrator multiplies it in. Transmission follows radiance transport
//! (the 1/eta^2 scaling of pbrt-v4's `TransportMode::Radiance`).
//!
//! # The model
//!
//! glTF 2.0's metallic-roughness BRDF (Appendix B) with `KHR_materials_specular`,
//! `KHR_materials_ior` and `KHR_materials_transmission`:
//!
//! ```text
//! material   = mix(dielectric, metal, metallic)
//! metal      = F_schlick(f0 = base_color, f90 = 1) * specular_brdf
//! dielectric = F_d * specular_brdf + (1 - max_channel(F_d)) * base
//! F_d        = F_schlick(f0 = min(f0(ior) * specular_color, 1) * specular, f90 = specular)
//! base       = mix(diffuse, base_color * specular_btdf, transmission)
//! ```
//!
//! (the ratified `KHR_materials_specular`'s `fresnel_mix`: the specular layer is weighted per
//! channel, the base by one minus the largest channel, which keeps a coloured
//! `specular_color` energy conserving). Specular Fresnel terms are evaluated at the
//! microfacet normal of their lobe (`VdotH`). `specular_brdf` is a microfacet BRDF
//! D G2 / (4 |wo.z| |wi.z|) with height-correlated Smith G2 and alpha = roughness^2; below
//! alpha = 1e-3 (roughness ~0.032) the specular lobes are Dirac deltas.
//!
//! The diffuse lobe departs from the letter of Appendix B, whose `(1 - F(VdotH))` weight
//! gains energy under a smooth or glossy layer (the mirror reflects F(wo.z) while the
//! diffuse keeps ~1 - f0: +60% at grazing angles). Here
//!
//! ```text
//! diffuse = base_color / pi * (1 - F(|wo.z|)) (1 - F(|wi.z|)) / (1 - F_avg)
//! ```
//!
//! with F = max_channel(F_d) and F_avg = f0 + (f90 - f0) / 21 its cosine-weighted
//! hemispherical average: reciprocal, exactly `base_color / pi` when `specular` = 0, and with
//! a smooth layer R + T = 1 exactly for a white base (the diffuse albedo is then
//! `base_color (1 - F(|wo.z|))`).
//!
//! `specular_btdf`:
//! * `thin_walled`: the reflection lobe mirrored through the surface plane (a sheet without
//!   refraction; smooth: `wi = -wo`), weighted by (1 - F_d), no eta scaling;
//! * otherwise Walter et al. 2007's rough dielectric BTDF with the generalised half vector,
//!   transmittance (1 - max_channel(F_d)) and radiance scaling 1/eta^2; eta = ior when
//!   `wo.z > 0` and 1/ior when `wo.z < 0`. From the denser side Schlick is evaluated at the
//!   transmitted angle, and F_d = f90 beyond the critical angle (total internal reflection).
//!   `ior` within 1e-3 of 1 makes the (then straight) transmission a delta lobe.
//!
//! # Back side
//!
//! Every lobe is defined relative to the hemisphere of `wo`: a BSDF seen with `wo.z < 0` is
//! the mirror image (z -> -z) of the one seen from above, except that a refracting surface
//! uses eta = 1/ior there. Reflection lobes vanish when `wo.z` and `wi.z` differ in sign,
//! transmission lobes when they agree. A double-sided opaque material is therefore the same
//! whether or not the integrator flips the frame.
//!
//! # Sampling
//!
//! One lobe (specular reflection, diffuse, transmission) is picked with probabilities from
//! its albedo estimated with Fresnel at `wo.z` (non-delta lobes floored so that every
//! direction with f > 0 has pdf > 0). GGX samples visible normals (Dupuy & Benyoub 2023),
//! Beckmann samples D(m) m.z (Walter et al. 2007), the diffuse lobe the cosine. A non-delta
//! sample returns the one-sample-MIS density of the whole non-delta mixture and the sum of
//! the non-delta lobes, exactly what `pdf` and `eval` return for that `wi`.

pub(crate) mod fresnel;
pub(crate) mod microfacet;
pub mod specular_albedo;
#[cfg(test)]
mod tests;

use fresnel::{f0_from_ior, schlick, schlick_cos};
use glam::{Vec2, Vec3};
use microfacet::{reflect, refract, Ndf};
use serde::{Deserialize, Serialize};
use std::f32::consts::{FRAC_1_PI, TAU};

/// Below this microfacet alpha the specular lobes are treated as perfectly smooth.
pub const DELTA_ALPHA: f32 = 1e-3;

/// The microfacet normal distribution of the specular lobes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Microfacet {
    /// GGX / Trowbridge-Reitz with visible-normal sampling (glTF's choice).
    #[default]
    Ggx,
    /// Beckmann, as in Walter et al. 2007 (seed 000's BRDF).
    Beckmann,
}

/// Material parameters at one shading point, textures already applied.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BsdfParams {
    /// Linear base colour (glTF `baseColor`; the diffuse albedo of a dielectric).
    pub base_color: Vec3,
    pub metallic: f32,
    /// Perceptual roughness; microfacet alpha = roughness^2.
    pub roughness: f32,
    /// `KHR_materials_specular` weight (0: no dielectric specular layer, exactly Lambertian).
    pub specular: f32,
    pub specular_color: Vec3,
    pub ior: f32,
    /// `KHR_materials_transmission` weight.
    pub transmission: f32,
    /// True without `KHR_materials_volume`: transmission passes through a thin sheet without
    /// refraction. False: the surface bounds a refracting volume.
    pub thin_walled: bool,
    pub distribution: Microfacet,
}

impl BsdfParams {
    /// A Lambertian reflector of the given albedo.
    pub fn lambertian(albedo: Vec3) -> Self {
        Self {
            base_color: albedo,
            metallic: 0.0,
            roughness: 1.0,
            specular: 0.0,
            specular_color: Vec3::ONE,
            ior: 1.5,
            transmission: 0.0,
            thin_walled: true,
            distribution: Microfacet::Ggx,
        }
    }
}

/// One sampled direction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BsdfSample {
    pub wi: Vec3,
    /// BSDF value (no cosine). For a delta lobe: the lobe's weight divided by |wi.z|, so that
    /// `f * |wi.z| / pdf` is the throughput in every case.
    pub f: Vec3,
    /// Solid-angle density, including the lobe selection probability. For a delta lobe: the
    /// selection probability alone.
    pub pdf: f32,
    /// True when the sampled lobe is a Dirac delta (mirror, smooth dielectric).
    pub delta: bool,
    /// True when `wi` is on the other side of the surface from `wo`.
    pub transmitted: bool,
}

/// A BSDF ready to evaluate and sample.
#[derive(Debug, Clone, Copy)]
pub struct Bsdf {
    params: BsdfParams,
    /// Clamped to >= 0.
    base: Vec3,
    ndf: Ndf,
    /// alpha < [`DELTA_ALPHA`]: specular reflection and transmission are deltas.
    smooth: bool,
    metallic: f32,
    specular: f32,
    /// (1 - metallic) (1 - transmission).
    w_diffuse: f32,
    /// (1 - metallic) transmission.
    w_trans: f32,
    /// Some specular reflection exists (metallic > 0 or specular > 0).
    has_spec: bool,
    diel_f0: Vec3,
    diel_f90: f32,
    /// max_channel(diel_f0).
    diel_f0_max: f32,
    /// w_diffuse / (1 - F_avg): the diffuse normalisation.
    diffuse_norm: f32,
    /// The transmission refracts (not thin-walled, and there is some transmission).
    refracts: bool,
    /// The transmission lobe is a delta.
    trans_delta: bool,
    ior: f32,
    /// Only the diffuse lobe, without a specular layer (Fresnel 0): exactly Lambertian, with
    /// a short path through eval and sample (the same values as the general one).
    lambertian: bool,
}

/// A BSDF's per-`wo` quantities ([`Bsdf::at`]).
#[derive(Debug, Clone, Copy)]
pub struct BsdfAt {
    wo: Vec3,
    /// `None` for the Lambertian short path, or where `wo` is grazing or not finite.
    lobes: Option<Lobes>,
}

/// Per-`wo` quantities shared by eval, pdf and sample.
#[derive(Debug, Clone, Copy)]
struct Lobes {
    /// +1 when `wo.z > 0`, -1 otherwise.
    sign: f32,
    /// `wo` flipped into the upper hemisphere.
    wo_up: Vec3,
    /// eta_transmitted / eta_incident for refraction (1 when the surface does not refract).
    etap: f32,
    /// Smith Lambda(wo) (0 when the specular lobes are deltas).
    lambda_o: f32,
    /// Combined specular reflectance (m F_metal + (1 - m) F_d) at `wo`'s angle to the macro
    /// normal.
    spec_f: Vec3,
    /// 1 - max_channel(F_d) at `wo`'s angle to the macro normal.
    diel_t: f32,
    p_r: f32,
    p_d: f32,
    p_t: f32,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Lobe {
    Reflection,
    Diffuse,
    Transmission,
}

/// A cosine-distributed direction about +Z (`sign` 1) or -Z (`sign` -1), from `u` in [0,1)^2.
#[inline]
fn cosine_direction(u: Vec2, sign: f32) -> Vec3 {
    let r = u.x.sqrt();
    let (s, c) = (TAU * u.y).sin_cos();
    Vec3::new(r * c, r * s, (1.0 - u.x).sqrt() * sign)
}

/// `x > 0`, false for NaN.
#[inline]
fn positive(x: f32) -> bool {
    x > 0.0
}

#[inline]
fn avg(v: Vec3) -> f32 {
    (v.x + v.y + v.z) * (1.0 / 3.0)
}

impl Bsdf {
    pub fn new(params: &BsdfParams) -> Self {
        let metallic = params.metallic.clamp(0.0, 1.0);
        let transmission = params.transmission.clamp(0.0, 1.0);
        let specular = params.specular.clamp(0.0, 1.0);
        let roughness = params.roughness.clamp(0.0, 1.0);
        let alpha = roughness * roughness;
        let smooth = alpha < DELTA_ALPHA;
        let ior = if params.ior.is_finite() && params.ior > 0.0 {
            params.ior
        } else {
            1.0
        };
        let diel_f0 = (f0_from_ior(params.ior) * params.specular_color.max(Vec3::ZERO))
            .min(Vec3::ONE)
            * specular;
        let w_trans = (1.0 - metallic) * transmission;
        let w_diffuse = (1.0 - metallic) * (1.0 - transmission);
        let diel_f0_max = diel_f0.max_element();
        // Cosine-weighted hemispherical average of Schlick: 2 int (1 - mu)^5 mu dmu = 1/21.
        let f_avg = diel_f0_max + (specular - diel_f0_max) * (1.0 / 21.0);
        let diffuse_norm = if f_avg < 1.0 {
            w_diffuse / (1.0 - f_avg)
        } else {
            0.0
        };
        let refracts = !params.thin_walled && w_trans > 0.0;
        Self {
            params: *params,
            base: params.base_color.max(Vec3::ZERO),
            ndf: Ndf::new(params.distribution, alpha.max(DELTA_ALPHA)),
            smooth,
            metallic,
            specular,
            w_diffuse: if diffuse_norm > 0.0 { w_diffuse } else { 0.0 },
            w_trans,
            has_spec: metallic > 0.0 || specular > 0.0,
            diel_f0,
            diel_f90: specular,
            diel_f0_max,
            diffuse_norm,
            refracts,
            trans_delta: smooth || (refracts && (ior - 1.0).abs() < 1e-3),
            ior,
            lambertian: !(metallic > 0.0 || specular > 0.0) && w_trans == 0.0 && diffuse_norm > 0.0,
        }
    }

    /// [`eval_pdf`](Self::eval_pdf) of a Lambertian BSDF: `base * diffuse_norm / pi` and the
    /// cosine density on `wo`'s side, nothing on the other.
    #[inline]
    fn lambertian_eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        if wo.z == 0.0 || !wo.z.is_finite() || wi.z == 0.0 || wo.z * wi.z <= 0.0 {
            return (Vec3::ZERO, 0.0);
        }
        (
            self.base * (self.diffuse_norm * FRAC_1_PI),
            wi.z.abs() * FRAC_1_PI,
        )
    }

    pub fn params(&self) -> &BsdfParams {
        &self.params
    }

    /// The dielectric Fresnel F_d at `cos` = |wo.m| seen from the side with relative index
    /// `etap`.
    #[inline]
    fn diel_fresnel(&self, cos: f32, etap: f32) -> Vec3 {
        schlick(self.diel_f0, self.diel_f90, schlick_cos(cos, etap))
    }

    /// max_channel(F_d) at the macro-normal cosine `cos`.
    #[inline]
    fn diel_fresnel_max(&self, cos: f32, etap: f32) -> f32 {
        let w = fresnel::schlick_weight(schlick_cos(cos, etap));
        self.diel_f0_max + (self.diel_f90 - self.diel_f0_max) * w
    }

    /// m F_metal + (1 - m) F_d: the colour of the specular reflection lobe.
    #[inline]
    fn spec_fresnel(&self, cos: f32, etap: f32) -> Vec3 {
        let fd = self.diel_fresnel(cos, etap);
        if self.metallic > 0.0 {
            fd * (1.0 - self.metallic) + schlick(self.base, 1.0, cos) * self.metallic
        } else {
            fd
        }
    }

    #[inline]
    fn lobes(&self, wo: Vec3) -> Option<Lobes> {
        if wo.z == 0.0 || !wo.z.is_finite() {
            return None;
        }
        let sign = if wo.z > 0.0 { 1.0 } else { -1.0 };
        let wo_up = wo * sign;
        let etap = match (self.refracts, wo.z > 0.0) {
            (false, _) => 1.0,
            (true, true) => self.ior,
            (true, false) => 1.0 / self.ior,
        };
        let c0 = wo_up.z.min(1.0);
        let fd = self.diel_fresnel(c0, etap);
        let spec_f = if self.metallic > 0.0 {
            fd * (1.0 - self.metallic) + schlick(self.base, 1.0, c0) * self.metallic
        } else {
            fd
        };
        let diel_t = 1.0 - self.diel_fresnel_max(c0, etap);
        // Selection weights: each lobe's albedo estimated with Fresnel at the macro normal.
        // Non-delta lobes get a floor so that every direction where eval > 0 has pdf > 0
        // (the microfacet Fresnel can be far from the macro one at grazing angles).
        let e_r = if !self.has_spec {
            0.0
        } else if self.smooth {
            avg(spec_f)
        } else {
            avg(spec_f).max(0.1 * (self.metallic + (1.0 - self.metallic) * self.specular))
        };
        let base = avg(self.base);
        // The diffuse albedo is exactly w_diffuse base (1 - F(wo)): no floor needed.
        let e_d = self.w_diffuse * base * diel_t;
        let e_t = self.w_trans
            * base
            * if self.trans_delta {
                diel_t
            } else {
                diel_t.max(0.1)
            };
        let sum = e_r + e_d + e_t;
        if !positive(sum) {
            return None;
        }
        // Divisions, not a reciprocal: a single lobe gets probability exactly 1.
        let lambda_o = if self.smooth || !(self.has_spec || self.w_trans > 0.0) {
            0.0
        } else {
            self.ndf.lambda(wo)
        };
        Some(Lobes {
            sign,
            wo_up,
            etap,
            lambda_o,
            spec_f,
            diel_t,
            p_r: e_r / sum,
            p_d: e_d / sum,
            p_t: e_t / sum,
        })
    }

    /// f and (with `PDF`) pdf of the non-delta lobes.
    #[inline]
    fn eval_pdf_lobes<const PDF: bool>(&self, lo: &Lobes, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        let cos_o = wo.z;
        let cos_i = wi.z;
        let mut f = Vec3::ZERO;
        let mut pdf = 0.0;
        if cos_i == 0.0 {
            return (f, pdf);
        }
        if cos_o * cos_i > 0.0 {
            let spec = self.has_spec && !self.smooth && lo.p_r > 0.0;
            let diffuse = self.w_diffuse > 0.0;
            if !(spec || diffuse) {
                return (f, pdf);
            }
            if spec {
                let h = ((wo + wi) * lo.sign).normalize();
                let c = wo.dot(h).abs().min(1.0);
                let fr = self.spec_fresnel(c, lo.etap);
                let d = self.ndf.d(h);
                let g2 = self.ndf.g2_with(lo.lambda_o, wi);
                if c > 0.0 {
                    f += fr * (d * g2 / (4.0 * (cos_o * cos_i).abs()));
                    if PDF {
                        pdf += lo.p_r * self.ndf.pdf_m_with(lo.wo_up, lo.lambda_o, h) / (4.0 * c);
                    }
                }
            }
            if diffuse {
                let k = self.diffuse_norm
                    * lo.diel_t
                    * (1.0 - self.diel_fresnel_max(cos_i.abs().min(1.0), lo.etap));
                f += self.base * (k * FRAC_1_PI);
                if PDF {
                    pdf += lo.p_d * cos_i.abs() * FRAC_1_PI;
                }
            }
        } else if self.w_trans > 0.0 && !self.trans_delta && lo.p_t > 0.0 {
            if self.refracts {
                let etap = lo.etap;
                let m = wo + wi * etap;
                let len2 = m.length_squared();
                if !positive(len2) {
                    return (f, pdf);
                }
                let mut m = m / len2.sqrt();
                if m.z < 0.0 {
                    m = -m;
                }
                let d_o = wo.dot(m);
                let d_i = wi.dot(m);
                // Back-facing microfacets.
                if d_o * cos_o <= 0.0 || d_i * cos_i <= 0.0 {
                    return (f, pdf);
                }
                let denom = d_i + d_o / etap;
                let denom2 = denom * denom;
                if !positive(denom2) {
                    return (f, pdf);
                }
                let t = 1.0 - self.diel_fresnel(d_o.abs().min(1.0), etap).max_element();
                let d = self.ndf.d(m);
                let g2 = self.ndf.g2_with(lo.lambda_o, wi);
                let ft = self.w_trans * t * d * g2 * (d_i * d_o).abs()
                    / ((cos_i * cos_o).abs() * denom2 * etap * etap);
                f += self.base * ft;
                if PDF {
                    pdf +=
                        lo.p_t * self.ndf.pdf_m_with(lo.wo_up, lo.lambda_o, m) * d_i.abs() / denom2;
                }
            } else {
                // Thin-walled: the reflection lobe mirrored through the surface plane.
                let wr = Vec3::new(wi.x, wi.y, -wi.z);
                let h = ((wo + wr) * lo.sign).normalize();
                let c = wo.dot(h).abs().min(1.0);
                if !positive(c) {
                    return (f, pdf);
                }
                let t = 1.0 - self.diel_fresnel(c, 1.0).max_element();
                let d = self.ndf.d(h);
                let g2 = self.ndf.g2_with(lo.lambda_o, wi);
                f += self.base * (self.w_trans * t * d * g2 / (4.0 * (cos_o * cos_i).abs()));
                if PDF {
                    pdf += lo.p_t * self.ndf.pdf_m_with(lo.wo_up, lo.lambda_o, h) / (4.0 * c);
                }
            }
        }
        (f, pdf)
    }

    /// f(wo, wi) of the non-delta lobes (no cosine).
    #[inline]
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        self.eval_pdf(wo, wi).0
    }

    /// The density with which [`sample`](Self::sample) returns `wi` through a non-delta lobe.
    #[inline]
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.eval_pdf(wo, wi).1
    }

    /// [`eval`](Self::eval) and [`pdf`](Self::pdf) together, sharing their work (what light
    /// sampling with MIS needs).
    #[inline]
    pub fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        if self.lambertian {
            return self.lambertian_eval_pdf(wo, wi);
        }
        match self.lobes(wo) {
            Some(lo) => self.eval_pdf_lobes::<true>(&lo, wo, wi),
            None => (Vec3::ZERO, 0.0),
        }
    }

    /// The BSDF seen from `wo`: what depends on `wo` alone computed once, for
    /// [`eval_at`](Self::eval_at) over many incident directions (seed 004's light candidates).
    #[inline]
    pub fn at(&self, wo: Vec3) -> BsdfAt {
        BsdfAt {
            wo,
            lobes: if self.lambertian {
                None
            } else {
                self.lobes(wo)
            },
        }
    }

    /// f(wo, wi) of the non-delta lobes (no cosine), `wo` the direction of `at`: exactly
    /// [`eval`](Self::eval)'s value, without the densities.
    #[inline]
    pub fn eval_at(&self, at: &BsdfAt, wi: Vec3) -> Vec3 {
        if self.lambertian {
            return self.lambertian_eval_pdf(at.wo, wi).0;
        }
        match &at.lobes {
            Some(lo) => self.eval_pdf_lobes::<false>(lo, at.wo, wi).0,
            None => Vec3::ZERO,
        }
    }

    /// [`eval_lane`](Self::eval_lane) computes this BSDF: Lambertian, or reflecting only
    /// (no transmission lobe, no refraction) with the GGX distribution.
    pub fn has_lanes(&self) -> bool {
        self.lambertian
            || (!self.refracts
                && self.ndf.kind == Microfacet::Ggx
                && (self.w_trans <= 0.0 || self.trans_delta))
    }

    /// [`eval_at`](Self::eval_at) without branches that depend on `wi` (bit for bit the same
    /// value), for a BSDF that [`has_lanes`](Self::has_lanes): the body of loops over
    /// several directions that the compiler turns into SIMD lanes (seed 004's candidates).
    #[inline(always)]
    pub fn eval_lane(&self, at: &BsdfAt, wi: Vec3) -> Vec3 {
        let wo = at.wo;
        if self.lambertian {
            let none = wo.z == 0.0 || !wo.z.is_finite() || wi.z == 0.0 || wo.z * wi.z <= 0.0;
            let f = self.base * (self.diffuse_norm * FRAC_1_PI);
            return if none { Vec3::ZERO } else { f };
        }
        let Some(lo) = &at.lobes else {
            return Vec3::ZERO;
        };
        let (cos_o, cos_i) = (wo.z, wi.z);
        let mut f = Vec3::ZERO;
        if self.has_spec && !self.smooth && lo.p_r > 0.0 {
            let h = ((wo + wi) * lo.sign).normalize();
            let c = wo.dot(h).abs().min(1.0);
            // No refraction: `etap` is 1 and Schlick's cosine is `c` itself.
            let fd = schlick(self.diel_f0, self.diel_f90, c);
            let fr = if self.metallic > 0.0 {
                fd * (1.0 - self.metallic) + schlick(self.base, 1.0, c) * self.metallic
            } else {
                fd
            };
            let d = self.ndf.d_ggx_lane(h);
            let g2 = 1.0 / (1.0 + lo.lambda_o + self.ndf.lambda_ggx_lane(wi));
            let term = fr * (d * g2 / (4.0 * (cos_o * cos_i).abs()));
            f += if c > 0.0 { term } else { Vec3::ZERO };
        }
        if self.w_diffuse > 0.0 {
            let w = fresnel::schlick_weight(cos_i.abs().min(1.0));
            let fd_max = self.diel_f0_max + (self.diel_f90 - self.diel_f0_max) * w;
            let k = self.diffuse_norm * lo.diel_t * (1.0 - fd_max);
            f += self.base * (k * FRAC_1_PI);
        }
        if cos_i != 0.0 && cos_o * cos_i > 0.0 {
            f
        } else {
            Vec3::ZERO
        }
    }

    /// Samples a direction: `u_lobe` picks a lobe, `u` the direction within it.
    pub fn sample(&self, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        if self.lambertian {
            if wo.z == 0.0 || !wo.z.is_finite() {
                return None;
            }
            let wi = cosine_direction(u, wo.z.signum());
            let (f, pdf) = self.lambertian_eval_pdf(wo, wi);
            return (positive(pdf) && pdf.is_finite()).then_some(BsdfSample {
                wi,
                f,
                pdf,
                delta: false,
                transmitted: false,
            });
        }
        let lo = self.lobes(wo)?;
        let lobe = if u_lobe < lo.p_r {
            Lobe::Reflection
        } else if u_lobe < lo.p_r + lo.p_d {
            Lobe::Diffuse
        } else if lo.p_t > 0.0 {
            Lobe::Transmission
        } else if lo.p_d > 0.0 {
            Lobe::Diffuse
        } else {
            Lobe::Reflection
        };
        let wi = match lobe {
            Lobe::Reflection => {
                if self.smooth {
                    let wi = Vec3::new(-wo.x, -wo.y, wo.z);
                    return Some(BsdfSample {
                        wi,
                        f: lo.spec_f / wo.z.abs(),
                        pdf: lo.p_r,
                        delta: true,
                        transmitted: false,
                    });
                }
                let m = self.ndf.sample_m(lo.wo_up, u);
                if m.z <= 0.0 || lo.wo_up.dot(m) <= 0.0 {
                    return None;
                }
                let wi = reflect(wo, m);
                if wi.z * wo.z <= 0.0 {
                    return None;
                }
                wi
            }
            Lobe::Diffuse => cosine_direction(u, lo.sign),
            Lobe::Transmission => {
                if self.trans_delta {
                    let (wi, scale) = if self.refracts {
                        let wi = refract(wo, Vec3::new(0.0, 0.0, lo.sign), lo.etap)?;
                        (wi, 1.0 / (lo.etap * lo.etap))
                    } else {
                        (-wo, 1.0)
                    };
                    let w = self.w_trans * lo.diel_t * scale;
                    return Some(BsdfSample {
                        wi,
                        f: self.base * (w / wi.z.abs()),
                        pdf: lo.p_t,
                        delta: true,
                        transmitted: true,
                    });
                }
                let m = self.ndf.sample_m(lo.wo_up, u);
                if m.z <= 0.0 || lo.wo_up.dot(m) <= 0.0 {
                    return None;
                }
                if self.refracts {
                    let wi = refract(wo, m * lo.sign, lo.etap)?;
                    if wi.z * wo.z >= 0.0 {
                        return None;
                    }
                    wi
                } else {
                    let wr = reflect(wo, m);
                    if wr.z * wo.z <= 0.0 {
                        return None;
                    }
                    Vec3::new(wr.x, wr.y, -wr.z)
                }
            }
        };
        let (f, pdf) = self.eval_pdf_lobes::<true>(&lo, wo, wi);
        if !positive(pdf) || !pdf.is_finite() {
            return None;
        }
        Some(BsdfSample {
            wi,
            f,
            pdf,
            delta: false,
            transmitted: wi.z * wo.z < 0.0,
        })
    }

    /// True when some lobe is a delta (a smooth specular reflection or transmission), whose
    /// light only BSDF sampling can find.
    pub fn has_delta_lobe(&self) -> bool {
        (self.smooth && self.has_spec) || (self.trans_delta && self.w_trans > 0.0)
    }

    /// True when every lobe is a delta (light sampling cannot contribute).
    pub fn is_delta(&self) -> bool {
        self.w_diffuse == 0.0
            && (self.smooth || !self.has_spec)
            && (self.trans_delta || self.w_trans == 0.0)
    }

    /// The directional albedo at `wo` (the fraction of light from a uniform surround that it
    /// reflects or transmits towards `wo`), for energy: the diffuse lobe exactly (`w_diffuse
    /// base (1 - F(wo))`, its normalisation's integral), the rough specular reflection by one
    /// sample of its microfacet normals per entry of `u` (`F D G2 |wo.m| / (wo.z pdf(m))`:
    /// `F G2 / G1` with GGX's visible normals, nearly constant), a smooth one exactly, the
    /// transmission as [`albedo`](Self::albedo) has it. Unbiased where it samples.
    pub fn directional_albedo(&self, wo: Vec3, u: &[Vec2]) -> Vec3 {
        if self.lambertian {
            return if wo.z != 0.0 && wo.z.is_finite() {
                self.base * self.diffuse_norm
            } else {
                Vec3::ZERO
            };
        }
        let Some(lo) = self.lobes(wo) else {
            return Vec3::ZERO;
        };
        let diel_t = lo.diel_t.clamp(0.0, 1.0);
        let mut a = self.base * ((self.w_diffuse + self.w_trans) * diel_t);
        if !self.has_spec {
            return a;
        }
        if self.smooth || u.is_empty() {
            return a + lo.spec_f;
        }
        let mut spec = Vec3::ZERO;
        for &u in u {
            let m = self.ndf.sample_m(lo.wo_up, u);
            if m.z <= 0.0 {
                continue;
            }
            let c = lo.wo_up.dot(m);
            let wi = reflect(lo.wo_up, m);
            let pdf = self.ndf.pdf_m_with(lo.wo_up, lo.lambda_o, m);
            if c <= 0.0 || wi.z <= 0.0 || !positive(pdf) {
                continue;
            }
            let g2 = self.ndf.g2_with(lo.lambda_o, wi);
            spec += self.spec_fresnel(c.min(1.0), lo.etap)
                * (self.ndf.d(m) * g2 * c / (lo.wo_up.z * pdf));
        }
        a += spec / u.len() as f32;
        if a.is_finite() {
            a
        } else {
            Vec3::ZERO
        }
    }

    /// [`directional_albedo`](Self::directional_albedo) with the rough specular reflection
    /// from its precomputed table ([`specular_albedo`]: `F0 A + F90 B`, bilinear in the
    /// cosine and the roughness) instead of samples, where the table holds (reflection
    /// without refraction at `wo`); elsewhere from `u`'s samples as
    /// [`directional_albedo`](Self::directional_albedo).
    pub fn directional_albedo_tabulated(&self, wo: Vec3, u: &[Vec2]) -> Vec3 {
        if self.lambertian || !self.has_spec || self.smooth {
            return self.directional_albedo(wo, u);
        }
        let Some(lo) = self.lobes(wo) else {
            return Vec3::ZERO;
        };
        if lo.etap < 1.0 {
            return self.directional_albedo(wo, u);
        }
        let diel_t = lo.diel_t.clamp(0.0, 1.0);
        let diffuse = self.base * ((self.w_diffuse + self.w_trans) * diel_t);
        let (a, b) =
            specular_albedo::scale_and_bias(self.ndf.kind, lo.wo_up.z.min(1.0), self.ndf.alpha);
        let m = self.metallic;
        let f0 = self.diel_f0 * (1.0 - m) + self.base * m;
        let f90 = self.diel_f90 * (1.0 - m) + m;
        let albedo = diffuse + f0 * a + Vec3::splat(f90 * b);
        if albedo.is_finite() {
            albedo
        } else {
            Vec3::ZERO
        }
    }

    /// A cheap estimate of the directional albedo at `wo` (Fresnel at the macro normal, no
    /// masking), e.g. for albedo AOVs and denoisers. Not exact: do not use it for energy.
    pub fn albedo(&self, wo: Vec3) -> Vec3 {
        match self.lobes(wo) {
            Some(lo) => {
                lo.spec_f
                    + self.base * ((self.w_diffuse + self.w_trans) * lo.diel_t.clamp(0.0, 1.0))
            }
            None => Vec3::ZERO,
        }
    }
}
