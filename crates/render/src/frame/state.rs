//! The frame state the stages share: the image's size, this epoch's path-tracer settings and
//! cameras, the G-buffer, this frame's lighting, the history, the whole frame's first hits
//! (when a stage needs them before lighting), the epoch and frame counters, what changed since
//! the last frame, and the passes' times. Each stage keeps its own state; this is what more
//! than one of them reads or writes.

use std::time::Instant;

use pathlight_core::rng::hash;
use serde::Serialize;

use crate::camera::Camera;
use crate::path::PathSettings;

use super::accumulation::PixelStats;
use super::gbuffer::{GBuffer, PrimaryHit};
use super::lighting::LightSample;

/// What changed since the last frame, when a frame starts a new epoch.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Change {
    /// Nothing, in a pipeline that does not accumulate: each frame is an epoch of its own.
    Repeat,
    /// The camera's view, and nothing else: forward reprojection may carry the history over,
    /// ReSTIR's reservoirs follow the motion vectors.
    Camera,
    /// The render size alone (the frame-time target's scale, [`super::target`]): the stages
    /// that keep per-pixel state at the render size start afresh; the output's history and
    /// the texture-space cache (which lives on the surfaces) do not.
    Scale,
    /// Anything else that changes the image, a reset, or the first frame: every stage starts
    /// afresh.
    Settings,
}

impl Change {
    /// Two changes between frames: the larger one.
    pub fn and(self, other: Change) -> Change {
        if self == Change::Settings || other == Change::Settings {
            Change::Settings
        } else if self == Change::Scale || other == Change::Scale {
            Change::Scale
        } else if self == Change::Camera || other == Change::Camera {
            Change::Camera
        } else {
            Change::Repeat
        }
    }
}

/// The time one pass took.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PassTime {
    pub pass: &'static str,
    pub ms: f64,
}

/// The passes' times of one frame, in the order they first ran (a pass that runs twice, the
/// lighting and its repair, adds up).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Times(pub Vec<PassTime>);

impl Times {
    /// Adds `ms` to pass `pass`.
    pub fn add(&mut self, pass: &'static str, ms: f64) {
        match self.0.iter_mut().find(|p| p.pass == pass) {
            Some(p) => p.ms += ms,
            None => self.0.push(PassTime { pass, ms }),
        }
    }

    /// Adds the time since `start` to pass `pass`.
    pub fn since(&mut self, pass: &'static str, start: Instant) {
        self.add(pass, start.elapsed().as_secs_f64() * 1e3);
    }
}

/// What the stages share (the image's size is the G-buffer's).
pub struct FrameState {
    /// Samples per pixel per frame.
    pub spp: u32,
    /// The path tracer's settings this epoch: epoch 0 uses the configuration's seed, later
    /// epochs seeds hashed from it.
    pub settings: PathSettings,
    /// This epoch's camera (after the first frame).
    pub camera: Option<Camera>,
    /// The camera of the last frame traced (motion vectors).
    pub previous_camera: Option<Camera>,
    pub gbuffer: GBuffer,
    /// The lighting pass's output for the current frame.
    pub lighting: Vec<LightSample>,
    /// Running statistics over this epoch's frames (and what reprojection carried into it).
    pub history: Vec<PixelStats>,
    /// The frame's first hits by runs of pixels, kept for the whole frame when a stage needs
    /// every pixel's surface before the lighting pass (ReSTIR); `None` where a pixel was not
    /// traced.
    pub hits: Vec<Vec<Option<PrimaryHit>>>,
    /// Epochs started before this one.
    pub epoch: u64,
    /// Frames traced in this epoch.
    pub frames: u32,
    /// Frames rendered since the pipeline was made.
    pub number: u64,
    /// The passes' times of the frame being rendered.
    pub times: Times,
}

impl Default for FrameState {
    fn default() -> Self {
        Self::new(PathSettings::default())
    }
}

impl FrameState {
    /// The state before the first frame, for the path tracer's `settings`.
    pub fn new(settings: PathSettings) -> Self {
        Self {
            spp: 1,
            settings,
            camera: None,
            previous_camera: None,
            gbuffer: GBuffer::default(),
            lighting: Vec::new(),
            history: Vec::new(),
            hits: Vec::new(),
            epoch: 0,
            frames: 0,
            number: 0,
            times: Times::default(),
        }
    }

    /// Pixels of the frame's buffers.
    pub fn pixels(&self) -> usize {
        self.gbuffer.pixels.len()
    }

    /// Starts a new epoch of a `width` x `height` image seen by `camera`, `spp` samples per
    /// pixel and frame, the path tracer's `settings` (its seed that of epoch 0): the epoch's
    /// seed, the buffers sized (kept as they are at the same size: the first frame overwrites
    /// the history, or a stage clears or carries it). Returns the last epoch's camera and
    /// whether the buffers changed size.
    pub fn start_epoch(
        &mut self,
        settings: PathSettings,
        spp: u32,
        camera: Camera,
        width: u32,
        height: u32,
    ) -> (Option<Camera>, bool) {
        if self.number > 0 {
            self.epoch += 1;
        }
        self.frames = 0;
        self.settings = settings;
        if self.epoch > 0 {
            self.settings.seed = hash(&[settings.seed, self.epoch]);
        }
        self.spp = spp.max(1);
        let previous = self.camera.replace(camera);
        let resized = (self.gbuffer.width, self.gbuffer.height) != (width, height);
        self.gbuffer.resize(width, height);
        let n = width as usize * height as usize;
        self.history.resize(n, PixelStats::default());
        self.lighting.resize(n, LightSample::default());
        (previous, resized)
    }

    /// The sample index of this frame's first sample in an epoch whose pixels all take the
    /// same samples.
    pub fn sample_index(&self) -> u32 {
        self.frames.saturating_mul(self.spp)
    }

    /// Bytes of the shared per-pixel buffers.
    pub fn bytes(&self) -> usize {
        use std::mem::size_of;
        self.gbuffer.pixels.capacity() * size_of::<super::gbuffer::GPixel>()
            + self.lighting.capacity() * size_of::<LightSample>()
            + self.history.capacity() * size_of::<PixelStats>()
    }

    /// Bytes of the whole frame's first hits (a technique's: ReSTIR's).
    pub fn hits_bytes(&self) -> usize {
        self.hits.iter().map(|r| r.capacity()).sum::<usize>()
            * std::mem::size_of::<Option<PrimaryHit>>()
    }
}
