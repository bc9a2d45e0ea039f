//! Seed 000's adaptive sampling (Schalk 2018, section 3.1, Algorithm 1): each frame is one
//! *iteration* that gives every pixel at most one new sample (`spp` samples with more per
//! frame), spent where the luminance-scaled deviation of the pixel's samples is large.
//!
//! Per pixel, the accumulation pass already keeps Welford statistics of the samples (Eqs. 9
//! and 10: [`PixelStats`], per channel). From them:
//! - Eq. 11, the pixel variance: the mean over the three channels of `M2 / (n - 1)`;
//! - Eq. 12, `V = (sqrt(Var) + eps) / (L + eps)` with `L` the luminance of the pixel's mean
//!   and `eps` = [`EPSILON`] (the thesis's pseudocode puts `eps` inside the square root, its
//!   Eq. 12 outside; this follows Eq. 12).
//!
//! The schedule, from the last reset (any change of camera or settings) on: iterations
//! `0 .. min_spp` sample every pixel. From iteration `min_spp` a threshold `tau` starts at 1
//! and falls by `1 / (max_spp - min_spp)` per iteration; a pixel is sampled while it has fewer
//! than `min_spp` samples or `V >= tau` (the thesis's pseudocode decrements `tau`; its printed
//! `tau := 1 / (max - min)` is read as `tau -= ...`). At iteration `max_spp` each pixel's
//! probability is fixed at `P = spp / max_spp` (in `[min_spp / max_spp, 1]`), and from then on
//! a pixel is sampled when a uniform random number (hashed from the seed, the pixel and the
//! iteration, so independent of threads) is below `P`, until the next reset. With
//! `min_spp > 0` every pixel keeps a positive probability, so the image still converges.
//!
//! Beyond the thesis, [`AdaptiveConfig::skip_empty`] (on by default): an iteration in which
//! no pixel would take a sample (the threshold still above every pixel's `V`) costs no frame;
//! the next frame runs the first iteration that samples something. The decisions, samples and
//! probabilities are the thesis's (`skipping_empty_iterations_keeps_the_schedules_decisions`
//! in `tests/pipeline.rs`); only the frames that would trace nothing are gone. (With the
//! tone-mapped `V`, which is small everywhere, most of the schedule was such frames.)
//!
//! Beyond the thesis, [`AdaptiveConfig::budget`] (on by default): every frame traces about
//! as many samples as a uniform frame. The thesis's frames each sample a fraction of the
//! pixels, yet each still pays for deciding, accumulating and showing all of them, and the
//! traced pixels no longer form whole packets of camera rays; at equal time that fixed cost
//! ate the gain (`BENCHMARKS.md`). With `budget`, a frame of the schedule runs iterations
//! `i .. j`, `j` the last whose samples stay within one per pixel ([`Adaptive::budget_end`]),
//! each pixel taking the samples those iterations would give it with its `V` frozen at the
//! frame's start ([`Schedule::count`]: the thesis recomputes `V` after each iteration; the
//! threshold falls, so a pixel whose `V` passes it at iteration `k` is sampled at every
//! iteration from `k` on). Once the probabilities are fixed, a pixel takes `P / mean(P)`
//! samples per frame on average (the integer part, and one more with the fraction's
//! probability): the thesis's distribution of samples, in frames of uniform cost.
//!
//! Beyond the thesis, two more measures ([`Measure`]): `absolute`, a pixel's deviation in
//! radiance estimated over its 7x7 neighbourhood relative to the image's mean (with the
//! schedule, samples in proportion to the deviation: the allocation that minimises the
//! squared error at a given number of samples), and `error`, the same over the pixel's sample
//! count, `sigma / n` (the pixels whose next sample lowers the squared error most first). With
//! `budget` and forward reprojection, `error` is the combination's best setting: after a move
//! the new pixels, with a few samples, take most of each frame's samples and the carried ones,
//! with hundreds, few.
//!
//! With forward reprojection on as well, the pipeline runs the thesis's combination
//! (Algorithm 2): reprojected pixels bring their samples, statistics and probability; after a
//! camera move the schedule restarts, and pixels that already have a probability take no
//! samples until iteration `max_spp`, when every pixel's probability is set again from its
//! sample count (a pixel that brought a probability but kept fewer than `min_spp` samples,
//! its states dropped by the aliasing test, counts as new: the thesis does not say, and
//! waiting would leave it black for the whole schedule). The thesis's known flaw follows: a reprojected pixel that had no probability
//! yet can go past `max_spp` samples (and so gets a probability above 1). [`AdaptiveConfig::cap`]
//! is the fix: no schedule samples for a pixel that has `max_spp` already, and pixels keep a
//! probability they brought. The frame that fixes the probabilities reports how many ended
//! above 1 ([`FrameReport::probability_above_one`](super::FrameReport)). Beyond the thesis,
//! [`AdaptiveConfig::keep_sampling`] (off by default): the reprojected pixels do not wait for
//! iteration `max_spp` but keep being sampled with the probability they brought (while they
//! wait, one schedule of 32 frames, they are the only pixels that do not improve);
//! [`AdaptiveConfig::keep_sampling_after`] lets them wait for that many iterations first, so
//! that the frames right after a move trace the new pixels alone, as in Algorithm 2.
//!
//! Defaults: `measure = "error"`, `budget = true` and `cap = true`, the settings measured
//! best (BENCHMARKS.md, "Seed 000"); the thesis's Algorithm 1 is `measure = "luminance"`,
//! `budget = false`, `cap = false`, `skip_empty = false` (the configuration
//! `luminance-4-32-every-iteration` of `experiments/000-adaptive.toml`), and its Algorithm 2
//! the same with forward reprojection (`combination` in `experiments/000-rotation.toml`, with
//! `skip_empty`, which changes no decision).
//!
//! Passes: this stage has no pass of its own. Before tracing, [`Adaptive::prepare`] measures
//! the image and skips empty iterations, and [`Adaptive::schedule`] gives the frame's
//! decisions ([`Schedule::wants`]), which the plan ([`super::plan::Planned`]) hands the
//! primary and lighting passes (which pixels are traced); after the accumulation pass,
//! [`Adaptive::end_frame`] moves the schedule on and fixes the probabilities at its end
//! ([`Adaptive::fix_probabilities`]). Its per-pixel state is `P` (view `probability`).
//!
//! Its rule at a new epoch: the schedule restarts; the probabilities are cleared, except that
//! forward reprojection carries them into the new view after a camera move.

use glam::Vec3;
use pathlight_core::color::luminance;
use pathlight_core::rng::{hash, unit_f32};
use serde::{Deserialize, Serialize};

use super::accumulation::PixelStats;
use super::display::{View, ViewKind};
use super::stage::Stage;
use super::state::FrameState;
use crate::error::ConfigError;

/// The stage's name (the menu's heading of its view).
pub const ADAPTIVE: &str = "adaptive";

/// `eps` of Eq. 12, in units of radiance: a pixel without variance or luminance (black after a
/// few samples) has `V = 1`, so it keeps being sampled during the schedule.
pub const EPSILON: f32 = 1e-3;

/// Longest schedule (`max_spp`) accepted.
pub const MAX_SCHEDULE: u32 = 1 << 16;

/// Marks a pixel whose probability is not fixed yet.
pub const NO_PROBABILITY: f32 = -1.0;

/// Settings of adaptive sampling (`[frame.adaptive]`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AdaptiveConfig {
    pub enabled: bool,
    /// Samples every pixel gets before the threshold applies (the thesis recommends 4).
    pub min_spp: u32,
    /// The iteration at which probabilities are fixed (the thesis recommends 32).
    pub max_spp: u32,
    /// How the deviation of a pixel's samples is scaled into `V`.
    pub measure: Measure,
    /// The fix of the combination's flaw (Algorithm 2): during the schedule a pixel with
    /// `max_spp` samples already takes no more, and a pixel keeps the probability it brought
    /// from the previous view instead of one recomputed from an inflated sample count. On by
    /// default (the same error or lower in every table measured; not in the thesis).
    pub cap: bool,
    /// Beyond the thesis: an iteration of the schedule in which no pixel would take a sample
    /// is skipped instead of spending a frame on it (the same decisions, fewer frames).
    pub skip_empty: bool,
    /// Beyond the thesis, for the combination: during the schedule after a move, a
    /// reprojected pixel keeps being sampled with the probability it brought, instead of
    /// waiting for iteration `max_spp` (Algorithm 2) while only the new pixels are sampled.
    pub keep_sampling: bool,
    /// With [`keep_sampling`](Self::keep_sampling): the iterations after a move during which
    /// the reprojected pixels still wait (0: none). The new pixels have the first frames to
    /// themselves, as in Algorithm 2, and the carried ones do not then stall for the rest of
    /// the schedule.
    pub keep_sampling_after: u32,
    /// Beyond the thesis: every frame traces about as many samples as a uniform frame
    /// (`spp` per pixel on average), so that adaptive frames cost what uniform ones cost.
    /// During the schedule a frame runs as many iterations as fit that budget (each pixel's
    /// `V` as it stood at the frame's start); once the probabilities are fixed each pixel
    /// takes `spp P / mean(P)` samples per frame (the integer part, and one more with the
    /// fraction's probability): the same distribution of samples as the thesis's, without a
    /// frame for every `max_spp / mean(P)` samples. On by default, with the `error` measure
    /// (module docs).
    pub budget: bool,
}

impl Default for AdaptiveConfig {
    fn default() -> Self {
        Self {
            enabled: false,
            min_spp: 4,
            max_spp: 32,
            measure: Measure::Error,
            cap: true,
            skip_empty: true,
            keep_sampling: false,
            keep_sampling_after: 0,
            budget: true,
        }
    }
}

/// The measure `V` the threshold is compared with.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Measure {
    /// Eq. 12: the standard deviation of a sample over the luminance of the pixel's mean
    /// (relative error: dark pixels, such as shadows under a sun, take the most samples).
    Luminance,
    /// Beyond the thesis: the standard deviation of a sample after tone mapping, to first
    /// order: `2 sigma / (1 + L)^2`, the deviation through Reinhard's `L / (1 + L)` (whose
    /// slope is `1 / (1 + L)^2`), doubled so that it spans [0, 1] as a display value's does.
    /// Noise as the displayed image shows it: neither the shadows' relative noise nor the
    /// highlights' absolute noise dominates.
    Tonemapped,
    /// Beyond the thesis: the standard deviation of a sample in radiance, estimated over the
    /// pixel's neighbourhood ([`REGION`]: the mean of Eq. 11 over the pixels of the window),
    /// over [`ABSOLUTE_SPAN`] times the image's mean of it ([`Adaptive::reference`]). With the
    /// schedule, `P` grows about linearly with that deviation (from `min_spp / max_spp` up to
    /// 1 at `ABSOLUTE_SPAN` times the mean), so samples go in proportion to it: the
    /// allocation that minimises the image's mean squared error at a given number of samples
    /// (Neyman's), with every pixel keeping `min_spp / max_spp` of it. The neighbourhood
    /// because a pixel's own few samples estimate a heavy-tailed variance badly: the pixels
    /// that caught a firefly would take the samples, those that have not yet would not.
    Absolute,
    /// Beyond the thesis: [`Absolute`](Self::Absolute)'s deviation divided by the pixel's
    /// sample count, `sigma / n`, over [`ABSOLUTE_SPAN`] times the image's mean of it: the
    /// pixels whose next sample lowers the image's squared error the most (`sigma^2 / n^2`)
    /// first. On a still camera the same allocation (in proportion to `sigma`, reached as
    /// the counts grow); after a move in the combination, where carried pixels hold hundreds
    /// of samples and new ones a few, the new ones take the samples. The default: with
    /// `budget`, 0.28-0.54x uniform sampling's MSE at equal time on the Cornell box where
    /// the thesis's Eq. 12 gave up to 2.3x (BENCHMARKS.md, "Seed 000").
    #[default]
    Error,
}

/// [`Measure::Absolute`] and [`Measure::Error`]: the multiple of the image's mean at which a
/// pixel is sampled at every iteration.
pub const ABSOLUTE_SPAN: f32 = 8.0;

/// [`Measure::Absolute`] and [`Measure::Error`]: the radius in pixels of the square window
/// whose variance a pixel's deviation is.
pub const REGION: usize = 3;

impl Measure {
    pub const ALL: [Measure; 4] = [
        Measure::Luminance,
        Measure::Tonemapped,
        Measure::Absolute,
        Measure::Error,
    ];

    /// Its name in configuration files.
    pub fn name(self) -> &'static str {
        match self {
            Measure::Luminance => "luminance",
            Measure::Tonemapped => "tonemapped",
            Measure::Absolute => "absolute",
            Measure::Error => "error",
        }
    }
}

impl AdaptiveConfig {
    /// The first iteration of the schedule at which the combination's reprojected pixels take
    /// samples with their probability: `max_spp` (Algorithm 2: they wait), or
    /// `keep_sampling_after` with [`keep_sampling`](Self::keep_sampling).
    pub fn carried_from(&self) -> u32 {
        if self.keep_sampling {
            self.keep_sampling_after.min(self.max_spp)
        } else {
            self.max_spp
        }
    }

    /// Checks the ranges: `1 <= min_spp <= max_spp <= 65536`.
    pub fn validate(&self) -> Result<(), ConfigError> {
        if self.min_spp == 0 {
            return Err(ConfigError::new(
                "frame.adaptive.min_spp",
                self.min_spp,
                "at least 1 (every pixel must keep converging)",
            ));
        }
        if self.max_spp < self.min_spp || self.max_spp > MAX_SCHEDULE {
            return Err(ConfigError::new(
                "frame.adaptive.max_spp",
                self.max_spp,
                format!("between min_spp ({}) and {MAX_SCHEDULE}", self.min_spp),
            ));
        }
        Ok(())
    }
}

/// Eq. 11: the variance of one sample, averaged over the three channels (0 below two
/// samples).
#[inline]
pub fn pixel_variance(stats: &PixelStats) -> f32 {
    let v: Vec3 = stats.variance();
    (v.x + v.y + v.z) * (1.0 / 3.0)
}

/// Eq. 12: `V = (sqrt(Var) + eps) / (L + eps)`, or another [`Measure`] of the pixel's own
/// samples. `reference` is the image's mean deviation ([`Adaptive::reference`]), read by
/// [`Measure::Absolute`] and [`Measure::Error`] only.
#[inline]
pub fn deviation(stats: &PixelStats, measure: Measure, reference: f32) -> f32 {
    match measure {
        Measure::Luminance => {
            let l = luminance(stats.mean()).max(0.0);
            (pixel_variance(stats).max(0.0).sqrt() + EPSILON) / (l + EPSILON)
        }
        Measure::Tonemapped => {
            let l = luminance(stats.mean()).max(0.0);
            2.0 * pixel_variance(stats).max(0.0).sqrt() / ((1.0 + l) * (1.0 + l)) + EPSILON
        }
        Measure::Absolute => absolute(pixel_variance(stats).max(0.0).sqrt(), reference),
        Measure::Error => absolute(
            pixel_variance(stats).max(0.0).sqrt() / stats.n.max(1) as f32,
            reference,
        ),
    }
}

/// `V` of pixel `pixel`: from its regional deviation ([`Adaptive::regional`], for
/// [`Measure::Absolute`] and [`Measure::Error`]) where there is one, else from its own
/// statistics.
#[inline]
fn measured(
    regional: &[f32],
    reference: f32,
    pixel: usize,
    stats: &PixelStats,
    measure: Measure,
) -> f32 {
    match regional.get(pixel) {
        Some(&sigma) => absolute(sigma, reference),
        None => deviation(stats, measure, reference),
    }
}

/// [`Measure::Absolute`]'s `V` of a deviation `sigma` when the image's mean is `reference`.
#[inline]
fn absolute(sigma: f32, reference: f32) -> f32 {
    if reference > 0.0 {
        sigma / (ABSOLUTE_SPAN * reference) + EPSILON
    } else {
        // No pixel varies yet: every one is as noisy as the mean.
        1.0 / ABSOLUTE_SPAN
    }
}

/// The combination: whether a pixel with probability `probability` and `n` samples is a
/// carried one (it brought a probability from the previous view), which waits or takes samples
/// with its probability. One that brought a probability but kept fewer than `min_spp`
/// samples (the aliasing test dropped its states) is new again and follows the schedule, as
/// a pixel nothing landed on does; otherwise it would wait, black, until iteration `max_spp`.
#[inline]
fn carried(probability: f32, n: u32, min_spp: u32) -> bool {
    probability != NO_PROBABILITY && n >= min_spp
}

/// The threshold `tau` at iteration `iteration` (1 until `min_spp`, then falling by
/// `1 / (max_spp - min_spp)` per iteration; only read before `max_spp`).
#[inline]
pub fn threshold(iteration: u32, min_spp: u32, max_spp: u32) -> f32 {
    if iteration <= min_spp || max_spp <= min_spp {
        return 1.0;
    }
    1.0 - (iteration - min_spp) as f32 / (max_spp - min_spp) as f32
}

/// The per-pixel state: each pixel's fixed probability ([`NO_PROBABILITY`] before it is
/// fixed).
#[derive(Debug, Clone, Default)]
pub struct Adaptive {
    pub probability: Vec<f32>,
    /// The iteration of the schedule the next frame runs (0 at every reset).
    pub iteration: u32,
    /// `1 / mean(P)` over the pixels, set when the probabilities are fixed
    /// ([`AdaptiveConfig::budget`]'s samples per frame are `spp P scale`).
    pub scale: f32,
    /// [`Measure::Absolute`]: each pixel's deviation of a sample over its neighbourhood
    /// ([`Measure::Error`]: divided by the pixel's sample count), and the image's mean of it
    /// ([`Adaptive::measure_image`]); empty and 0 with the other measures.
    pub regional: Vec<f32>,
    pub reference: f32,
    /// Scratch of [`measure_image`](Self::measure_image): each pixel's variance and whether it
    /// has one, then their sums along each row's window.
    own: Vec<(f32, f32)>,
    rows: Vec<(f32, f32)>,
}

/// One iteration's decisions: which pixels are sampled.
#[derive(Debug, Clone, Copy)]
pub struct Schedule<'a> {
    /// The first iteration this frame runs.
    pub iteration: u32,
    /// The end (exclusive) of the iterations this frame runs: `iteration + 1` except with
    /// [`AdaptiveConfig::budget`] during the schedule.
    pub end: u32,
    /// Once the probabilities are fixed, with [`AdaptiveConfig::budget`]: a pixel's samples
    /// per frame are `P scale` (otherwise 0: one sample with probability `P`).
    pub scale: f32,
    pub tau: f32,
    pub min_spp: u32,
    pub max_spp: u32,
    pub measure: Measure,
    /// [`Measure::Absolute`] and [`Measure::Error`]: the pixels' regional deviations and
    /// their mean ([`Adaptive::regional`]); empty and 0 with the other measures.
    pub regional: &'a [f32],
    pub reference: f32,
    /// Algorithm 2: pixels with a probability wait for the probability phase.
    pub combination: bool,
    pub cap: bool,
    /// [`AdaptiveConfig::keep_sampling`]: the first iteration at which reprojected pixels
    /// take samples with their probability (`max_spp` without it: they wait).
    pub carried_from: u32,
    /// Seeds the probability phase's random numbers (the epoch's seed).
    pub seed: u64,
}

impl<'a> Schedule<'a> {
    pub fn new(config: &AdaptiveConfig, iteration: u32, combination: bool, seed: u64) -> Self {
        Self {
            iteration,
            end: iteration.saturating_add(1),
            scale: 0.0,
            tau: threshold(iteration, config.min_spp, config.max_spp),
            min_spp: config.min_spp,
            max_spp: config.max_spp,
            measure: config.measure,
            regional: &[],
            reference: 0.0,
            combination,
            cap: config.cap,
            carried_from: config.carried_from(),
            seed,
        }
    }

    /// The schedule's measure `V` of pixel `pixel` with statistics `stats`.
    #[inline]
    fn v(&self, pixel: usize, stats: &PixelStats) -> f32 {
        measured(self.regional, self.reference, pixel, stats, self.measure)
    }

    /// Whether pixel `pixel`, with statistics `stats` and probability `probability`, takes a
    /// sample in this frame.
    #[inline]
    pub fn wants(&self, pixel: usize, stats: &PixelStats, probability: f32) -> bool {
        self.count(pixel, stats, probability) > 0
    }

    /// How many of this frame's iterations sample pixel `pixel` (each iteration: `spp`
    /// samples): 0 or 1 in the thesis's algorithm, where a frame is one iteration; up to
    /// `end - iteration` when a frame runs several ([`AdaptiveConfig::budget`]), or
    /// `P scale` on average once the probabilities are fixed.
    #[inline]
    pub fn count(&self, pixel: usize, stats: &PixelStats, probability: f32) -> u32 {
        let draw =
            |iteration: u32| unit_f32(hash(&[self.seed, pixel as u64, iteration as u64]) as u32);
        if self.iteration >= self.max_spp {
            if probability == NO_PROBABILITY {
                // Only when adaptive sampling was switched on past the schedule's end.
                return 1;
            }
            if self.scale > 0.0 {
                let x = probability * self.scale;
                let whole = x.floor();
                return whole as u32 + u32::from(draw(self.iteration) < x - whole);
            }
            return u32::from(draw(self.iteration) < probability);
        }
        let end = self.end.min(self.max_spp);
        if self.combination && carried(probability, stats.n, self.min_spp) {
            return (self.iteration.max(self.carried_from)..end)
                .map(|i| u32::from(draw(i) < probability))
                .sum();
        }
        if self.cap && stats.n >= self.max_spp {
            return 0;
        }
        if end == self.iteration + 1 {
            // One iteration (the thesis): `V` decides unless the pixel is below `min_spp`.
            return u32::from(stats.n < self.min_spp || self.v(pixel, stats) >= self.tau);
        }
        // Several: first the iterations the pixel needs to reach `min_spp` (counted as one
        // sample each, `spp` per frame being a sample count of its own), then every
        // iteration whose threshold is at most the pixel's `V` (the threshold falls, so
        // these are the iterations from the first such one on).
        let span = end - self.iteration;
        let below = self.min_spp.saturating_sub(stats.n).min(span);
        let from = self.iteration + below;
        let v = self.v(pixel, stats);
        let (mut first, mut last) = (from, end);
        while first < last {
            let mid = first + (last - first) / 2;
            if threshold(mid, self.min_spp, self.max_spp) > v {
                first = mid + 1;
            } else {
                last = mid;
            }
        }
        let count = below + (end - first);
        if self.cap {
            count.min(self.max_spp - stats.n)
        } else {
            count
        }
    }
}

impl Adaptive {
    pub const VIEWS: &'static [View] = &[View {
        name: "probability",
        about: "each pixel's fixed probability P of a sample per frame, as a heat map 0 to 1 \
                (dark grey before the schedule fixes it)",
        kind: ViewKind::Heat,
    }];

    /// At a new epoch: the schedule restarts; `clear`: the probabilities of the frame's
    /// `pixels` start unfixed (not when reprojection carried them into the new view).
    pub fn restart(&mut self, pixels: usize, clear: bool) {
        if clear {
            self.reset(pixels);
        }
        self.iteration = 0;
    }

    /// Before a frame's tracing (with seed 000's techniques on): measures the image for the
    /// regional measures, and with `skip_empty` moves on to the first iteration that samples
    /// something (fixing the probabilities when that is the schedule's end: returns then the
    /// pixels above 1). `combination`: forward reprojection is on.
    pub fn prepare(
        &mut self,
        config: &AdaptiveConfig,
        history: &[PixelStats],
        width: usize,
        combination: bool,
    ) -> Option<u64> {
        if !config.enabled {
            return None;
        }
        if self.iteration < config.max_spp {
            // V is read during the schedule only.
            self.measure_image(config.measure, history, width);
        }
        let mut above_one = None;
        if config.skip_empty {
            let busy = self.first_busy(config, history, combination);
            if busy == config.max_spp && self.iteration < config.max_spp {
                // The rest of the schedule would sample nothing: its end now.
                above_one = Some(self.fix_probabilities(history, config.max_spp, config.cap));
            }
            self.iteration = busy;
        }
        above_one
    }

    /// The frame's decisions (`None` with adaptive sampling off): the schedule at this
    /// iteration, with `budget` the iterations that fit one frame's samples (not in the frame
    /// after a move, `after_move`, where every pixel is traced); `seed` is the epoch's.
    pub fn schedule(
        &self,
        config: &AdaptiveConfig,
        history: &[PixelStats],
        combination: bool,
        after_move: bool,
        seed: u64,
    ) -> Option<Schedule<'_>> {
        config.enabled.then(|| {
            let mut s = Schedule::new(config, self.iteration, combination, seed);
            s.regional = &self.regional;
            s.reference = self.reference;
            if config.budget && !after_move {
                if s.iteration < s.max_spp {
                    s.end = self.budget_end(&s, history, history.len() as u64);
                } else {
                    s.scale = self.scale;
                }
            }
            s
        })
    }

    /// After the frame's accumulation: the schedule moves on to `end` (the end of the
    /// iterations the frame ran, or the next iteration), fixing the probabilities when it
    /// reaches `max_spp` (returns then the pixels above 1).
    pub fn end_frame(
        &mut self,
        config: &AdaptiveConfig,
        history: &[PixelStats],
        end: Option<u32>,
    ) -> Option<u64> {
        let i = self.iteration;
        let end = end.unwrap_or(i.saturating_add(1));
        let mut above_one = None;
        if config.enabled && i < config.max_spp && end >= config.max_spp {
            above_one = Some(self.fix_probabilities(history, config.max_spp, config.cap));
        }
        self.iteration = end;
        above_one
    }

    /// [`Measure::Absolute`]: sets [`regional`](Self::regional), each pixel's deviation of a
    /// sample over the window of radius [`REGION`] around it (the square root of the mean of
    /// Eq. 11 over the window's pixels with two samples or more; [`Measure::Error`]: divided
    /// by the pixel's sample count), and [`reference`](Self::reference), its mean over the
    /// image. Other measures clear them.
    /// The same whatever the thread count (rows filtered apart, sums in fixed chunks).
    pub fn measure_image(&mut self, measure: Measure, history: &[PixelStats], width: usize) {
        use rayon::prelude::*;
        if !matches!(measure, Measure::Absolute | Measure::Error) || width == 0 {
            self.regional.clear();
            self.reference = 0.0;
            return;
        }
        let height = history.len() / width;
        let per_sample = measure == Measure::Error;
        // Each pixel's variance and whether it has one; their window sums along each row
        // (a sliding sum), then along the columns.
        let (own, rows) = (&mut self.own, &mut self.rows);
        own.resize(history.len(), (0.0, 0.0));
        own.par_iter_mut()
            .zip(history.par_iter())
            .for_each(|(o, h)| {
                *o = if h.n >= 2 {
                    (pixel_variance(h).max(0.0), 1.0)
                } else {
                    (0.0, 0.0)
                };
            });
        rows.resize(history.len(), (0.0, 0.0));
        rows.par_chunks_mut(width)
            .zip(own.par_chunks(width))
            .for_each(|(out, row)| {
                let (mut v, mut c) = (0.0f32, 0.0f32);
                for &(dv, dc) in &row[..REGION.min(width)] {
                    v += dv;
                    c += dc;
                }
                for (x, o) in out.iter_mut().enumerate() {
                    if let Some(&(dv, dc)) = row.get(x + REGION) {
                        v += dv;
                        c += dc;
                    }
                    if let Some(&(dv, dc)) = x.checked_sub(REGION + 1).map(|i| &row[i]) {
                        v -= dv;
                        c -= dc;
                    }
                    *o = (v.max(0.0), c.max(0.0));
                }
            });
        let rows = &self.rows;
        self.regional.resize(history.len(), 0.0);
        self.regional
            .par_chunks_mut(width)
            .enumerate()
            .for_each(|(y, out)| {
                let ys = y.saturating_sub(REGION)..(y + REGION + 1).min(height);
                for (x, o) in out.iter_mut().enumerate() {
                    let (v, c) = ys
                        .clone()
                        .map(|yy| rows[yy * width + x])
                        .fold((0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1));
                    *o = if c >= 0.5 { (v / c).sqrt() } else { 0.0 };
                    if per_sample {
                        *o /= history[y * width + x].n.max(1) as f32;
                    }
                }
            });
        let sum: f64 = self
            .regional
            .par_chunks(4096)
            .map(|chunk| chunk.iter().map(|&s| f64::from(s)).sum::<f64>())
            .collect::<Vec<_>>()
            .into_iter()
            .sum();
        self.reference = (sum / self.regional.len().max(1) as f64) as f32;
    }

    /// Sizes the state for `pixels` pixels, every probability unfixed.
    pub fn reset(&mut self, pixels: usize) {
        self.probability.clear();
        self.probability.resize(pixels, NO_PROBABILITY);
        self.iteration = 0;
    }

    /// The first iteration from `self.iteration` on in which some pixel of `history` takes a
    /// sample ([`AdaptiveConfig::skip_empty`]; `max_spp` when none does before the
    /// probabilities are fixed). An iteration before `max_spp` is empty when every pixel that
    /// may still be sampled has `min_spp` samples and the threshold `tau` is above the largest
    /// `V` among them (or, in the combination, when every pixel waits with its probability).
    /// Pixels do not change between skipped iterations, so the decisions are the thesis's.
    pub fn first_busy(
        &self,
        config: &AdaptiveConfig,
        history: &[PixelStats],
        combination: bool,
    ) -> u32 {
        use rayon::prelude::*;
        let (min, max) = (config.min_spp, config.max_spp);
        let i = self.iteration;
        if i >= max {
            return i;
        }
        let carried_from = config.carried_from();
        // The largest V among the pixels the threshold decides (infinite: a pixel below
        // min_spp, or a reprojected one sampled with its probability, (almost) never
        // empty), and whether some reprojected pixel waits.
        let (largest, carried) = history
            .par_iter()
            .zip(self.probability.par_iter())
            .enumerate()
            .map(|(pixel, (h, &p))| {
                if combination && carried(p, h.n, min) {
                    if carried_from <= i {
                        (f32::INFINITY, false)
                    } else {
                        (f32::NEG_INFINITY, true)
                    }
                } else if config.cap && h.n >= max {
                    (f32::NEG_INFINITY, false)
                } else if h.n < min {
                    (f32::INFINITY, false)
                } else {
                    (
                        measured(&self.regional, self.reference, pixel, h, config.measure),
                        false,
                    )
                }
            })
            .reduce(
                || (f32::NEG_INFINITY, false),
                |a, b| (a.0.max(b.0), a.1 || b.1),
            );
        let busy = (i..max)
            .find(|&j| threshold(j, min, max) <= largest)
            .unwrap_or(max);
        if carried {
            busy.min(carried_from)
        } else {
            busy
        }
    }

    /// The end of iteration `max_spp - 1`: every pixel's probability becomes
    /// `spp / max_spp` (Algorithm 1 and 2). With `cap`, a pixel keeps a probability it has
    /// and counts at most `max_spp` samples. Returns the pixels whose probability is above 1
    /// (the combination's flaw: they hold more than `max_spp` samples; none with `cap`).
    pub fn fix_probabilities(&mut self, history: &[PixelStats], max_spp: u32, cap: bool) -> u64 {
        use rayon::prelude::*;
        let (above, sum) = self
            .probability
            .par_iter_mut()
            .zip(history.par_iter())
            .map(|(p, h)| {
                if !(cap && *p != NO_PROBABILITY) {
                    let n = if cap { h.n.min(max_spp) } else { h.n };
                    *p = n as f32 / max_spp as f32;
                }
                (u64::from(*p > 1.0), f64::from(*p))
            })
            .reduce(|| (0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1));
        self.scale = if sum > 0.0 {
            (self.probability.len() as f64 / sum) as f32
        } else {
            1.0
        };
        above
    }

    /// [`AdaptiveConfig::budget`] during the schedule: the end of the iterations a frame
    /// that starts at `schedule.iteration` runs, the last one whose samples (counted as in
    /// [`Schedule::count`]) stay within `budget` iterations' worth (a pixel's sample each);
    /// at least one iteration, at most up to `max_spp`.
    pub fn budget_end(&self, schedule: &Schedule, history: &[PixelStats], budget: u64) -> u32 {
        use rayon::prelude::*;
        let samples = |end: u32| -> u64 {
            let s = Schedule { end, ..*schedule };
            history
                .par_iter()
                .zip(self.probability.par_iter())
                .enumerate()
                .map(|(i, (h, &p))| u64::from(s.count(i, h, p)))
                .sum()
        };
        // The largest end in (iteration, max_spp] within the budget (sample counts grow
        // with the end).
        let (mut fits, mut over) = (schedule.iteration + 1, schedule.max_spp + 1);
        while fits + 1 < over {
            let mid = fits + (over - fits) / 2;
            if samples(mid) <= budget {
                fits = mid;
            } else {
                over = mid;
            }
        }
        fits
    }
}

impl Stage for Adaptive {
    fn name(&self) -> &'static str {
        ADAPTIVE
    }

    fn views(&self) -> &'static [View] {
        Self::VIEWS
    }

    /// None of its own: its work is part of the plan and of accumulation.
    fn passes(&self) -> Vec<&'static str> {
        Vec::new()
    }

    /// The probability (-1 before it is fixed, or when adaptive sampling never ran).
    fn value(&self, _: &FrameState, _: usize, i: usize) -> Vec3 {
        Vec3::splat(self.probability.get(i).copied().unwrap_or(-1.0))
    }

    fn bytes(&self) -> usize {
        (self.probability.capacity() + self.regional.capacity()) * std::mem::size_of::<f32>()
            + (self.own.capacity() + self.rows.capacity()) * std::mem::size_of::<(f32, f32)>()
    }
}

#[cfg(test)]
mod tests;
