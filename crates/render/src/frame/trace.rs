//! The primary visibility and lighting passes over the pixels a [`Plan`] picks, run by runs of
//! pixels in parallel, and their stages ([`Primary`], [`Lighting`]), whose views are the
//! G-buffer and this frame's lighting.
//!
//! ```text
//! primary   camera, previous camera, plan  -> G-buffer, first hits
//! lighting  first hits, G-buffer, plan,    -> lighting (direct / indirect statistics, first
//!           the light at the first hits       bounce)
//! ```
//!
//! The lighting pass asks one trait, [`FirstHitLight`], for the light at each pixel's first
//! hit. The plain lighting's ([`NextEvent`]: next event estimation there) needs nothing of the
//! whole frame, and the two passes are fused: a run's first hits go straight from one pass to
//! the other while they are in cache ([`fused`]). Otherwise ([`primary`], the light's own
//! passes ([`FirstHitLight::prepare`]), then [`lighting`](fn@lighting)) the first hits are
//! kept for the whole frame in [`FrameState::hits`](super::state::FrameState::hits), and the
//! lighting pass hands each run's traced pixels ([`Run`]) to the light: ReSTIR's reservoirs
//! give each pixel's direct light at its first hit; the texture cache looks each pixel's light
//! up, its direct light from the light beneath it (next event estimation or the reservoirs).
//! A stage plugs in by implementing the trait on its frame's state and handing it to the
//! driver, wrapping the light beneath it if it composes.

use std::time::Instant;

use glam::Vec3;
use pathlight_accel::{Hit, Ray};
use rayon::prelude::*;

use crate::camera::Camera;
use crate::path::{CameraSample, PathTracer};

use super::display::{View, ViewKind};
use super::gbuffer::{self, GBuffer, GPixel, PrimaryHit};
use super::lighting::{self, LightSample};
use super::stage::Stage;
use super::state::{FrameState, Times};

/// Pixels per parallel task: a run of pixels in row-major order, small enough that its first
/// hits stay in the L1/L2 cache between the primary and the lighting pass.
pub const RUN: usize = 128;

/// Which pixels a frame traces, and from which sample index.
pub trait Plan: Sync {
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
pub struct Uniform(pub u32, pub u32);

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

/// What the passes traced: rays, and the thread time (seconds) of each pass.
#[derive(Debug, Clone, Copy, Default)]
pub struct Traced {
    pub rays: u64,
    pub primary_s: f64,
    pub lighting_s: f64,
}

impl std::ops::Add for Traced {
    type Output = Traced;

    fn add(self, b: Traced) -> Traced {
        Traced {
            rays: self.rays + b.rays,
            primary_s: self.primary_s + b.primary_s,
            lighting_s: self.lighting_s + b.lighting_s,
        }
    }
}

/// The pixels of the run of `len` pixels from pixel `start` of an image `w` wide, in order (no
/// division per pixel).
#[inline(always)]
fn run_pixels(start: usize, w: usize) -> impl Iterator<Item = (u32, u32)> {
    let (mut x, mut y) = ((start % w) as u32, (start / w) as u32);
    std::iter::from_fn(move || {
        let p = (x, y);
        x += 1;
        if x as usize == w {
            (x, y) = (0, y + 1);
        }
        Some(p)
    })
}

/// The camera samples of the run of `pixels` from pixel `start` that `plan` traces, in a loop
/// of independent iterations (their hash and Sobol latency chains overlap instead of stalling
/// each trace), and the traced pixels' (index in the run, x, y, sample index); `untraced(k)`
/// is called for the others.
#[inline(always)]
fn camera_samples<P: Plan>(
    tracer: &PathTracer,
    plan: &P,
    start: usize,
    pixels: impl Iterator<Item = (u32, u32)>,
    cameras: &mut Vec<CameraSample>,
    traced: &mut Vec<(usize, u32, u32, u32)>,
    mut untraced: impl FnMut(usize),
) {
    cameras.clear();
    traced.clear();
    if P::EVERY_PIXEL {
        let index = plan.sample(start).unwrap_or(0);
        cameras.extend(pixels.map(|(x, y)| tracer.camera_sample(x, y, index)));
    } else {
        for (k, (x, y)) in pixels.enumerate() {
            match plan.sample(start + k) {
                Some(index) => {
                    cameras.push(tracer.camera_sample(x, y, index));
                    traced.push((k, x, y, index));
                }
                None => untraced(k),
            }
        }
    }
}

/// Per-thread scratch of a run.
type Scratch = (
    Vec<CameraSample>,
    Vec<Ray>,
    Vec<Option<Hit>>,
    Vec<PrimaryHit>,
    Vec<(usize, u32, u32, u32)>,
);

fn scratch() -> Scratch {
    (
        Vec::with_capacity(RUN),
        Vec::with_capacity(RUN),
        Vec::with_capacity(RUN),
        Vec::with_capacity(RUN),
        Vec::with_capacity(RUN),
    )
}

/// The primary and lighting passes fused, run by run: the pixels `plan` picks traced into
/// `gbuffer` and `lighting` (`previous`: the previous frame's camera, for motion vectors).
pub fn fused<P: Plan>(
    gbuffer: &mut GBuffer,
    lighting: &mut [LightSample],
    previous: Option<&Camera>,
    tracer: &PathTracer,
    plan: &P,
) -> Traced {
    let w = gbuffer.width.max(1) as usize;
    gbuffer
        .pixels
        .par_chunks_mut(RUN)
        .zip(lighting.par_chunks_mut(RUN))
        .enumerate()
        .map_init(
            scratch,
            |(cameras, camera_rays, first_hits, hits, traced), (b, (gpixels, lpixels))| {
                let start = b * RUN;
                let mut rays = 0u64;
                let t0 = Instant::now();
                camera_samples(
                    tracer,
                    plan,
                    start,
                    run_pixels(start, w).take(gpixels.len()),
                    cameras,
                    traced,
                    |k| lpixels[k] = LightSample::default(),
                );
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
                    for ((l, hit), (x, y)) in lpixels
                        .iter_mut()
                        .zip(hits.iter())
                        .zip(run_pixels(start, w))
                    {
                        let (sample, r) =
                            lighting::lighting::<false>(tracer, x, y, hit, index, spp, None);
                        *l = sample;
                        rays += r;
                    }
                } else {
                    let along = plan.along_first_bounce();
                    for (&(k, x, y, index), hit) in traced.iter().zip(hits.iter()) {
                        let spp = plan.keep(start + k, &gpixels[k]);
                        let (sample, r) =
                            lighting::light(tracer, x, y, hit, index, spp, along, None);
                        lpixels[k] = sample;
                        rays += r;
                    }
                }
                let t2 = Instant::now();
                Traced {
                    rays,
                    primary_s: (t1 - t0).as_secs_f64(),
                    lighting_s: (t2 - t1).as_secs_f64(),
                }
            },
        )
        .reduce(Traced::default, |a, b| a + b)
}

/// The primary pass alone over the pixels `plan` picks, keeping every pixel's first hit in
/// `hits` by runs (`None` where a pixel is not traced, whose lighting is emptied). Returns the
/// rays traced.
pub fn primary<P: Plan>(
    gbuffer: &mut GBuffer,
    lighting: &mut [LightSample],
    hits: &mut Vec<Vec<Option<PrimaryHit>>>,
    previous: Option<&Camera>,
    tracer: &PathTracer,
    plan: &P,
) -> u64 {
    let w = gbuffer.width.max(1) as usize;
    // Each run's vector keeps its capacity across frames.
    hits.resize_with(gbuffer.pixels.len().div_ceil(RUN), Vec::new);
    gbuffer
        .pixels
        .par_chunks_mut(RUN)
        .zip(lighting.par_chunks_mut(RUN))
        .zip(hits.par_iter_mut())
        .enumerate()
        .map_init(
            scratch,
            |(cameras, camera_rays, first_hits, _, traced), (b, ((gpixels, lpixels), out))| {
                let start = b * RUN;
                out.clear();
                camera_samples(
                    tracer,
                    plan,
                    start,
                    run_pixels(start, w).take(gpixels.len()),
                    cameras,
                    traced,
                    |k| lpixels[k] = LightSample::default(),
                );
                if !P::EVERY_PIXEL {
                    out.resize(gpixels.len(), None);
                }
                primary_run(
                    tracer,
                    previous,
                    cameras,
                    camera_rays,
                    first_hits,
                    |i, pixel, hit| {
                        if P::EVERY_PIXEL {
                            gpixels[i] = pixel;
                            out.push(Some(hit));
                        } else {
                            let k = traced[i].0;
                            gpixels[k] = pixel;
                            out[k] = Some(hit);
                        }
                    },
                )
            },
        )
        .sum()
}

/// The lighting pass over the first hits [`primary`] kept: each run's traced pixels lit by
/// `light` ([`FirstHitLight::light_run`]), along the image's rows or down its columns as it
/// asks. Returns the rays traced.
pub fn lighting<P: Plan>(
    gbuffer: &GBuffer,
    lighting: &mut [LightSample],
    hits: &[Vec<Option<PrimaryHit>>],
    tracer: &PathTracer,
    plan: &P,
    light: &dyn FirstHitLight,
) -> u64 {
    let w = gbuffer.width.max(1) as usize;
    let along = plan.along_first_bounce();
    // Run `b` (its pixels' light `ls`, first hits `hits`): its traced pixels listed in
    // `pixels` (scratch), then lit.
    let light_run = |pixels: &mut Vec<RunPixel>,
                     b: usize,
                     ls: &mut [LightSample],
                     hits: &[Option<PrimaryHit>]| {
        let start = b * RUN;
        pixels.clear();
        for (k, (hit, (x, y))) in hits.iter().zip(run_pixels(start, w)).enumerate() {
            let p = start + k;
            let Some(index) = hit.as_ref().and_then(|_| plan.sample(p)) else {
                continue;
            };
            let spp = plan.keep(p, &gbuffer.pixels[p]);
            pixels.push(RunPixel {
                k,
                x,
                y,
                index,
                spp,
            });
        }
        let run = Run {
            start,
            pixels,
            hits,
            gbuffer,
            along,
        };
        light.light_run(tracer, &run, ls)
    };
    if !light.by_columns() {
        return lighting
            .par_chunks_mut(RUN)
            .zip(hits.par_iter())
            .enumerate()
            .map_init(Vec::new, |pixels, (b, (ls, run))| {
                light_run(pixels, b, ls, run)
            })
            .sum();
    }
    // Down columns of the image, one after the other, rather than along its rows (the texture
    // cache): the cells a run needs (with their filter's neighbours) are then mostly those the
    // runs just above needed, and a small cache holds them. Columns of an eighth of the
    // image's width (at least a run): at 1920x1080 and one byte per pixel (the paper's
    // budget), 25% more cells shaded than with an unbounded cache, 31% with columns of 128
    // pixels, 72% with 512, 17x along the rows (BENCHMARKS.md, "Seed 002").
    let band = (w / 8).max(RUN);
    let mut runs: Vec<_> = lighting.chunks_mut(RUN).zip(hits).enumerate().collect();
    runs.sort_by_key(|&(b, _)| ((b * RUN % w) / band, b));
    runs.into_par_iter()
        .map_init(Vec::new, |pixels, (b, (ls, run))| {
            light_run(pixels, b, ls, run)
        })
        .sum()
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

/// A traced pixel of a run, as the lighting pass hands it to a [`FirstHitLight`]: its index in
/// the run, its place, its first sample index and its samples this frame.
#[derive(Debug, Clone, Copy)]
pub struct RunPixel {
    pub k: usize,
    pub x: u32,
    pub y: u32,
    pub index: u32,
    pub spp: u32,
}

/// A run of pixels in the lighting pass: those traced ([`RunPixel`]), the run's first hits
/// (by index in the run), the G-buffer, and whether the first sample measures the radiance
/// along its first bounce.
pub struct Run<'a> {
    /// The run's first pixel (a multiple of [`RUN`]).
    pub start: usize,
    pub pixels: &'a [RunPixel],
    pub hits: &'a [Option<PrimaryHit>],
    pub gbuffer: &'a GBuffer,
    pub along: bool,
}

impl Run<'_> {
    /// Each traced pixel's lighting into `out` (by index in the run): `light(pixel, its first
    /// hit, its first sample's direct light there)`, that direct light from `direct(pixel's
    /// index in the frame, &mut shadow rays)` where the pixel takes samples. Returns the rays
    /// traced, shadow rays included.
    #[inline(always)]
    pub fn each(
        &self,
        out: &mut [LightSample],
        direct: impl Fn(usize, &mut u32) -> Option<Vec3>,
        mut light: impl FnMut(&RunPixel, &PrimaryHit, Option<Vec3>) -> (LightSample, u64),
    ) -> u64 {
        let mut rays = 0;
        for px in self.pixels {
            let Some(hit) = &self.hits[px.k] else {
                continue;
            };
            let mut shadow = 0;
            let d = match px.spp > 0 {
                true => direct(self.start + px.k, &mut shadow),
                false => None,
            };
            let (sample, r) = light(px, hit, d);
            out[px.k] = sample;
            rays += r + shadow as u64;
        }
        rays
    }
}

/// The light at a pixel's first hit: what the lighting pass asks each pixel's lighting of. The
/// plain lighting's is next event estimation ([`NextEvent`]); a stage that lights the first
/// hits from the whole frame's (ReSTIR's reservoirs) gives each pixel's direct light there; a
/// stage that looks the light up (the texture cache) lights whole runs itself, asking the light
/// beneath it for the direct light (a cached pixel's is then its reservoir's). Each is called
/// once per run of pixels ([`light_run`](Self::light_run), dynamically dispatched), and within
/// it per pixel and sample by its own code (monomorphised).
pub trait FirstHitLight: Sync {
    /// Its light is next event estimation's at every first hit and it needs no pass of its
    /// own: the primary and lighting passes are then fused by runs ([`fused`]).
    fn fused(&self) -> bool {
        false
    }
    /// Its passes over the frame's first hits (`hits`, by runs of [`RUN`] pixels; `None`
    /// where a pixel is not traced), between the primary and the lighting pass, timed into
    /// `times`; returns the rays traced.
    fn prepare(
        &mut self,
        tracer: &PathTracer,
        gbuffer: &GBuffer,
        hits: &[Vec<Option<PrimaryHit>>],
        times: &mut Times,
    ) -> u64 {
        let _ = (tracer, gbuffer, hits, times);
        0
    }
    /// The direct light of pixel `pixel`'s first sample at its first hit, which replaces next
    /// event estimation there (`None`: next event estimation), counting its shadow rays.
    fn direct(&self, tracer: &PathTracer, pixel: usize, rays: &mut u32) -> Option<Vec3> {
        let _ = (tracer, pixel, rays);
        None
    }
    /// The lighting pass takes the runs down columns of the image instead of along its rows.
    fn by_columns(&self) -> bool {
        false
    }
    /// The lighting of `run`'s traced pixels into `out` (by index in the run); returns the
    /// rays traced. By default each pixel's path traced from its first hit
    /// ([`lighting::light`]) with its [`direct`](Self::direct) light there.
    fn light_run(&self, tracer: &PathTracer, run: &Run, out: &mut [LightSample]) -> u64 {
        run.each(
            out,
            |p, r| self.direct(tracer, p, r),
            |px, hit, d| lighting::light(tracer, px.x, px.y, hit, px.index, px.spp, run.along, d),
        )
    }
    /// After the lighting pass: the frame's state becomes the previous frame's.
    fn finish(&mut self, gbuffer: &GBuffer) {
        let _ = gbuffer;
    }
}

/// The plain lighting: next event estimation (with multiple importance sampling) at every
/// first hit, fused with the primary pass.
#[derive(Debug, Clone, Copy, Default)]
pub struct NextEvent;

impl FirstHitLight for NextEvent {
    fn fused(&self) -> bool {
        true
    }
}

/// The frame's primary and lighting passes over the pixels `plan` picks, each pixel's first
/// hit lit by `light`: fused by runs (next event estimation, [`FirstHitLight::fused`]), or
/// the primary pass over the whole frame, `light`'s passes, then the lighting pass. Timed into
/// `times` (the fused passes' wall time split in proportion to the thread time each took);
/// returns the rays traced.
#[allow(clippy::too_many_arguments)]
pub fn frame<P: Plan>(
    gbuffer: &mut GBuffer,
    lighting: &mut [LightSample],
    hits: &mut Vec<Vec<Option<PrimaryHit>>>,
    times: &mut Times,
    previous: Option<&Camera>,
    tracer: &PathTracer,
    plan: &P,
    light: &mut dyn FirstHitLight,
) -> u64 {
    let t = Instant::now();
    if light.fused() {
        let traced = fused(gbuffer, lighting, previous, tracer, plan);
        let wall = t.elapsed().as_secs_f64() * 1e3;
        let primary_ms =
            wall * traced.primary_s / (traced.primary_s + traced.lighting_s).max(1e-12);
        times.add(PRIMARY, primary_ms);
        times.add(LIGHTING, wall - primary_ms);
        return traced.rays;
    }
    let mut rays = primary(gbuffer, lighting, hits, previous, tracer, plan);
    times.since(PRIMARY, t);
    rays += light.prepare(tracer, gbuffer, hits, times);
    let t = Instant::now();
    rays += self::lighting(gbuffer, lighting, hits, tracer, plan, &*light);
    light.finish(gbuffer);
    times.since(LIGHTING, t);
    rays
}

/// The primary visibility pass's name (timings, the menu's heading of the G-buffer's views).
pub const PRIMARY: &str = "primary";
/// The lighting pass's name (timings, the menu's heading of its views).
pub const LIGHTING: &str = "lighting";

/// The primary visibility pass as a stage: its views are the G-buffer's (which the frame
/// state holds).
#[derive(Debug, Default)]
pub struct Primary;

impl Primary {
    pub const VIEWS: &'static [View] = &[
        View {
            name: "albedo",
            about: "G-buffer: base colour at the first hit",
            kind: ViewKind::Colour,
        },
        View {
            name: "normal",
            about: "G-buffer: shading normal (x, y, z mapped from [-1, 1] to [0, 1])",
            kind: ViewKind::Direction,
        },
        View {
            name: "depth",
            about: "G-buffer: depth, near white to far black; the sky black",
            kind: ViewKind::Depth,
        },
        View {
            name: "motion",
            about: "G-buffer: motion since the previous frame (red: x, green: y; grey is \
                    still; 32 pixels to full scale)",
            kind: ViewKind::Motion,
        },
        View {
            name: "roughness",
            about: "G-buffer: perceptual roughness (grey)",
            kind: ViewKind::Unit,
        },
        View {
            name: "metallic",
            about: "G-buffer: metallic (grey)",
            kind: ViewKind::Unit,
        },
    ];
}

impl Stage for Primary {
    fn name(&self) -> &'static str {
        PRIMARY
    }

    fn views(&self) -> &'static [View] {
        Self::VIEWS
    }

    /// The feature itself: base colour, normal in [-1, 1], depth in scene units (the sky
    /// infinite), motion in pixels as (x, y, 0), roughness, metallic.
    fn value(&self, frame: &FrameState, view: usize, i: usize) -> Vec3 {
        let g = &frame.gbuffer.pixels[i];
        match view {
            0 => g.albedo,
            1 => g.normal,
            2 => Vec3::splat(g.depth),
            3 => g.motion.extend(0.0),
            4 => Vec3::splat(g.roughness),
            _ => Vec3::splat(g.metallic),
        }
    }
}

/// The lighting pass as a stage: its views are this frame's lighting (which the frame state
/// holds).
#[derive(Debug, Default)]
pub struct Lighting;

impl Lighting {
    pub const VIEWS: &'static [View] = &[
        View {
            name: "noisy",
            about: "this frame's radiance alone (the pipeline's noisy input)",
            kind: ViewKind::Radiance,
        },
        View {
            name: "frame-direct",
            about: "this frame's direct light alone (with ReSTIR, what the reservoirs gave)",
            kind: ViewKind::Radiance,
        },
        View {
            name: "bounce-albedo",
            about: "base colour at the first non-specular vertex after the first hit (seed \
                    001's \"texture2\")",
            kind: ViewKind::Colour,
        },
        View {
            name: "bounce-direction",
            about: "the direction chosen at the first hit (mapped from [-1, 1] to [0, 1])",
            kind: ViewKind::Direction,
        },
    ];
}

impl Stage for Lighting {
    fn name(&self) -> &'static str {
        LIGHTING
    }

    fn views(&self) -> &'static [View] {
        Self::VIEWS
    }

    fn value(&self, frame: &FrameState, view: usize, i: usize) -> Vec3 {
        let l = &frame.lighting[i];
        match view {
            0 => l.stats.mean(),
            1 => l.stats.direct.mean,
            2 => l.bounce.albedo,
            _ => l.bounce.direction,
        }
    }
}
