//! The real-time frame pipeline: a frame is a fixed sequence of passes over screen-sized
//! buffers, each a function from named inputs to named outputs.
//!
//! ```text
//! reproject   states, previous camera, camera     -> states and history in the new view
//!             (seed 000, after a camera move; [`reprojection`])
//! primary     camera, previous camera, plan       -> G-buffer (features, motion, first hits)
//! lighting    G-buffer, plan                      -> lighting (direct / indirect statistics,
//!                                                    first bounce)
//! accumulate  lighting, history (states)          -> history (running statistics over frames)
//! filter      history, G-buffer, lighting         -> filtered image (seed 001, when on;
//!                                                    [`filter`])
//! display     history, lighting, G-buffer, ...    -> 8-bit RGBA of the chosen display mode
//! ```
//!
//! The *plan* says which pixels the primary and lighting passes trace and from which sample
//! index: every pixel from `frames * spp` in the plain pipeline; with seed 000's techniques,
//! each pixel from its own sample count, and with adaptive sampling ([`adaptive`]) only the
//! pixels its schedule picks.
//!
//! One [`Config`] drives it: the resolution, samples per frame, bounces, the passes' switches
//! and parameters ([`crate::config::FrameConfig`]) and the display. While the camera and the
//! settings stay the same, frames accumulate (progressive refinement); any change starts a
//! new *epoch*: the samples are drawn afresh and the history is cleared, except that with
//! forward reprojection on, a change of the camera alone carries the history into the new
//! view. Frame `f` of an epoch takes sample indices `f * spp ..`, and epoch 0 uses the
//! configuration's seed unchanged, so `N` still frames of one sample are the reference path
//! tracer's image at `N` samples per pixel. Later epochs use seeds hashed from it, so every
//! frame is deterministic for a given scene, configuration and sequence of camera moves,
//! whatever the thread count. With the techniques' switches off, frames are bit for bit those
//! of the plain pipeline.
//!
//! Buffers live across frames and are reallocated only when the resolution changes.

pub mod accumulation;
pub mod adaptive;
pub mod display;
pub mod filter;
pub mod gbuffer;
pub mod lighting;
pub mod ping_pong;
pub mod reprojection;
pub mod restir;

use std::time::Instant;

use pathlight_core::rng::hash;
use rayon::prelude::*;
use serde::Serialize;

use crate::camera::Camera;
use crate::config::Config;
use crate::path::{CameraSample, PathTracer};
use crate::world::World;
use pathlight_accel::{Hit, Ray};

use accumulation::PixelStats;
use adaptive::{Adaptive, Schedule, NO_PROBABILITY};
use display::{DisplayMode, Sources};
use gbuffer::{GBuffer, GPixel, PrimaryHit};
use lighting::LightSample;
use reprojection::{Reprojection, ReprojectionReport};
use restir::{Restir, RestirConfig, RestirTimes};

/// The passes' names, as in timings and display modes.
pub const REPROJECT: &str = "reproject";
pub const PRIMARY: &str = "primary";
pub const LIGHTING: &str = "lighting";
/// Seed 004's passes: the reservoirs' candidates (with visibility reuse), temporal and
/// spatial reuse.
pub const RESTIR: &str = "restir";
pub const RESTIR_TEMPORAL: &str = "restir temporal";
pub const RESTIR_SPATIAL: &str = "restir spatial";
pub const ACCUMULATE: &str = "accumulate";
/// Seed 001's reconstruction filter.
pub const FILTER: &str = "filter";
pub const DISPLAY: &str = "display";
/// Every pass, in the order a frame runs them.
pub const PASSES: [&str; 9] = [
    REPROJECT,
    PRIMARY,
    RESTIR,
    RESTIR_TEMPORAL,
    RESTIR_SPATIAL,
    LIGHTING,
    ACCUMULATE,
    FILTER,
    DISPLAY,
];

/// Pixels per parallel task: a run of pixels in row-major order, small enough that its first
/// hits stay in the L1/L2 cache between the primary and the lighting pass.
const RUN: usize = 128;

/// The time one pass took.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PassTime {
    pub pass: &'static str,
    pub ms: f64,
}

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

/// The frame pipeline and its buffers.
pub struct Pipeline {
    /// The configuration in force (as last given).
    config: Config,
    /// The configuration the tracer uses this epoch (its seed derived from the epoch).
    epoch_config: Config,
    camera: Option<Camera>,
    previous_camera: Option<Camera>,
    pub gbuffer: GBuffer,
    /// The lighting pass's output for the current frame.
    pub lighting: Vec<LightSample>,
    /// Running statistics over this epoch's frames.
    pub history: Vec<PixelStats>,
    /// The display pass's output: 8-bit RGBA, row-major.
    pub rgba: Vec<u8>,
    /// Adaptive sampling's per-pixel state (seed 000).
    pub adaptive: Adaptive,
    /// Forward reprojection's per-pixel states (seed 000).
    pub reprojection: Reprojection,
    /// ReSTIR's reservoirs (seed 004).
    pub restir: Restir,
    /// The reconstruction filter's features and output (seed 001).
    pub filter: filter::Filter,
    /// The frame's first hits, kept for the whole frame when ReSTIR runs (its passes need
    /// every pixel's surface before the lighting pass).
    hits: Vec<Vec<PrimaryHit>>,
    /// Reprojection with `fresh_spp`: the samples each pixel still lacks after the
    /// accumulation pass's drops, and the buffers their pass traces into.
    repair: Repair,
    epoch: u64,
    frames: u32,
    frame_number: u64,
    /// Why the next frame must start a new epoch (none: it continues this one).
    reset: Option<Reset>,
    /// This frame follows a reprojection: its accumulation runs the aliasing test.
    after_move: bool,
    /// This epoch began with a reprojection (its pixels without history are holes).
    carried: bool,
    /// SVGF with `svgf_still_handover`: an epoch's first frame leaves its G-buffer and
    /// lighting for the features' statistics to the next frame, which gathers them only if
    /// it continues the epoch (the camera stayed); a camera that moves at every frame then
    /// gathers nothing. The epoch whose first frame waits in the frame's own buffers.
    deferred: Option<u64>,
    /// The buffers the next frame traces into meanwhile.
    spare: Spare,
    /// When the data-driven filter last filtered the accumulated image (`refresh_growth`).
    filtered: Option<Filtered>,
}

/// The epoch, its frames and the filter's configuration when the data-driven filter last
/// filtered the accumulated image.
struct Filtered {
    epoch: u64,
    frames: u32,
    config: pathlight_denoise::FilterConfig,
}

/// The G-buffer and lighting of a frame whose features wait to be gathered, and its epoch
/// (none once gathered or dropped).
#[derive(Default)]
struct Spare {
    gbuffer: GBuffer,
    lighting: Vec<LightSample>,
    epoch: Option<u64>,
}

/// Why a frame starts a new epoch.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Reset {
    /// The camera's view changed and nothing else: reprojection may carry the history over.
    Camera,
    /// Anything else that changes the image (or the first frame): start afresh.
    Settings,
}

impl Pipeline {
    /// A pipeline for `config` (checked by [`Config::validate`] beforehand by the caller).
    pub fn new(config: Config) -> Self {
        Self {
            epoch_config: config.clone(),
            config,
            camera: None,
            previous_camera: None,
            gbuffer: GBuffer::default(),
            lighting: Vec::new(),
            history: Vec::new(),
            rgba: Vec::new(),
            adaptive: Adaptive::default(),
            reprojection: Reprojection::default(),
            restir: Restir::default(),
            filter: filter::Filter::default(),
            hits: Vec::new(),
            repair: Repair::default(),
            epoch: 0,
            frames: 0,
            frame_number: 0,
            reset: Some(Reset::Settings),
            after_move: false,
            carried: false,
            deferred: None,
            spare: Spare::default(),
            filtered: None,
        }
    }

    pub fn config(&self) -> &Config {
        &self.config
    }

    /// The camera of the current epoch (after the first frame).
    pub fn camera(&self) -> Option<&Camera> {
        self.camera.as_ref()
    }

    /// Replaces the configuration. Anything that changes the image (camera, resolution,
    /// samples, passes) starts a new epoch at the next frame; the display settings,
    /// `max_frames` and the reconstruction filter (a post-process of the history) do not. A
    /// change of the view alone (position, direction, up, field of view) is a camera move,
    /// which forward reprojection survives.
    pub fn set_config(&mut self, config: &Config) {
        let image = |c: &Config| Config {
            display: Default::default(),
            frame: crate::config::FrameConfig {
                max_frames: 0,
                filter: Default::default(),
                ..c.frame.clone()
            },
            ..c.clone()
        };
        let (new, old) = (image(config), image(&self.config));
        if new != old {
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
            let reset = if moved {
                Reset::Camera
            } else {
                // Last frame's reservoirs mean nothing under other settings (a camera move,
                // or a frame of a pipeline that does not accumulate, keeps them).
                self.restir.reset();
                Reset::Settings
            };
            self.reset = Some(match self.reset {
                Some(Reset::Settings) => Reset::Settings,
                _ => reset,
            });
        }
        self.config = config.clone();
    }

    /// Clears the history: the next frame starts a new epoch afresh.
    pub fn reset(&mut self) {
        self.reset = Some(Reset::Settings);
        self.restir.reset();
    }

    /// Frames accumulated in this epoch.
    pub fn accumulated(&self) -> u32 {
        self.frames
    }

    /// Starts a new epoch: camera, seed, buffers; the techniques' state carried into the new
    /// view (returns what reprojection did) or cleared.
    fn start_epoch(&mut self, world: &World, reset: Reset) -> Option<ReprojectionReport> {
        if self.frame_number > 0 {
            self.epoch += 1;
        }
        self.frames = 0;
        self.adaptive.iteration = 0;
        let mut c = self.config.clone();
        if self.epoch > 0 {
            c.seed = hash(&[self.config.seed, self.epoch]);
        }
        self.epoch_config = c;
        let previous = self.camera.take();
        let camera = self.config.render_camera(world);
        let (w, h) = (self.config.width, self.config.height);
        let resized = (self.gbuffer.width, self.gbuffer.height) != (w, h);
        self.gbuffer.resize(w, h);
        let n = w as usize * h as usize;
        // Same size: kept as they are (the first frame of the epoch overwrites the history).
        self.history.resize(n, PixelStats::default());
        self.lighting.resize(n, LightSample::default());
        self.after_move = false;
        self.carried = false;
        let frame = &self.config.frame;
        let mut report = None;
        if frame.adaptive.enabled || frame.reprojection.enabled {
            let k = frame.reprojection.samples as usize;
            let r = &mut self.reprojection;
            let carry = frame.reprojection.enabled
                && frame.accumulate
                && reset == Reset::Camera
                && r.valid
                && r.samples == k
                && !resized
                && self.adaptive.probability.len() == n;
            match previous.as_ref().filter(|_| carry) {
                Some(previous) => {
                    report = Some(r.reproject(
                        world,
                        previous,
                        &camera,
                        w,
                        &frame.reprojection,
                        &mut self.history,
                        &mut self.adaptive.probability,
                    ));
                    self.after_move = true;
                    self.carried = true;
                }
                None => {
                    self.history.fill(PixelStats::default());
                    self.adaptive.reset(n);
                    if frame.reprojection.enabled {
                        r.reset(n, k);
                    } else {
                        r.valid = false;
                    }
                }
            }
        } else {
            self.reprojection.valid = false;
        }
        self.camera = Some(camera);
        report
    }

    /// Renders one frame of `world`: reprojection (after a camera move, when on), primary
    /// visibility, lighting and accumulation. The display pass is
    /// [`display`](Self::display), run by those who show or write frames.
    pub fn render_frame(&mut self, world: &World) -> FrameReport {
        let start = Instant::now();
        let mut passes = Vec::with_capacity(5);
        let mut reprojection = None;
        let reset = match self.reset.take() {
            None if !self.config.frame.accumulate => Some(Reset::Settings),
            r => r,
        };
        if let Some(reset) = reset {
            let t = Instant::now();
            reprojection = self.start_epoch(world, reset);
            if reprojection.is_some() {
                passes.push(PassTime {
                    pass: REPROJECT,
                    ms: t.elapsed().as_secs_f64() * 1e3,
                });
            }
        }
        let max = self.config.frame.max_frames;
        let traced = !(self.config.frame.accumulate && max > 0 && self.frames >= max);
        let mut rays = 0;
        let mut samples = 0;
        let mut tau = None;
        let mut above_one = None;
        // The end of the iterations of adaptive sampling's schedule this frame runs.
        let mut end = None;
        let mut restir_times: Option<RestirTimes> = None;
        let frame = &self.config.frame;
        let techniques = frame.adaptive.enabled || frame.reprojection.enabled;
        // Every pixel traced the plain way (neither seed 000's techniques nor ReSTIR).
        let uniform = !(techniques || frame.restir.enabled);
        if traced {
            let camera = self.camera.as_ref().expect("set by start_epoch");
            let tracer = PathTracer {
                world,
                camera,
                settings: self.epoch_config.path_settings(),
            };
            let spp = self.epoch_config.spp.max(1);
            let pixels = self.history.len() as u64;

            // Primary visibility and lighting run by runs of pixels: a run's first hits go
            // straight from one pass to the other while they are in cache. Each pass's time is
            // the wall time split in proportion to the thread time it took.
            let t = Instant::now();
            let previous = self.previous_camera.as_ref();
            let (r, primary_s, lighting_s) = if techniques {
                let a = &frame.adaptive;
                if a.enabled && self.adaptive.iteration < a.max_spp {
                    // V is read during the schedule only.
                    self.adaptive.measure_image(
                        a.measure,
                        &self.history,
                        self.gbuffer.width as usize,
                    );
                }
                if a.enabled && a.skip_empty {
                    let busy =
                        self.adaptive
                            .first_busy(a, &self.history, frame.reprojection.enabled);
                    if busy == a.max_spp && self.adaptive.iteration < a.max_spp {
                        // The rest of the schedule would sample nothing: its end now.
                        above_one = Some(self.adaptive.fix_probabilities(
                            &self.history,
                            a.max_spp,
                            a.cap,
                        ));
                    }
                    self.adaptive.iteration = busy;
                }
                let schedule = frame.adaptive.enabled.then(|| {
                    let mut s = Schedule::new(
                        &frame.adaptive,
                        self.adaptive.iteration,
                        frame.reprojection.enabled,
                        self.epoch_config.seed,
                    );
                    s.regional = &self.adaptive.regional;
                    s.reference = self.adaptive.reference;
                    if a.budget && !self.after_move {
                        if s.iteration < s.max_spp {
                            s.end = self.adaptive.budget_end(&s, &self.history, pixels);
                        } else {
                            s.scale = self.adaptive.scale;
                        }
                    }
                    s
                });
                end = schedule.map(|s| s.end);
                tau = schedule.filter(|s| s.iteration < s.max_spp).map(|s| s.tau);
                let plan = Planned {
                    history: &self.history,
                    probability: &self.adaptive.probability,
                    schedule,
                    after_move: self
                        .after_move
                        .then_some((&self.reprojection, frame.reprojection.depth_tolerance)),
                    reprojection: frame.reprojection.enabled,
                    spp,
                    fresh: if self.carried {
                        frame.reprojection.fresh_spp
                    } else {
                        0
                    },
                };
                trace(
                    &mut self.gbuffer,
                    &mut self.lighting,
                    previous,
                    &tracer,
                    &plan,
                )
            } else if frame.restir.enabled {
                samples = spp as u64 * pixels;
                let index = self.frames.saturating_mul(spp);
                let (r, times) = trace_restir(
                    &mut self.gbuffer,
                    &mut self.lighting,
                    &mut self.hits,
                    &mut self.restir,
                    &frame.restir,
                    previous,
                    &tracer,
                    index,
                    spp,
                );
                restir_times = Some(times);
                r
            } else {
                samples = spp as u64 * pixels;
                let index = self.frames.saturating_mul(spp);
                if let Some(epoch) = self.deferred.take() {
                    // The waiting frame's buffers become the spare ones; this frame traces
                    // into the others (every pixel of them).
                    let spare = &mut self.spare;
                    std::mem::swap(&mut self.gbuffer, &mut spare.gbuffer);
                    std::mem::swap(&mut self.lighting, &mut spare.lighting);
                    spare.epoch = Some(epoch);
                    self.gbuffer
                        .resize(spare.gbuffer.width, spare.gbuffer.height);
                    self.lighting
                        .resize(spare.lighting.len(), LightSample::default());
                }
                trace(
                    &mut self.gbuffer,
                    &mut self.lighting,
                    previous,
                    &tracer,
                    &Uniform(index, spp),
                )
            };
            rays += r;
            let mut wall = t.elapsed().as_secs_f64() * 1e3;
            if let Some(times) = &restir_times {
                wall -= times.candidates_ms + times.temporal_ms + times.spatial_ms;
            }
            let primary_ms = wall * primary_s / (primary_s + lighting_s).max(1e-12);
            passes.push(PassTime {
                pass: PRIMARY,
                ms: primary_ms,
            });
            if let Some(times) = restir_times {
                rays += times.rays;
                passes.extend([
                    PassTime {
                        pass: RESTIR,
                        ms: times.candidates_ms,
                    },
                    PassTime {
                        pass: RESTIR_TEMPORAL,
                        ms: times.temporal_ms,
                    },
                    PassTime {
                        pass: RESTIR_SPATIAL,
                        ms: times.spatial_ms,
                    },
                ]);
            }
            let mut lighting_ms = wall - primary_ms;
            if techniques && self.carried && frame.reprojection.fresh_spp > 0 {
                let t = Instant::now();
                rays += self.repair.run(
                    &self.reprojection,
                    &self.history,
                    &mut self.lighting,
                    &self.gbuffer,
                    frame.reprojection.fresh_spp,
                    frame.reprojection.depth_tolerance,
                    self.after_move,
                    previous,
                    &tracer,
                );
                lighting_ms += t.elapsed().as_secs_f64() * 1e3;
            }
            passes.push(PassTime {
                pass: LIGHTING,
                ms: lighting_ms,
            });

            let t = Instant::now();
            if techniques {
                samples = self.lighting.par_iter().map(|l| l.stats.n as u64).sum();
                if frame.reprojection.enabled {
                    let dropped = self.reprojection.accumulate(
                        world,
                        camera,
                        &self.gbuffer,
                        &self.lighting,
                        frame.reprojection.depth_tolerance,
                        self.after_move,
                        &mut self.history,
                        &mut self.adaptive.probability,
                    );
                    if let Some(r) = reprojection.as_mut() {
                        r.aliasing = dropped;
                        r.kept -= dropped;
                    }
                } else {
                    self.history
                        .par_iter_mut()
                        .zip(self.lighting.par_iter())
                        .for_each(|(h, l)| h.merge(&l.stats));
                }
                let a = &frame.adaptive;
                let i = self.adaptive.iteration;
                let end = end.unwrap_or(i.saturating_add(1));
                if a.enabled && i < a.max_spp && end >= a.max_spp {
                    above_one = Some(self.adaptive.fix_probabilities(
                        &self.history,
                        a.max_spp,
                        a.cap,
                    ));
                }
                self.adaptive.iteration = end;
            } else {
                let first = self.frames == 0;
                self.history
                    .par_iter_mut()
                    .zip(self.lighting.par_iter())
                    .for_each(|(h, l)| {
                        if first {
                            *h = l.stats;
                        } else {
                            h.merge(&l.stats);
                        }
                    });
            }
            passes.push(PassTime {
                pass: ACCUMULATE,
                ms: t.elapsed().as_secs_f64() * 1e3,
            });

            self.after_move = false;
            self.frames += 1;
            self.previous_camera = self.camera.clone();
        }
        self.frame_number += 1;
        let filter = &self.config.frame.filter;
        // (`self.frames` counts this one: the frames of a still camera.)
        let method = filter.method_after(self.frames);
        if method.in_frame() {
            let t = Instant::now();
            let svgf = method == pathlight_denoise::Method::Svgf;
            let data_driven = method == pathlight_denoise::Method::DataDriven;
            // An epoch's first frame waits to be gathered until a second one comes (a camera
            // that moves at every frame never gathers): SVGF does not read the statistics,
            // and the data-driven filter reads that frame's features from the frame itself.
            let waits = traced && filter.gathers_features() && self.frames == 1 && uniform;
            if traced && filter.gathers_features() {
                // The epoch's first frame, if it waited, before this one (the statistics
                // are then those of gathering every frame, bit for bit).
                let spare = &mut self.spare;
                if spare.epoch.take() == Some(self.epoch) {
                    self.filter
                        .gather(self.epoch, &spare.gbuffer, &spare.lighting);
                }
                if waits {
                    self.deferred = Some(self.epoch);
                } else {
                    self.filter
                        .gather(self.epoch, &self.gbuffer, &self.lighting);
                }
            }
            // With `refresh_growth`, a still view's data-driven image stays as it was until
            // the frames have grown by that factor.
            let stays = data_driven
                && !self.filter.image.is_empty()
                && self.filtered.as_ref().is_some_and(|f| {
                    f.epoch == self.epoch
                        && f.config == *filter
                        && (self.frames as f32) < f.frames as f32 * filter.refresh_growth
                });
            let run = (traced || !svgf).then(|| {
                if stays {
                    self.filter.refresh_own_light(&self.history);
                    return Ok(());
                }
                self.filtered = data_driven.then(|| Filtered {
                    epoch: self.epoch,
                    frames: self.frames,
                    config: filter.clone(),
                });
                self.filter.run(
                    method,
                    filter,
                    &self.history,
                    &self.gbuffer,
                    &self.lighting,
                    !waits,
                )
            });
            if let Some(Err(_)) = run {
                // Not reached: the configuration was validated and the buffers are the
                // frame's. Show the unfiltered image rather than a stale one.
                self.filter.clear();
            }
            passes.push(PassTime {
                pass: FILTER,
                ms: t.elapsed().as_secs_f64() * 1e3,
            });
        } else if !self.filter.image.is_empty() {
            self.filter.clear();
            (self.deferred, self.spare.epoch) = (None, None);
        }
        let spp = if techniques {
            let total: u64 = self.history.par_iter().map(|h| h.n as u64).sum();
            (total / self.history.len().max(1) as u64) as u32
        } else {
            self.history.first().map_or(0, |h| h.n)
        };
        FrameReport {
            frame: self.frame_number,
            epoch: self.epoch,
            accumulated: self.frames,
            spp,
            traced,
            samples,
            passes,
            ms: start.elapsed().as_secs_f64() * 1e3,
            rays,
            reprojection,
            tau,
            probability_above_one: above_one,
        }
    }

    /// The display pass: the configured display mode as 8-bit RGBA into
    /// [`rgba`](Self::rgba); its time is added to `report`.
    pub fn display(&mut self, report: &mut FrameReport) {
        let t = Instant::now();
        let mut rgba = std::mem::take(&mut self.rgba);
        self.sources()
            .rgba8(self.config.display.mode, &self.config.display, &mut rgba);
        self.rgba = rgba;
        let ms = t.elapsed().as_secs_f64() * 1e3;
        report.passes.push(PassTime { pass: DISPLAY, ms });
        report.ms += ms;
    }

    /// Bytes the pipeline's per-pixel buffers hold: the plain pipeline's (G-buffer,
    /// lighting, history, display) and the techniques' (seed 000's probabilities, states and
    /// their scratch, seed 004's reservoirs, seed 001's filters and the spare G-buffer and
    /// lighting of SVGF's handover).
    pub fn bytes(&self) -> (usize, usize) {
        use std::mem::size_of;
        let plain = self.gbuffer.pixels.capacity() * size_of::<GPixel>()
            + self.lighting.capacity() * size_of::<LightSample>()
            + self.history.capacity() * size_of::<PixelStats>()
            + self.rgba.capacity();
        let techniques = self.adaptive.probability.capacity() * size_of::<f32>()
            + self.reprojection.bytes()
            + self.restir.bytes()
            + self.filter.bytes()
            + self.repair.bytes()
            + self.hits.iter().map(|r| r.capacity()).sum::<usize>() * size_of::<PrimaryHit>()
            + self.spare.gbuffer.pixels.capacity() * size_of::<GPixel>()
            + self.spare.lighting.capacity() * size_of::<LightSample>();
        (plain, techniques)
    }

    /// The buffers the display modes read.
    pub fn sources(&self) -> Sources<'_> {
        Sources {
            gbuffer: &self.gbuffer,
            lighting: &self.lighting,
            history: &self.history,
            probability: &self.adaptive.probability,
            reprojection: &self.reprojection,
            reservoirs: self.restir.shaded(),
            filtered: &self.filter.image,
            feature_variance: &self.filter.variance,
            sure_shares: self.filter.shares(),
        }
    }

    /// The image (mean radiance, filtered when the filter is on), row-major.
    pub fn image(&self) -> Vec<glam::Vec3> {
        self.sources().linear(DisplayMode::Final)
    }
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
struct Repair {
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
        let (rays, _, _) = trace(
            &mut self.gbuffer,
            &mut self.lighting,
            previous,
            tracer,
            &plan,
        );
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

/// Which pixels a frame traces, and from which sample index.
trait Plan: Sync {
    /// Every pixel is traced from [`sample`](Self::sample)`(0)` and lit: the plain
    /// pipeline's loops, without per-pixel bookkeeping.
    const EVERY_PIXEL: bool = false;
    /// The first sample index of pixel `pixel` this frame; `None`: the pixel is not traced
    /// (its G-buffer pixel stays as it was, its lighting is empty).
    fn sample(&self, pixel: usize) -> Option<u32>;
    /// After the primary pass filled G-buffer pixel `g`: how many samples the lighting pass
    /// takes in the pixel (0: none).
    fn keep(&self, pixel: usize, g: &GPixel) -> u32;
    /// The lighting pass measures the radiance along each pixel's first bounce.
    fn along_first_bounce(&self) -> bool {
        false
    }
}

/// The plain pipeline: every pixel, all from one sample index (`.0`), `.1` samples each.
struct Uniform(u32, u32);

impl Plan for Uniform {
    const EVERY_PIXEL: bool = true;

    #[inline(always)]
    fn sample(&self, _: usize) -> Option<u32> {
        Some(self.0)
    }

    #[inline(always)]
    fn keep(&self, _: usize, _: &GPixel) -> u32 {
        self.1
    }
}

/// Seed 000's techniques: each pixel continues its own sample sequence; adaptive sampling
/// picks the pixels.
struct Planned<'a> {
    history: &'a [PixelStats],
    probability: &'a [f32],
    schedule: Option<Schedule<'a>>,
    /// The frame after a reprojection, with the aliasing test's tolerance: every pixel gets
    /// its primary ray (the test needs the new G-buffer), and adaptive sampling decides on
    /// the states that survive the test.
    after_move: Option<(&'a Reprojection, f32)>,
    /// Forward reprojection is on: its states need the radiance along the first bounce.
    reprojection: bool,
    /// Samples per pixel per frame.
    spp: u32,
    /// In an epoch that began with a reprojection: a pixel holding fewer samples takes the
    /// missing ones at once (`fresh_spp`; 0: off).
    fresh: u32,
}

impl Planned<'_> {
    /// The samples a pixel the primary pass traced takes, outside the frame after a move:
    /// `spp`, or `spp` for each of the schedule's iterations that sample it when a frame runs
    /// several ([`AdaptiveConfig::budget`](adaptive::AdaptiveConfig::budget)).
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

/// The primary and lighting passes over the pixels `plan` picks, run by run in parallel.
/// Returns the rays traced and the thread time (seconds) of each pass.
fn trace<P: Plan>(
    gbuffer: &mut GBuffer,
    lighting: &mut [LightSample],
    previous: Option<&Camera>,
    tracer: &PathTracer,
    plan: &P,
) -> (u64, f64, f64) {
    let w = gbuffer.width.max(1) as usize;
    gbuffer
        .pixels
        .par_chunks_mut(RUN)
        .zip(lighting.par_chunks_mut(RUN))
        .enumerate()
        .map_init(
            || {
                (
                    Vec::with_capacity(RUN),
                    Vec::with_capacity(RUN),
                    Vec::with_capacity(RUN),
                    Vec::with_capacity(RUN),
                    Vec::with_capacity(RUN),
                )
            },
            |(cameras, camera_rays, first_hits, hits, traced), (b, (gpixels, lpixels))| {
                // The pixels of the run, in order (no division per pixel).
                let start = b * RUN;
                let pixels = || {
                    let (mut x, mut y) = ((start % w) as u32, (start / w) as u32);
                    std::iter::from_fn(move || {
                        let p = (x, y);
                        x += 1;
                        if x as usize == w {
                            (x, y) = (0, y + 1);
                        }
                        Some(p)
                    })
                };
                let mut rays = 0u64;
                let t0 = Instant::now();
                // The run's camera samples first, in a loop of independent iterations, so that
                // their hash and Sobol latency chains overlap instead of stalling each trace.
                cameras.clear();
                traced.clear();
                if P::EVERY_PIXEL {
                    let index = plan.sample(start).unwrap_or(0);
                    cameras.extend(
                        pixels()
                            .take(gpixels.len())
                            .map(|(x, y)| tracer.camera_sample(x, y, index)),
                    );
                } else {
                    for (k, (x, y)) in pixels().take(gpixels.len()).enumerate() {
                        match plan.sample(start + k) {
                            Some(index) => {
                                cameras.push(tracer.camera_sample(x, y, index));
                                traced.push((k, x, y, index));
                            }
                            None => lpixels[k] = LightSample::default(),
                        }
                    }
                }
                hits.clear();
                rays += primary_run(
                    tracer,
                    previous,
                    cameras,
                    camera_rays,
                    first_hits,
                    |i, pixel, hit| {
                        // The i-th camera sample's pixel of the run.
                        let k = if P::EVERY_PIXEL { i } else { traced[i].0 };
                        gpixels[k] = pixel;
                        hits.push(hit);
                    },
                );
                let t1 = Instant::now();
                if P::EVERY_PIXEL {
                    let index = plan.sample(start).unwrap_or(0);
                    let spp = plan.keep(start, &gpixels[0]);
                    for ((l, hit), (x, y)) in lpixels.iter_mut().zip(hits.iter()).zip(pixels()) {
                        let (sample, r) =
                            lighting::lighting::<false>(tracer, x, y, hit, index, spp, None);
                        *l = sample;
                        rays += r;
                    }
                } else {
                    let along = plan.along_first_bounce();
                    for (&(k, x, y, index), hit) in traced.iter().zip(hits.iter()) {
                        let spp = plan.keep(start + k, &gpixels[k]);
                        lpixels[k] = if spp > 0 {
                            let (sample, r) = if along {
                                lighting::lighting::<true>(tracer, x, y, hit, index, spp, None)
                            } else {
                                lighting::lighting::<false>(tracer, x, y, hit, index, spp, None)
                            };
                            rays += r;
                            sample
                        } else {
                            LightSample::default()
                        };
                    }
                }
                let t2 = Instant::now();
                (rays, (t1 - t0).as_secs_f64(), (t2 - t1).as_secs_f64())
            },
        )
        .reduce(|| (0, 0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1, a.2 + b.2))
}

/// The primary pass over a run's camera samples (drained): their rays traced together
/// (neighbouring pixels' rays go as packets), then each followed to its first surface;
/// `emit(i, pixel, hit)` takes the i-th sample's G-buffer pixel and first hit. Returns the
/// rays traced.
#[inline(always)]
fn primary_run(
    tracer: &PathTracer,
    previous: Option<&Camera>,
    cameras: &mut Vec<CameraSample>,
    camera_rays: &mut Vec<Ray>,
    first_hits: &mut Vec<Option<Hit>>,
    mut emit: impl FnMut(usize, GPixel, PrimaryHit),
) -> u64 {
    camera_rays.clear();
    camera_rays.extend(cameras.iter().map(|c| c.ray));
    first_hits.resize(camera_rays.len(), None);
    tracer.world.accel.intersect_batch(camera_rays, first_hits);
    let mut rays = 0;
    for (i, (sample, &first)) in cameras.drain(..).zip(&*first_hits).enumerate() {
        let (pixel, hit, r) = gbuffer::primary(tracer, sample, first, previous);
        emit(i, pixel, hit);
        rays += r as u64;
    }
    rays
}

/// The frame with ReSTIR (seed 004): the primary pass over every pixel (sample `index`), the
/// ReSTIR passes over the whole frame's first hits, then the lighting pass, whose first
/// sample of each pixel takes its direct light at the first hit from the pixel's reservoir.
/// Returns the rays traced, the primary and lighting passes' thread times (seconds) and the
/// ReSTIR passes' times.
#[allow(clippy::too_many_arguments)]
fn trace_restir(
    gbuffer: &mut GBuffer,
    lighting: &mut [LightSample],
    hits: &mut Vec<Vec<PrimaryHit>>,
    restir: &mut Restir,
    config: &RestirConfig,
    previous: Option<&Camera>,
    tracer: &PathTracer,
    index: u32,
    spp: u32,
) -> ((u64, f64, f64), RestirTimes) {
    let w = gbuffer.width.max(1) as usize;
    let t = Instant::now();
    // The first hits by runs of pixels (each run's vector keeps its capacity across frames).
    hits.resize_with(gbuffer.pixels.len().div_ceil(RUN), Vec::new);
    let mut rays: u64 = gbuffer
        .pixels
        .par_chunks_mut(RUN)
        .zip(hits.par_iter_mut())
        .enumerate()
        .map_init(
            || {
                (
                    Vec::with_capacity(RUN),
                    Vec::with_capacity(RUN),
                    Vec::with_capacity(RUN),
                )
            },
            |(cameras, camera_rays, first_hits), (b, (gpixels, out))| {
                let start = b * RUN;
                cameras.extend(
                    (start..start + gpixels.len())
                        .map(|p| tracer.camera_sample((p % w) as u32, (p / w) as u32, index)),
                );
                out.clear();
                primary_run(
                    tracer,
                    previous,
                    cameras,
                    camera_rays,
                    first_hits,
                    |i, pixel, hit| {
                        gpixels[i] = pixel;
                        out.push(hit);
                    },
                )
            },
        )
        .sum();
    let primary_s = t.elapsed().as_secs_f64();

    let times = restir.run(tracer, config, gbuffer, index, hits, RUN);

    let t = Instant::now();
    let (receivers, reservoirs) = (&restir.receivers, &restir.reservoirs);
    rays += lighting
        .par_chunks_mut(RUN)
        .zip(hits.par_iter())
        .enumerate()
        .map(|(b, (ls, run))| {
            let mut rays = 0;
            for (k, (l, hit)) in ls.iter_mut().zip(run).enumerate() {
                let p = b * RUN + k;
                let (x, y) = ((p % w) as u32, (p / w) as u32);
                let mut shadow = 0;
                let direct = receivers[p]
                    .as_ref()
                    .map(|rec| rec.shade(tracer, &reservoirs[p], &mut shadow));
                let (sample, r) =
                    lighting::lighting::<false>(tracer, x, y, hit, index, spp, direct);
                *l = sample;
                rays += r + shadow as u64;
            }
            rays
        })
        .sum::<u64>();
    let lighting_s = t.elapsed().as_secs_f64();
    restir.keep(&gbuffer.pixels);
    ((rays, primary_s, lighting_s), times)
}
