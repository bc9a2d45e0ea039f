//! Which pixels a frame traces and from which sample index: the plain pipeline's [`Uniform`]
//! plan (every pixel, one sample index for all), or seed 000's [`Planned`] one, where each
//! pixel continues its own sample sequence, adaptive sampling ([`super::adaptive`]) picks the
//! pixels, and forward reprojection ([`super::reprojection`]) decides what the frame after a
//! move takes (their combination is the thesis's Algorithm 2).

use super::accumulation::PixelStats;
use super::adaptive::{Schedule, NO_PROBABILITY};
use super::gbuffer::GPixel;
use super::reprojection::Reprojection;
use super::trace::{Plan, Uniform};

/// A frame's plan.
pub enum FramePlan<'a> {
    /// Every pixel alike.
    Uniform(Uniform),
    /// Seed 000's techniques.
    Planned(Planned<'a>),
}

/// Runs `$body` with `$plan` bound to the frame plan's concrete [`Plan`] (the passes are
/// generic over it, so that the plain pipeline's loops carry no per-pixel bookkeeping).
macro_rules! with_plan {
    ($frame_plan:expr, $plan:ident => $body:expr) => {
        match $frame_plan {
            $crate::frame::plan::FramePlan::Uniform($plan) => $body,
            $crate::frame::plan::FramePlan::Planned($plan) => $body,
        }
    };
}
pub(crate) use with_plan;

/// Seed 000's techniques: each pixel continues its own sample sequence; adaptive sampling
/// picks the pixels.
pub struct Planned<'a> {
    pub history: &'a [PixelStats],
    pub probability: &'a [f32],
    pub schedule: Option<Schedule<'a>>,
    /// The frame after a reprojection, with the aliasing test's tolerance: every pixel gets
    /// its primary ray (the test needs the new G-buffer), and adaptive sampling decides on
    /// the states that survive the test.
    pub after_move: Option<(&'a Reprojection, f32)>,
    /// Forward reprojection is on: its states need the radiance along the first bounce.
    pub reprojection: bool,
    /// Samples per pixel per frame.
    pub spp: u32,
    /// In an epoch that began with a reprojection: a pixel holding fewer samples takes the
    /// missing ones at once (`fresh_spp`; 0: off).
    pub fresh: u32,
}

impl Planned<'_> {
    /// The samples a pixel the primary pass traced takes, outside the frame after a move:
    /// `spp`, or `spp` for each of the schedule's iterations that sample it when a frame runs
    /// several ([`AdaptiveConfig::budget`](super::adaptive::AdaptiveConfig::budget)).
    #[inline]
    fn scheduled(&self, pixel: usize) -> u32 {
        match &self.schedule {
            Some(s) if s.end > s.iteration + 1 || s.scale > 0.0 => {
                self.spp * s.count(pixel, &self.history[pixel], self.probability[pixel])
            }
            _ => self.spp,
        }
    }
}

impl Plan for Planned<'_> {
    fn along_first_bounce(&self) -> bool {
        self.reprojection
    }

    #[inline]
    fn sample(&self, pixel: usize) -> Option<u32> {
        let h = &self.history[pixel];
        match &self.schedule {
            Some(s) if self.after_move.is_none() => {
                s.wants(pixel, h, self.probability[pixel]).then_some(h.n)
            }
            _ => Some(h.n),
        }
    }

    #[inline]
    fn keep(&self, pixel: usize, g: &GPixel) -> u32 {
        if self.fresh == 0 && (self.schedule.is_none() || self.after_move.is_none()) {
            return self.scheduled(pixel);
        }
        let surviving = self
            .after_move
            .map(|(reprojection, tolerance)| reprojection.surviving(pixel, g, tolerance));
        let h = surviving.as_ref().unwrap_or(&self.history[pixel]);
        if h.n < self.fresh {
            return (self.fresh - h.n).max(self.spp);
        }
        let (Some(s), Some(_)) = (&self.schedule, self.after_move) else {
            return self.scheduled(pixel);
        };
        let p = if h.n == 0 {
            NO_PROBABILITY
        } else {
            self.probability[pixel]
        };
        if s.wants(pixel, h, p) {
            self.spp
        } else {
            0
        }
    }
}
