//! Runs an experiment: loads the scene, renders (or finds in the cache) the reference of every
//! measured view, then runs each configuration and repetition through the real-time frame
//! pipeline along the camera path, and measures every image against its reference.
//!
//! Views before a measured one are rendered for `frames_per_view` frames each (seed 000's
//! samples per step, at one sample per frame). At a measured view the pipeline renders frames
//! until every budget has passed (equal samples: samples traced at the view; equal time:
//! render time at the view, metric computation excluded) and the accumulated image is measured
//! at each. A still camera with accumulation is the progressive reference render: its error
//! falls as 1/frames.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};

use pathlight_core::rng::hash;
use pathlight_render::config::{CameraConfig, MAX_SPP};
use pathlight_render::denoise::Method;
use pathlight_render::frame::display::DisplayMode;
use pathlight_render::frame::{FrameReport, Pipeline};
use pathlight_render::{Config, World};

use crate::image::Image;
use crate::metrics;
use crate::reference::{ReferenceCache, SceneIdentity, RENDERER_VERSION};
use crate::results::{slopes, BudgetPoint, Measurement, Results, ViewReference};
use crate::spec::Layer;
use crate::spec::Spec;
use crate::EvalError;

/// Where a run is: `done` of `total` units (samples or milliseconds) of `task`.
pub struct Progress<'a> {
    pub task: &'a str,
    pub done: u64,
    pub total: u64,
}

/// The images shown next to the reference: each configuration's image at its last budget
/// point, first repetition, last measured view.
pub struct Snapshots {
    pub view: usize,
    pub reference: Image,
    /// (configuration, what the image is, e.g. "64 spp, 312 ms", image).
    pub images: Vec<(String, String, Image)>,
    /// (configuration, display mode, RGBA8 pixels) of the spec's `display_modes`.
    pub displays: Vec<(String, DisplayMode, Vec<u8>)>,
}

/// What a run produced.
pub struct Outcome {
    pub results: Results,
    pub snapshots: Option<Snapshots>,
}

/// An experiment's scene, loaded, and its camera path.
pub struct Setup {
    pub world: World,
    pub identity: SceneIdentity,
    /// The camera of every view along the path.
    pub views: Vec<CameraConfig>,
    /// Indices of the measured views.
    pub measured: Vec<usize>,
}

/// The reference of one measured view.
pub struct NeededReference {
    pub view: usize,
    /// Its key in the reference cache.
    pub key: String,
    /// What the reference path tracer renders (`spp` the reference's).
    pub config: Config,
    /// True when the cache holds it.
    pub cached: bool,
}

pub struct Runner<'a> {
    pub spec: &'a Spec,
    /// Paths in the spec are relative to this folder.
    pub spec_dir: PathBuf,
    pub cache: ReferenceCache,
    pub progress: &'a (dyn Fn(&Progress) + Sync),
    pub cancel: &'a AtomicBool,
}

impl Runner<'_> {
    /// Loads the experiment's scene and lays out its camera path.
    pub fn setup(&self) -> Result<Setup, EvalError> {
        let spec = self.spec;
        let scene_path = spec.scene_path(&self.spec_dir);
        let options = spec.load_options(&self.spec_dir);
        let scene = pathlight_scene::load(scene_path.as_deref(), &options)?;
        let s = scene.stats();
        let identity = SceneIdentity::new(
            scene_path.as_deref(),
            options.environment.as_deref(),
            &format!(
                "env rot {} x{} +{} lights{}",
                options.environment_rotation,
                options.environment_intensity,
                options.point_lights,
                // (Left out at 1, so that earlier references keep their keys.)
                match options.point_light_intensity {
                    1.0 => String::new(),
                    x => format!(" x{x}"),
                }
            ),
            &format!(
                "{}: {} triangles, {} materials, {} textures, {} lights, {} emissive triangles",
                scene.name,
                s.triangles,
                s.materials,
                s.textures,
                scene.lights.len(),
                scene.emissive_triangles.len()
            ),
        )?;
        // One world; its light sampler follows each configuration's light selection.
        let world = World::new(scene, spec.reference.config.light_selection);
        let views = world.path_views(&spec.camera);
        let measured = spec.measured_views(views.len());
        Ok(Setup {
            world,
            identity,
            views,
            measured,
        })
    }

    /// The references the run measures against (one per measured view), and whether the
    /// cache already holds each: what a cluster renders ahead of the run
    /// (`pathlight eval --cluster`).
    pub fn references(&self, setup: &Setup) -> Vec<NeededReference> {
        setup
            .measured
            .iter()
            .map(|&view| {
                let config = self.spec.reference_config(&setup.views[view]);
                let key = ReferenceCache::key(&setup.identity, &config);
                let cached = self
                    .cache
                    .get(&key, config.width, config.height, self.spec.layer)
                    .is_some();
                NeededReference {
                    view,
                    key,
                    config,
                    cached,
                }
            })
            .collect()
    }

    /// Runs the whole experiment. When cancelled, returns what was measured so far with
    /// `complete: false`.
    pub fn run(&self) -> Result<Outcome, EvalError> {
        let spec = self.spec;
        let Setup {
            mut world,
            identity,
            views,
            measured,
        } = self.setup()?;
        let mut results = Results {
            spec: spec.clone(),
            renderer: RENDERER_VERSION.to_owned(),
            threads: rayon::current_num_threads(),
            complete: false,
            views: views.clone(),
            references: Vec::new(),
            measurements: Vec::new(),
            slopes: Vec::new(),
        };

        let mut references = Vec::new();
        for &v in &measured {
            let config = spec.reference_config(&views[v]);
            let task = format!("reference, view {}/{}", v + 1, views.len());
            world.set_light_selection(config.light_selection);
            let world = &world;
            let found = self.cache.get_or_render(
                &identity,
                world,
                &config,
                spec.layer,
                self.cancel,
                &|done, total| {
                    (self.progress)(&Progress {
                        task: &task,
                        done,
                        total,
                    })
                },
            )?;
            let Some((image, info)) = found else {
                return Ok(Outcome {
                    results,
                    snapshots: None,
                });
            };
            results.references.push(ViewReference { view: v, info });
            references.push((v, image));
        }

        let last_view = *measured.last().expect("at least one view");
        let mut snapshots = Snapshots {
            view: last_view,
            reference: references.last().expect("one per measured view").1.clone(),
            images: Vec::new(),
            displays: Vec::new(),
        };
        for c in &spec.configurations {
            let config = c.config_for(&world.lights);
            let c = &crate::spec::Configuration {
                config,
                ..c.clone()
            };
            world.set_light_selection(c.config.light_selection);
            let world = &world;
            for rep in 0..spec.repetitions {
                let seed = if rep == 0 {
                    c.config.seed
                } else {
                    hash(&[c.config.seed, rep as u64])
                };
                let config_at = |view| Config {
                    seed,
                    ..spec.configuration_config(&c.config, view)
                };
                let view_run = |v, reference, task| ViewRun {
                    runner: self,
                    world,
                    reference,
                    task,
                    name: &c.name,
                    rep,
                    seed,
                    view: v,
                    previous: None,
                };
                if c.config.frame.filter.method == Method::Rpf {
                    // The offline filter: each measured view on its own, from the reference
                    // path tracer's samples at each sample budget.
                    for &(v, ref reference) in &references {
                        let task =
                            format!("{} (RPF), run {}/{}", c.name, rep + 1, spec.repetitions);
                        let snapshot = view_run(v, reference, task)
                            .measure_rpf(&config_at(&views[v]), &mut results.measurements)?;
                        let Some(snapshot) = snapshot else {
                            results.slopes = slopes(spec, &results.measurements);
                            return Ok(Outcome {
                                results,
                                snapshots: None,
                            });
                        };
                        if rep == 0 && v == last_view {
                            snapshots
                                .images
                                .push((c.name.clone(), snapshot.0, snapshot.1));
                        }
                    }
                    continue;
                }
                let mut pipeline = Pipeline::new(config_at(&views[0]));
                // The previous view's images at each budget point and its reference, for the
                // temporal metrics (kept only when the spec asks for one).
                let temporal = spec.metrics.iter().any(|m| m.is_temporal());
                let mut previous: Option<(usize, Vec<(BudgetPoint, Image)>)> = None;
                for (v, view) in views.iter().enumerate() {
                    pipeline.set_config(&config_at(view));
                    let Some(reference) = references.iter().find(|r| r.0 == v).map(|r| &r.1) else {
                        // A step before the measured view.
                        for _ in 0..spec.camera.frames_per_view {
                            pipeline.render_frame(world);
                        }
                        continue;
                    };
                    let task = format!(
                        "{}, run {}/{}, view {}/{}",
                        c.name,
                        rep + 1,
                        spec.repetitions,
                        v + 1,
                        views.len()
                    );
                    let before = previous.as_ref().filter(|p| p.0 + 1 == v).and_then(|p| {
                        let r = references.iter().find(|r| r.0 == p.0)?;
                        Some((&r.1, p.1.as_slice()))
                    });
                    let (snapshot, images) = ViewRun {
                        previous: before,
                        ..view_run(v, reference, task)
                    }
                    .measure(
                        &mut pipeline,
                        &mut results.measurements,
                        temporal,
                    )?;
                    previous = temporal.then_some((v, images));
                    if self.cancel.load(Ordering::Relaxed) {
                        results.slopes = slopes(spec, &results.measurements);
                        return Ok(Outcome {
                            results,
                            snapshots: None,
                        });
                    }
                    if rep == 0 && v == last_view {
                        if let Some((label, image)) = snapshot {
                            snapshots.images.push((c.name.clone(), label, image));
                        }
                        for mode in &spec.display_modes {
                            let mut rgba = Vec::new();
                            let display = &pipeline.config().display;
                            pipeline.rgba8(mode, display, &mut rgba);
                            snapshots
                                .displays
                                .push((c.name.clone(), mode.clone(), rgba));
                        }
                    }
                }
            }
        }
        results.complete = true;
        results.slopes = slopes(spec, &results.measurements);
        Ok(Outcome {
            results,
            snapshots: Some(snapshots),
        })
    }
}

/// One configuration, repetition and measured view.
struct ViewRun<'a> {
    runner: &'a Runner<'a>,
    world: &'a World,
    reference: &'a Image,
    task: String,
    name: &'a str,
    rep: u32,
    seed: u64,
    view: usize,
    /// The previous view's reference and its images at each budget point (the temporal
    /// metrics'), if it was measured.
    previous: Option<(&'a Image, &'a [(BudgetPoint, Image)])>,
}

impl ViewRun<'_> {
    /// Renders frames at the view until every budget point has passed, pushing a measurement
    /// at each. Returns the image at the last budget point with its label (none when
    /// cancelled), and with `keep` the image at each budget point.
    #[allow(clippy::type_complexity)]
    fn measure(
        &self,
        pipeline: &mut Pipeline,
        out: &mut Vec<Measurement>,
        keep: bool,
    ) -> Result<(Option<(String, Image)>, Vec<(BudgetPoint, Image)>), EvalError> {
        let budget = &self.runner.spec.budget;
        let cancel = self.runner.cancel;
        let (w, h) = (pipeline.config().width, pipeline.config().height);
        let pixels = (w as u64 * h as u64).max(1);
        let max_spp = budget.spp.last().copied().unwrap_or(0);
        let max_ms = budget.time_ms.last().copied().unwrap_or(0.0);
        let (mut next_spp, mut next_ms) = (0, 0);
        // Equal samples count the samples the frames actually traced (`FrameReport::samples`),
        // per pixel on average: a technique that traces some pixels and not others (adaptive
        // sampling, reprojection's holes) is measured at the same number of camera paths as
        // the plain pipeline, not at the same number of frames.
        let mut traced = 0u64;
        let mut spp = 0u32;
        let mut stages: BTreeMap<String, f64> = BTreeMap::new();
        let (mut last, mut kept) = (None, Vec::new());
        // Once only sample budgets remain: a guard against a technique whose frames trace
        // (almost) nothing (not reached in practice: adaptive sampling's probabilities are at
        // least min_spp / max_spp).
        let max_frames = 64 * max_spp as u64 + 1024;
        let mut frames = 0u64;
        while (next_spp < budget.spp.len() || next_ms < budget.time_ms.len())
            && spp < MAX_SPP
            && (next_ms < budget.time_ms.len() || frames < max_frames)
        {
            if cancel.load(Ordering::Relaxed) {
                return Ok((None, kept));
            }
            let report: FrameReport = pipeline.render_frame(self.world);
            frames += 1;
            if !report.traced {
                // Accumulation has stopped (`max_frames`): no later frame adds anything.
                break;
            }
            traced += report.samples;
            spp = (traced / pixels).min(MAX_SPP as u64) as u32;
            for p in &report.passes {
                *stages.entry(p.pass.to_owned()).or_default() += p.ms;
            }
            // Render time at the view: the sum of the stages (so that they add up exactly).
            let ms: f64 = stages.values().sum();
            let done = f64::max(
                spp as f64 / max_spp.max(1) as f64,
                if max_ms > 0.0 { ms / max_ms } else { 0.0 },
            );
            (self.runner.progress)(&Progress {
                task: &self.task,
                done: ((done.min(1.0)) * 1000.0) as u64,
                total: 1000,
            });
            let mut points = Vec::new();
            while next_spp < budget.spp.len() && spp >= budget.spp[next_spp] {
                points.push(BudgetPoint::Spp(budget.spp[next_spp]));
                next_spp += 1;
            }
            while next_ms < budget.time_ms.len() && ms >= budget.time_ms[next_ms] {
                points.push(BudgetPoint::TimeMs(budget.time_ms[next_ms]));
                next_ms += 1;
            }
            if points.is_empty() {
                continue;
            }
            let image = Image::new(
                w,
                h,
                match self.runner.spec.layer {
                    Layer::Final => pipeline.image(),
                    Layer::Indirect => pipeline.linear(&DisplayMode::named("indirect")),
                },
            );
            let mean_spp = pipeline
                .frame
                .history
                .iter()
                .map(|p| p.n as f64)
                .sum::<f64>()
                / pipeline.frame.history.len().max(1) as f64;
            for point in points {
                out.push(self.measurement(point, mean_spp, ms, &stages, &image)?);
                let label = match point {
                    BudgetPoint::Spp(n) => format!("{n} spp, {ms:.0} ms"),
                    BudgetPoint::TimeMs(t) => format!("{t:.0} ms budget, {mean_spp:.0} spp"),
                };
                last = Some((label, image.clone()));
                if keep {
                    kept.push((point, image.clone()));
                }
            }
        }
        Ok((last, kept))
    }

    /// RPF ([`pathlight_render::rpf`]) at each sample budget: the reference path tracer's
    /// samples at that count, filtered; the time is the tracing's and the filter's (stages
    /// `trace` and `rpf`). Time budgets are not measured (the filter takes seconds to
    /// minutes). Returns the last image with its label, or none when cancelled.
    fn measure_rpf(
        &self,
        config: &Config,
        out: &mut Vec<Measurement>,
    ) -> Result<Option<(String, Image)>, EvalError> {
        let budget = &self.runner.spec.budget;
        let mut last = None;
        for &spp in &budget.spp {
            let config = Config {
                spp,
                ..config.clone()
            };
            let camera = config.render_camera(self.world);
            let task = format!("{}, {spp} spp", self.task);
            let progress = |f: f32| {
                (self.runner.progress)(&Progress {
                    task: &task,
                    done: (f.clamp(0.0, 1.0) * 1000.0) as u64,
                    total: 1000,
                })
            };
            let rendered = pathlight_render::rpf::render(
                self.world,
                &camera,
                &config,
                self.runner.cancel,
                &progress,
            )
            .map_err(|error| EvalError::Filter {
                configuration: self.name.to_owned(),
                error,
            })?;
            // Stopped while tracing, or while filtering.
            let Some(mut r) = rendered else {
                return Ok(None);
            };
            let Some(filtered) = r.filtered.take() else {
                return Ok(None);
            };
            let stages = BTreeMap::from([
                ("trace".to_owned(), r.trace_ms),
                ("rpf".to_owned(), r.filter_ms),
            ]);
            let ms = r.trace_ms + r.filter_ms;
            let image = Image::new(config.width, config.height, filtered);
            out.push(self.measurement(BudgetPoint::Spp(spp), spp as f64, ms, &stages, &image)?);
            last = Some((format!("{spp} spp, RPF, {:.1} s", ms / 1e3), image));
        }
        Ok(last)
    }

    fn measurement(
        &self,
        budget: BudgetPoint,
        spp: f64,
        ms: f64,
        stages: &BTreeMap<String, f64>,
        image: &Image,
    ) -> Result<Measurement, EvalError> {
        let mut values = BTreeMap::new();
        for &metric in &self.runner.spec.metrics {
            if !metric.is_temporal() {
                values.insert(metric, metrics::compute(metric, image, self.reference)?);
                continue;
            }
            // The previous view's image at the same budget point, if measured.
            let Some((reference, images)) = self.previous else {
                continue;
            };
            if let Some((_, before)) = images.iter().find(|(p, _)| *p == budget) {
                let now = (image, self.reference);
                let value = metrics::compute_temporal(metric, now, (before, reference))?;
                values.insert(metric, value);
            }
        }
        Ok(Measurement {
            configuration: self.name.to_owned(),
            repetition: self.rep,
            seed: self.seed,
            view: self.view,
            budget,
            spp,
            ms,
            stages: stages.clone(),
            metrics: values,
        })
    }
}

/// The folder a spec's relative paths start from.
pub fn spec_dir(spec_path: &Path) -> PathBuf {
    spec_path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .map_or_else(|| PathBuf::from("."), Path::to_owned)
}
