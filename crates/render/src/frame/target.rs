//! The frame-time target (issue 60, `[frame] target_ms`): the frame holds a frame time by
//! choosing its render scale (temporal upsampling's, [`super::upsample`]) frame by frame.
//!
//! It follows the frames' times smoothed (an exponential mean, a fifth of each new frame), and
//! steps the scale along [`STEPS`]: down when the smoothed time is over the target, to the
//! first step at which the time predicted is within [`HEADROOM`] of it (at most every
//! [`DOWN_AFTER`] frames, so a step's effect is seen first); up one step when the time
//! predicted there is within [`HEADROOM`] too, at most every [`UP_AFTER`] frames. The
//! headroom leaves the frames that take longer than the mean (a new part of the scene coming
//! into view, the host's own hiccups) under the target. Both predictions err on the safe
//! side of a frame made of a part that scales with the render's pixels and a part that does
//! not (the texture-space cache's cells, the upsampling at the output size): down, the
//! smoothed time times the ratio of the scales (as if half of it did not scale), up, times
//! the ratio of the pixel counts (as if all of it did). So a step up does not land over the
//! target (unless the frame's cost itself changes), which with the wait upwards keeps it
//! from oscillating. A step is a new render
//! size: the stages that keep per-pixel state at the render size start afresh, the output's
//! history and the texture-space cache do not ([`super::state::Change::Scale`]).
//!
//! With `target_ms = 0` it does nothing, and the scale is the configuration's.

/// The targets accepted, in ms (0: none): what `validate()` checks and the viewer's slider
/// spans.
pub const TARGET_MS: std::ops::RangeInclusive<f32> = 0.0..=1000.0;

/// The target the real-time commands (`view`, `play`, `bench frame`) hold when they run the
/// preset the scene's lights choose (no configuration given): 30 frames a second. A
/// configuration file, `--plain` or a technique's flag runs as written (`target_ms` 0 unless it
/// sets one), and `--target-ms 0` turns it off.
pub const DEFAULT_MS: f32 = 33.0;

/// The render scales the target steps through, largest first, down to upsampling's smallest
/// (a frame whose part that does not shrink with its pixels is near the target needs the
/// last steps: the interior at 640x360, whose upsampling pass alone takes a third of it).
pub const STEPS: [f32; 8] = [
    1.0,
    0.85,
    0.7,
    0.6,
    0.5,
    0.4,
    0.3,
    super::upsample::MIN_SCALE,
];
/// Frames after a step before the next step down.
pub const DOWN_AFTER: u32 = 2;
/// The fraction of the target a step aims at (its time predicted).
pub const HEADROOM: f64 = 0.9;
/// Frames after a step before a step up.
pub const UP_AFTER: u32 = 30;

/// The target's state.
#[derive(Debug, Clone, Default)]
pub struct Target {
    /// The index into [`STEPS`] in force.
    step: usize,
    /// The frames' smoothed time (ms); `None` before the first frame that counts.
    smoothed: Option<f64>,
    /// Frames since the last step.
    since: u32,
}

impl Target {
    /// The render scale in force, at most `ceiling` (the configuration's scale).
    pub fn scale(&self, ceiling: f32) -> f32 {
        STEPS[self.step].min(ceiling)
    }

    /// Forgets the frames' times and goes back to the largest scale.
    pub fn reset(&mut self) {
        *self = Self::default();
    }

    /// After a frame that took `ms` (of a target of `target_ms`, the scale at most `ceiling`):
    /// returns the new scale when it steps.
    pub fn after_frame(&mut self, ms: f64, target_ms: f32, ceiling: f32) -> Option<f32> {
        let target = target_ms as f64;
        // (The largest step at or below the ceiling, if the ceiling came down.)
        while self.step + 1 < STEPS.len() && STEPS[self.step + 1] >= ceiling {
            self.step += 1;
        }
        let smoothed = self.smoothed.map_or(ms, |s| s + 0.2 * (ms - s));
        self.smoothed = Some(smoothed);
        self.since = self.since.saturating_add(1);
        let now = self.scale(ceiling);
        // The time predicted at step `to`: the scales' ratio to the power `p` (1 down, 2 up).
        let ratio = |to: usize, p: i32| (STEPS[to].min(ceiling) / now).powi(p) as f64;
        let lower = self.step + 1 < STEPS.len();
        let higher = self.step > 0 && STEPS[self.step - 1].min(ceiling) > now;
        let (to, p) = if lower && self.since >= DOWN_AFTER && smoothed > target {
            // As many steps as the prediction says it takes to fit, one at least.
            let to = (self.step + 1..STEPS.len())
                .find(|&to| smoothed * ratio(to, 1) <= HEADROOM * target)
                .unwrap_or(STEPS.len() - 1);
            (to, 1)
        } else if higher
            && self.since >= UP_AFTER
            && smoothed * ratio(self.step - 1, 2) <= HEADROOM * target
        {
            (self.step - 1, 2)
        } else {
            return None;
        };
        // The smoothed time carried to the new scale, as predicted.
        self.smoothed = Some(smoothed * ratio(to, p));
        (self.step, self.since) = (to, 0);
        Some(self.scale(ceiling))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A frame whose time is `fixed + per_pixel * scale^2` ms.
    fn run(target: &mut Target, frames: usize, mut ms: impl FnMut(f32) -> f64) -> (f32, usize) {
        let mut steps = 0;
        for _ in 0..frames {
            let scale = target.scale(1.0);
            if target.after_frame(ms(scale), 33.0, 1.0).is_some() {
                steps += 1;
            }
        }
        (target.scale(1.0), steps)
    }

    /// A slow frame lowers the scale until it fits; a fast one raises it back to 1.
    #[test]
    fn a_slow_frame_lowers_the_scale_and_a_fast_one_raises_it() {
        let mut t = Target::default();
        let (scale, _) = run(&mut t, 200, |s| 5.0 + 60.0 * (s * s) as f64);
        // 5 + 60 s^2 <= 0.9 * 33 needs s^2 <= 0.41: 0.6 (26.6 ms) is the largest step that
        // fits with the headroom (0.7 would take 34.4 ms). The way down overshoots to 0.4
        // (65 ms at 1, predicted 26 ms at 0.4), the way up climbs back step by step.
        assert_eq!(scale, 0.6);
        let (scale, _) = run(&mut t, 200, |s| 2.0 + 10.0 * (s * s) as f64);
        assert_eq!(scale, 1.0);
    }

    /// Where the frame's time sits between two steps' the scale settles and stays: a few
    /// steps over 1,000 frames, none after the first 100, even with noise.
    #[test]
    fn it_does_not_oscillate() {
        let mut t = Target::default();
        let mut noise = pathlight_core::rng::Rng::new(1, 2);
        let mut ms =
            move |s: f32| (8.0 + 40.0 * (s * s) as f64) * (0.85 + 0.3 * noise.next_f32() as f64);
        let (settled, first) = run(&mut t, 100, &mut ms);
        assert!(first <= 3, "{first} steps");
        let (scale, later) = run(&mut t, 900, &mut ms);
        assert_eq!((scale, later), (settled, 0));
    }

    /// The configuration's scale is the ceiling; a frame already on target keeps it.
    #[test]
    fn the_configured_scale_is_the_ceiling() {
        let mut t = Target::default();
        for _ in 0..100 {
            assert_eq!(t.after_frame(10.0, 33.0, 0.6), None);
        }
        assert_eq!(t.scale(0.6), 0.6);
        // Slow: below it, from the ceiling's time (the second slow frame: smoothed 42.4 ms,
        // predicted 35.3 at 0.5 and 28.3 at 0.4).
        let slow = (0..10).find_map(|_| t.after_frame(100.0, 33.0, 0.6));
        assert_eq!(slow, Some(0.4));
    }
}
