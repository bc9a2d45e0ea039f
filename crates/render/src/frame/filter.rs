//! Seed 001's reconstruction filters as the frame's last pass before display
//! ([`pathlight_denoise`] holds the filters themselves): the data-driven filter of the
//! accumulated image (below), or the spatio-temporal filter (`svgf`) of each frame's own samples
//! with the G-buffer (its history lives in the filter and survives camera moves).
//!
//! ```text
//! features  G-buffer, lighting (first bounce)   -> feature statistics (running mean and
//!                                                  variance per pixel over the epoch)
//! filter    history (direct, indirect light and  -> filtered image (the `final` display mode)
//!           their variances), feature statistics
//! ```
//!
//! Choices the thesis leaves open, written down:
//! - **Which samples give the features.** The thesis keeps the features of every sample. Here
//!   each frame adds the features of each traced pixel's first sample of the frame: depth,
//!   normal and albedo from the G-buffer, texture2 (the albedo at the first non-specular vertex
//!   after the first hit) and the first bounce's direction from the lighting pass. With one
//!   sample per frame (the real-time case) that is every sample.
//! - **The sky.** A sample whose camera ray leaves the scene adds nothing to the features; a
//!   pixel none of whose samples hit anything is sky (infinite depth), which the filter passes
//!   through. A pixel on a silhouette against the sky is filtered with the features of its
//!   hits, and (`sky_coverage`, not in the thesis) as its hits alone: its mean light is
//!   `c L_s + S`, with `c` the share of its samples that hit a surface, `L_s` their mean light
//!   and `S` the mean over all its samples of the environment's radiance the escaped ones saw
//!   (their light), so the filter is given `(L - S) / c`, which is like its neighbours'
//!   light, and the pixel shows `c F + S` of the filtered `F`. Before, the sky's light was
//!   filtered as the surface's: a leaf's edge against a grey sky spread the sky into the
//!   leaf, and the leaf's red into the sky (measured on the garden: CIELUV MSE at 8 spp 0.36x
//!   the unfiltered image's without, 0.28x with; BENCHMARKS.md, "Seed 001"). `c` and `S`
//!   are exact where the statistics gathered every sample of the history (one per frame);
//!   elsewhere (several samples per frame, a history carried over by reprojection) the
//!   mixture is filtered as before. The pixel's standard error stays its mixture's.
//! - **Light sources** (not in the thesis, whose paths end at a light): a pixel any of whose
//!   samples saw a light source first (an emissive triangle of the light list: textured
//!   emission counts where its texels are not black) is passed through like the sky and is
//!   nobody's neighbour. Its light is emission, not noise, and filtering it with its surroundings
//!   blurred the Cornell box's light into the ceiling (measured: the filtered image's linear
//!   MSE 3.6-5.6x the unfiltered one's at 8 spp, nearly all of it around the light).
//! - **Epochs.** The statistics start afresh with the history (a new epoch). Forward
//!   reprojection carries the history's light into a new view but not these statistics: they
//!   start again from the frame after the move. Switching the filter on mid-epoch starts them
//!   then (the history is not reset for a post-process). An epoch's first frame waits to be
//!   gathered until the epoch's second (below, as in SVGF's handover): the data-driven filter
//!   reads that frame's features from the frame itself, the statistics of one frame, bit for
//!   bit, so a camera that moves at every frame gathers nothing (the pass along an orbit at
//!   640x360: the 2.4-2.5 ms gathering gone, the features read from the frame's larger
//!   buffers 1.6-1.9 ms slower).
//! - **SVGF handing over while still** (`svgf.still_handover`, not in the thesis or SVGF's
//!   paper): with SVGF, once the camera has been still for that many frames the data-driven
//!   filter of the accumulated image runs instead, until the camera moves (a new epoch). The
//!   features' statistics hold every frame of the epoch, from its first on, as for the
//!   data-driven filter (started at the second frame instead, the silhouettes lacked a
//!   sample, and on the still views of `experiments/001-still.toml` CIELUV MSE at 128
//!   frames was up to 1.5x as high, e.g. the Cornell box 0.57x the unfiltered image's against
//!   0.39x). The epoch's first frame is gathered by the second, from the buffers it left
//!   (the frame pipeline keeps them), so that a camera that moves at every frame gathers
//!   nothing; the statistics are the same, bit for bit. SVGF does not run
//!   meanwhile: its history stays the still view's, the
//!   view the next move's motion vectors start from, so it carries on as if those frames had
//!   not been.
//! - **Filtering a still view again as it grows** (`refresh_growth`, not in the thesis): the
//!   data-driven filter's image of the accumulated history (alone or in SVGF's handover) is
//!   filtered again only once the epoch's frames have grown by that factor since it was last
//!   filtered, and shown as it was meanwhile, as offline renderers denoise every so many
//!   passes: the filter's cost grows with the logarithm of a still view's frames, and the time
//!   goes to samples. The pipeline keeps the epoch, the frame and the filter's configuration it
//!   last filtered at (`frame::Filtered`); a new configuration or epoch filters at once. The
//!   features' statistics are gathered every frame all the same. What a pixel showed as its
//!   own light does not age: at a refresh each pixel keeps its shares of its own direct and
//!   indirect light in the image (1 where it passed through, the `sure` blend's elsewhere, 0
//!   without the blend and on a silhouette filtered as its hits, whose sky part is not its
//!   own light alone) and the image less those shares of the history's light; between
//!   refreshes it shows that plus the same shares of the history's light as it is now.

use glam::{Vec2, Vec3};
use pathlight_core::color::luminance;
use pathlight_denoise::{
    ColourWeights, DataDriven, Features, FilterConfig, FilterError, Method, Svgf, SvgfFrame,
};
use rayon::prelude::*;

use super::accumulation::PixelStats;
use super::display::{encode, unorm8, DisplayConfig, View, ViewKind, NONE};
use super::gbuffer::{GBuffer, GPixel};
use super::lighting::LightSample;
use super::stage::Stage;
use super::state::FrameState;

/// Seed 001's reconstruction filter's pass (timings, the menu's heading of its views).
pub const FILTER: &str = "filter";

/// Running means and sums of squared deviations (summed over components) of one pixel's
/// features.
#[derive(Debug, Clone, Copy, Default)]
struct FeatureStats {
    /// Samples that hit a surface.
    n: u32,
    /// Some sample saw an emissive surface first.
    emitter: bool,
    /// Frames gathered (each one sample's features), and the samples they traced: the
    /// history's, when it holds nothing else.
    frames: u32,
    samples: u32,
    /// Mean over the frames of the environment's radiance their first sample saw (zero where
    /// it hit a surface).
    sky: Vec3,
    depth: f32,
    depth_m2: f32,
    normal: Vec3,
    normal_m2: f32,
    albedo: Vec3,
    albedo_m2: f32,
    texture2: Vec3,
    texture2_m2: f32,
    direction: Vec3,
    direction_m2: f32,
    /// Means of the material's roughness and metallic factor.
    roughness: f32,
    metallic: f32,
}

impl FeatureStats {
    /// Adds a frame's pixel: its G-buffer's features and its lighting (nothing where the frame
    /// traced no sample).
    fn add_frame(&mut self, g: &GPixel, l: &LightSample) {
        if l.stats.n == 0 {
            return;
        }
        self.frames += 1;
        self.samples = self.samples.saturating_add(l.stats.n);
        // A hit adds its features; an escaped sample's light is the environment's radiance
        // (the lighting pass's direct light; used where the frame traced one sample).
        let sky = if g.depth.is_finite() {
            self.emitter |= g.emitter;
            self.add(g, l.bounce.albedo, l.bounce.direction);
            Vec3::ZERO
        } else {
            l.stats.direct.mean
        };
        self.sky += (sky - self.sky) / self.frames as f32;
    }

    /// Adds one sample's features (Welford).
    fn add(&mut self, g: &GPixel, texture2: Vec3, direction: Vec3) {
        let (depth, normal, albedo) = (g.depth, g.normal, g.albedo);
        self.n += 1;
        let inv = 1.0 / self.n as f32;
        let d = depth - self.depth;
        self.depth += d * inv;
        self.depth_m2 += d * (depth - self.depth);
        self.roughness += (g.roughness - self.roughness) * inv;
        self.metallic += (g.metallic - self.metallic) * inv;
        for (mean, m2, x) in [
            (&mut self.normal, &mut self.normal_m2, normal),
            (&mut self.albedo, &mut self.albedo_m2, albedo),
            (&mut self.texture2, &mut self.texture2_m2, texture2),
            (&mut self.direction, &mut self.direction_m2, direction),
        ] {
            let delta = x - *mean;
            *mean += delta * inv;
            *m2 += delta.dot(x - *mean);
        }
    }

    /// Sample variances (n - 1) of depth, normal, texture, direction and texture2, each
    /// summed over its components (0 below two samples).
    fn variance(&self) -> [f32; 5] {
        if self.n < 2 {
            return [0.0; 5];
        }
        let k = 1.0 / (self.n - 1) as f32;
        [
            self.depth_m2 * k,
            self.normal_m2 * k,
            self.albedo_m2 * k,
            self.direction_m2 * k,
            self.texture2_m2 * k,
        ]
    }
}

/// The filter's state: feature statistics, the buffers it reads, its output.
#[derive(Default)]
pub struct Filter {
    stats: Vec<FeatureStats>,
    /// The epoch the statistics belong to.
    epoch: Option<u64>,
    direct: Vec<Vec3>,
    indirect: Vec<Vec3>,
    depth: Vec<f32>,
    normal: Vec<Vec3>,
    albedo: Vec<Vec3>,
    texture2: Vec<Vec3>,
    /// The feature variances the filter read (display modes `variance-*`).
    pub variance: Vec<[f32; 5]>,
    /// The variance of the mean of the direct and indirect light's luminance, or of its
    /// channels' mean (`colour_weights = "albedo"`; NaN below two samples).
    light_variance: Vec<[f32; 2]>,
    /// Means of the first hit's roughness and metallic factor (the data-driven filter's).
    roughness: Vec<f32>,
    metallic: Vec<f32>,
    /// The filtered image (empty when the filter is off).
    pub image: Vec<Vec3>,
    data_driven: DataDriven,
    /// The spatio-temporal filter's history, and its inputs.
    svgf: Svgf,
    /// Temporal antialiasing alone (`method = "taa"`): its last output.
    taa: pathlight_denoise::taa::Taa,
    motion: Vec<Vec2>,
    emitter: Vec<bool>,
    /// Data-driven, `sky_coverage`: per pixel the share of samples that hit a surface and the
    /// sky's part of the mean light (1 and zero where the pixel is filtered as it is).
    coverage: Vec<(f32, Vec3)>,
    /// `refresh_growth`: per pixel, the image at the last refresh less its shares of the
    /// pixel's own direct and indirect light then, and those shares ([`Self::keep_refresh`]).
    kept: Vec<(Vec3, [f32; 2])>,
    /// An epoch's first frame waits to be gathered until a second one comes (a camera that
    /// moves at every frame then gathers nothing): the epoch whose first frame waits in the
    /// frame's own buffers.
    waiting: Option<u64>,
    /// The G-buffer and lighting of the frame that waits, once the next frame traces into
    /// the others.
    spare: Spare,
    /// When the data-driven filter last filtered the accumulated image (`refresh_growth`).
    filtered: Option<Filtered>,
}

/// The epoch, its frames and the filter's configuration when the data-driven filter last
/// filtered the accumulated image.
struct Filtered {
    epoch: u64,
    frames: u32,
    config: FilterConfig,
}

/// The G-buffer and lighting of a frame whose features wait to be gathered, and its epoch
/// (none once gathered or dropped).
#[derive(Default)]
struct Spare {
    gbuffer: GBuffer,
    lighting: Vec<LightSample>,
    epoch: Option<u64>,
}

impl Filter {
    pub const VIEWS: &'static [View] = &[
        View {
            name: "final",
            about: "the image: the accumulated mean radiance over the frames so far, filtered \
                    when the reconstruction filter (seed 001) is on",
            kind: ViewKind::Radiance,
        },
        View {
            name: "variance-depth",
            about: "the sample variance of the depth, relative to the depth squared, as a \
                    heat map 0 to 1 (dark grey when the filter is off)",
            kind: ViewKind::Heat,
        },
        View {
            name: "variance-normal",
            about: "the variance of the normal (summed over x, y, z), heat map 0 to 1",
            kind: ViewKind::Heat,
        },
        View {
            name: "variance-texture",
            about: "the variance of the texture (albedo at the first hit), heat map 0 to 1",
            kind: ViewKind::Heat,
        },
        View {
            name: "variance-direction",
            about: "the variance of the first bounce's direction, heat map 0 to 1",
            kind: ViewKind::Heat,
        },
        View {
            name: "variance-texture2",
            about: "the variance of texture2, heat map 0 to 1",
            kind: ViewKind::Heat,
        },
        View {
            name: "sure-share",
            about: "data-driven filter, `sure`: each pixel's share of its own (unfiltered) \
                    light in the blend, direct light in red and indirect in green, 0 to 1 \
                    (blue where the pixel passed through; dark grey when the blend did not \
                    run)",
            kind: ViewKind::Painted,
        },
    ];

    /// Before the frame's tracing, in a frame that traces every pixel afresh (`every_pixel`):
    /// if the epoch's first frame waits to be gathered in the frame's buffers, they become the
    /// spare ones and the frame traces into the others.
    pub fn before_trace(
        &mut self,
        gbuffer: &mut GBuffer,
        lighting: &mut Vec<LightSample>,
        every_pixel: bool,
    ) {
        if !every_pixel {
            return;
        }
        if let Some(epoch) = self.waiting.take() {
            let spare = &mut self.spare;
            std::mem::swap(gbuffer, &mut spare.gbuffer);
            std::mem::swap(lighting, &mut spare.lighting);
            spare.epoch = Some(epoch);
            gbuffer.resize(spare.gbuffer.width, spare.gbuffer.height);
            lighting.resize(spare.lighting.len(), LightSample::default());
        }
    }

    /// The filter pass after the frame (`traced`: it traced samples; `every_pixel`: every
    /// pixel afresh, from one sample index), with `config`: gathers the features, and runs the
    /// method in force after the epoch's frames into [`image`](Self::image), or forgets the
    /// output when the filter is off.
    pub fn pass(
        &mut self,
        config: &FilterConfig,
        frame: &mut FrameState,
        traced: bool,
        every_pixel: bool,
    ) {
        // (`frames` counts this one: the frames of a still camera.)
        let (epoch, frames) = (frame.epoch, frame.frames);
        let method = config.method_after(frames);
        if !method.in_frame() {
            if !self.image.is_empty() {
                self.clear();
                (self.waiting, self.spare.epoch) = (None, None);
            }
            return;
        }
        let t = std::time::Instant::now();
        let svgf = method == Method::Svgf;
        let data_driven = method == Method::DataDriven;
        // An epoch's first frame waits to be gathered until a second one comes (a camera
        // that moves at every frame never gathers): SVGF does not read the statistics, and
        // the data-driven filter reads that frame's features from the frame itself.
        let gathers = traced && config.gathers_features();
        let waits = gathers && frames == 1 && every_pixel;
        if gathers {
            // The epoch's first frame, if it waited, before this one (the statistics are
            // then those of gathering every frame, bit for bit).
            if self.spare.epoch.take() == Some(epoch) {
                let spare = std::mem::take(&mut self.spare);
                self.gather(epoch, &spare.gbuffer, &spare.lighting);
                self.spare = spare;
            }
            if waits {
                self.waiting = Some(epoch);
            } else {
                self.gather(epoch, &frame.gbuffer, &frame.lighting);
            }
        }
        // With `refresh_growth`, a still view's data-driven image stays as it was until the
        // frames have grown by that factor.
        let stays = data_driven
            && !self.image.is_empty()
            && self.filtered.as_ref().is_some_and(|f| {
                f.epoch == epoch
                    && f.config == *config
                    && (frames as f32) < f.frames as f32 * config.data_driven.refresh_growth
            });
        let run = (traced || !svgf).then(|| {
            if stays {
                self.refresh_own_light(&frame.history);
                return Ok(());
            }
            self.filtered = data_driven.then(|| Filtered {
                epoch,
                frames,
                config: config.clone(),
            });
            self.run(
                method,
                config,
                &frame.history,
                &frame.gbuffer,
                &frame.lighting,
                !waits,
            )
        });
        if let Some(Err(_)) = run {
            // Not reached: the configuration was validated and the buffers are the frame's.
            // Show the unfiltered image rather than a stale one.
            self.clear();
        }
        frame.times.since(FILTER, t);
    }

    /// Adds the features of the pixels this frame traced (`lighting` holds samples) to the
    /// statistics of `epoch`, starting them afresh for a new epoch.
    pub fn gather(&mut self, epoch: u64, gbuffer: &GBuffer, lighting: &[LightSample]) {
        let n = gbuffer.pixels.len();
        // A new epoch's statistics start afresh in the same parallel sweep (a camera that
        // moves at every frame starts one each frame).
        let fresh = self.epoch != Some(epoch) || self.stats.len() != n;
        if self.stats.len() != n {
            self.stats.resize(n, FeatureStats::default());
        }
        self.epoch = Some(epoch);
        self.stats
            .par_iter_mut()
            .zip(gbuffer.pixels.par_iter().zip(lighting.par_iter()))
            .for_each(|(s, (g, l))| {
                if fresh {
                    *s = FeatureStats::default();
                }
                s.add_frame(g, l);
            });
    }

    /// Runs filter `method` with `config`'s parameters into [`image`](Self::image): the
    /// data-driven filter on the history with the gathered features, or the spatio-temporal
    /// filter on this frame's samples (`lighting`, the history where a pixel took none) with
    /// the G-buffer. `gathered`: this frame's features are in the statistics ([`Self::gather`]);
    /// else the frame is its epoch's first, whose gathering waits (the pipeline gathers it
    /// with the next frame of the epoch, if one comes), and the data-driven filter reads its
    /// features from the frame itself: the statistics of one frame, the same bit for bit.
    pub fn run(
        &mut self,
        method: Method,
        config: &FilterConfig,
        history: &[PixelStats],
        gbuffer: &GBuffer,
        lighting: &[LightSample],
        gathered: bool,
    ) -> Result<(), FilterError> {
        let (width, height) = (gbuffer.width as usize, gbuffer.height as usize);
        if method != Method::DataDriven {
            self.data_driven.forget_shares();
        }
        match method {
            Method::DataDriven => {
                let first = (!gathered).then_some((gbuffer, lighting));
                self.run_data_driven(config, history, first, width, height)
            }
            Method::Svgf => self.run_svgf(config, history, gbuffer, lighting),
            Method::Taa => {
                self.taa.set_alpha(config.taa.alpha);
                self.taa.set_gamma(config.taa.gamma);
                self.run_taa(history, gbuffer);
                Ok(())
            }
            Method::None | Method::Rpf => Ok(()),
        }
    }

    /// Temporal antialiasing alone: the history's mean (the unfiltered image) blended with
    /// the last output where its surface was.
    fn run_taa(&mut self, history: &[PixelStats], gbuffer: &GBuffer) {
        let n = history.len();
        self.resize(n);
        self.variance.clear();
        self.motion.resize(n, Vec2::ZERO);
        (&mut self.image, &mut self.motion)
            .into_par_iter()
            .zip(history.par_iter().zip(gbuffer.pixels.par_iter()))
            .for_each(|((out, motion), (h, g))| {
                *out = h.mean();
                *motion = g.motion;
            });
        let (width, height) = (gbuffer.width as usize, gbuffer.height as usize);
        self.taa.apply(&mut self.image, &self.motion, width, height);
    }

    fn run_svgf(
        &mut self,
        config: &FilterConfig,
        history: &[PixelStats],
        gbuffer: &GBuffer,
        lighting: &[LightSample],
    ) -> Result<(), FilterError> {
        let n = history.len();
        self.resize(n);
        // The feature variances are the data-driven filter's (their display modes go dark).
        self.variance.clear();
        self.motion.resize(n, Vec2::ZERO);
        self.emitter.resize(n, false);
        (
            &mut self.direct,
            &mut self.indirect,
            &mut self.normal,
            &mut self.albedo,
            &mut self.depth,
            &mut self.motion,
        )
            .into_par_iter()
            .zip(self.emitter.par_iter_mut())
            .zip(
                gbuffer
                    .pixels
                    .par_iter()
                    .zip(lighting.par_iter().zip(history.par_iter())),
            )
            .for_each(
                |(((d, i, normal, albedo, depth, motion), emitter), (g, (l, h)))| {
                    // A pixel the frame did not trace (adaptive sampling) shows its history.
                    let s = if l.stats.n > 0 { &l.stats } else { h };
                    *d = s.direct.mean;
                    *i = s.indirect.mean;
                    *normal = g.normal;
                    *albedo = g.albedo;
                    *depth = g.depth;
                    *motion = g.motion;
                    *emitter = g.emitter;
                },
            );
        let frame = SvgfFrame {
            width: gbuffer.width as usize,
            height: gbuffer.height as usize,
            direct: &self.direct,
            indirect: &self.indirect,
            albedo: &self.albedo,
            normal: &self.normal,
            depth: &self.depth,
            motion: &self.motion,
            emitter: &self.emitter,
        };
        self.svgf
            .filter(&frame, &config.svgf_params(), &mut self.image)
    }

    /// The data-driven filter, with the statistics gathered, or those of the epoch's `first`
    /// frame (its G-buffer and lighting) alone.
    fn run_data_driven(
        &mut self,
        config: &FilterConfig,
        history: &[PixelStats],
        first: Option<(&GBuffer, &[LightSample])>,
        width: usize,
        height: usize,
    ) -> Result<(), FilterError> {
        let n = history.len();
        self.resize(n);
        self.texture2.resize(n, Vec3::ZERO);
        self.variance.resize(n, [0.0; 5]);
        self.light_variance.resize(n, [0.0; 2]);
        if first.is_none() {
            self.stats.resize(n, FeatureStats::default());
        }
        self.roughness.resize(n, 0.0);
        self.metallic.resize(n, 0.0);
        self.coverage.resize(n, (1.0, Vec3::ZERO));
        let split = config.data_driven.sky_coverage;
        // The light's variance as the colour test measures it: the luminance's, or the
        // channels' mean with the channel weights.
        let measure: fn(Vec3) -> f32 = match config.data_driven.colour_weights {
            ColourWeights::Equal => luminance,
            ColourWeights::Albedo => |v| v.element_sum() / 3.0,
        };
        let stats = &self.stats;
        let features = |i: usize| match first {
            Some((g, l)) => {
                let mut s = FeatureStats::default();
                s.add_frame(&g.pixels[i], &l[i]);
                s
            }
            None => stats[i],
        };
        (
            &mut self.direct,
            &mut self.indirect,
            &mut self.depth,
            &mut self.normal,
            &mut self.albedo,
            &mut self.texture2,
            &mut self.coverage,
        )
            .into_par_iter()
            .zip(
                self.variance
                    .par_iter_mut()
                    .zip(self.light_variance.par_iter_mut()),
            )
            .zip(history.par_iter().enumerate())
            .zip(
                self.roughness
                    .par_iter_mut()
                    .zip(self.metallic.par_iter_mut()),
            )
            .for_each(
                |((((d, i, depth, normal, albedo, t2, c), (v, lv)), (k, h)), (r, m))| {
                    let s = &features(k);
                    *lv = if h.n >= 2 {
                        let k = 1.0 / ((h.n - 1) as f32 * h.n as f32);
                        [measure(h.direct.m2) * k, measure(h.indirect.m2) * k]
                    } else {
                        [f32::NAN; 2]
                    };
                    *d = h.direct.mean;
                    *i = h.indirect.mean;
                    // A silhouette whose samples the statistics all saw: its hits alone.
                    let all_seen = s.frames == s.samples && s.samples == h.n;
                    *c = (1.0, Vec3::ZERO);
                    if split && all_seen && s.n > 0 && s.n < s.frames {
                        let share = s.n as f32 / s.frames as f32;
                        *c = (share, s.sky);
                        *d = (h.direct.mean - s.sky) / share;
                        *i = h.indirect.mean / share;
                    }
                    // The sky and light sources pass through.
                    *depth = if s.n > 0 && !s.emitter {
                        s.depth
                    } else {
                        f32::INFINITY
                    };
                    *normal = s.normal;
                    *albedo = s.albedo;
                    *t2 = s.texture2;
                    *v = s.variance();
                    (*r, *m) = (s.roughness, s.metallic);
                },
            );
        let features = Features {
            width,
            height,
            direct: &self.direct,
            indirect: &self.indirect,
            depth: &self.depth,
            normal: &self.normal,
            albedo: &self.albedo,
            texture2: &self.texture2,
            variance: &self.variance,
            light_variance: &self.light_variance,
            roughness: &self.roughness,
            metallic: &self.metallic,
        };
        self.data_driven
            .filter(&features, &config.data_driven, &mut self.image)?;
        if split {
            self.image
                .par_iter_mut()
                .zip(self.coverage.par_iter())
                .filter(|(_, (share, _))| *share != 1.0)
                .for_each(|(o, (share, sky))| *o = *o * *share + *sky);
        }
        if config.data_driven.refresh_growth > 1.0 {
            self.keep_refresh(history);
        }
        Ok(())
    }

    /// After the data-driven filter refreshed the image (`refresh_growth`): keeps each pixel's
    /// shares of its own direct and indirect light in it (the `sure` blend's; 1 where the
    /// pixel passes through; 0 without the blend and on a silhouette filtered as its hits) and
    /// the image less those shares of the history's light, for [`Self::refresh_own_light`].
    fn keep_refresh(&mut self, history: &[PixelStats]) {
        let shares = self.data_driven.shares();
        self.kept.resize(history.len(), (Vec3::ZERO, [0.0; 2]));
        self.kept
            .par_iter_mut()
            .enumerate()
            .zip(self.image.par_iter().zip(history.par_iter()))
            .for_each(|((i, kept), (&image, h))| {
                let share = if self.depth[i].is_infinite() {
                    [1.0; 2]
                } else if self.coverage[i].0 != 1.0 {
                    [0.0; 2]
                } else {
                    shares.get(i).copied().unwrap_or([0.0; 2])
                };
                let base = image - h.direct.mean * share[0] - h.indirect.mean * share[1];
                *kept = if share.iter().all(|s| s.is_finite()) && base.is_finite() {
                    (base, share)
                } else {
                    (image, [0.0; 2])
                };
            });
    }

    /// Between the data-driven filter's refreshes (`refresh_growth`): each pixel's image with
    /// its shares of its own light (`keep_refresh`) as the history has them now, so
    /// that the light a pixel shows as its own (the sky, light sources, where the `sure` blend
    /// gives it back) does not age.
    pub fn refresh_own_light(&mut self, history: &[PixelStats]) {
        if self.kept.len() != self.image.len() {
            return;
        }
        self.image
            .par_iter_mut()
            .zip(self.kept.par_iter().zip(history.par_iter()))
            .filter(|(_, ((_, share), _))| *share != [0.0; 2])
            .for_each(|(image, (&(base, share), h))| {
                let now = base + h.direct.mean * share[0] + h.indirect.mean * share[1];
                if now.is_finite() {
                    *image = now;
                }
            });
    }

    /// Sizes the buffers both filters read and the output for `n` pixels.
    fn resize(&mut self, n: usize) {
        for v in [
            &mut self.direct,
            &mut self.indirect,
            &mut self.normal,
            &mut self.albedo,
            &mut self.image,
        ] {
            v.resize(n, Vec3::ZERO);
        }
        self.depth.resize(n, 0.0);
    }

    /// Data-driven, `sure`: each pixel's share of its own light in the last image, direct and
    /// indirect (NaN where it passed through; empty when the blend did not run).
    pub fn shares(&self) -> &[[f32; 2]] {
        self.data_driven.shares()
    }

    /// Caps the filters' lanes at AVX2 (`avx2`) or plain arrays (`portable`) instead of the
    /// widest the processor has (for tests: the frames of a processor without AVX-512 on one
    /// with it).
    #[doc(hidden)]
    pub fn set_lanes(&mut self, lanes: &str) {
        self.data_driven.set_lanes(lanes);
        self.svgf.set_lanes(lanes);
        self.taa.set_lanes(lanes);
    }

    /// Forgets the output (the filter was switched off).
    pub fn clear(&mut self) {
        self.data_driven.forget_shares();
        self.svgf.reset();
        self.taa.reset();
        self.image.clear();
        self.variance.clear();
        self.kept.clear();
        self.epoch = None;
    }

    /// Bytes of the per-pixel buffers (with the spare G-buffer and lighting of a frame that
    /// waits to be gathered).
    pub fn bytes(&self) -> usize {
        use std::mem::size_of;
        self.spare.gbuffer.pixels.capacity() * size_of::<GPixel>()
            + self.spare.lighting.capacity() * size_of::<LightSample>()
            + self.stats.capacity() * size_of::<FeatureStats>()
            + (self.direct.capacity()
                + self.indirect.capacity()
                + self.normal.capacity()
                + self.albedo.capacity()
                + self.texture2.capacity()
                + self.image.capacity())
                * size_of::<Vec3>()
            + (self.depth.capacity() + self.roughness.capacity() + self.metallic.capacity())
                * size_of::<f32>()
            + self.coverage.capacity() * size_of::<(f32, Vec3)>()
            + self.variance.capacity() * size_of::<[f32; 5]>()
            + self.kept.capacity() * size_of::<(Vec3, [f32; 2])>()
    }
}

impl Stage for Filter {
    fn name(&self) -> &'static str {
        FILTER
    }

    fn views(&self) -> &'static [View] {
        Self::VIEWS
    }

    /// `final`: the filtered image, or the history's mean where the filter is off; the
    /// feature variances (the depth's relative to the depth squared; -1 where the filter is
    /// off); `sure-share`: the shares (-1 where the blend did not run, NaN where the pixel
    /// passed through).
    fn value(&self, frame: &FrameState, view: usize, i: usize) -> Vec3 {
        match view {
            0 => self
                .image
                .get(i)
                .copied()
                .unwrap_or_else(|| frame.history[i].mean()),
            1..=5 => {
                let k = view - 1;
                let v = self.variance.get(i).map_or(-1.0, |v| v[k]);
                if k == 0 && v >= 0.0 {
                    let depth = frame.gbuffer.pixels[i].depth;
                    Vec3::splat(v / (depth * depth).max(1e-12))
                } else {
                    Vec3::splat(v)
                }
            }
            _ => self
                .shares()
                .get(i)
                .map_or(Vec3::splat(-1.0), |s| Vec3::new(s[0], s[1], 0.0)),
        }
    }

    /// `final` without a filtered image: the history's mean in a loop of its own (the usual
    /// display of the plain pipeline).
    fn rgba8(&self, frame: &FrameState, view: usize, display: &DisplayConfig, out: &mut Vec<u8>) {
        let n = frame.pixels();
        let paint = |i| self.paint(frame, view, i);
        if view == 0 && self.image.is_empty() {
            let mean = |i: usize| frame.history[i].mean();
            encode(ViewKind::Radiance, n, mean, paint, display, out);
        } else {
            let value = |i| self.value(frame, view, i);
            encode(Self::VIEWS[view].kind, n, value, paint, display, out);
        }
    }

    fn paint(&self, frame: &FrameState, view: usize, i: usize) -> [u8; 3] {
        let v = self.value(frame, view, i);
        if v.x < 0.0 {
            NONE
        } else if v.x.is_nan() {
            [0, 0, 160]
        } else {
            unorm8(v)
        }
    }

    fn bytes(&self) -> usize {
        Filter::bytes(self)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The data-driven filter after 8 frames of one sample each: a wall of albedo 0.5 lit at
    /// 0.5, whose column `x = 10` is a silhouette (its even frames' samples hit the wall, its
    /// odd ones a sky of radiance 2), then sky. Returns the filtered image and its width.
    /// (The colour tests loose, so that without the option the mixture visibly blends.)
    fn silhouette(sky_coverage: bool) -> (Vec<Vec3>, usize) {
        let (w, h) = (16, 6);
        let config = FilterConfig {
            method: pathlight_denoise::Method::DataDriven,
            data_driven: pathlight_denoise::DataDrivenConfig {
                kernel: 7,
                sigma_direct: 4.0,
                sigma_indirect: 4.0,
                sky_coverage,
                ..Default::default()
            },
            ..FilterConfig::default()
        };
        let mut filter = Filter::default();
        let mut gbuffer = GBuffer::default();
        gbuffer.resize(w as u32, h as u32);
        let mut history = vec![PixelStats::default(); w * h];
        let mut lighting = vec![LightSample::default(); w * h];
        for frame in 0..8 {
            for (i, (g, l)) in gbuffer.pixels.iter_mut().zip(&mut lighting).enumerate() {
                let x = i % w;
                let hit = x < 10 || (x == 10 && frame % 2 == 0);
                *g = if hit {
                    GPixel {
                        depth: 2.0,
                        normal: Vec3::Z,
                        albedo: Vec3::splat(0.5),
                        material: 0,
                        ..GPixel::default()
                    }
                } else {
                    GPixel::default()
                };
                let light = Vec3::splat(if hit { 0.5 } else { 2.0 });
                l.stats = PixelStats::one(light, Vec3::ZERO);
                history[i].merge(&l.stats);
            }
            filter.gather(0, &gbuffer, &lighting);
        }
        filter
            .run(config.method, &config, &history, &gbuffer, &lighting, true)
            .unwrap();
        (filter.image, w)
    }

    /// An epoch's first frame filtered from the frame itself (its gathering waits) gives the
    /// image of its gathered statistics, bit for bit: hits of two materials and depths, an
    /// emitter, sky, and a pixel the frame did not trace.
    #[test]
    fn a_first_frame_filtered_from_the_frame_is_its_gathered_statistics_bit_for_bit() {
        let (w, h) = (24, 10);
        let config = FilterConfig {
            method: pathlight_denoise::Method::DataDriven,
            data_driven: pathlight_denoise::DataDrivenConfig {
                kernel: 7,
                ..Default::default()
            },
            ..FilterConfig::default()
        };
        let mut gbuffer = GBuffer::default();
        gbuffer.resize(w as u32, h as u32);
        let mut history = vec![PixelStats::default(); w * h];
        let mut lighting = vec![LightSample::default(); w * h];
        for (i, (g, l)) in gbuffer.pixels.iter_mut().zip(&mut lighting).enumerate() {
            let (x, y) = (i % w, i / w);
            let v = ((i * 7919) % 97) as f32 / 97.0;
            if x < 20 {
                *g = GPixel {
                    depth: if x < 9 { 2.0 + 0.1 * v } else { 3.5 },
                    normal: if x < 9 { Vec3::Z } else { Vec3::X },
                    albedo: Vec3::new(0.2 + 0.5 * v, 0.5, 0.3),
                    roughness: v,
                    metallic: if y % 3 == 0 { 1.0 } else { 0.0 },
                    emitter: x == 15 && y < 2,
                    ..GPixel::default()
                };
                l.bounce.albedo = Vec3::splat(0.4 + 0.2 * v);
                l.bounce.direction = Vec3::new(v, 0.3, 0.9).normalize();
            }
            if (x, y) != (4, 4) {
                l.stats = PixelStats::one(Vec3::splat(0.1 + v), Vec3::splat(0.3 * v));
                history[i].merge(&l.stats);
            }
        }
        let mut gathered = Filter::default();
        gathered.gather(0, &gbuffer, &lighting);
        gathered
            .run(config.method, &config, &history, &gbuffer, &lighting, true)
            .unwrap();
        let mut waiting = Filter::default();
        waiting
            .run(config.method, &config, &history, &gbuffer, &lighting, false)
            .unwrap();
        assert!(gathered.image.iter().any(|o| *o != Vec3::ZERO));
        assert!(gathered.image == waiting.image);
        assert!(gathered.variance == waiting.variance);
    }

    #[test]
    fn a_silhouette_against_the_sky_is_filtered_as_its_hits() {
        // Its hits' light is the wall's, so the filter gives it back: its mean 0.5 * 0.5 + 1
        // exactly, and the wall keeps its light.
        let (out, w) = silhouette(true);
        for (i, o) in out.iter().enumerate() {
            let want = match i % w {
                0..10 => 0.5,
                10 => 1.25,
                _ => 2.0,
            };
            assert!((o.x - want).abs() < 1e-5, "pixel {i}: {o}, want {want}");
        }
        // Without, the silhouette's mixture of sky and wall is filtered as the wall's light.
        let (out, w) = silhouette(false);
        let (wall, edge) = (out[3 * w + 9].x, out[3 * w + 10].x);
        assert!(
            (edge - 1.25).abs() > 0.01 && (wall - 0.5).abs() > 1e-3,
            "{wall} {edge}"
        );
    }
}
