//! The history: each pixel's running statistics ([`PixelStats`]) over the epoch's frames, and
//! the accumulation pass that merges a frame's lighting into it.
//!
//! ```text
//! accumulate  lighting, history -> history
//! ```
//!
//! Its rule at a new epoch: a history of the same size is kept as it is and the epoch's first
//! frame overwrites it, except where a stage reads it before that frame's accumulation: with
//! seed 000's techniques each pixel continues its own sample count, so the history is cleared
//! ([`History::clear`]), or carried into the new view by forward reprojection, which then
//! accumulates into its states itself ([`super::reprojection::Reprojection::accumulate`]).

use glam::Vec3;
use pathlight_core::color::luminance;
use rayon::prelude::*;

use super::accumulation::PixelStats;
use super::display::{viridis, View, ViewKind};
use super::lighting::LightSample;
use super::stage::Stage;
use super::state::FrameState;

/// The accumulation pass's name (timings, the menu's heading of the history's views).
pub const ACCUMULATE: &str = "accumulate";

/// The history as a stage (the frame state holds the statistics).
#[derive(Debug, Default)]
pub struct History;

impl History {
    pub const VIEWS: &'static [View] = &[
        View {
            name: "accumulated",
            about: "the accumulated image before the reconstruction filter (its input light)",
            kind: ViewKind::Radiance,
        },
        View {
            name: "direct",
            about: "accumulated direct light (from emitters straight to the first surface)",
            kind: ViewKind::Radiance,
        },
        View {
            name: "indirect",
            about: "accumulated indirect light (everything that bounced more)",
            kind: ViewKind::Radiance,
        },
        View {
            name: "variance",
            about: "relative standard error of the accumulated mean (luminance), as a heat \
                    map 0 to 1",
            kind: ViewKind::Painted,
        },
        View {
            name: "samples",
            about: "samples per pixel accumulated, from black (none) to white (the most)",
            kind: ViewKind::Count,
        },
    ];

    /// The accumulation pass: merges this frame's `lighting` into `history`; the epoch's
    /// `first` frame overwrites it.
    pub fn accumulate(history: &mut [PixelStats], lighting: &[LightSample], first: bool) {
        history
            .par_iter_mut()
            .zip(lighting.par_iter())
            .for_each(|(h, l)| {
                if first {
                    *h = l.stats;
                } else {
                    h.merge(&l.stats);
                }
            });
    }

    /// Empties every pixel's statistics (a new epoch whose pixels keep their own counts).
    pub fn clear(history: &mut [PixelStats]) {
        history.fill(PixelStats::default());
    }

    /// The samples a frame's `lighting` holds, over all pixels.
    pub fn samples(lighting: &[LightSample]) -> u64 {
        lighting.par_iter().map(|l| l.stats.n as u64).sum()
    }

    /// The mean of the pixels' sample counts.
    pub fn mean_samples(history: &[PixelStats]) -> u32 {
        let total: u64 = history.par_iter().map(|h| h.n as u64).sum();
        (total / history.len().max(1) as u64) as u32
    }
}

impl Stage for History {
    fn name(&self) -> &'static str {
        ACCUMULATE
    }

    fn views(&self) -> &'static [View] {
        Self::VIEWS
    }

    /// Radiance; the variance of the accumulated mean (`variance`); the sample count.
    fn value(&self, frame: &FrameState, view: usize, i: usize) -> Vec3 {
        let h = &frame.history[i];
        match view {
            0 => h.mean(),
            1 => h.direct.mean,
            2 => h.indirect.mean,
            3 => h.variance() / h.n.max(1) as f32,
            _ => Vec3::splat(h.n as f32),
        }
    }

    /// `variance`: the standard error over the mean's luminance.
    fn paint(&self, frame: &FrameState, view: usize, i: usize) -> [u8; 3] {
        let v = self.value(frame, view, i);
        let relative =
            luminance(v).max(0.0).sqrt() / (luminance(frame.history[i].mean()).max(0.0) + 1e-3);
        viridis(relative)
    }
}
