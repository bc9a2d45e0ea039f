//! A reprojection state ([`Slot`]), packed, and the thesis's material-dependent error test
//! (Eq. 13 and Eq. 15: [`reflection`], [`view_error`]).

use glam::Vec3;
use pathlight_scene::Material;

use crate::bsdf::fresnel::{f0_from_ior, schlick_weight};
use crate::bsdf::microfacet::Ndf;
use crate::bsdf::{Microfacet, DELTA_ALPHA};
use crate::frame::accumulation::PixelStats;
use crate::frame::gbuffer::GPixel;
use crate::frame::lighting::LightSample;
use crate::path::Bounce;

/// One reprojection state: a share of a pixel's samples and what the checks need, packed
/// (124 bytes instead of 144: the passes that move the states are bound by memory traffic):
/// what only Eq. 15 reads (the first bounce's direction in 32-bit octahedral form, the base
/// colour and the lobe's parameters as 16-bit fractions of 1) and the booleans as bits. The
/// precision lost is far below what the test resolves (the direction to about 1e-4 radians,
/// the rest to 1.5e-5). The normal, which the aliasing test reads at every pixel of every
/// frame, stays as it is (decoding it there cost more than its bytes).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Slot {
    /// The samples (empty: `stats.n == 0`).
    pub stats: PixelStats,
    /// World position of the first sample's first hit; for the sky, the unit direction.
    pub point: Vec3,
    /// `I`: the radiance arriving along `L`, averaged over the slot's samples.
    pub irradiance: Vec3,
    /// The material at the first hit ([`NO_MATERIAL`](super::gbuffer::NO_MATERIAL): sky).
    pub material: u32,
    /// Unit shading normal there, facing the camera that saw it.
    pub normal: Vec3,
    /// `L`: the unit direction the first sample left the first hit in (octahedral; the
    /// [`ENDED`] bit where it ended there).
    pub(super) direction: u32,
    /// `A`: the base colour at the first hit (clamped to [0, 1]).
    pub(super) albedo: [u16; 3],
    /// The specular lobe: Beckmann alpha (glTF roughness squared); the reflectance at normal
    /// incidence (the dielectric layer's F0 blended to 1 by metallic); at grazing incidence
    /// (the layer's `specular` weight blended to 1 by metallic; 0: no lobe, Lambertian).
    pub(super) lobe: [u16; 3],
    /// [`SKY`], [`SPECULAR`], [`MIXED`], [`CARRIED`], [`ENDED`].
    pub(super) flags: u8,
}

/// The state saw the environment (`point` is a direction).
pub(super) const SKY: u8 = 1;
/// Never reprojected: a specular lobe with alpha < 0.01, or transmitting.
pub(super) const SPECULAR: u8 = 2;
/// Never reprojected: its samples saw more than one surface (another material, or a point
/// off this one's tangent plane): a mix that belongs to its old footprint.
pub(super) const MIXED: u8 = 4;
/// Its samples came from another view (dropped when a new sample disagrees).
pub(super) const CARRIED: u8 = 8;
/// The first sample's path ended at the first hit (`L` is zero).
pub(super) const ENDED: u8 = 16;

/// Alpha below which a surface counts as specular (the thesis's 0.01).
pub const SPECULAR_ALPHA: f32 = 0.01;

/// `v` in [0, 1] as a 16-bit fraction.
#[inline]
pub(super) fn unorm(v: f32) -> u16 {
    (v.clamp(0.0, 1.0) * 65535.0).round() as u16
}

#[inline]
pub(super) fn from_unorm(v: u16) -> f32 {
    f32::from(v) * (1.0 / 65535.0)
}

/// A unit vector in octahedral form (Cigolle et al. 2014), 16 bits per coordinate.
#[inline]
pub(super) fn octahedral(v: Vec3) -> u32 {
    let v = v / (v.x.abs() + v.y.abs() + v.z.abs());
    let (x, y) = if v.z >= 0.0 {
        (v.x, v.y)
    } else {
        (
            (1.0 - v.y.abs()) * v.x.signum(),
            (1.0 - v.x.abs()) * v.y.signum(),
        )
    };
    let snorm = |c: f32| {
        let c = if c.is_nan() { 0.0 } else { c };
        ((c.clamp(-1.0, 1.0) * 32767.0).round() as i16) as u16 as u32
    };
    snorm(x) | (snorm(y) << 16)
}

#[inline]
pub(super) fn from_octahedral(e: u32) -> Vec3 {
    let snorm = |b: u32| f32::from(b as u16 as i16) * (1.0 / 32767.0);
    let (x, y) = (snorm(e), snorm(e >> 16));
    let z = 1.0 - x.abs() - y.abs();
    let t = (-z).max(0.0);
    Vec3::new(x - t.copysign(x), y - t.copysign(y), z).normalize_or_zero()
}

impl Slot {
    /// A state on a surface (empty of samples): first hit `point` with unit normal
    /// `normal`, first bounce `direction` (zero: the path ended), base colour `albedo`, and
    /// the specular lobe's `alpha`, `f0` and `f90`.
    pub fn surface(
        point: Vec3,
        normal: Vec3,
        direction: Vec3,
        albedo: Vec3,
        [alpha, f0, f90]: [f32; 3],
        material: u32,
    ) -> Self {
        let ended = direction == Vec3::ZERO || !direction.is_finite();
        Slot {
            point,
            material,
            normal,
            direction: if ended { 0 } else { octahedral(direction) },
            albedo: albedo.to_array().map(unorm),
            lobe: [alpha, f0, f90].map(unorm),
            flags: if ended { ENDED } else { 0 },
            ..Slot::default()
        }
    }

    /// A state that saw the environment in direction `direction` (empty of samples).
    pub fn sky(direction: Vec3, material: u32) -> Self {
        Slot {
            point: direction,
            material,
            flags: SKY,
            ..Slot::default()
        }
    }

    /// A state started by a frame's first sample: G-buffer pixel `g`, its first bounce and
    /// its material (none for the sky, whose direction the caller sets).
    pub fn start(g: &GPixel, bounce: &Bounce, material: Option<&Material>) -> Self {
        let Some(m) = material.filter(|_| !g.is_sky()) else {
            return Slot::sky(Vec3::ZERO, g.material);
        };
        let alpha = g.roughness.clamp(0.0, 1.0).powi(2);
        // As the BSDF's dielectric layer (`bsdf` module docs), reduced to one channel.
        let weight = m.specular.clamp(0.0, 1.0);
        let dielectric =
            (f0_from_ior(m.ior) * m.specular_color.max_element().max(0.0)).min(1.0) * weight;
        let metallic = g.metallic.clamp(0.0, 1.0);
        let f90 = weight + (1.0 - weight) * metallic;
        let f0 = (dielectric + (1.0 - dielectric) * metallic).clamp(0.0, 1.0);
        let mut slot = Slot::surface(
            g.position,
            g.normal,
            bounce.direction,
            g.albedo,
            [alpha, f0, f90],
            g.material,
        );
        slot.set(
            SPECULAR,
            (f90 > 0.0 && alpha < SPECULAR_ALPHA) || m.transmission > 0.0,
        );
        slot
    }

    #[inline]
    pub(super) fn has(&self, flag: u8) -> bool {
        self.flags & flag != 0
    }

    #[inline]
    pub(super) fn set(&mut self, flag: u8, on: bool) {
        if on {
            self.flags |= flag;
        } else {
            self.flags &= !flag;
        }
    }

    /// The state saw the environment (`point` is a direction).
    pub fn is_sky(&self) -> bool {
        self.has(SKY)
    }

    /// Never reprojected: a specular lobe with alpha < 0.01, or transmitting.
    pub fn is_specular(&self) -> bool {
        self.has(SPECULAR)
    }

    /// Never reprojected: its samples saw more than one surface.
    pub fn is_mixed(&self) -> bool {
        self.has(MIXED)
    }

    /// Its samples came from another view.
    pub fn is_carried(&self) -> bool {
        self.has(CARRIED)
    }

    /// `L`: the unit direction the first sample left the first hit in (zero where it ended).
    pub fn direction(&self) -> Vec3 {
        if self.has(ENDED) {
            Vec3::ZERO
        } else {
            from_octahedral(self.direction)
        }
    }

    /// `A`: the base colour at the first hit.
    pub fn albedo(&self) -> Vec3 {
        Vec3::from_array(self.albedo.map(from_unorm))
    }

    /// The specular lobe: alpha, reflectance at normal and at grazing incidence.
    pub fn lobe(&self) -> [f32; 3] {
        self.lobe.map(from_unorm)
    }

    /// The plane the aliasing test compares new hits with.
    #[inline]
    pub(super) fn plane(&self) -> Plane {
        Plane {
            point: self.point,
            normal: self.normal,
            material: self.material,
            sky: self.is_sky(),
        }
    }

    /// Adds a frame's samples (`l.stats`) and the radiance along their first bounce.
    #[inline]
    pub(super) fn add(&mut self, l: &LightSample) {
        let n = self.stats.n + l.stats.n;
        let w = l.stats.n as f32 / n as f32;
        self.irradiance += (l.bounce.radiance - self.irradiance) * w;
        self.stats.merge(&l.stats);
    }
}

/// What the aliasing test needs of a state, unpacked once for the pixels it is compared with.
#[derive(Debug, Clone, Copy)]
pub(super) struct Plane {
    point: Vec3,
    normal: Vec3,
    material: u32,
    sky: bool,
}

impl Plane {
    /// Whether a sample with first hit `g` saw this surface (`tolerance`: as the aliasing
    /// test's).
    #[inline]
    pub(super) fn agrees(&self, g: &GPixel, tolerance: f32) -> bool {
        g.material == self.material && self.same_surface(g, tolerance)
    }

    /// The aliasing depth test: whether the new camera ray through the pixel (G-buffer pixel
    /// `g`) sees this surface.
    #[inline]
    pub(super) fn same_surface(&self, g: &GPixel, tolerance: f32) -> bool {
        if self.sky || g.is_sky() {
            return self.sky && g.is_sky();
        }
        (g.position - self.point).dot(self.normal).abs() <= tolerance * g.depth
    }
}

/// Eq. 13: Walter et al.'s microfacet reflection term `F G D / (4 |i.n| |o.n|)` with the
/// Beckmann distribution of alpha `alpha`, Schlick's Fresnel term from `f0` to `f90` and
/// Smith's separable shadowing-masking (Walter's rational approximation). `i`, `o` and `n`
/// are unit vectors; 0 unless both directions are on the normal's side (the thesis's
/// `sign(i.n)` flips `h` for `i` below the surface, where reflection is 0 anyway).
pub fn reflection(i: Vec3, o: Vec3, n: Vec3, alpha: f32, f0: f32, f90: f32) -> f32 {
    if f90 <= 0.0 {
        return 0.0;
    }
    let (cos_i, cos_o) = (i.dot(n), o.dot(n));
    if !(cos_i > 0.0 && cos_o > 0.0) {
        return 0.0;
    }
    let h = (i + o).normalize_or_zero();
    let cos_h = h.dot(n);
    if cos_h <= 0.0 {
        return 0.0;
    }
    // The distribution and Lambda depend only on angles to the normal: a local vector with
    // that cosine stands for each direction.
    let local = |c: f32| Vec3::new((1.0 - c * c).max(0.0).sqrt(), 0.0, c.min(1.0));
    let ndf = Ndf::new(Microfacet::Beckmann, alpha.max(DELTA_ALPHA));
    let d = ndf.d(local(cos_h));
    let g = 1.0 / ((1.0 + ndf.lambda(local(cos_i))) * (1.0 + ndf.lambda(local(cos_o))));
    let f = f0 + (f90 - f0) * schlick_weight(i.dot(h));
    f * g * d / (4.0 * cos_i * cos_o)
}

/// Eq. 15: the view-dependency error of moving `slot` from a camera at `from` to one at `to`,
/// the largest channel of `|f_r(V_t, L, N) - f_r(V_{t-1}, L, N)| A I` (0 for the sky).
pub fn view_error(slot: &Slot, from: Vec3, to: Vec3) -> f32 {
    let [alpha, f0, f90] = slot.lobe();
    if slot.is_sky() || f90 <= 0.0 || from == to {
        return 0.0;
    }
    let (direction, normal) = (slot.direction(), slot.normal);
    let view = |eye: Vec3| (eye - slot.point).normalize_or_zero();
    let f = |v: Vec3| reflection(v, direction, normal, alpha, f0, f90);
    let df = (f(view(to)) - f(view(from))).abs();
    (slot.albedo() * slot.irradiance * df).max_element()
}
