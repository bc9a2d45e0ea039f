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
//! Its rule at a new epoch ([`Reprojection::carry`]): after a change of the camera alone
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

use std::sync::atomic::{AtomicU64, AtomicU8};

use glam::{Vec2, Vec3};
use serde::{Deserialize, Serialize};

use crate::camera::Camera;
use crate::error::ConfigError;
use crate::path::PathTracer;
use crate::world::World;

use super::accumulation::PixelStats;
use super::display::{View, ViewKind};
use super::ping_pong::PingPong;
use super::stage::Stage;
use super::state::{Change, FrameState};

/// The reprojection pass's name (timings, the menu's heading of its views).
mod accumulate;
mod forward;
mod repair;
mod slot;

use repair::Repair;
pub use slot::{reflection, view_error, Slot, SPECULAR_ALPHA};

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
    pub fn carry(
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
        let (gbuffer, w) = (&frame.gbuffer, frame.gbuffer.width.max(1) as usize);
        let (tolerance, after_move) = (config.depth_tolerance, self.after_move);
        let rays = repair.run(
            |p| self.kept_by_sampled(p, &gbuffer.pixels, w, tolerance, after_move),
            &frame.history,
            &mut frame.lighting,
            &frame.gbuffer,
            config.fresh_spp,
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
mod tests;
