//! Runs an experiment: loads the scene, renders (or finds in the cache) the reference of every
//! measured view, then renders each configuration, repetition and view within the budgets and
//! measures every image against its reference.
//!
//! Today each configuration is the reference path tracer with its settings, accumulating
//! samples progressively; render time excludes metric computation. Views before a measured one
//! (seed 000's camera steps) are rendered with `samples_per_step` samples per pixel.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::Instant;

use pathlight_core::rng::hash;
use pathlight_render::config::MAX_SPP;
use pathlight_render::light::LightSelection;
use pathlight_render::renderer::render_pass;
use pathlight_render::{Config, Film, World};

use crate::image::Image;
use crate::metrics;
use crate::reference::{film_image, ReferenceCache, SceneIdentity, RENDERER_VERSION};
use crate::results::{slopes, BudgetPoint, Measurement, Results, ViewReference};
use crate::spec::Spec;
use crate::EvalError;

/// The name of the one stage of the path tracer's timings.
pub const PATH_TRACING: &str = "path tracing";

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
}

/// What a run produced.
pub struct Outcome {
    pub results: Results,
    pub snapshots: Option<Snapshots>,
}

pub struct Runner<'a> {
    pub spec: &'a Spec,
    /// Paths in the spec are relative to this folder.
    pub spec_dir: PathBuf,
    pub cache: ReferenceCache,
    pub progress: &'a (dyn Fn(&Progress) + Sync),
    pub cancel: &'a AtomicBool,
}

/// One world per light selection a configuration asks for (the light sampler is built with
/// the world).
struct Worlds {
    worlds: Vec<(LightSelection, World)>,
}

impl Worlds {
    fn get(&mut self, selection: LightSelection) -> &World {
        if let Some(i) = self.worlds.iter().position(|(s, _)| *s == selection) {
            return &self.worlds[i].1;
        }
        let scene = self.worlds[0].1.scene.clone();
        self.worlds.push((selection, World::new(scene, selection)));
        &self.worlds.last().expect("just pushed").1
    }
}

impl Runner<'_> {
    /// Runs the whole experiment. When cancelled, returns what was measured so far with
    /// `complete: false`.
    pub fn run(&self) -> Result<Outcome, EvalError> {
        let spec = self.spec;
        let scene_path = spec.scene_path(&self.spec_dir);
        let options = spec.load_options(&self.spec_dir);
        let scene = pathlight_scene::load(scene_path.as_deref(), &options)?;
        let s = scene.stats();
        let identity = SceneIdentity::new(
            scene_path.as_deref(),
            options.environment.as_deref(),
            &format!(
                "env rot {} x{} +{} lights",
                options.environment_rotation, options.environment_intensity, options.point_lights
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
        let first = spec.reference.config.light_selection;
        let mut worlds = Worlds {
            worlds: vec![(first, World::new(scene, first))],
        };
        let views = spec.views(&worlds.get(first).scene_camera());
        let measured = spec.measured_views(views.len());
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
            let world = worlds.get(config.light_selection);
            let found = self.cache.get_or_render(
                &identity,
                world,
                &config,
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
        };
        for c in &spec.configurations {
            let world = worlds.get(c.config.light_selection);
            for rep in 0..spec.repetitions {
                let seed = if rep == 0 {
                    c.config.seed
                } else {
                    hash(&[c.config.seed, rep as u64])
                };
                for (v, view) in views.iter().enumerate() {
                    let task = format!(
                        "{}, run {}/{}, view {}/{}",
                        c.name,
                        rep + 1,
                        spec.repetitions,
                        v + 1,
                        views.len()
                    );
                    let mut config = spec.configuration_config(&c.config, view, 1);
                    config.seed = seed;
                    let Some(reference) = references.iter().find(|r| r.0 == v).map(|r| &r.1) else {
                        // A step before the measured view.
                        if spec.camera.samples_per_step > 0 {
                            config.spp = spec.camera.samples_per_step;
                            let mut film = Film::new(config.width, config.height);
                            let camera = world.camera(&config);
                            render_pass(
                                world,
                                &camera,
                                &config,
                                &mut film,
                                config.spp,
                                self.cancel,
                                &|_| {},
                            );
                        }
                        continue;
                    };
                    let run = ViewRun {
                        runner: self,
                        world,
                        config: &config,
                        reference,
                        task: &task,
                        name: &c.name,
                        rep,
                        view: v,
                    };
                    let snapshot = run.measure(&mut results.measurements)?;
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
    config: &'a Config,
    reference: &'a Image,
    task: &'a str,
    name: &'a str,
    rep: u32,
    view: usize,
}

impl ViewRun<'_> {
    /// Renders within the equal-samples budgets, then (afresh) within the equal-time budgets,
    /// pushing a measurement at every budget point. Returns the image at the last budget point
    /// with its label.
    fn measure(&self, out: &mut Vec<Measurement>) -> Result<Option<(String, Image)>, EvalError> {
        let spec = self.runner.spec;
        let camera = self.world.camera(self.config);
        let (w, h) = (self.config.width, self.config.height);
        let pixels = w as u64 * h as u64;
        let cancel = self.runner.cancel;
        let mut last = None;

        // Equal samples: one progressive render, measured as it passes each budget.
        if let Some(&max_spp) = spec.budget.spp.last() {
            let mut film = Film::new(w, h);
            let done = AtomicU64::new(0);
            let total = pixels * max_spp as u64;
            let mut ms = 0.0;
            for &target in &spec.budget.spp {
                let start = Instant::now();
                let finished = render_pass(
                    self.world,
                    &camera,
                    self.config,
                    &mut film,
                    target,
                    cancel,
                    &|n| {
                        let d = done.fetch_add(n, Ordering::Relaxed) + n;
                        (self.runner.progress)(&Progress {
                            task: self.task,
                            done: d,
                            total,
                        });
                    },
                );
                ms += start.elapsed().as_secs_f64() * 1e3;
                if !finished {
                    return Ok(None);
                }
                let image = film_image(&film);
                out.push(self.measurement(BudgetPoint::Spp(target), target as f64, ms, &image)?);
                last = Some((format!("{target} spp, {ms:.0} ms"), image));
            }
        }

        // Equal time: passes of one sample per pixel until each time budget has passed.
        if !spec.budget.time_ms.is_empty() {
            let budgets = &spec.budget.time_ms;
            let total = budgets.last().copied().unwrap_or(0.0).ceil() as u64;
            let mut film = Film::new(w, h);
            let mut ms = 0.0;
            let mut next = 0;
            let mut spp = 0;
            while next < budgets.len() && spp < MAX_SPP {
                spp += 1;
                let start = Instant::now();
                if !render_pass(
                    self.world,
                    &camera,
                    self.config,
                    &mut film,
                    spp,
                    cancel,
                    &|_| {},
                ) {
                    return Ok(None);
                }
                ms += start.elapsed().as_secs_f64() * 1e3;
                (self.runner.progress)(&Progress {
                    task: self.task,
                    done: (ms as u64).min(total),
                    total,
                });
                while next < budgets.len() && ms >= budgets[next] {
                    let image = film_image(&film);
                    out.push(self.measurement(
                        BudgetPoint::TimeMs(budgets[next]),
                        spp as f64,
                        ms,
                        &image,
                    )?);
                    last = Some((format!("{:.0} ms budget, {spp} spp", budgets[next]), image));
                    next += 1;
                }
            }
        }
        Ok(last)
    }

    fn measurement(
        &self,
        budget: BudgetPoint,
        spp: f64,
        ms: f64,
        image: &Image,
    ) -> Result<Measurement, EvalError> {
        let mut values = BTreeMap::new();
        for &metric in &self.runner.spec.metrics {
            values.insert(metric, metrics::compute(metric, image, self.reference)?);
        }
        Ok(Measurement {
            configuration: self.name.to_owned(),
            repetition: self.rep,
            seed: self.config.seed,
            view: self.view,
            budget,
            spp,
            ms,
            stages: [(PATH_TRACING.to_owned(), ms)].into_iter().collect(),
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
