//! The frame driver: the stages called in order ([`Pipeline::render_frame`]), what a frame
//! reports, and the display pass over the stages' views.

use std::time::Instant;

use glam::Vec3;
use pathlight_denoise::FilterConfig;
use rayon::prelude::*;
use serde::Serialize;

use crate::config::{Config, FrameConfig};
use crate::path::PathTracer;
use crate::world::World;

use super::accumulation::PixelStats;
use super::adaptive::Adaptive;
use super::display::{encode, DisplayConfig, DisplayMode, DISPLAY};
use super::history::{History, ACCUMULATE};
use super::plan::{with_plan, FramePlan, Planned};
use super::reprojection::{Reprojection, ReprojectionReport};
use super::stage::{view_index, Stage};
use super::stages::Stages;
use super::state::{Change, FrameState, PassTime, Times};
use super::target::Target;
use super::texture_cache::CacheReport;
use super::trace::{self, FirstHitLight, NextEvent, Uniform, LIGHTING};
use super::upsample::{render_size, UPSAMPLE};

/// What one call of [`Pipeline::render_frame`] did.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FrameReport {
    /// Frames rendered since the pipeline was made (this one included).
    pub frame: u64,
    /// Resets so far (camera or settings changes).
    pub epoch: u64,
    /// Frames in the history (this epoch).
    pub accumulated: u32,
    /// Samples per pixel in the history.
    pub spp: u32,
    /// Samples traced in this frame, over all pixels (each a camera path). Divided by the
    /// pixel count: the frame's mean samples per pixel, which differs from `spp` per frame
    /// when a technique (adaptive sampling) gives pixels different counts.
    pub samples: u64,
    /// False when accumulation had reached `max_frames`: nothing was traced and the history
    /// is as it was.
    pub traced: bool,
    pub passes: Vec<PassTime>,
    /// Wall time of the whole frame.
    pub ms: f64,
    /// Rays traced (closest-hit and shadow queries; the reprojection pass's occlusion rays
    /// are not counted).
    pub rays: u64,
    /// What forward reprojection did, on the frame after a camera move.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reprojection: Option<ReprojectionReport>,
    /// Adaptive sampling's threshold this frame (`None` off, or past the schedule).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tau: Option<f32>,
    /// On the frame that fixed adaptive sampling's probabilities: the pixels whose
    /// probability is above 1 (the combination's flaw, Algorithm 2: they went past
    /// `max_spp`; none with `cap`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub probability_above_one: Option<u64>,
    /// What seed 002's texture cache did (when it is on).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub texture_cache: Option<CacheReport>,
    /// The render scale the frame was traced at (1: the output's size; below 1, upsampled).
    pub scale: f32,
}

impl FrameReport {
    /// Milliseconds of pass `name` (0 when it did not run).
    pub fn pass_ms(&self, name: &str) -> f64 {
        self.passes
            .iter()
            .filter(|p| p.pass == name)
            .map(|p| p.ms)
            .sum()
    }
}

/// The frame pipeline: the frame state the stages share, and each stage's own state.
#[derive(Default)]
pub struct Pipeline {
    /// The configuration in force (as last given).
    config: Config,
    /// Why the next frame must start a new epoch (none: it continues this one).
    reset: Option<Change>,
    /// What the stages share: buffers, cameras, counters.
    pub frame: FrameState,
    /// The display pass's output: 8-bit RGBA, row-major.
    pub rgba: Vec<u8>,
    /// Each stage's own state, in the frame's order.
    pub stages: Stages,
    /// The frame-time target's state.
    target: Target,
}

impl Pipeline {
    /// A pipeline for `config` (checked by [`Config::validate`] beforehand by the caller).
    pub fn new(config: Config) -> Self {
        Self {
            frame: FrameState::new(config.path_settings()),
            config,
            reset: Some(Change::Settings),
            ..Default::default()
        }
    }

    pub fn config(&self) -> &Config {
        &self.config
    }

    /// The camera of the current epoch (after the first frame).
    pub fn camera(&self) -> Option<&crate::camera::Camera> {
        self.frame.camera.as_ref()
    }

    /// The render scale of the next frame: the configuration's (`[frame.upsample] scale`),
    /// or below it the frame-time target's.
    pub fn scale(&self) -> f32 {
        let c = &self.config.frame;
        match c.target_ms > 0.0 {
            true => self.target.scale(c.upsample.scale),
            false => c.upsample.scale,
        }
    }

    /// Frames accumulated in this epoch.
    pub fn accumulated(&self) -> u32 {
        self.frame.frames
    }

    /// Replaces the configuration. Anything that changes the image (camera, resolution,
    /// samples, passes) starts a new epoch at the next frame; the display settings,
    /// `max_frames` and the reconstruction filter (a post-process of the history) do not. A
    /// change of the view alone (position, direction, up, field of view) is a camera move,
    /// which forward reprojection and ReSTIR's reservoirs survive.
    pub fn set_config(&mut self, config: &Config) {
        if let Some(change) = change(&self.config, config) {
            self.reset = Some(self.reset.map_or(change, |r| r.and(change)));
        }
        self.config = config.clone();
    }

    /// Clears the history: the next frame starts a new epoch afresh.
    pub fn reset(&mut self) {
        self.reset = Some(Change::Settings);
    }

    /// Makes what the stages switched on keep per world (the texture cache's grids, its split
    /// of the environment into sun and sky, and the rough specular albedo's table), as a
    /// renderer does at load: the first frame then costs what any cold frame costs. Without
    /// it, the first frame makes them; the frames are the same either way.
    pub fn prepare_world(&mut self, world: &World) {
        if self.config.frame.texture_cache.enabled {
            let microfacet = self.config.path_settings().microfacet;
            self.stages.texture_cache.prepare_world(world, microfacet);
        }
    }

    /// Renders one frame of `world`: a new epoch when something changed (each stage by its
    /// own rule), then the frame's passes in order. The display pass is
    /// [`display`](Self::display), run by those who show or write frames.
    pub fn render_frame(&mut self, world: &World) -> FrameReport {
        let start = Instant::now();
        self.frame.times = Times::default();
        let change =
            (self.reset.take()).or((!self.config.frame.accumulate).then_some(Change::Repeat));
        let mut reprojected = change.and_then(|change| self.start_epoch(world, change));
        let scale = self.scale();
        let (config, f, s) = (&self.config, &mut self.frame, &mut self.stages);
        let cfg = &config.frame;
        // Seed 000's techniques: each pixel continues its own sample count.
        let counts = cfg.adaptive.enabled || cfg.reprojection.enabled;
        // Pixels' counts differ (the report counts them): seed 000's, or the cache's edges'.
        let tc = &cfg.texture_cache;
        let varying = counts || (tc.enabled && tc.edge_spp > f.spp);
        let traced = !(cfg.accumulate && cfg.max_frames > 0 && f.frames >= cfg.max_frames);
        let (mut rays, mut samples, mut tau, mut above_one) = (0, 0, None, None);
        let mut cache_report = None;
        if traced {
            let camera = f.camera.clone().expect("set by start_epoch");
            let tracer = PathTracer {
                world,
                camera: &camera,
                settings: f.settings,
            };
            s.filter
                .before_trace(&mut f.gbuffer, &mut f.lighting, !counts);
            // Seed 000: adaptive sampling's schedule, and the plan.
            let index = f.sample_index();
            let frame = (index, f.spp, f.gbuffer.width as usize, f.settings.seed);
            let (plan, above, end, threshold) =
                plan(cfg, &f.history, frame, &mut s.adaptive, &s.reprojection);
            (above_one, tau) = (above, threshold);
            // Primary visibility, the light at the first hits (seeds 004 and 002), lighting.
            let (mut plain, mut cache) = (NextEvent, None);
            let r = &cfg.restir;
            let mut restir = r.enabled.then(|| s.restir.frame(r, index));
            let below: &mut dyn FirstHitLight = restir.as_mut().map_or(&mut plain as _, |r| r as _);
            let light = match tc.enabled {
                true => cache.insert(s.texture_cache.begin(&tracer, tc, f.pixels(), below)) as _,
                false => below,
            };
            let previous = f.previous_camera.as_ref();
            let (g, l, hits, times) = (&mut f.gbuffer, &mut f.lighting, &mut f.hits, &mut f.times);
            rays += with_plan!(&plan, p => trace::frame(g, l, hits, times, previous, &tracer, p, light));
            drop(cache);
            let ended = tc
                .enabled
                .then(|| s.texture_cache.end(&tracer, tc, &mut f.times, LIGHTING));
            (rays, cache_report) = (rays + ended.map_or(0, |e| e.0), ended.map(|e| e.1));
            // Seed 000: the samples reprojected pixels lack (`fresh_spp`).
            let t = Instant::now();
            rays += s.reprojection.repair(&cfg.reprojection, f, &tracer);
            f.times.since(LIGHTING, t);
            // Accumulation: into reprojection's states when it is on.
            let t = Instant::now();
            samples = match varying {
                true => History::samples(&f.lighting),
                false => f.spp as u64 * f.pixels() as u64,
            };
            if cfg.reprojection.enabled {
                let (r, p) = (&cfg.reprojection, &mut s.adaptive.probability);
                s.reprojection
                    .accumulate_frame(world, r, f, p, reprojected.as_mut());
            } else {
                History::accumulate(&mut f.history, &f.lighting, f.frames == 0);
            }
            let fixed = s.adaptive.end_frame(&cfg.adaptive, &f.history, end);
            above_one = fixed.or(above_one);
            f.times.since(ACCUMULATE, t);
            f.frames += 1;
            f.previous_camera = Some(camera);
        }
        f.number += 1;
        // Seed 001's reconstruction filter, or temporal upsampling.
        let output = (config.width as usize, config.height as usize);
        reconstruct(cfg, output, scale, f, s, traced, !counts);
        let report = FrameReport {
            frame: f.number,
            epoch: f.epoch,
            accumulated: f.frames,
            spp: match varying {
                true => History::mean_samples(&f.history),
                false => f.history.first().map_or(0, |h| h.n),
            },
            traced,
            samples,
            passes: std::mem::take(&mut f.times.0),
            ms: start.elapsed().as_secs_f64() * 1e3,
            rays,
            reprojection: reprojected,
            tau,
            probability_above_one: above_one,
            texture_cache: cache_report,
            scale,
        };
        self.hold_target(&report, change);
        report
    }

    /// The frame-time target after a frame (`change`: what started its epoch, if anything):
    /// its time counted unless the frame started afresh (a cold frame), and a step of the
    /// scale makes the next frame a new render size. Without a target, it starts over.
    fn hold_target(&mut self, report: &FrameReport, change: Option<Change>) {
        let c = &self.config.frame;
        if c.target_ms <= 0.0 {
            self.target.reset();
            return;
        }
        if !report.traced || change == Some(Change::Settings) {
            return;
        }
        if self
            .target
            .after_frame(report.ms, c.target_ms, c.upsample.scale)
            .is_some()
        {
            self.reset = Some(self.reset.map_or(Change::Scale, |r| r.and(Change::Scale)));
        }
    }

    /// A new epoch after `change`: the frame state (seed, camera, buffers), then each stage
    /// by its own rule. Returns what forward reprojection did, when it carried the history.
    fn start_epoch(&mut self, world: &World, change: Change) -> Option<ReprojectionReport> {
        // The frame is traced at the render size (the output's unless upsampling); after a
        // step of the scale, the previous frame's camera was of another size: no motion.
        let scale = self.scale();
        let (c, f) = (&self.config, &mut self.frame);
        let (width, height) = render_size(scale, c.width, c.height);
        if change == Change::Scale {
            f.previous_camera = None;
        }
        let camera = world.camera(&c.camera, width, height);
        let (previous, resized) = f.start_epoch(c.path_settings(), c.spp, camera, width, height);
        let cfg = &c.frame;
        let stages = &mut self.stages;
        let reprojected = stages.reprojection.carry(
            world,
            &cfg.reprojection,
            cfg.accumulate,
            change,
            resized,
            previous.as_ref(),
            f,
            &mut stages.adaptive.probability,
        );
        // Seed 000's techniques read the history before the frame's accumulation: it is
        // cleared, unless reprojection carried it.
        let clear = (cfg.adaptive.enabled || cfg.reprojection.enabled) && reprojected.is_none();
        stages.adaptive.restart(f.pixels(), clear);
        if clear {
            History::clear(&mut f.history);
        }
        stages.start_epoch(change);
        reprojected
    }

    /// The stage that has view `mode`, and the view's index among its views.
    fn view(&self, mode: &DisplayMode) -> Option<(&dyn Stage, usize)> {
        self.stages
            .all()
            .into_iter()
            .find_map(|s| Some((s, view_index(s.views(), mode.name())?)))
    }

    /// The display pass: the configured display mode as 8-bit RGBA into
    /// [`rgba`](Self::rgba); its time is added to `report`.
    pub fn display(&mut self, report: &mut FrameReport) {
        let t = Instant::now();
        let mut rgba = std::mem::take(&mut self.rgba);
        self.rgba8(&self.config.display.mode, &self.config.display, &mut rgba);
        self.rgba = rgba;
        let ms = t.elapsed().as_secs_f64() * 1e3;
        report.passes.push(PassTime { pass: DISPLAY, ms });
        report.ms += ms;
    }

    /// View `mode` as 8-bit RGBA into `out` with the settings `display` (black for a name no
    /// stage has).
    pub fn rgba8(&self, mode: &DisplayMode, display: &DisplayConfig, out: &mut Vec<u8>) {
        match (self.view(mode), self.output()) {
            (Some((stage, view)), None) => stage.rgba8(&self.frame, view, display, out),
            (Some((stage, view)), Some(n)) => {
                let kind = stage.views()[view].kind;
                let paint = |i| stage.paint(&self.frame, view, self.render_pixel(i));
                encode(kind, n, self.values(mode), paint, display, out);
            }
            (None, n) => {
                out.clear();
                out.resize(n.unwrap_or(self.frame.pixels()) * 4, 0);
            }
        }
    }

    /// View `mode`'s linear values, row-major (zero for a name no stage has).
    pub fn linear(&self, mode: &DisplayMode) -> Vec<Vec3> {
        match (self.view(mode), self.output()) {
            (Some((stage, view)), None) => stage.linear(&self.frame, view),
            (_, Some(n)) => (0..n).into_par_iter().map(self.values(mode)).collect(),
            (None, None) => vec![Vec3::ZERO; self.frame.pixels()],
        }
    }

    /// View `mode`'s linear value at pixel `pixel` (of the output: while upsampling, the
    /// output's own for `final` and the upsampler's view, the nearest render pixel's for the
    /// others).
    pub fn value(&self, mode: &DisplayMode, pixel: usize) -> Vec3 {
        self.values(mode)(pixel)
    }

    /// View `mode`'s linear value at each output pixel, as [`value`](Self::value) says: the
    /// stage and view found once, not per pixel.
    fn values(&self, mode: &DisplayMode) -> impl Fn(usize) -> Vec3 + Sync + '_ {
        let up = &self.stages.upsample;
        let output = up.active() && *mode == DisplayMode::FINAL;
        let found = self.view(mode);
        let own = found.is_some_and(|(stage, _)| up.active() && stage.name() == up.name());
        move |pixel| match (output, found) {
            (true, _) => up.colour(pixel),
            (false, None) => Vec3::ZERO,
            (false, Some((stage, view))) => {
                let at = if own { pixel } else { self.render_pixel(pixel) };
                stage.value(&self.frame, view, at)
            }
        }
    }

    /// The output's pixel count while upsampling (`None`: the output is the frame's own).
    fn output(&self) -> Option<usize> {
        let up = &self.stages.upsample;
        up.active().then(|| up.size().0 * up.size().1)
    }

    /// The render pixel nearest output pixel `i` while upsampling (`i` itself otherwise).
    fn render_pixel(&self, i: usize) -> usize {
        let up = &self.stages.upsample;
        if !up.active() {
            return i;
        }
        let ((w, h), g) = (up.size(), &self.frame.gbuffer);
        let (rw, rh) = (g.width as usize, g.height as usize);
        let (x, y) = (i % w, i / w);
        (y * rh / h) * rw + x * rw / w
    }

    /// The image (mean radiance, filtered when the filter is on), row-major.
    pub fn image(&self) -> Vec<Vec3> {
        self.linear(&DisplayMode::FINAL)
    }

    /// Bytes the pipeline's per-pixel buffers hold: the plain pipeline's (G-buffer,
    /// lighting, history, display) and the techniques' (each stage's own, and the whole
    /// frame's first hits that ReSTIR reads).
    pub fn bytes(&self) -> (usize, usize) {
        let plain = self.frame.bytes() + self.rgba.capacity();
        let techniques =
            self.stages.all().iter().map(|s| s.bytes()).sum::<usize>() + self.frame.hits_bytes();
        (plain, techniques)
    }
}

/// The image at the output's size after a frame (`traced`: it traced samples; `every_pixel`:
/// every pixel afresh): the render size's reconstruction filter (seed 001's) when it is the
/// output's; below it (render `scale` under 1) temporal upsampling of the frame's samples to
/// the `output` size instead, the filter standing aside.
fn reconstruct(
    cfg: &FrameConfig,
    output: (usize, usize),
    scale: f32,
    f: &mut FrameState,
    s: &mut Stages,
    traced: bool,
    every_pixel: bool,
) {
    let upsampling = scale < 1.0;
    let off = FilterConfig::default();
    s.filter.pass(
        if upsampling { &off } else { &cfg.filter },
        f,
        traced,
        every_pixel,
    );
    if upsampling && traced {
        let t = Instant::now();
        let samples: Vec<Vec3> = f.lighting.par_iter().map(|l| l.stats.mean()).collect();
        s.upsample.pass(&cfg.upsample, &samples, &f.gbuffer, output);
        f.times.since(UPSAMPLE, t);
    } else if !upsampling && s.upsample.active() {
        s.upsample.clear();
    }
}

/// The frame's plan: seed 000's when its techniques are on (each pixel from its own count in
/// `history`, adaptive sampling's `schedule`), else every pixel from sample index `index`;
/// `spp` samples per pixel and frame.
/// Seed 000's decisions at a traced frame (its sample `index`, samples per pixel `spp`, image
/// width and epoch seed in `frame`): adaptive sampling's probabilities brought up to date, its
/// schedule, and the plan of the frame's samples. Returns the plan, the pixels whose
/// probability is above one (when they are fixed), the iteration the frame ends at and the
/// threshold while it falls.
#[allow(clippy::type_complexity)]
fn plan<'a>(
    cfg: &FrameConfig,
    history: &'a [PixelStats],
    (index, spp, width, seed): (u32, u32, usize, u64),
    adaptive: &'a mut Adaptive,
    reprojection: &'a Reprojection,
) -> (FramePlan<'a>, Option<u64>, Option<u32>, Option<f32>) {
    let (combination, after_move) = (cfg.reprojection.enabled, reprojection.after_move);
    let above_one = adaptive.prepare(&cfg.adaptive, history, width, combination);
    let adaptive: &'a Adaptive = adaptive;
    let schedule = adaptive.schedule(&cfg.adaptive, history, combination, after_move, seed);
    let end = schedule.map(|s| s.end);
    let tau = schedule.filter(|s| s.iteration < s.max_spp).map(|s| s.tau);
    let r = &cfg.reprojection;
    if !(cfg.adaptive.enabled || r.enabled) {
        return (FramePlan::Uniform(Uniform(index, spp)), above_one, end, tau);
    }
    let plan = FramePlan::Planned(Planned {
        history,
        probability: &adaptive.probability,
        schedule,
        after_move: reprojection
            .after_move
            .then_some((reprojection, r.depth_tolerance)),
        reprojection: r.enabled,
        spp,
        fresh: if reprojection.carried { r.fresh_spp } else { 0 },
    });
    (plan, above_one, end, tau)
}

/// What a change of the configuration from `old` to `new` asks of the next frame: a camera
/// move (the view alone changed), a new epoch (anything else that changes the image), or
/// nothing (the display settings, `max_frames` and the reconstruction filter, a post-process
/// of the history).
fn change(old: &Config, new: &Config) -> Option<Change> {
    let image = |c: &Config| Config {
        display: Default::default(),
        frame: FrameConfig {
            max_frames: 0,
            target_ms: 0.0,
            filter: Default::default(),
            ..c.frame.clone()
        },
        ..c.clone()
    };
    let (new, old) = (image(new), image(old));
    if new == old {
        return None;
    }
    let view = |c: &Config| crate::config::CameraConfig {
        look_from: None,
        look_at: None,
        up: None,
        fov_y: None,
        ..c.camera.clone()
    };
    let moved = Config {
        camera: view(&new),
        ..new.clone()
    } == Config {
        camera: view(&old),
        ..old
    };
    Some(if moved {
        Change::Camera
    } else {
        Change::Settings
    })
}
