//! The real-time frame pipeline: a frame is a fixed sequence of passes over screen-sized
//! buffers, each a function from named inputs to named outputs.
//!
//! ```text
//! primary     camera, previous camera        -> G-buffer (features, motion, first hits)
//! lighting    G-buffer                        -> lighting (direct / indirect statistics, bounce)
//! accumulate  lighting, history               -> history (running statistics over frames)
//! display     history, lighting, G-buffer     -> 8-bit RGBA of the chosen display mode
//! ```
//!
//! One [`Config`] drives it: the resolution, samples per frame, bounces, the passes' switches
//! and parameters ([`crate::config::FrameConfig`]) and the display. While the camera and the
//! settings stay the same, frames accumulate (progressive refinement); any change starts a
//! new *epoch*: the history is cleared and the samples are drawn afresh. Frame `f` of an epoch
//! takes sample indices `f * spp ..`, and epoch 0 uses the configuration's seed unchanged, so
//! `N` still frames of one sample are the reference path tracer's image at `N` samples per
//! pixel. Later epochs use seeds hashed from it, so every frame is deterministic for a given
//! scene, configuration and sequence of camera moves, whatever the thread count.
//!
//! Buffers live across frames and are reallocated only when the resolution changes.

pub mod accumulation;
pub mod display;
pub mod gbuffer;
pub mod lighting;

use std::time::Instant;

use pathlight_core::rng::hash;
use rayon::prelude::*;
use serde::Serialize;

use crate::camera::Camera;
use crate::config::Config;
use crate::path::PathTracer;
use crate::world::World;

use accumulation::PixelStats;
use display::{DisplayMode, Sources};
use gbuffer::GBuffer;
use lighting::LightSample;

/// The passes' names, as in timings and display modes.
pub const PRIMARY: &str = "primary";
pub const LIGHTING: &str = "lighting";
pub const ACCUMULATE: &str = "accumulate";
pub const DISPLAY: &str = "display";
/// Every pass, in the order a frame runs them.
pub const PASSES: [&str; 4] = [PRIMARY, LIGHTING, ACCUMULATE, DISPLAY];

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
    /// Rays traced (closest-hit and shadow queries).
    pub rays: u64,
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
    epoch: u64,
    frames: u32,
    frame_number: u64,
    /// True when the next frame must start a new epoch.
    stale: bool,
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
            epoch: 0,
            frames: 0,
            frame_number: 0,
            stale: true,
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
    /// samples, passes) starts a new epoch at the next frame; the display settings and
    /// `max_frames` do not.
    pub fn set_config(&mut self, config: &Config) {
        let image = |c: &Config| Config {
            display: Default::default(),
            frame: crate::config::FrameConfig {
                max_frames: 0,
                ..c.frame.clone()
            },
            ..c.clone()
        };
        if image(config) != image(&self.config) {
            self.stale = true;
        }
        self.config = config.clone();
    }

    /// Clears the history: the next frame starts a new epoch.
    pub fn reset(&mut self) {
        self.stale = true;
    }

    /// Frames accumulated in this epoch.
    pub fn accumulated(&self) -> u32 {
        self.frames
    }

    /// Starts a new epoch: camera, seed, buffers.
    fn start_epoch(&mut self, world: &World) {
        if self.frame_number > 0 {
            self.epoch += 1;
        }
        self.frames = 0;
        let mut c = self.config.clone();
        if self.epoch > 0 {
            c.seed = hash(&[self.config.seed, self.epoch]);
        }
        self.epoch_config = c;
        self.camera = Some(world.camera(&self.config));
        let (w, h) = (self.config.width, self.config.height);
        self.gbuffer.resize(w, h);
        let n = w as usize * h as usize;
        // Same size: kept as they are (the first frame of the epoch overwrites the history).
        self.history.resize(n, PixelStats::default());
        self.lighting.resize(n, LightSample::default());
        self.stale = false;
    }

    /// Renders one frame of `world`: primary visibility, lighting and accumulation. The
    /// display pass is [`display`](Self::display), run by those who show or write frames.
    pub fn render_frame(&mut self, world: &World) -> FrameReport {
        let start = Instant::now();
        if self.stale || !self.config.frame.accumulate {
            self.start_epoch(world);
        }
        let mut passes = Vec::with_capacity(4);
        let max = self.config.frame.max_frames;
        let traced = !(self.config.frame.accumulate && max > 0 && self.frames >= max);
        let mut rays = 0;
        let mut samples = 0;
        if traced {
            let camera = self.camera.as_ref().expect("set by start_epoch");
            let tracer = PathTracer {
                world,
                camera,
                config: &self.epoch_config,
            };
            let spp = self.epoch_config.spp.max(1);
            let index = self.frames.saturating_mul(spp);
            samples = spp as u64 * self.history.len() as u64;

            // Primary visibility and lighting run by runs of pixels: a run's first hits go
            // straight from one pass to the other while they are in cache. Each pass's time is
            // the wall time split in proportion to the thread time it took.
            let t = Instant::now();
            let (r, primary_s, lighting_s) = trace(
                &mut self.gbuffer,
                &mut self.lighting,
                self.previous_camera.as_ref(),
                &tracer,
                index,
                spp,
            );
            rays += r;
            let wall = t.elapsed().as_secs_f64() * 1e3;
            let primary_ms = wall * primary_s / (primary_s + lighting_s).max(1e-12);
            passes.push(PassTime {
                pass: PRIMARY,
                ms: primary_ms,
            });
            passes.push(PassTime {
                pass: LIGHTING,
                ms: wall - primary_ms,
            });

            let t = Instant::now();
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
            passes.push(PassTime {
                pass: ACCUMULATE,
                ms: t.elapsed().as_secs_f64() * 1e3,
            });

            self.frames += 1;
            self.previous_camera = self.camera.clone();
        }
        self.frame_number += 1;
        FrameReport {
            frame: self.frame_number,
            epoch: self.epoch,
            accumulated: self.frames,
            spp: self.history.first().map_or(0, |h| h.n),
            traced,
            samples,
            passes,
            ms: start.elapsed().as_secs_f64() * 1e3,
            rays,
        }
    }

    /// The display pass: the configured display mode as 8-bit RGBA into
    /// [`rgba`](Self::rgba); its time is added to `report`.
    pub fn display(&mut self, report: &mut FrameReport) {
        let t = Instant::now();
        let sources = Sources {
            gbuffer: &self.gbuffer,
            lighting: &self.lighting,
            history: &self.history,
        };
        sources.rgba8(
            self.config.display.mode,
            &self.config.display,
            &mut self.rgba,
        );
        let ms = t.elapsed().as_secs_f64() * 1e3;
        report.passes.push(PassTime { pass: DISPLAY, ms });
        report.ms += ms;
    }

    /// The buffers the display modes read.
    pub fn sources(&self) -> Sources<'_> {
        Sources {
            gbuffer: &self.gbuffer,
            lighting: &self.lighting,
            history: &self.history,
        }
    }

    /// The accumulated image (mean radiance), row-major.
    pub fn image(&self) -> Vec<glam::Vec3> {
        self.sources().linear(DisplayMode::Final)
    }
}

/// The primary and lighting passes over every pixel, run by run in parallel. Returns the
/// rays traced and the thread time (seconds) of each pass.
fn trace(
    gbuffer: &mut GBuffer,
    lighting: &mut [LightSample],
    previous: Option<&Camera>,
    tracer: &PathTracer,
    index: u32,
    spp: u32,
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
                )
            },
            |(cameras, camera_rays, first_hits, hits), (b, (gpixels, lpixels))| {
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
                cameras.extend(
                    pixels()
                        .take(gpixels.len())
                        .map(|(x, y)| tracer.camera_sample(x, y, index)),
                );
                // Their rays together: neighbouring pixels' rays go as packets.
                camera_rays.clear();
                camera_rays.extend(cameras.iter().map(|c| c.ray));
                first_hits.resize(camera_rays.len(), None);
                tracer.world.accel.intersect_batch(camera_rays, first_hits);
                hits.clear();
                for ((g, sample), &first) in
                    gpixels.iter_mut().zip(cameras.drain(..)).zip(&*first_hits)
                {
                    let (pixel, hit, r) = gbuffer::primary(tracer, sample, first, previous);
                    *g = pixel;
                    hits.push(hit);
                    rays += r as u64;
                }
                let t1 = Instant::now();
                for ((l, hit), (x, y)) in lpixels.iter_mut().zip(hits.iter()).zip(pixels()) {
                    let (sample, r) = lighting::lighting(tracer, x, y, hit, index, spp);
                    *l = sample;
                    rays += r;
                }
                let t2 = Instant::now();
                (rays, (t1 - t0).as_secs_f64(), (t2 - t1).as_secs_f64())
            },
        )
        .reduce(|| (0, 0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1, a.2 + b.2))
}
