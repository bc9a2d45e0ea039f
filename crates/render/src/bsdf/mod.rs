//! Bidirectional scattering distribution functions.
//!
//! Everything here works in the local shading frame: +Z is the shading normal, `wo` points
//! toward the viewer (or the previous path vertex) and `wi` toward the light (or the next
//! vertex); both are unit vectors. `wo.z < 0` means the path arrives from the back side (for a
//! dielectric: from inside the object). Values returned by `eval` do NOT include the cosine
//! factor |wi.z|; the integrator multiplies it in. Transmission follows radiance transport
//! (the 1/eta^2 scaling of pbrt-v4's `TransportMode::Radiance`).

use glam::{Vec2, Vec3};
use serde::{Deserialize, Serialize};

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
}

impl Bsdf {
    pub fn new(params: &BsdfParams) -> Self {
        Self { params: *params }
    }

    pub fn params(&self) -> &BsdfParams {
        &self.params
    }

    /// f(wo, wi) of the non-delta lobes (no cosine).
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        let _ = (wo, wi);
        todo!("bsdf")
    }

    /// The density with which [`sample`](Self::sample) returns `wi` through a non-delta lobe.
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        let _ = (wo, wi);
        todo!("bsdf")
    }

    /// Samples a direction: `u_lobe` picks a lobe, `u` the direction within it.
    pub fn sample(&self, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        let _ = (wo, u_lobe, u);
        todo!("bsdf")
    }

    /// True when every lobe is a delta (light sampling cannot contribute).
    pub fn is_delta(&self) -> bool {
        todo!("bsdf")
    }
}
