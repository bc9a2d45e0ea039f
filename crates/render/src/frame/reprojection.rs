//! Seed 000's forward reprojection (Schalk 2018, section 3.2): when the camera moves, each
//! pixel's accumulated samples move with the surface point they saw into the new view, where
//! they are still valid, instead of being thrown away.
//!
//! # State
//! Each pixel keeps `samples` (1 or 4) *states* ([`Slot`]): the statistics of its samples
//! (count, mean and M2 of direct and indirect light, as the history keeps them) and what
//! Eq. 15 needs, taken from the state's first sample: the first hit point (for the sky, the
//! direction through the pixel's centre), the first outgoing direction `L`, the Beckmann
//! alpha (glTF roughness squared), the shading normal `N`, the base colour `A`, the reflectance
//! at normal incidence, and `I`, the radiance arriving along `L` averaged over the state's
//! samples (the thesis's approximation: one state per pixel, not one per sample). With 4
//! states, each covers a quarter of the pixel: a sample goes to the state of the quadrant its
//! first hit projects into (the sky always to the first), so the 4 states of a pixel move
//! apart when the view changes, as its samples would. The pixel's history is the merge of
//! its states. The thesis's stored `f_r(V_{t-1}, L, N)` is recomputed instead (it needs only
//! the previous camera's position).
//!
//! # Passes
//! ```text
//! reproject   states, previous camera, camera, scene -> states in the new view, history,
//!             probabilities (adaptive), fates
//! repair      states, G-buffer, lighting (fresh_spp)   -> lighting (the samples pixels
//!                                                       lack, merged; [`Repair`])
//! accumulate  states, G-buffer, lighting             -> states, history (aliasing test on
//!             the frame after a move)
//! ```
//! Its rule at a new epoch ([`Reprojection::start_epoch`]): after a change of the camera alone
//! (in a pipeline that accumulates, at the same size and state count) the reprojection pass
//! carries the states, the history and adaptive sampling's probabilities into the new view;
//! after any other change the states start afresh. Its views: `reprojected` and `rejection`.
//! `reproject` runs at the first frame after a camera move (any other change starts afresh).
//! Each state is projected with the new camera and kept only if it passes, in this order:
//! 1. the screen bounds;
//! 2. specular exclusion: a specular lobe with alpha < 0.01, or any transmission (glass,
//!    thin or refracting). A Lambertian surface (no specular layer) is never specular,
//!    whatever its roughness;
//! 3. (beyond the thesis) *mixed* states: a state whose samples saw more than one surface
//!    (another material, or a point off its tangent plane, the aliasing test's criterion)
//!    straddles an edge; its colour mixes both sides in the proportions of its old
//!    footprint, which the new footprint does not share. Without this, every moved edge
//!    (a light's rim above all) carries a wrong mix that further samples never correct;
//! 4. the view-dependency error of Eq. 15, `|f_r(V_t, L, N) - f_r(V_{t-1}, L, N)| A I`, at
//!    most `max_error` (its largest channel; `f_r` is Walter et al.'s reflection term with
//!    the Beckmann distribution, Eq. 13, with Schlick's Fresnel term from the material's
//!    reflectance at normal incidence and Smith's separable shadowing-masking with Walter's
//!    rational approximation; `V` points from the surface to the camera position). Under pure
//!    rotation `V_t == V_{t-1}`, so the error is exactly 0;
//! 5. occlusion: a ray from the new camera towards the stored point must reach it, short by
//!    `occlusion_tolerance` of the distance (the sky: a ray in its direction must escape).
//!    Cut-out (alpha) surfaces count as opaque here. The rays of neighbouring states go
//!    together as packets. None is traced when the camera's position did not change (what
//!    the eye saw first along a ray it still sees first), nor with `occlusion_rays` off
//!    (a speed option beyond the thesis: the aliasing test still refuses a hidden state
//!    unless its occluder is smaller than a pixel);
//! 6. (in the accumulation pass of that frame, where the new G-buffer is known) the aliasing
//!    depth test: the frame's camera ray through the target pixel must hit the stored
//!    point's surface: the same material, and a distance to the stored point's tangent plane
//!    of at most `depth_tolerance` times its depth (the thesis compares the distance between
//!    the points with a maximum distance it does not give; the plane distance accepts a
//!    surface seen at a grazing angle, where the pixel's samples lie far apart on one plane;
//!    the material separates coplanar surfaces such as a light in its ceiling). Sky states
//!    need sky there, and surface states a surface. Beyond the thesis, the rays through the
//!    8 neighbouring pixels must see the state's surface too: a state that lands next to
//!    another surface lies on an edge of the new view, where its footprint's one surface is
//!    not all the pixel sees (a light's rim above all: without this, translating the Cornell
//!    box left the reprojected image worse than starting afresh). A pixel that adaptive
//!    sampling leaves unsampled that frame keeps such a state until its next sample.
//!
//! Beyond the thesis, the same agreement test runs at every later frame: a carried state
//! that a new sample of its pixel disagrees with is dropped (its footprint's mix of surfaces
//! was not this pixel's), and a state started in this view that a sample of its quadrant
//! disagrees with becomes mixed. So a pixel on an edge converges to the right mix once a
//! sample has seen the other side, instead of keeping the wrong one for the rest of the
//! epoch.
//!
//! Holes, and pixels whose states were all refused, start afresh; with `fresh_spp` (beyond
//! the thesis, off by default) a pixel of an epoch that began with a move takes at once the
//! samples it lacks up to `fresh_spp`, instead of one per frame: these pixels are few, but
//! left at one sample they dominate the error of the reprojected image. The lighting pass
//! counts what the states hold before the aliasing test's edge check (which needs the
//! neighbours' G-buffer pixels, not yet traced when a pixel is lit) and before carried states
//! that the new sample disagrees with are dropped; the pipeline's repair step, between the
//! lighting and accumulation passes, counts them with [`Reprojection::kept_by_sampled`] and
//! traces the samples such pixels still lack, so that they too show `fresh_spp` samples in
//! the frame of the move. (Without it they showed a single sample for one frame: right after
//! each move the image's error rose four-fold for that frame, `BENCHMARKS.md`.)
//!
//! With 4 states the pixel's history merges its states' samples, each sample weighing the
//! same. Weighing the states' means equally (as strata) was tried and measured worse: a
//! quarter holding one new sample beside three holding hundreds makes the pixel as noisy as
//! a quarter of one sample, and the bias it removes, at pixels whose quarters see different
//! surfaces, is gone with the states that land on an edge.
//!
//! A state's point is *snapped*, when the state starts, to where the camera ray through the
//! centre of its pixel (or quadrant) meets the first hit's tangent plane: the point that
//! stands for the pixel's footprint. The first hit of a jittered sample lies anywhere in the
//! pixel; projected as it is, the states of neighbouring pixels collide and leave holes even
//! under a small rotation (on the Cornell box at 320x180, 5-degree steps: 10.7k of 57.6k
//! states lost to collisions unsnapped, 1.9k snapped). Carried states keep their point
//! exactly (snapping them again to the pixel they land in would drop the fraction of a
//! pixel they moved at each step: under steps smaller than half a pixel they would never
//! move).
//!
//! Two states that land on one target (a state per pixel, or per quadrant with 4): the one
//! nearest the new camera wins (the thesis's related work, Adelson and Hodges), ties to the
//! lower source index, so the result does not depend on the threads. Pixels (or quadrants)
//! that receive nothing are holes: they start afresh with the frame's new samples. A frame
//! after a move also takes a new sample in every pixel (without adaptive sampling), so
//! reprojected pixels keep refining.
//!
//! Sample indices continue from a pixel's sample count, in the new epoch's random sequence.

use std::sync::atomic::{AtomicU64, AtomicU8, Ordering};

use glam::{Vec2, Vec3};
use pathlight_accel::Ray;
use pathlight_scene::Material;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::bsdf::fresnel::{f0_from_ior, schlick_weight};
use crate::bsdf::microfacet::Ndf;
use crate::bsdf::{Microfacet, DELTA_ALPHA};
use crate::camera::Camera;
use crate::error::ConfigError;
use crate::path::{Bounce, PathTracer};
use crate::world::World;

use super::accumulation::PixelStats;
use super::adaptive::NO_PROBABILITY;
use super::display::{View, ViewKind};
use super::gbuffer::{GBuffer, GPixel};
use super::lighting::LightSample;
use super::ping_pong::PingPong;
use super::stage::Stage;
use super::state::{Change, FrameState};
use super::trace::{self, Plan};

/// The reprojection pass's name (timings, the menu's heading of its views).
pub const REPROJECT: &str = "reproject";

/// Settings of forward reprojection (`[frame.reprojection]`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ReprojectionConfig {
    pub enabled: bool,
    /// States per pixel: 1, or 4 (one per quarter of the pixel).
    pub samples: u32,
    /// Largest view-dependency error (Eq. 15) of a reprojected state, in units of radiance
    /// (the thesis: 1/256).
    pub max_error: f32,
    /// Trace the occlusion ray of every state (the thesis). Without it, a hidden state is
    /// still refused by the aliasing test on the next frame unless its occluder is smaller
    /// than a pixel. Under pure rotation (the camera's position unchanged) no ray is traced
    /// either way: what the eye saw first along a ray it still sees first.
    pub occlusion_rays: bool,
    /// The occlusion ray stops this fraction of the distance short of the stored point.
    pub occlusion_tolerance: f32,
    /// The aliasing depth test: largest distance of the new hit from the stored point's
    /// tangent plane, as a fraction of the new hit's depth.
    pub depth_tolerance: f32,
    /// Beyond the thesis: after a move, a pixel holding fewer samples than this (a hole, or
    /// a pixel whose states were refused) takes the missing ones in one frame instead of one
    /// per frame, so that the pixels the move could not help do not stay the noisiest of
    /// the image. 0 or 1: the thesis (one sample per frame like every pixel).
    pub fresh_spp: u32,
}

impl Default for ReprojectionConfig {
    fn default() -> Self {
        Self {
            enabled: false,
            samples: 1,
            max_error: 1.0 / 256.0,
            occlusion_rays: true,
            occlusion_tolerance: 1e-3,
            depth_tolerance: 0.02,
            fresh_spp: 0,
        }
    }
}

impl ReprojectionConfig {
    /// Checks: 1 or 4 states, `max_error >= 0` (infinite switches the test off), tolerances
    /// in (0, 1).
    pub fn validate(&self) -> Result<(), ConfigError> {
        if !matches!(self.samples, 1 | 4) {
            return Err(ConfigError::new(
                "frame.reprojection.samples",
                self.samples,
                "1 or 4",
            ));
        }
        if self.fresh_spp > MAX_FRESH_SPP {
            return Err(ConfigError::new(
                "frame.reprojection.fresh_spp",
                self.fresh_spp,
                format!("at most {MAX_FRESH_SPP}"),
            ));
        }
        if self.max_error.is_nan() || self.max_error < 0.0 {
            return Err(ConfigError::new(
                "frame.reprojection.max_error",
                self.max_error,
                ">= 0",
            ));
        }
        for (name, v) in [
            (
                "frame.reprojection.occlusion_tolerance",
                self.occlusion_tolerance,
            ),
            ("frame.reprojection.depth_tolerance", self.depth_tolerance),
        ] {
            if !(v > 0.0 && v < 1.0) {
                return Err(ConfigError::new(name, v, "between 0 and 1"));
            }
        }
        Ok(())
    }
}

/// Largest `fresh_spp`.
pub const MAX_FRESH_SPP: u32 = 256;

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
    direction: u32,
    /// `A`: the base colour at the first hit (clamped to [0, 1]).
    albedo: [u16; 3],
    /// The specular lobe: Beckmann alpha (glTF roughness squared); the reflectance at normal
    /// incidence (the dielectric layer's F0 blended to 1 by metallic); at grazing incidence
    /// (the layer's `specular` weight blended to 1 by metallic; 0: no lobe, Lambertian).
    lobe: [u16; 3],
    /// [`SKY`], [`SPECULAR`], [`MIXED`], [`CARRIED`], [`ENDED`].
    flags: u8,
}

/// The state saw the environment (`point` is a direction).
const SKY: u8 = 1;
/// Never reprojected: a specular lobe with alpha < 0.01, or transmitting.
const SPECULAR: u8 = 2;
/// Never reprojected: its samples saw more than one surface (another material, or a point
/// off this one's tangent plane): a mix that belongs to its old footprint.
const MIXED: u8 = 4;
/// Its samples came from another view (dropped when a new sample disagrees).
const CARRIED: u8 = 8;
/// The first sample's path ended at the first hit (`L` is zero).
const ENDED: u8 = 16;

/// Alpha below which a surface counts as specular (the thesis's 0.01).
pub const SPECULAR_ALPHA: f32 = 0.01;

/// `v` in [0, 1] as a 16-bit fraction.
#[inline]
fn unorm(v: f32) -> u16 {
    (v.clamp(0.0, 1.0) * 65535.0).round() as u16
}

#[inline]
fn from_unorm(v: u16) -> f32 {
    f32::from(v) * (1.0 / 65535.0)
}

/// A unit vector in octahedral form (Cigolle et al. 2014), 16 bits per coordinate.
#[inline]
fn octahedral(v: Vec3) -> u32 {
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
fn from_octahedral(e: u32) -> Vec3 {
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
    fn has(&self, flag: u8) -> bool {
        self.flags & flag != 0
    }

    #[inline]
    fn set(&mut self, flag: u8, on: bool) {
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
    fn plane(&self) -> Plane {
        Plane {
            point: self.point,
            normal: self.normal,
            material: self.material,
            sky: self.is_sky(),
        }
    }

    /// Adds a frame's samples (`l.stats`) and the radiance along their first bounce.
    #[inline]
    fn add(&mut self, l: &LightSample) {
        let n = self.stats.n + l.stats.n;
        let w = l.stats.n as f32 / n as f32;
        self.irradiance += (l.bounce.radiance - self.irradiance) * w;
        self.stats.merge(&l.stats);
    }
}

/// What the aliasing test needs of a state, unpacked once for the pixels it is compared with.
#[derive(Debug, Clone, Copy)]
struct Plane {
    point: Vec3,
    normal: Vec3,
    material: u32,
    sky: bool,
}

impl Plane {
    /// Whether a sample with first hit `g` saw this surface (`tolerance`: as the aliasing
    /// test's).
    #[inline]
    fn agrees(&self, g: &GPixel, tolerance: f32) -> bool {
        g.material == self.material && self.same_surface(g, tolerance)
    }

    /// The aliasing depth test: whether the new camera ray through the pixel (G-buffer pixel
    /// `g`) sees this surface.
    #[inline]
    fn same_surface(&self, g: &GPixel, tolerance: f32) -> bool {
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

/// What happened to a pixel's states at the last camera move (the `rejection` display mode):
/// the best outcome among the states that landed on it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
#[repr(u8)]
pub enum Fate {
    /// Nothing landed here: newly seen (or no move yet).
    New = 0,
    /// The state that landed here was hidden from the new camera.
    Occluded = 1,
    /// Its view-dependency error was too large.
    ViewError = 2,
    /// It was on a specular surface.
    Specular = 3,
    /// Its samples saw more than one surface (an edge).
    Mixed = 4,
    /// The new ray through the pixel saw another surface (aliasing depth test).
    Aliasing = 5,
    /// At least one state kept its history here.
    Kept = 6,
}

impl Fate {
    pub const ALL: [Fate; 7] = [
        Fate::New,
        Fate::Occluded,
        Fate::ViewError,
        Fate::Specular,
        Fate::Mixed,
        Fate::Aliasing,
        Fate::Kept,
    ];

    fn from_u8(v: u8) -> Fate {
        Fate::ALL[(v as usize).min(Fate::ALL.len() - 1)]
    }

    /// Its colour in the `rejection` display mode.
    pub fn colour(self) -> [u8; 3] {
        match self {
            Fate::New => [0, 0, 0],
            Fate::Occluded => [230, 40, 40],
            Fate::ViewError => [240, 200, 30],
            Fate::Specular => [50, 110, 240],
            Fate::Mixed => [240, 130, 30],
            Fate::Aliasing => [220, 60, 220],
            Fate::Kept => [60, 200, 80],
        }
    }
}

/// Counts of one reprojection pass (and the aliasing test of the frame that followed).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct ReprojectionReport {
    /// States that held samples.
    pub states: u64,
    /// States kept in the new view.
    pub kept: u64,
    pub out_of_view: u64,
    pub specular: u64,
    /// States whose samples saw more than one surface.
    pub mixed: u64,
    pub view_error: u64,
    pub occluded: u64,
    /// States that lost to a nearer one on the same target.
    pub collisions: u64,
    /// States that failed the aliasing depth test.
    pub aliasing: u64,
}

impl ReprojectionReport {
    fn add(mut self, o: Self) -> Self {
        self.states += o.states;
        self.kept += o.kept;
        self.out_of_view += o.out_of_view;
        self.specular += o.specular;
        self.mixed += o.mixed;
        self.view_error += o.view_error;
        self.occluded += o.occluded;
        self.collisions += o.collisions;
        self.aliasing += o.aliasing;
        self
    }
}

/// Forward reprojection's state and buffers.
#[derive(Debug, Default)]
pub struct Reprojection {
    /// `samples` states per pixel, row-major: `current` this view's, `previous` scratch.
    pub slots: PingPong<Slot>,
    /// States per pixel.
    pub samples: usize,
    /// Per pixel, the [`Fate`] at the last move.
    pub fates: Vec<u8>,
    /// Per pixel, how many states kept their history at the last move.
    pub kept: Vec<u8>,
    /// Per target state: the best claim (depth bits, source index) of this move.
    claims: Vec<AtomicU64>,
    /// Per target pixel: the best rejection among the states that landed there.
    marks: Vec<AtomicU8>,
    /// Probabilities before the move (adaptive sampling's, carried by the states).
    probability: Vec<f32>,
    /// The states hold this view's samples (false after the technique was off).
    pub valid: bool,
    /// This frame follows a reprojection: its accumulation runs the aliasing test.
    pub after_move: bool,
    /// This epoch began with a reprojection (its pixels without history are holes).
    pub carried: bool,
    repair: Repair,
}

const NO_CLAIM: u64 = u64::MAX;

/// The source state of a claim, if any.
#[inline]
fn winner(claim: u64) -> Option<usize> {
    (claim != NO_CLAIM).then_some((claim & 0xffff_ffff) as usize)
}

/// Pixels per parallel task of the passes here.
const CHUNK: usize = 256;

/// The quarter of its pixel (0 to 3: left/right, then top/bottom) of film position `f`.
#[inline]
fn quadrant(f: Vec2) -> usize {
    usize::from(f.x.fract() >= 0.5) + 2 * usize::from(f.y.fract() >= 0.5)
}

/// The history of a pixel: the merge of its states' samples, each sample weighing the same
/// (module docs).
#[inline]
fn merged<'a>(slots: impl IntoIterator<Item = &'a Slot>) -> PixelStats {
    let mut h = PixelStats::default();
    for s in slots {
        h.merge(&s.stats);
    }
    h
}

/// Whether the new camera rays through pixel `t` and its 8 neighbours (of `pixels`, `w`
/// wide) all see `plane`'s surface (the aliasing test's criterion). A state that lands on a
/// pixel next to another surface in the new view lies on one of its edges, where its
/// footprint's single surface is not all the pixel sees. (The diagonal neighbours count: a
/// surface that covers only a corner of the pixel reaches the diagonal neighbour's ray first.)
#[inline]
fn inside(plane: &Plane, pixels: &[GPixel], t: usize, w: usize, tolerance: f32) -> bool {
    let rows = pixels.len() / w;
    let (x, y) = (t % w, t / w);
    let (x0, x1) = (x.saturating_sub(1), (x + 1).min(w - 1));
    (y.saturating_sub(1)..=(y + 1).min(rows - 1)).all(|v| {
        pixels[v * w + x0..=v * w + x1]
            .iter()
            .all(|g| plane.agrees(g, tolerance))
    })
}

impl Reprojection {
    pub const VIEWS: &'static [View] = &[
        View {
            name: "reprojected",
            about: "which pixels kept their history at the last camera move (white: all their \
                    states, grey: some of the 4, black: none)",
            kind: ViewKind::Unit,
        },
        View {
            name: "rejection",
            about: "what happened at the last camera move, per pixel: kept (green), newly seen \
                    (black), occluded (red), view-dependency error (yellow), specular (blue), \
                    mixed (orange), aliasing depth test (magenta)",
            kind: ViewKind::Painted,
        },
    ];

    /// At a new epoch, after `change` (with seed 000's techniques on; `resized`: the frame's
    /// buffers changed size): after a move of the camera alone, from `previous` to the frame's
    /// camera, the reprojection pass carries the states, the history and adaptive sampling's
    /// `probability` into the new view (returns what it did; the pass's time is the frame's);
    /// otherwise the states start afresh (or are marked stale with the technique off).
    #[allow(clippy::too_many_arguments)]
    pub fn start_epoch(
        &mut self,
        world: &World,
        config: &ReprojectionConfig,
        accumulate: bool,
        change: Change,
        resized: bool,
        previous: Option<&Camera>,
        frame: &mut FrameState,
        probability: &mut [f32],
    ) -> Option<ReprojectionReport> {
        let t = std::time::Instant::now();
        let n = frame.history.len();
        let k = config.samples as usize;
        self.after_move = false;
        self.carried = false;
        if !config.enabled {
            self.valid = false;
            return None;
        }
        let carry = accumulate
            && change == Change::Camera
            && self.valid
            && self.samples == k
            && !resized
            && probability.len() == n;
        let (Some(previous), Some(camera), true) = (previous, frame.camera.as_ref(), carry) else {
            self.reset(n, k);
            return None;
        };
        let report = self.reproject(
            world,
            previous,
            camera,
            frame.gbuffer.width,
            config,
            &mut frame.history,
            probability,
        );
        (self.after_move, self.carried) = (true, true);
        frame.times.since(REPROJECT, t);
        Some(report)
    }

    /// With `fresh_spp`, between the lighting and accumulation passes of an epoch that began
    /// with a move: traces the samples pixels lack ([`Repair`]); returns the rays traced.
    pub fn repair(
        &mut self,
        config: &ReprojectionConfig,
        frame: &mut FrameState,
        tracer: &PathTracer,
    ) -> u64 {
        if !(config.enabled && self.carried && config.fresh_spp > 0) {
            return 0;
        }
        let mut repair = std::mem::take(&mut self.repair);
        let rays = repair.run(
            self,
            &frame.history,
            &mut frame.lighting,
            &frame.gbuffer,
            config.fresh_spp,
            config.depth_tolerance,
            self.after_move,
            frame.previous_camera.as_ref(),
            tracer,
        );
        self.repair = repair;
        rays
    }

    /// The accumulation pass with `config` over the frame: the frame's samples into the
    /// states and the history (the aliasing test on the frame after a move, whose `report`
    /// counts what it dropped); ends the frame after a move.
    pub fn accumulate_frame(
        &mut self,
        world: &World,
        config: &ReprojectionConfig,
        frame: &mut FrameState,
        probability: &mut [f32],
        report: Option<&mut ReprojectionReport>,
    ) {
        let camera = frame.camera.as_ref().expect("a frame's camera");
        let dropped = self.accumulate(
            world,
            camera,
            &frame.gbuffer,
            &frame.lighting,
            config.depth_tolerance,
            self.after_move,
            &mut frame.history,
            probability,
        );
        if let Some(r) = report {
            r.aliasing = dropped;
            r.kept -= dropped;
        }
        self.after_move = false;
    }

    /// Empties every state, for `pixels` pixels of `samples` states.
    pub fn reset(&mut self, pixels: usize, samples: usize) {
        self.samples = samples;
        let n = pixels * samples;
        for buffer in [&mut self.slots.current, &mut self.slots.previous] {
            buffer.clear();
            buffer.resize(n, Slot::default());
        }
        self.claims.resize_with(n, || AtomicU64::new(NO_CLAIM));
        self.marks.resize_with(pixels, || AtomicU8::new(0));
        self.fates.clear();
        self.fates.resize(pixels, Fate::New as u8);
        self.kept.clear();
        self.kept.resize(pixels, 0);
        self.valid = true;
    }

    /// Bytes held (states, claims, marks, fates, scratch, the repair's buffers).
    pub fn bytes(&self) -> usize {
        self.repair.bytes()
            + self.slots.bytes()
            + self.claims.capacity() * 8
            + self.marks.capacity()
            + self.fates.capacity()
            + self.kept.capacity()
            + self.probability.capacity() * 4
    }

    /// The reprojection pass: moves every state seen by `from` into the view of `to` (both for
    /// images of `width` x `height`, the size the states were made for) and rebuilds each
    /// pixel's `history` from its states; carries adaptive sampling's `probability` (a pixel
    /// takes the largest its states bring, [`NO_PROBABILITY`] when none brings one).
    #[allow(clippy::too_many_arguments)]
    pub fn reproject(
        &mut self,
        world: &World,
        from: &Camera,
        to: &Camera,
        width: u32,
        config: &ReprojectionConfig,
        history: &mut [PixelStats],
        probability: &mut [f32],
    ) -> ReprojectionReport {
        let height = history.len() / (width as usize).max(1);
        let mut report = self.claim(world, from, to, width as usize, height, config);
        let kept_states = self.take_claims(history, probability);
        self.slots.swap();
        report.collisions = report.kept - kept_states;
        report.kept = kept_states;
        report
    }

    /// The reprojection pass's first half: every state seen by `from` projected into the
    /// view of `to` (`w` x `h` pixels) and checked; a survivor claims its target (the
    /// nearest wins), the others mark it with their fate. Returns the counts.
    fn claim(
        &self,
        world: &World,
        from: &Camera,
        to: &Camera,
        w: usize,
        h: usize,
        config: &ReprojectionConfig,
    ) -> ReprojectionReport {
        let k = self.samples;
        let (eye_from, eye_to) = (from.position(), to.position());
        let (claims, marks) = (&self.claims, &self.marks);
        let mark = |t: usize, fate: Fate| {
            marks[t].fetch_max(fate as u8, Ordering::Relaxed);
        };
        // Each state: its target and the checks; then the occlusion rays of a chunk's
        // survivors together (rays from one eye into neighbouring pixels: coherent packets);
        // then a claim on the target (nearest wins).
        let tolerance = config.occlusion_tolerance;
        let trace_rays = config.occlusion_rays && eye_from != eye_to;
        self.slots
            .current
            .par_chunks(CHUNK)
            .enumerate()
            .map_init(
                || {
                    (
                        Vec::with_capacity(CHUNK),
                        Vec::with_capacity(CHUNK),
                        Vec::new(),
                    )
                },
                |(candidates, rays, hits), (c, chunk)| {
                    let mut r = ReprojectionReport::default();
                    candidates.clear();
                    rays.clear();
                    for (i, s) in chunk.iter().enumerate() {
                        if s.stats.n == 0 {
                            continue;
                        }
                        r.states += 1;
                        let film = if s.is_sky() {
                            to.project_direction(s.point)
                        } else {
                            to.project(s.point)
                        };
                        let Some(f) = film.filter(|f| {
                            f.x >= 0.0 && f.y >= 0.0 && (f.x as usize) < w && (f.y as usize) < h
                        }) else {
                            r.out_of_view += 1;
                            continue;
                        };
                        let t = f.y as usize * w + f.x as usize;
                        if s.is_specular() {
                            mark(t, Fate::Specular);
                            r.specular += 1;
                            continue;
                        }
                        if s.is_mixed() {
                            mark(t, Fate::Mixed);
                            r.mixed += 1;
                            continue;
                        }
                        let error = view_error(s, eye_from, eye_to);
                        if error.is_nan() || error > config.max_error {
                            mark(t, Fate::ViewError);
                            r.view_error += 1;
                            continue;
                        }
                        let q = if k == 4 && !s.is_sky() {
                            quadrant(f)
                        } else {
                            0
                        };
                        let distance = if trace_rays {
                            let (ray, distance) = occlusion_ray(eye_to, s, tolerance);
                            rays.push(ray);
                            distance
                        } else {
                            eye_distance(eye_to, s)
                        };
                        candidates.push((c * CHUNK + i, t, q, distance));
                    }
                    hits.clear();
                    hits.resize(candidates.len(), None);
                    if trace_rays {
                        world.accel.intersect_batch(rays, hits);
                    }
                    for (&(j, t, q, distance), hit) in
                        candidates.iter().zip(hits.iter().map(Option::is_some))
                    {
                        if hit {
                            mark(t, Fate::Occluded);
                            r.occluded += 1;
                        } else {
                            let key = ((distance.to_bits() as u64) << 32) | j as u64;
                            claims[t * k + q].fetch_min(key, Ordering::Relaxed);
                            r.kept += 1;
                        }
                    }
                    r
                },
            )
            .reduce(ReprojectionReport::default, ReprojectionReport::add)
    }

    /// The reprojection pass's second half: each target takes its winning states (into the
    /// scratch buffer), rebuilds its `history` from them and takes the largest `probability`
    /// they bring. Returns the states kept.
    fn take_claims(&mut self, history: &mut [PixelStats], probability: &mut [f32]) -> u64 {
        let k = self.samples;
        // Each target takes its winning states, and the largest probability they bring. The
        // claims and marks are this pass's alone now: plain loads and stores, not locked swaps.
        self.probability.clear();
        self.probability.extend_from_slice(probability);
        let (source, before) = (&self.slots.current, &self.probability);
        self.slots
            .previous
            .par_chunks_mut(k * CHUNK)
            .zip(self.claims.par_chunks_mut(k * CHUNK))
            .zip(self.marks.par_chunks_mut(CHUNK))
            .zip(history.par_chunks_mut(CHUNK))
            .zip(probability.par_chunks_mut(CHUNK))
            .zip(self.fates.par_chunks_mut(CHUNK))
            .zip(self.kept.par_chunks_mut(CHUNK))
            .map(
                |((((((targets, claims), marks), hist), prob), fates), kept)| {
                    let mut count = 0;
                    let pixels = hist
                        .iter_mut()
                        .zip(prob.iter_mut())
                        .zip(fates.iter_mut().zip(kept))
                        .zip(marks.iter_mut().zip(claims.chunks_mut(k)));
                    for (slots, (((h, prob), (fate, kept)), (mark, claims))) in
                        targets.chunks_mut(k).zip(pixels)
                    {
                        let mut n = 0;
                        *prob = NO_PROBABILITY;
                        for (slot, claim) in slots.iter_mut().zip(claims) {
                            let claim = std::mem::replace(claim.get_mut(), NO_CLAIM);
                            *slot = match winner(claim) {
                                None => Slot::default(),
                                Some(j) => {
                                    n += 1;
                                    *prob = prob.max(before[j / k]);
                                    // Its point stays where it is: re-centred on the pixel it
                                    // landed in, a state would lose the fraction of a pixel it
                                    // moved at every step, and under small steps never move.
                                    let mut slot = source[j];
                                    slot.set(CARRIED, true);
                                    slot
                                }
                            };
                        }
                        let mark = std::mem::take(mark.get_mut());
                        *fate = if n > 0 { Fate::Kept as u8 } else { mark };
                        *kept = n;
                        *h = merged(slots.iter());
                        count += n as u64;
                    }
                    count
                },
            )
            .sum()
    }
}

/// A carried state of a pixel sampled this frame that the sample disagrees with (`seen`:
/// its plane agrees with the new G-buffer pixel), or that was marked mixed: its old
/// footprint's surface is not all this pixel sees (a carried quarter's place in its new pixel
/// is only approximate). The accumulation pass drops it.
#[inline]
fn carried_disagrees(s: &Slot, seen: bool) -> bool {
    s.is_mixed() || !seen
}

impl Reprojection {
    /// The samples the states of pixel `pixel`, sampled this frame, keep through the
    /// accumulation pass (before its new samples are merged): what the aliasing test (on
    /// the frame after a move) and the disagreement of carried states leave. `pixels` is the
    /// frame's whole G-buffer, `w` its width.
    pub fn kept_by_sampled(
        &self,
        pixel: usize,
        pixels: &[GPixel],
        w: usize,
        tolerance: f32,
        after_move: bool,
    ) -> u32 {
        let k = self.samples;
        let g = &pixels[pixel];
        self.slots.current[pixel * k..pixel * k + k]
            .iter()
            .filter(|s| {
                if s.stats.n == 0 {
                    return false;
                }
                let plane = s.plane();
                let seen = plane.agrees(g, tolerance);
                if after_move && !(seen && inside(&plane, pixels, pixel, w, tolerance)) {
                    return false;
                }
                !(s.is_carried() && carried_disagrees(s, seen))
            })
            .map(|s| s.stats.n)
            .sum()
    }

    /// The statistics pixel `pixel` keeps after the aliasing depth test against its new
    /// G-buffer pixel `g` (what the accumulation pass will leave of its states).
    #[inline]
    pub fn surviving(&self, pixel: usize, g: &GPixel, tolerance: f32) -> PixelStats {
        let k = self.samples;
        merged(
            self.slots.current[pixel * k..pixel * k + k]
                .iter()
                .filter(|s| s.stats.n > 0 && s.plane().agrees(g, tolerance)),
        )
    }

    /// The fate of pixel `pixel` at the last move.
    pub fn fate(&self, pixel: usize) -> Fate {
        Fate::from_u8(self.fates.get(pixel).copied().unwrap_or(0))
    }

    /// The accumulation pass: on the frame after a move (`after_move`) first drops the
    /// states that fail the aliasing depth test (of tolerance `tolerance`), then merges each
    /// pixel's new samples into the state of the quadrant its first hit projects into
    /// (starting the state from this frame's G-buffer and first bounce when it was empty),
    /// and rebuilds the pixel's history. A pixel that loses all its states to the test loses
    /// the probability they brought too. A carried state that a later sample of its quadrant
    /// disagrees with is dropped too. Returns the states dropped.
    #[allow(clippy::too_many_arguments)]
    pub fn accumulate(
        &mut self,
        world: &World,
        camera: &Camera,
        gbuffer: &super::gbuffer::GBuffer,
        lighting: &[LightSample],
        tolerance: f32,
        after_move: bool,
        history: &mut [PixelStats],
        probability: &mut [f32],
    ) -> u64 {
        let k = self.samples;
        let w = gbuffer.width.max(1) as usize;
        let materials = &world.scene.materials;
        self.slots
            .current
            .par_chunks_mut(k * CHUNK)
            .zip(gbuffer.pixels.par_chunks(CHUNK))
            .zip(lighting.par_chunks(CHUNK))
            .zip(
                history
                    .par_chunks_mut(CHUNK)
                    .zip(probability.par_chunks_mut(CHUNK)),
            )
            .zip(
                self.fates
                    .par_chunks_mut(CHUNK)
                    .zip(self.kept.par_chunks_mut(CHUNK)),
            )
            .enumerate()
            .map(|(c, ((((slots, gs), ls), (hs, ps)), (fates, kept)))| {
                let mut dropped = 0;
                let pixels = gs
                    .iter()
                    .zip(ls)
                    .zip(hs.iter_mut().zip(ps))
                    .zip(fates.iter_mut().zip(kept));
                for (p, (slots, (((g, l), (h, prob)), (fate, kept)))) in
                    slots.chunks_mut(k).zip(pixels).enumerate()
                {
                    let t = c * CHUNK + p;
                    let sampled = l.stats.n > 0;
                    let q = if sampled && k == 4 && !g.is_sky() {
                        camera.project(g.position).map_or(0, quadrant)
                    } else {
                        0
                    };
                    for (i, s) in slots.iter_mut().enumerate() {
                        if s.stats.n == 0 {
                            continue;
                        }
                        let plane = s.plane();
                        let seen = plane.agrees(g, tolerance);
                        if after_move {
                            let edge = seen && !inside(&plane, &gbuffer.pixels, t, w, tolerance);
                            if edge && !sampled {
                                // Not sampled this frame (adaptive sampling): kept for now,
                                // dropped by the pixel's next sample.
                                s.set(MIXED, true);
                            } else if edge || !seen {
                                *s = Slot::default();
                                dropped += 1;
                                *kept -= 1;
                                if *kept == 0 {
                                    *fate = Fate::Aliasing as u8;
                                    *prob = NO_PROBABILITY;
                                }
                                continue;
                            }
                        }
                        if !sampled {
                            continue;
                        }
                        if s.is_carried() {
                            if carried_disagrees(s, seen) {
                                *s = Slot::default();
                                dropped += 1;
                            }
                        } else if i == q && !seen {
                            s.set(MIXED, true);
                        }
                    }
                    if sampled {
                        let s = &mut slots[q];
                        if s.stats.n == 0 {
                            let film = centre(t, w, q, k);
                            *s = Slot::start(g, &l.bounce, materials.get(g.material as usize));
                            s.point = if s.is_sky() {
                                camera.primary_ray(film, Vec2::splat(0.5)).direction
                            } else {
                                snap(camera, film, s.point, g.normal)
                            };
                        }
                        s.add(l);
                    }
                    *h = merged(slots.iter());
                }
                dropped
            })
            .sum()
    }
}

/// Where the camera ray through film position `film` meets the plane through `point` with
/// normal `normal`: a state's point as seen from its pixel's (or quadrant's) centre. `point`
/// itself where the ray grazes the plane or meets it far (a quarter of the distance) from it.
#[inline]
fn snap(camera: &Camera, film: Vec2, point: Vec3, normal: Vec3) -> Vec3 {
    let ray = camera.primary_ray(film, Vec2::splat(0.5));
    let to_point = point - ray.origin;
    let cos = normal.dot(ray.direction);
    if cos.is_nan() || cos.abs() <= 1e-3 {
        return point;
    }
    let t = normal.dot(to_point) / cos;
    let p = ray.origin + ray.direction * t;
    if t > 0.0 && (p - point).length_squared() <= 0.0625 * to_point.length_squared() {
        p
    } else {
        point
    }
}

/// The centre of quadrant `q` of pixel `t` (of an image `w` wide) with `k` states per pixel
/// (the pixel's centre with one).
#[inline]
fn centre(t: usize, w: usize, q: usize, k: usize) -> Vec2 {
    let pixel = Vec2::new((t % w) as f32, (t / w) as f32);
    if k == 4 {
        pixel + Vec2::new(0.25 + 0.5 * (q & 1) as f32, 0.25 + 0.5 * (q >> 1) as f32)
    } else {
        pixel + 0.5
    }
}

/// The distance from a camera at `eye` to `slot`'s stored point (infinite for the sky): the
/// key by which the nearest of the states that land on one target wins.
#[inline]
fn eye_distance(eye: Vec3, slot: &Slot) -> f32 {
    if slot.is_sky() {
        return f32::INFINITY;
    }
    let distance = (slot.point - eye).length();
    // At the eye (or not finite): nearest of all.
    if distance > 0.0 {
        distance
    } else {
        0.0
    }
}

/// The ray from a camera at `eye` towards `slot`'s stored point (stopping `tolerance` of the
/// distance short of it; for the sky, unbounded in its direction), and the distance (infinite
/// for the sky). Anything it hits hides the point.
#[inline]
fn occlusion_ray(eye: Vec3, slot: &Slot, tolerance: f32) -> (Ray, f32) {
    let distance = eye_distance(eye, slot);
    if slot.is_sky() {
        return (Ray::new(eye, slot.point), distance);
    }
    if distance == 0.0 {
        // At the eye: nothing can hide it (an empty segment).
        return (Ray::segment(eye, Vec3::Z, 0.0, 0.0), 0.0);
    }
    let d = slot.point - eye;
    let ray = Ray::segment(eye, d / distance, 0.0, distance * (1.0 - tolerance));
    (ray, distance)
}

/// Reprojection with `fresh_spp`, between the lighting and accumulation passes: a pixel
/// sampled this frame (or any pixel in the frame of a move) whose states the accumulation
/// pass will drop (the aliasing test after a
/// move, a carried state its new sample disagrees with) would be left with this frame's
/// samples alone, one where a hole takes `fresh_spp` (the lighting pass counted the states
/// before the test, which needs the neighbours' G-buffer pixels). This pass traces the
/// samples such pixels lack and merges them into their lighting, so that they show
/// `fresh_spp` samples in this frame rather than in the next.
#[derive(Debug, Default)]
pub struct Repair {
    /// Samples each pixel lacks (0: none).
    need: Vec<u32>,
    gbuffer: GBuffer,
    lighting: Vec<LightSample>,
}

impl Repair {
    /// Counts the missing samples, traces them and merges them into `lighting`; returns the
    /// rays traced.
    #[allow(clippy::too_many_arguments)]
    fn run(
        &mut self,
        reprojection: &Reprojection,
        history: &[PixelStats],
        lighting: &mut [LightSample],
        gbuffer: &GBuffer,
        fresh: u32,
        tolerance: f32,
        after_move: bool,
        previous: Option<&Camera>,
        tracer: &PathTracer,
    ) -> u64 {
        let w = gbuffer.width.max(1) as usize;
        self.need.resize(lighting.len(), 0);
        let missing: u64 = self
            .need
            .par_iter_mut()
            .zip(lighting.par_iter())
            .enumerate()
            .map(|(p, (need, l))| {
                // A pixel not sampled has no G-buffer pixel of this frame to test, except in
                // the frame of a move, where every pixel is traced (the combination's carried
                // pixels wait then, and their states may be dropped all the same).
                *need = if l.stats.n == 0 && !after_move {
                    0
                } else {
                    let kept =
                        reprojection.kept_by_sampled(p, &gbuffer.pixels, w, tolerance, after_move);
                    fresh.saturating_sub(kept + l.stats.n)
                };
                u64::from(*need)
            })
            .sum();
        if missing == 0 {
            return 0;
        }
        self.gbuffer.resize(gbuffer.width, gbuffer.height);
        self.lighting.resize(lighting.len(), LightSample::default());
        let plan = Missing {
            need: &self.need,
            history,
            lighting,
        };
        let rays = trace::fused(
            &mut self.gbuffer,
            &mut self.lighting,
            previous,
            tracer,
            &plan,
        )
        .rays;
        lighting
            .par_iter_mut()
            .zip(self.lighting.par_iter())
            .zip(self.need.par_iter())
            .for_each(|((l, extra), &need)| {
                if need > 0 {
                    l.stats.merge(&extra.stats);
                }
            });
        rays
    }

    fn bytes(&self) -> usize {
        use std::mem::size_of;
        self.need.capacity() * size_of::<u32>()
            + self.gbuffer.pixels.capacity() * size_of::<GPixel>()
            + self.lighting.capacity() * size_of::<LightSample>()
    }
}

/// [`Repair`]'s pixels: the samples they lack, continuing their sample sequences after this
/// frame's.
struct Missing<'a> {
    need: &'a [u32],
    history: &'a [PixelStats],
    lighting: &'a [LightSample],
}

impl Plan for Missing<'_> {
    #[inline]
    fn sample(&self, pixel: usize) -> Option<u32> {
        (self.need[pixel] > 0).then(|| self.history[pixel].n + self.lighting[pixel].stats.n)
    }

    #[inline]
    fn keep(&self, pixel: usize, _: &GPixel) -> u32 {
        self.need[pixel]
    }
}

impl Stage for Reprojection {
    fn name(&self) -> &'static str {
        REPROJECT
    }

    fn views(&self) -> &'static [View] {
        Self::VIEWS
    }

    /// The fraction of the pixel's states kept at the last move (`reprojected`); its
    /// [`Fate`] as a number (`rejection`).
    fn value(&self, _: &FrameState, view: usize, i: usize) -> Vec3 {
        if view == 0 {
            let kept = self.kept.get(i).copied().unwrap_or(0);
            Vec3::splat(kept as f32 / self.samples.max(1) as f32)
        } else {
            Vec3::splat(self.fate(i) as u8 as f32)
        }
    }

    fn paint(&self, _: &FrameState, _: usize, i: usize) -> [u8; 3] {
        self.fate(i).colour()
    }

    fn bytes(&self) -> usize {
        Reprojection::bytes(self)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use pathlight_core::rng::Rng;
    use std::f32::consts::PI;

    fn slot(f0: f32, f90: f32, alpha: f32) -> Slot {
        Slot {
            stats: PixelStats::one(Vec3::ONE, Vec3::ZERO),
            irradiance: Vec3::ONE,
            ..Slot::surface(
                Vec3::ZERO,
                Vec3::Z,
                Vec3::new(0.3, 0.0, 1.0).normalize(),
                Vec3::ONE,
                [alpha, f0, f90],
                0,
            )
        }
    }

    #[test]
    fn packed_fields_read_back_within_their_precision() {
        let mut rng = Rng::new(11, 0);
        for _ in 0..10_000 {
            let v = Vec3::new(
                rng.next_f32() * 2.0 - 1.0,
                rng.next_f32() * 2.0 - 1.0,
                rng.next_f32() * 2.0 - 1.0,
            );
            if v.length() < 1e-3 {
                continue;
            }
            let v = v.normalize();
            let back = from_octahedral(octahedral(v));
            // 16 bits per coordinate: within 1e-4 radians.
            assert!((back - v).length() < 1e-4, "{v} read back as {back}");
            let u = [rng.next_f32(), rng.next_f32(), rng.next_f32()];
            let s = Slot::surface(Vec3::ONE, v, -v, Vec3::from_array(u), u, 3);
            let (albedo, lobe) = (s.albedo().to_array(), s.lobe());
            for i in 0..3 {
                assert!((albedo[i] - u[i]).abs() <= 1.0 / 131_070.0 + 1e-7);
                assert!((lobe[i] - u[i]).abs() <= 1.0 / 131_070.0 + 1e-7);
            }
            assert!((s.direction() + v).length() < 1e-4);
        }
        // The axes and their opposites exactly; a path that ended keeps no direction.
        for v in [Vec3::X, Vec3::Y, Vec3::Z, -Vec3::X, -Vec3::Y, -Vec3::Z] {
            assert_eq!(from_octahedral(octahedral(v)), v);
        }
        let ended = Slot::surface(Vec3::ZERO, Vec3::Z, Vec3::ZERO, Vec3::ONE, [0.5; 3], 0);
        assert_eq!(ended.direction(), Vec3::ZERO);
        assert!(!ended.is_sky() && !ended.is_specular() && !ended.is_carried());
    }

    #[test]
    fn reflection_at_normal_incidence_is_beckmanns_peak() {
        // i = o = n: h = n, D = 1 / (pi alpha^2), Lambda(n) = 0 so G = 1, F = f0.
        for (alpha, f0) in [(0.1, 0.04), (0.5, 1.0), (0.02, 0.5)] {
            let f = reflection(Vec3::Z, Vec3::Z, Vec3::Z, alpha, f0, 1.0);
            let expected = f0 / (4.0 * PI * alpha * alpha);
            assert!((f - expected).abs() < 1e-4 * expected, "{f} vs {expected}");
        }
    }

    #[test]
    fn reflection_is_reciprocal_and_conserves_energy() {
        let mut rng = Rng::new(3, 0);
        let n = Vec3::Z;
        for _ in 0..100 {
            let mut dir = || {
                let (u, v) = (rng.next_f32(), rng.next_f32());
                let r = (1.0 - u * u).max(0.0).sqrt();
                Vec3::new(r * (2.0 * PI * v).cos(), r * (2.0 * PI * v).sin(), u)
            };
            let (i, o) = (dir(), dir());
            let (a, b) = (
                reflection(i, o, n, 0.3, 0.2, 1.0),
                reflection(o, i, n, 0.3, 0.2, 1.0),
            );
            assert!((a - b).abs() <= 1e-5 * a.max(1.0), "{a} vs {b}");
        }
        // Directional albedo at normal incidence of a perfect reflector (F = 1), by uniform
        // hemisphere sampling: at most 1, and close to it for a smooth surface (Smith's
        // masking loses a few percent at grazing angles only).
        let mut rng = Rng::new(5, 1);
        for (alpha, low) in [(0.2, 0.95), (0.5, 0.85)] {
            let count = 200_000;
            let mut sum = 0.0f64;
            for _ in 0..count {
                let (u, v) = (rng.next_f32(), rng.next_f32());
                let r = (1.0 - u * u).max(0.0).sqrt();
                let o = Vec3::new(r * (2.0 * PI * v).cos(), r * (2.0 * PI * v).sin(), u);
                sum += f64::from(reflection(Vec3::Z, o, n, alpha, 1.0, 1.0) * u * 2.0 * PI);
            }
            let albedo = sum / count as f64;
            assert!(
                albedo > low && albedo < 1.01,
                "alpha {alpha}: albedo {albedo}"
            );
        }
    }

    #[test]
    fn the_view_error_vanishes_without_a_move_a_lobe_or_a_surface() {
        let glossy = slot(0.04, 1.0, 0.1);
        let (a, b) = (Vec3::new(0.0, 0.0, 3.0), Vec3::new(1.0, 0.0, 3.0));
        assert_eq!(view_error(&glossy, a, a), 0.0);
        assert!(view_error(&glossy, a, b) > 1.0 / 256.0);
        // Lambertian (no specular layer): view independent.
        assert_eq!(view_error(&slot(0.0, 0.0, 0.1), a, b), 0.0);
        let mut sky = glossy;
        sky.set(SKY, true);
        assert_eq!(view_error(&sky, a, b), 0.0);
        // Scales with what arrives along L and the base colour.
        let dim = Slot {
            irradiance: Vec3::splat(0.5),
            ..glossy
        };
        let e = view_error(&glossy, a, b);
        assert!((view_error(&dim, a, b) - 0.5 * e).abs() < 1e-6 * e);
    }

    #[test]
    fn only_smooth_lobes_and_transmission_count_as_specular() {
        let g = |roughness: f32, metallic: f32| GPixel {
            roughness,
            metallic,
            material: 0,
            ..GPixel::default()
        };
        let bounce = Bounce::default();
        let lambert = Material {
            roughness: 0.0,
            specular: 0.0,
            ..Material::default()
        };
        let plastic = Material {
            specular: 1.0,
            ..Material::default()
        };
        let glass = Material {
            transmission: 1.0,
            specular: 1.0,
            roughness: 0.5,
            ..Material::default()
        };
        assert!(!Slot::start(&g(0.0, 0.0), &bounce, Some(&lambert)).is_specular());
        assert!(
            Slot::start(&g(0.0, 1.0), &bounce, Some(&lambert)).is_specular(),
            "a mirror"
        );
        assert!(Slot::start(&g(0.05, 0.0), &bounce, Some(&plastic)).is_specular());
        assert!(!Slot::start(&g(0.2, 0.0), &bounce, Some(&plastic)).is_specular());
        assert!(Slot::start(&g(0.5, 0.0), &bounce, Some(&glass)).is_specular());
    }
}
