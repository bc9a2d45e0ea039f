//! The side panel: timings, the display, the camera, and a section per pass with its switch
//! and parameters.

use eframe::egui;
use pathlight_render::bsdf::Microfacet;
use pathlight_render::config::Tonemap;
use pathlight_render::denoise::{
    ranges as filter_ranges, ColourUnits, ColourWeights, DepthUnits, ErrorPair, Method,
};
use pathlight_render::frame::adaptive::Measure;
use pathlight_render::frame::display::{DisplayMode, View};
use pathlight_render::frame::reprojection::{Fate, MAX_FRESH_SPP};
use pathlight_render::frame::target::TARGET_MS;
use pathlight_render::frame::texture_cache::{
    ranges, CacheFilter, CachedTerms, LodMeasure, Temporal, MAX_KERNEL,
};
use pathlight_render::frame::upsample::MIN_SCALE;
use pathlight_render::frame::{stages, views};
use pathlight_render::frame::{
    ACCUMULATE, DISPLAY, FILTER, LIGHTING, PRIMARY, REPROJECT, RESTIR, TEXTURE_CACHE,
};
use pathlight_render::light::LightSelection;
use pathlight_render::preset::Preset;
use pathlight_render::sampler::SamplerKind;

use crate::navigation::Mode;

use crate::{Viewer, SHORTCUTS};

pub fn show(v: &mut Viewer, ui: &mut egui::Ui) {
    ui.heading("pathlight");
    timings(v, ui);
    ui.separator();
    egui::CollapsingHeader::new("Display")
        .default_open(true)
        .show(ui, |ui| display(v, ui));
    egui::CollapsingHeader::new("Camera")
        .default_open(true)
        .show(ui, |ui| camera(v, ui));
    egui::CollapsingHeader::new("Passes")
        .default_open(true)
        .show(ui, |ui| passes(v, ui));
    egui::CollapsingHeader::new("Keys").show(ui, |ui| {
        egui::Grid::new("keys").striped(true).show(ui, |ui| {
            for (k, what) in SHORTCUTS {
                ui.monospace(*k);
                ui.label(*what);
                ui.end_row();
            }
        });
    });
    if !v.message.is_empty() {
        ui.separator();
        ui.label(&v.message);
    }
}

fn timings(v: &mut Viewer, ui: &mut egui::Ui) {
    let Some((report, w, h)) = &v.shown else {
        ui.label("rendering the first frame...");
        return;
    };
    ui.label(format!(
        "{w} x {h}   {:.1} fps   {:.1} ms per frame",
        v.fps, report.ms
    ));
    let target = v.config.frame.target_ms;
    if target > 0.0 || report.scale < 1.0 {
        ui.label(format!(
            "render scale {}   target {target} ms: {} of {} frames over",
            report.scale, v.over_target, v.frames_shown
        ));
    }
    ui.label(format!(
        "{} frames accumulated, {} spp   {:.1} Mrays/s",
        report.accumulated,
        report.spp,
        if report.ms > 0.0 {
            report.rays as f64 / (report.ms * 1e3)
        } else {
            0.0
        }
    ));
    if let Some(r) = &report.reprojection {
        ui.label(format!(
            "reprojected {} of {} states: {} out of view, {} specular, {} mixed, {} view error, {} occluded, {} collided, {} aliased",
            r.kept, r.states, r.out_of_view, r.specular, r.mixed, r.view_error, r.occluded, r.collisions, r.aliasing
        ));
    }
    if let Some(tau) = report.tau {
        ui.label(format!(
            "adaptive: tau {tau:.3}, {:.2} samples per pixel this frame",
            report.samples as f64 / (*w as f64 * *h as f64).max(1.0)
        ));
    }
    let total = report.ms.max(1e-6);
    egui::Grid::new("passes").show(ui, |ui| {
        for p in &report.passes {
            ui.label(p.pass);
            ui.monospace(format!("{:7.2} ms", p.ms));
            ui.add(
                egui::ProgressBar::new((p.ms / total) as f32)
                    .desired_width(100.0)
                    .desired_height(8.0),
            );
            ui.end_row();
        }
    });
    ui.horizontal(|ui| {
        let label = if v.paused { "Resume" } else { "Pause" };
        if ui.button(label).clicked() {
            v.set_paused(!v.paused);
        }
        if ui.button("Restart").clicked() {
            v.worker.reset();
        }
        if ui.button("Save PNG").clicked() {
            v.save_screenshot();
        }
    });
    // The preset applied last, by name, and whether a setting was changed since.
    ui.label(match &v.preset {
        Some((name, c)) if v.config.is_preset(c) => format!("configuration: {name}"),
        Some((name, _)) => format!("configuration: {name}, changed"),
        None => "configuration: the command line's".to_owned(),
    });
    ui.horizontal(|ui| {
        for preset in Preset::ALL {
            let file = preset.file().unwrap_or("every technique off");
            if ui
                .button(preset.name())
                .on_hover_text(format!("{file}: {}", preset.about()))
                .clicked()
            {
                let c = preset.config(&v.config);
                v.preset = Some((preset.name().to_owned(), c.clone()));
                v.config = c;
            }
        }
    });
}

/// The display menu: every stage's views under its name, the frame's last stage (the final
/// image) first.
pub fn menu() -> impl Iterator<Item = (&'static str, &'static [View])> {
    stages::views().iter().rev().copied()
}

fn display(v: &mut Viewer, ui: &mut egui::Ui) {
    let d = &mut v.config.display;
    let stage = views::find(d.mode.name()).map_or("", |(stage, _)| stage);
    egui::ComboBox::from_label("mode")
        .selected_text(format!("{} ({stage})", d.mode.name()))
        .show_ui(ui, |ui| {
            for (stage, stage_views) in menu() {
                ui.label(egui::RichText::new(stage).strong());
                for v in stage_views {
                    ui.selectable_value(&mut d.mode, DisplayMode::named(v.name), v.name)
                        .on_hover_text(v.about);
                }
            }
        });
    if d.mode.name() == "rejection" {
        ui.horizontal_wrapped(|ui| {
            for fate in Fate::ALL {
                let [r, g, b] = fate.colour();
                ui.colored_label(egui::Color32::from_rgb(r, g, b), format!("{fate:?}"));
            }
        });
    }
    let mut stops = d.exposure.max(1e-6).log2();
    if ui
        .add(egui::Slider::new(&mut stops, -10.0..=10.0).text("exposure (stops)"))
        .changed()
    {
        d.exposure = stops.exp2();
    }
    egui::ComboBox::from_label("tone map")
        .selected_text(format!("{:?}", d.tonemap))
        .show_ui(ui, |ui| {
            ui.selectable_value(&mut d.tonemap, Tonemap::Clamp, "clamp");
            ui.selectable_value(&mut d.tonemap, Tonemap::Aces, "ACES");
        });
    ui.add(
        egui::Slider::new(&mut v.scale, 0.1..=2.0)
            .logarithmic(true)
            .text("resolution scale"),
    );
}

fn camera(v: &mut Viewer, ui: &mut egui::Ui) {
    let n = &mut v.navigation;
    ui.horizontal(|ui| {
        ui.radio_value(&mut n.mode, Mode::Orbit, "orbit");
        ui.radio_value(&mut n.mode, Mode::Fly, "fly");
        if ui.button("Home").clicked() {
            n.home();
        }
    });
    ui.add(
        egui::Slider::new(&mut n.speed, 1e-3..=1e4)
            .logarithmic(true)
            .text("fly speed (units/s)"),
    );
    ui.add(egui::Slider::new(&mut n.fov_y, 5.0..=150.0).text("field of view"));
    let c = &mut v.config.camera;
    ui.add(
        egui::Slider::new(&mut c.lens_radius, 0.0..=1.0)
            .logarithmic(true)
            .text("lens radius"),
    );
    let mut auto = c.focus_distance.is_none();
    ui.horizontal(|ui| {
        ui.checkbox(&mut auto, "autofocus");
        if !auto {
            let mut d = c.focus_distance.unwrap_or(1.0);
            ui.add(
                egui::Slider::new(&mut d, 1e-2..=1e3)
                    .logarithmic(true)
                    .text("focus"),
            );
            c.focus_distance = Some(d);
        } else {
            c.focus_distance = None;
        }
    });
    let p = n.position;
    ui.label(format!(
        "at ({:.2}, {:.2}, {:.2}), target {:.2} ahead",
        p.x, p.y, p.z, n.distance
    ));
}

fn passes(v: &mut Viewer, ui: &mut egui::Ui) {
    let c = &mut v.config;
    ui.label(egui::RichText::new("frame time").strong());
    ui.add(egui::Slider::new(&mut c.frame.target_ms, TARGET_MS).text("target ms"))
        .on_hover_text("0: none; else the render scale steps down to hold it");
    ui.add(egui::Slider::new(&mut c.frame.upsample.scale, MIN_SCALE..=1.0).text("render scale"))
        .on_hover_text("below 1: temporal upsampling; with a target, the largest it uses");
    ui.separator();
    ui.label(egui::RichText::new(REPROJECT).strong());
    let r = &mut c.frame.reprojection;
    ui.checkbox(
        &mut r.enabled,
        "forward reprojection (seed 000): keep samples through camera moves",
    );
    ui.add_enabled_ui(r.enabled, |ui| {
        ui.horizontal(|ui| {
            ui.label("states per pixel");
            ui.radio_value(&mut r.samples, 1, "1");
            ui.radio_value(&mut r.samples, 4, "4");
        });
        ui.add(
            egui::Slider::new(&mut r.max_error, 1e-4..=1.0)
                .logarithmic(true)
                .text("max view error (Eq. 15)"),
        );
        ui.checkbox(
            &mut r.occlusion_rays,
            "occlusion rays (else the aliasing test alone)",
        );
        ui.add(
            egui::Slider::new(&mut r.depth_tolerance, 1e-3..=0.5)
                .logarithmic(true)
                .text("aliasing depth tolerance"),
        );
        ui.add(
            egui::Slider::new(&mut r.fresh_spp, 0..=MAX_FRESH_SPP)
                .text("samples a hole takes at once (0: one per frame)"),
        );
    });
    ui.separator();

    ui.label(egui::RichText::new(PRIMARY).strong());
    ui.label("camera rays to the G-buffer: position, normal, albedo, roughness, metallic, material, depth, motion");
    ui.separator();

    ui.label(egui::RichText::new(RESTIR).strong());
    restir(c, ui);
    ui.separator();

    ui.label(egui::RichText::new(TEXTURE_CACHE).strong());
    texture_cache(c, ui);
    ui.separator();

    ui.label(egui::RichText::new(LIGHTING).strong());
    ui.add(egui::Slider::new(&mut c.spp, 1..=64).text("samples per pixel per frame"));
    let mut unlimited = c.max_bounces.is_none();
    ui.horizontal(|ui| {
        ui.checkbox(&mut unlimited, "unlimited bounces");
        if unlimited {
            c.max_bounces = None;
        } else {
            let mut b = c.max_bounces.unwrap_or(2);
            ui.add(egui::Slider::new(&mut b, 0..=32).text("bounces"));
            c.max_bounces = Some(b);
        }
    });
    ui.add(egui::Slider::new(&mut c.rr_start, 1..=32).text("Russian roulette from bounce"));
    egui::ComboBox::from_label("sampler")
        .selected_text(format!("{:?}", c.sampler))
        .show_ui(ui, |ui| {
            ui.selectable_value(&mut c.sampler, SamplerKind::Sobol, "Sobol (Owen)");
            ui.selectable_value(&mut c.sampler, SamplerKind::Independent, "independent");
        });
    egui::ComboBox::from_label("glossy lobes")
        .selected_text(format!("{:?}", c.microfacet))
        .show_ui(ui, |ui| {
            ui.selectable_value(&mut c.microfacet, Microfacet::Ggx, "GGX");
            ui.selectable_value(&mut c.microfacet, Microfacet::Beckmann, "Beckmann");
        });
    egui::ComboBox::from_label("light selection")
        .selected_text(format!("{:?}", c.light_selection))
        .show_ui(ui, |ui| {
            ui.selectable_value(&mut c.light_selection, LightSelection::Power, "by power");
            ui.selectable_value(&mut c.light_selection, LightSelection::Uniform, "uniform");
        });
    ui.horizontal(|ui| {
        ui.label("seed");
        ui.add(egui::DragValue::new(&mut c.seed));
    });
    ui.separator();

    ui.label(egui::RichText::new(ACCUMULATE).strong());
    ui.checkbox(
        &mut c.frame.accumulate,
        "accumulate while the camera is still",
    );
    ui.add(
        egui::Slider::new(&mut c.frame.max_frames, 0..=65536)
            .logarithmic(true)
            .text("stop after frames (0: never)"),
    );
    let a = &mut c.frame.adaptive;
    ui.checkbox(
        &mut a.enabled,
        "adaptive sampling (seed 000): samples where the variance is",
    );
    ui.add_enabled_ui(a.enabled, |ui| {
        ui.add(egui::Slider::new(&mut a.min_spp, 1..=64).text("min spp"));
        ui.add(
            egui::Slider::new(&mut a.max_spp, 1..=256)
                .logarithmic(true)
                .text("max spp"),
        );
        a.max_spp = a.max_spp.max(a.min_spp);
        egui::ComboBox::from_label("measure V")
            .selected_text(a.measure.name())
            .show_ui(ui, |ui| {
                for m in Measure::ALL {
                    ui.selectable_value(&mut a.measure, m, m.name());
                }
            });
        ui.checkbox(&mut a.cap, "cap at max spp (the combination's fix)");
        ui.checkbox(&mut a.skip_empty, "skip iterations that sample no pixel");
        ui.checkbox(&mut a.budget, "a uniform frame's samples per frame, by P");
        ui.checkbox(
            &mut a.keep_sampling,
            "combination: reprojected pixels keep their probability's samples",
        );
        ui.add_enabled(
            a.keep_sampling,
            egui::Slider::new(&mut a.keep_sampling_after, 0..=a.max_spp)
                .text("... after this many iterations"),
        );
    });
    ui.separator();

    ui.label(egui::RichText::new(FILTER).strong());
    filter(c, ui);
    ui.separator();

    ui.label(egui::RichText::new(DISPLAY).strong());
    ui.label("tone mapping and display modes: see Display above");
}

/// Seed 004's switches and parameters (ReSTIR runs with seed 000's techniques too: every
/// combination of the stages runs, `tests/combinations.rs`).
fn restir(c: &mut pathlight_render::Config, ui: &mut egui::Ui) {
    let r = &mut c.frame.restir;
    ui.checkbox(
        &mut r.enabled,
        "ReSTIR DI (seed 004): resampled light samples at the first hit",
    );
    ui.add_enabled_ui(r.enabled, |ui| {
        ui.add(
            egui::Slider::new(&mut r.candidates, 1..=1024)
                .logarithmic(true)
                .text("candidates"),
        );
        ui.checkbox(&mut r.visibility_reuse, "visibility reuse");
        ui.checkbox(&mut r.temporal, "temporal reuse");
        ui.add(egui::Slider::new(&mut r.m_cap, 0..=100).text("M cap (x current M; 0: none)"));
        ui.checkbox(&mut r.spatial, "spatial reuse");
        ui.add(egui::Slider::new(&mut r.neighbours, 1..=16).text("neighbours"));
        ui.add(egui::Slider::new(&mut r.iterations, 1..=4).text("iterations"));
        ui.add(egui::Slider::new(&mut r.radius, 1.0..=100.0).text("radius (pixels)"));
        ui.add(egui::Slider::new(&mut r.depth_threshold, 0.0..=1.0).text("depth threshold"));
        ui.add(egui::Slider::new(&mut r.normal_threshold, 0.0..=1.0).text("normal threshold"));
        ui.checkbox(&mut r.unbiased, "unbiased (1/Z with visibility)");
        ui.checkbox(
            &mut r.mis,
            "MIS weights (balance heuristic over the pixels)",
        );
    });
}

/// Seed 002's texture-space shading cache: its switch and parameters (key `T`).
fn texture_cache(c: &mut pathlight_render::Config, ui: &mut egui::Ui) {
    let t = &mut c.frame.texture_cache;
    ui.checkbox(&mut t.enabled, "texture-space cache (seed 002)");
    ui.add_enabled_ui(t.enabled, |ui| {
        ui.horizontal(|ui| {
            ui.label("cached light");
            ui.radio_value(&mut t.terms, CachedTerms::Indirect, "indirect");
            ui.radio_value(&mut t.terms, CachedTerms::All, "all");
            ui.radio_value(&mut t.terms, CachedTerms::Sky, "sky");
        });
        ui.add(egui::Slider::new(&mut t.lod_bias, ranges::LOD_BIAS).text("level bias"));
        ui.horizontal(|ui| {
            ui.label("level from");
            ui.radio_value(&mut t.lod, LodMeasure::Area, "area");
            ui.radio_value(&mut t.lod, LodMeasure::Finer, "Eq. 1");
        });
        egui::ComboBox::from_label("texture-space filter")
            .selected_text(format!("{:?}", t.filter))
            .show_ui(ui, |ui| {
                ui.selectable_value(&mut t.filter, CacheFilter::None, "none");
                ui.selectable_value(&mut t.filter, CacheFilter::Box, "box");
                ui.selectable_value(&mut t.filter, CacheFilter::Gaussian, "Gaussian");
                ui.selectable_value(&mut t.filter, CacheFilter::Linear, "linear");
            });
        let mut k = t.kernel;
        ui.add(egui::Slider::new(&mut k, 1..=MAX_KERNEL).text("filter window"));
        t.kernel = k | 1;
        egui::ComboBox::from_label("temporal reuse")
            .selected_text(format!("{:?}", t.temporal))
            .show_ui(ui, |ui| {
                ui.selectable_value(&mut t.temporal, Temporal::Mean, "mean");
                ui.selectable_value(&mut t.temporal, Temporal::Exponential, "Eq. 6");
                ui.selectable_value(&mut t.temporal, Temporal::None, "none");
            });
        ui.add(egui::Slider::new(&mut t.shrink, ranges::SHRINK).text("filter narrowing"));
        ui.checkbox(&mut t.interpolate, "interpolate texels");
        ui.add(egui::Slider::new(&mut t.temporal_alpha, 0.0..=0.99).text("Eq. 6 history weight"));
        ui.add(egui::Slider::new(&mut t.reshade, 0.0..=16.0).text("reshade rate (/ n)"));
        ui.add(
            egui::Slider::new(&mut t.max_count, 1..=4096)
                .logarithmic(true)
                .text("most samples a cell takes"),
        );
        ui.add(
            egui::Slider::new(&mut t.budget_mb, ranges::BUDGET_MB)
                .logarithmic(true)
                .text("budget (MB)"),
        );
        ui.add(
            egui::Slider::new(&mut t.min_roughness, ranges::MIN_ROUGHNESS)
                .text("bypass below roughness"),
        );
        ui.add(
            egui::Slider::new(&mut t.edge_spp, ranges::EDGE_SPP)
                .logarithmic(true)
                .text("samples on edges"),
        )
        .on_hover_text("Camera samples per frame of a pixel on a silhouette or a crease");
        ui.add(
            egui::Slider::new(&mut t.fresh_spp, ranges::FRESH_SPP)
                .logarithmic(true)
                .text("young cells' samples"),
        )
        .on_hover_text("Samples a cell newly seen is brought up to after the frame");
        ui.add(
            egui::Slider::new(&mut t.fresh_budget, ranges::FRESH_BUDGET)
                .logarithmic(true)
                .text("young cells' budget"),
        )
        .on_hover_text("Paths per pixel per frame for young cells");
        ui.add(
            egui::Slider::new(&mut t.cold_budget, ranges::FRESH_BUDGET)
                .logarithmic(true)
                .text("empty cache's budget"),
        )
        .on_hover_text("Paths per pixel for young cells at the first frame of an empty cache");
        ui.checkbox(&mut t.sun_ratio, "sun by its exact irradiance")
            .on_hover_text(
                "With terms = sky: the sun's unshadowed irradiance worked out over its texels, \
                 its one sample deciding the shadow alone",
            );
        ui.add(egui::Slider::new(&mut t.clamp, 0.0..=8.0).text("clamp (0: off)"))
            .on_hover_text(
                "A cell's indirect sample clamped to this multiple of the brightest light a \
                 white diffuse surface lit directly reflects",
            );
    });
}

/// Seed 001's reconstruction filter: the method and its parameters (changing them does not
/// restart the accumulation).
fn filter(c: &mut pathlight_render::Config, ui: &mut egui::Ui) {
    let f = &mut c.frame.filter;
    egui::ComboBox::from_label("reconstruction filter (seed 001)")
        .selected_text(match f.method {
            Method::None => "none",
            Method::DataDriven => "data-driven",
            Method::Svgf => "svgf",
            Method::Rpf => "rpf (offline: pathlight render)",
            Method::Taa => "taa",
        })
        .show_ui(ui, |ui| {
            ui.selectable_value(&mut f.method, Method::None, "none");
            ui.selectable_value(&mut f.method, Method::DataDriven, "data-driven");
            ui.selectable_value(&mut f.method, Method::Svgf, "svgf (spatio-temporal)");
            ui.selectable_value(&mut f.method, Method::Taa, "taa (antialiasing)");
        });
    ui.add_enabled_ui(
        f.method == Method::Taa || (f.method == Method::Svgf && f.svgf.taa),
        |ui| {
            ui.add(
                egui::Slider::new(&mut f.taa.alpha, filter_ranges::TAA_ALPHA)
                    .text("antialiasing weight"),
            )
            .on_hover_text("This frame's weight in the temporal antialiasing's blend");
            ui.add(
                egui::Slider::new(&mut f.taa.gamma, filter_ranges::TAA_GAMMA)
                    .logarithmic(true)
                    .text("antialiasing box"),
            )
            .on_hover_text(
                "The box the history is clamped to, in standard deviations of the \
                     neighbourhood: wider keeps more history",
            );
        },
    );
    ui.add_enabled_ui(f.method == Method::Svgf, |ui| {
        ui.add(
            egui::Slider::new(
                &mut f.svgf.atrous_iterations,
                filter_ranges::ATROUS_ITERATIONS,
            )
            .text("a-trous iterations"),
        );
        ui.horizontal(|ui| {
            ui.label("a-trous kernel");
            ui.radio_value(&mut f.svgf.atrous_kernel, 5, "5x5 (the paper's)");
            ui.radio_value(&mut f.svgf.atrous_kernel, 3, "3x3");
        });
        ui.checkbox(
            &mut f.svgf.split,
            "direct and indirect light apart (the paper; off: their sum, one signal)",
        );
        ui.add(
            egui::Slider::new(&mut f.svgf.normal_width, filter_ranges::NORMAL_WIDTH)
                .text("history normal test"),
        )
        .on_hover_text(
            "A previous normal is kept within k times the pixel's normal width plus 0.01 \
                 (16: the authors' implementation); 0: a cosine of at least 0.9",
        );
        ui.checkbox(&mut f.svgf.taa, "temporal antialiasing after it");
        ui.checkbox(&mut f.svgf.converge, "converge when still")
            .on_hover_text(
                "Not in the paper: a pixel that has not moved takes its frames into a plain \
                 mean and its luminance test narrows with the mean's noise",
            );
        ui.add(
            egui::Slider::new(&mut f.svgf.still_handover, filter_ranges::STILL_HANDOVER)
                .logarithmic(true)
                .text("hand over when still (frames)"),
        )
        .on_hover_text(
            "Not in the paper: once the camera has been still this many frames, the \
             data-driven filter (its parameters below) filters the accumulated image until the \
             camera moves (0: never); needs accumulation on",
        );
    });
    ui.add_enabled_ui(f.gathers_features(), |ui| {
        let mut radius = f.data_driven.kernel / 2;
        ui.add(
            egui::Slider::new(&mut radius, 0..=filter_ranges::KERNEL.end() / 2)
                .text("kernel radius (width 2r+1)"),
        );
        f.data_driven.kernel = 2 * radius + 1;
        ui.checkbox(&mut f.data_driven.holes, "with holes (every other pixel)");
        let sigma = |ui: &mut egui::Ui, v: &mut f32, what: &str| {
            ui.add(
                egui::Slider::new(v, filter_ranges::SIGMA)
                    .logarithmic(true)
                    .text(what),
            );
        };
        sigma(ui, &mut f.data_driven.sigma_direct, "sigma direct light");
        sigma(
            ui,
            &mut f.data_driven.sigma_indirect,
            "sigma indirect light",
        );
        sigma(ui, &mut f.data_driven.sigma_depth, "sigma depth");
        sigma(ui, &mut f.data_driven.sigma_normal, "sigma normal");
        ui.add(
            egui::Slider::new(
                &mut f.data_driven.sigma_normal_lobe,
                filter_ranges::SIGMA_NORMAL_LOBE,
            )
            .text("sigma normal of metal (x alpha)"),
        );
        sigma(ui, &mut f.data_driven.sigma_texture, "sigma texture");
        ui.checkbox(&mut f.data_driven.texture2_test, "texture2 test (thesis)");
        ui.add_enabled_ui(f.data_driven.texture2_test, |ui| {
            sigma(ui, &mut f.data_driven.sigma_texture2, "sigma texture2");
        });
        for (i, name) in ["depth", "normal", "texture", "direction", "texture2"]
            .into_iter()
            .enumerate()
        {
            ui.add(
                egui::Slider::new(
                    &mut f.data_driven.variance_scale[i],
                    filter_ranges::VARIANCE_SCALE,
                )
                .logarithmic(true)
                .text(format!("variance scale {name}")),
            );
        }
        ui.horizontal(|ui| {
            ui.radio_value(
                &mut f.data_driven.depth_units,
                DepthUnits::Relative,
                "depth relative",
            );
            ui.radio_value(
                &mut f.data_driven.depth_units,
                DepthUnits::Scene,
                "depth in scene units",
            );
        });
        ui.horizontal(|ui| {
            ui.label("colour differences");
            ui.radio_value(
                &mut f.data_driven.colour_units,
                ColourUnits::Variance,
                "in standard errors",
            );
            ui.radio_value(
                &mut f.data_driven.colour_units,
                ColourUnits::Relative,
                "relative",
            );
            ui.radio_value(
                &mut f.data_driven.colour_units,
                ColourUnits::Linear,
                "linear (thesis)",
            );
        });
        ui.horizontal(|ui| {
            ui.label("colour channels");
            ui.radio_value(
                &mut f.data_driven.colour_weights,
                ColourWeights::Equal,
                "alike",
            );
            ui.radio_value(
                &mut f.data_driven.colour_weights,
                ColourWeights::Albedo,
                "by the albedo",
            )
            .on_hover_text(
                "each channel of a difference weighed by the centre's albedo, (a_c / \
                     L(a))^2: the test sees the light as the pixel shows it (not in the thesis)",
            );
        });
        ui.add_enabled_ui(f.data_driven.colour_units == ColourUnits::Variance, |ui| {
            ui.horizontal(|ui| {
                ui.label("two pixels' errors");
                ui.radio_value(
                    &mut f.data_driven.error_pair,
                    ErrorPair::Sum,
                    "added in squares",
                );
                ui.radio_value(
                    &mut f.data_driven.error_pair,
                    ErrorPair::Product,
                    "multiplied",
                );
            });
        });
        ui.checkbox(&mut f.data_driven.demodulate, "demodulate by the albedo");
        ui.checkbox(
            &mut f.data_driven.sky_coverage,
            "silhouettes: their hits alone",
        );
        ui.add_enabled(
            f.data_driven.colour_units == ColourUnits::Variance,
            egui::Checkbox::new(
                &mut f.data_driven.error_blur,
                "standard errors over the 3x3 surface (not in the thesis)",
            ),
        );
        ui.add_enabled_ui(f.data_driven.colour_units == ColourUnits::Variance, |ui| {
            ui.checkbox(&mut f.data_driven.sure, "blend with own light by SURE")
                .on_hover_text(
                    "each pixel's filtered light blended with its own by their errors \
                     estimated with Stein's unbiased risk estimate (not in the thesis; the \
                     display mode sure-share shows the blend)",
                );
            ui.add_enabled(
                f.data_driven.sure,
                egui::Slider::new(&mut f.data_driven.sure_radius, filter_ranges::SURE_RADIUS)
                    .text("SURE radius"),
            );
        });
        ui.add(
            egui::Slider::new(
                &mut f.data_driven.refresh_growth,
                filter_ranges::REFRESH_GROWTH,
            )
            .text("filter again after the frames grow (x)"),
        )
        .on_hover_text(
            "Not in the thesis: a still view is filtered again only once its accumulated \
             frames have grown by this factor, and shown as it was meanwhile (at most 1: \
             every frame)",
        );
    });
}

#[cfg(test)]
mod tests {
    use super::*;
    use pathlight_render::frame::Pipeline;
    use pathlight_render::Config;

    /// The menu lists every view of every stage of the pipeline, each under its stage, and
    /// the number keys' modes are among them.
    #[test]
    fn the_menu_lists_a_view_of_every_stage() {
        let pipeline = Pipeline::new(Config::default());
        let menu: Vec<(&str, &[View])> = menu().collect();
        for stage in pipeline.stages.all() {
            let listed = menu
                .iter()
                .find(|(name, _)| *name == stage.name())
                .unwrap_or_else(|| panic!("stage {} is not in the menu", stage.name()));
            assert!(!stage.views().is_empty(), "{} has no view", stage.name());
            for view in stage.views() {
                assert!(
                    listed.1.contains(view),
                    "{} of {} missing",
                    view.name,
                    stage.name()
                );
            }
        }
        assert_eq!(menu.len(), pipeline.stages.all().len());
        for m in crate::NUMBER_MODES {
            assert!(views::find(m.name()).is_some(), "{m}");
        }
    }

    /// A preset replaces the configuration: applied after any other, it gives what it gives
    /// alone (the sun preset then the real-time preset used to leave the cache on under
    /// SVGF), and it keeps the user's view (camera, size, display, seed).
    #[test]
    fn a_preset_applied_after_another_equals_the_preset_alone() {
        let mut base = Config::default();
        base.camera.fov_y = Some(50.0);
        base.seed = 7;
        base.display.exposure = 1.5;
        for first in Preset::ALL {
            let after_first = first.config(&base);
            for second in Preset::ALL {
                let alone = second.config(&base);
                let stacked = second.config(&after_first);
                assert_eq!(stacked, alone, "{} after {}", second.name(), first.name());
                assert!(stacked.is_preset(&alone));
                assert_eq!(alone.camera, base.camera, "{}", second.name());
                assert_eq!((alone.seed, alone.display.exposure), (7, 1.5));
            }
        }
        // The sun preset's cache, then the real-time preset: no cache under SVGF.
        let sun = Preset::Sun.config(&base);
        assert!(sun.frame.texture_cache.enabled);
        let realtime = Preset::Realtime.config(&sun);
        assert!(!realtime.frame.texture_cache.enabled);
        // A setting changed after the preset: no longer the preset.
        let mut changed = realtime.clone();
        changed.frame.texture_cache.enabled = true;
        assert!(!changed.is_preset(&Preset::Realtime.config(&base)));
    }
}
