//! The experiment runner end to end on small Cornell box images: references are cached and
//! reused, equal-samples measurements are deterministic, a stopped reference resumes to the
//! same image, camera paths give one reference per measured view, and publishing writes the
//! files the report shows.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};

use pathlight_eval::experiment::{Outcome, Progress, Runner};
use pathlight_eval::metrics::Metric;
use pathlight_eval::publish::publish;
use pathlight_eval::reference::ReferenceCache;
use pathlight_eval::results::{BudgetPoint, Measurement, Results};
use pathlight_eval::spec::Spec;

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("pathlight-eval-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

const SPEC: &str = r#"
name = "small"
width = 24
height = 20
metrics = ["mse", "relmse", "ssim"]
repetitions = 2
[budget]
spp = [1, 2, 4]
[reference]
spp = 16
[[configuration]]
name = "independent"
[configuration.config]
sampler = "independent"
max_bounces = 3
[[configuration]]
name = "sobol"
[configuration.config]
max_bounces = 3
"#;

fn run(spec: &Spec, cache: &Path, cancel_after: Option<u64>) -> Outcome {
    let cancel = AtomicBool::new(false);
    let progress = |p: &Progress| {
        assert!(p.done <= p.total, "{} > {} in {}", p.done, p.total, p.task);
        if cancel_after.is_some_and(|n| p.done >= n) {
            cancel.store(true, Ordering::Relaxed);
        }
    };
    Runner {
        spec,
        spec_dir: PathBuf::from("."),
        cache: ReferenceCache::new(cache),
        progress: &progress,
        cancel: &cancel,
    }
    .run()
    .unwrap()
}

/// The measurements without their timings (which vary from run to run).
fn untimed(r: &Results) -> Vec<Measurement> {
    r.measurements
        .iter()
        .map(|m| Measurement {
            ms: 0.0,
            stages: Default::default(),
            ..m.clone()
        })
        .collect()
}

#[test]
fn references_are_cached_and_measurements_are_deterministic() {
    let spec = Spec::parse(SPEC).unwrap();
    let cache = temp_dir("cache");
    let first = run(&spec, &cache, None);
    let r = &first.results;
    assert!(r.complete);
    assert_eq!(r.references.len(), 1);
    assert!(!r.references[0].info.cached);
    // 2 configurations x 2 repetitions x 3 budgets.
    assert_eq!(r.measurements.len(), 12);
    for m in &r.measurements {
        let BudgetPoint::Spp(n) = m.budget else {
            panic!("no time budgets in this spec")
        };
        assert_eq!(m.spp, n as f64);
        assert!(m.ms > 0.0 && m.stages.values().sum::<f64>() == m.ms);
        assert_eq!(m.metrics.len(), 3);
        assert!(m.metrics[&Metric::Mse] > 0.0);
    }
    // Repetitions use different seeds.
    assert_ne!(r.measurements[0].seed, r.measurements[3].seed);
    assert_ne!(r.measurements[0].metrics, r.measurements[3].metrics);
    // Error falls with samples (each image's noise is independent of the others' only across
    // repetitions, but 4 spp beats 1 spp on any seed of this box).
    assert!(r.measurements[2].metrics[&Metric::Mse] < r.measurements[0].metrics[&Metric::Mse]);

    let second = run(&spec, &cache, None);
    assert!(second.results.references[0].info.cached);
    assert_eq!(
        second.results.references[0].info.key,
        r.references[0].info.key
    );
    assert_eq!(untimed(&second.results), untimed(r));
    let snaps = second.snapshots.as_ref().unwrap();
    assert_eq!(snaps.reference, first.snapshots.as_ref().unwrap().reference);
    assert_eq!(snaps.images.len(), 2);

    // Another reference setting is another cache entry.
    let mut other = spec.clone();
    other.reference.spp = 8;
    let third = run(&other, &cache, None);
    assert!(!third.results.references[0].info.cached);
    assert_ne!(
        third.results.references[0].info.key,
        r.references[0].info.key
    );
    std::fs::remove_dir_all(&cache).unwrap();
}

#[test]
fn a_stopped_reference_resumes_to_the_same_image() {
    let spec = Spec::parse(SPEC).unwrap();
    let whole = temp_dir("whole");
    let expected = run(&spec, &whole, None).snapshots.unwrap().reference;

    let cache = temp_dir("stopped");
    let stopped = run(&spec, &cache, Some(24 * 20 * 5));
    assert!(!stopped.results.complete);
    assert!(stopped.snapshots.is_none());
    let checkpoints: Vec<_> = std::fs::read_dir(cache.join("references"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "checkpoint"))
        .collect();
    assert_eq!(
        checkpoints.len(),
        1,
        "the stopped reference keeps a checkpoint"
    );

    let resumed = run(&spec, &cache, None);
    assert!(resumed.results.complete);
    assert_eq!(resumed.snapshots.unwrap().reference, expected);
    assert!(
        !checkpoints[0].exists(),
        "the finished reference drops its checkpoint"
    );
    for d in [whole, cache] {
        std::fs::remove_dir_all(d).unwrap();
    }
}

#[test]
fn rotation_measured_at_every_view_has_one_reference_per_view() {
    let mut spec = Spec::parse(SPEC).unwrap();
    spec.repetitions = 1;
    spec.configurations.truncate(1);
    spec.budget.spp = vec![2];
    spec.reference.spp = 4;
    spec.camera.path = pathlight_render::camera_path::PathKind::Rotation;
    spec.camera.degrees = 20.0;
    spec.camera.step_degrees = 10.0;
    spec.measure = pathlight_eval::spec::Measure::Every;
    let cache = temp_dir("rotation");
    let out = run(&spec, &cache, None).results;
    assert_eq!(out.views.len(), 3);
    assert_eq!(out.references.len(), 3);
    let keys: std::collections::HashSet<_> = out.references.iter().map(|r| &r.info.key).collect();
    assert_eq!(keys.len(), 3, "each view has its own reference");
    let views: Vec<usize> = out.measurements.iter().map(|m| m.view).collect();
    assert_eq!(views, vec![0, 1, 2]);

    // Measured only at the final view, after steps of frames_per_view frames.
    spec.measure = pathlight_eval::spec::Measure::Final;
    spec.camera.frames_per_view = 2;
    let out = run(&spec, &cache, None).results;
    assert_eq!(out.references.len(), 1);
    assert!(
        out.references[0].info.cached,
        "the last view's reference is reused"
    );
    assert_eq!(out.measurements.len(), 1);
    assert_eq!(out.measurements[0].view, 2);
    std::fs::remove_dir_all(&cache).unwrap();
}

/// Flicker compares consecutive measured views: none at the first, and a frame of one sample
/// per pixel changes between views by more than the references do, more than a frame of
/// sixteen.
#[test]
fn flicker_is_measured_between_consecutive_views() {
    let mut spec = Spec::parse(SPEC).unwrap();
    spec.repetitions = 1;
    spec.metrics = vec![Metric::Mse, Metric::Flicker];
    spec.budget.spp = vec![1, 16];
    spec.reference.spp = 64;
    spec.camera.path = pathlight_render::camera_path::PathKind::Rotation;
    spec.camera.degrees = 4.0;
    spec.camera.step_degrees = 1.0;
    spec.measure = pathlight_eval::spec::Measure::Every;
    spec.validate().unwrap();
    let cache = temp_dir("flicker");
    let out = run(&spec, &cache, None).results;
    assert_eq!(out.views.len(), 5);
    let flicker = |view: usize, spp: u32| {
        out.measurements
            .iter()
            .find(|m| {
                m.configuration == "sobol" && m.view == view && m.budget == BudgetPoint::Spp(spp)
            })
            .unwrap()
            .metrics
            .get(&Metric::Flicker)
            .copied()
    };
    assert_eq!(flicker(0, 1), None, "no view before the first");
    for v in 1..5 {
        let (one, sixteen) = (flicker(v, 1).unwrap(), flicker(v, 16).unwrap());
        assert!(
            one > 1.5 * sixteen && sixteen > 0.0,
            "view {v}: {one} vs {sixteen}"
        );
    }
    std::fs::remove_dir_all(&cache).unwrap();
}

#[test]
fn time_budgets_are_met_and_published_files_exist() {
    let mut spec = Spec::parse(SPEC).unwrap();
    spec.repetitions = 1;
    spec.budget.time_ms = vec![5.0, 20.0];
    let dir = temp_dir("publish");
    let outcome = run(&spec, &dir.join("cache"), None);
    let timed: Vec<_> = outcome
        .results
        .measurements
        .iter()
        .filter(|m| matches!(m.budget, BudgetPoint::TimeMs(_)))
        .collect();
    assert_eq!(timed.len(), 4);
    for m in &timed {
        let BudgetPoint::TimeMs(t) = m.budget else {
            unreachable!()
        };
        assert!(m.ms >= t && m.spp >= 1.0, "{m:?}");
    }
    let out = dir.join("out");
    let report = publish(&outcome, &out).unwrap();
    let html = std::fs::read_to_string(&report).unwrap();
    // results.json holds every measurement, and reads back as Results. (serde_json's default
    // number parser may differ from the written value in the last bit, so the comparison goes
    // through the same text on both sides.)
    let text = std::fs::read(out.join("results.json")).unwrap();
    let json: Results = serde_json::from_slice(&text).unwrap();
    assert_eq!(json.measurements.len(), outcome.results.measurements.len());
    let on_disk: serde_json::Value = serde_json::from_slice(&text).unwrap();
    let written: serde_json::Value =
        serde_json::from_str(&serde_json::to_string(&outcome.results.measurements).unwrap())
            .unwrap();
    assert_eq!(on_disk["measurements"], written);
    for file in [
        "plots/mse-vs-spp.png",
        "plots/relmse-vs-time.png",
        "plots/ssim-equal.png",
        "plots/stages.png",
        "images/reference.png",
        "images/0-independent.png",
        "images/1-sobol-error.png",
        "images/crop0-reference.png",
        "images/crop0-1-sobol-error.png",
    ] {
        assert!(out.join(file).is_file(), "{file} missing");
        assert!(html.contains(file), "the report does not show {file}");
    }
    // Every image the report shows exists.
    for part in html.split("src=\"").skip(1) {
        let src = &part[..part.find('"').unwrap()];
        assert!(out.join(src).is_file(), "{src} is shown but missing");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Every spec the repository ships (`experiments/*.toml`, except the real-time presets,
/// `realtime*.toml`, which are `Config`s) loads, with each of its `[[scenes]]` entries valid.
#[test]
fn the_shipped_experiments_load() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../experiments");
    let mut count = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        if !name.ends_with(".toml") || name.starts_with("realtime") {
            continue;
        }
        let spec = Spec::load(&path).unwrap_or_else(|e| panic!("{e}"));
        let entries = spec.entries().unwrap_or_else(|e| panic!("{name}: {e}"));
        assert!(!entries.is_empty());
        count += 1;
    }
    assert!(count >= 4, "{count} specs");
}

#[test]
fn sample_budgets_count_the_samples_frames_actually_traced() {
    // Adaptive sampling (2/8) traces a fraction of the pixels in most frames: an equal-samples
    // budget is reached when the frames have traced that many samples per pixel on average,
    // not after that many frames.
    let mut spec = Spec::parse(SPEC).unwrap();
    spec.repetitions = 1;
    spec.budget.spp = vec![6];
    spec.configurations.truncate(1);
    let c = &mut spec.configurations[0].config;
    c.frame.adaptive.enabled = true;
    c.frame.adaptive.min_spp = 2;
    c.frame.adaptive.max_spp = 8;
    let outcome = run(&spec, &temp_dir("adaptive-spp").join("cache"), None);
    let m = &outcome.results.measurements[0];
    assert_eq!(m.budget, BudgetPoint::Spp(6));
    // The mean samples per pixel in the history at the measurement: the budget, give or take
    // the last frame's samples (at most one per pixel).
    assert!(m.spp >= 6.0 && m.spp < 7.0, "{m:?}");
}

#[test]
fn an_rpf_configuration_filters_the_reference_tracers_samples_at_each_sample_budget() {
    // RPF is offline: measured at the sample budgets only (time budgets do not apply), with
    // the stages `trace` and `rpf`; at 8 spp and above (its regime: with fewer samples its
    // neighbourhoods are small and its mutual information mostly estimator bias) it lowers
    // relMSE against the unfiltered image of the same budget.
    let mut spec = Spec::parse(SPEC).unwrap();
    spec.repetitions = 1;
    spec.budget.spp = vec![8, 16];
    spec.budget.time_ms = vec![50.0];
    spec.reference.spp = 256;
    spec.metrics = vec![Metric::Relmse];
    spec.configurations.truncate(2);
    spec.configurations[0].name = "unfiltered".into();
    spec.configurations[1].name = "rpf".into();
    let c = &mut spec.configurations[1].config;
    c.frame.filter.method = pathlight_render::denoise::Method::Rpf;
    c.frame.filter.rpf.boxes = vec![15, 7];
    for c in &mut spec.configurations {
        c.config.sampler = Default::default();
    }
    let outcome = run(&spec, &temp_dir("rpf").join("cache"), None);
    let r = &outcome.results;
    let rpf: Vec<&Measurement> = r
        .measurements
        .iter()
        .filter(|m| m.configuration == "rpf")
        .collect();
    assert_eq!(
        rpf.iter().map(|m| m.budget).collect::<Vec<_>>(),
        vec![BudgetPoint::Spp(8), BudgetPoint::Spp(16)]
    );
    for m in &rpf {
        let stages: Vec<&str> = m.stages.keys().map(String::as_str).collect();
        assert_eq!(stages, ["rpf", "trace"]);
        let plain = r
            .measurements
            .iter()
            .find(|p| p.configuration == "unfiltered" && p.budget == m.budget)
            .unwrap();
        let (a, b) = (m.metrics[&Metric::Relmse], plain.metrics[&Metric::Relmse]);
        assert!(a < b, "{:?}: relMSE {a} with RPF, {b} without", m.budget);
    }
}

/// `layer = "indirect"` compares the pipeline's indirect light with the reference's: the
/// cached reference holds the layer (read back equal to what was rendered), its image is the
/// indirect light alone (darker than the whole image), and the error of the pipeline's
/// indirect light falls with samples; with the whole image, the same reference entry serves.
#[test]
fn the_indirect_layer_is_measured_against_the_references() {
    let text = SPEC.replace("name = \"small\"", "name = \"small\"\nlayer = \"indirect\"");
    let spec = Spec::parse(&text).unwrap();
    let cache = temp_dir("layer");
    let first = run(&spec, &cache, None);
    let second = run(&spec, &cache, None);
    assert!(second.results.references[0].info.cached);
    let indirect = &first.snapshots.as_ref().unwrap().reference;
    assert_eq!(indirect, &second.snapshots.as_ref().unwrap().reference);
    let whole = run(&Spec::parse(SPEC).unwrap(), &cache, None);
    assert!(
        whole.results.references[0].info.cached,
        "one reference entry"
    );
    let sum =
        |i: &pathlight_eval::image::Image| i.pixels.iter().map(|p| p.element_sum()).sum::<f32>();
    let whole_ref = &whole.snapshots.as_ref().unwrap().reference;
    assert!(sum(indirect) > 0.0 && sum(indirect) < 0.8 * sum(whole_ref));
    let m = &first.results.measurements;
    assert!(m[2].metrics[&Metric::Mse] < m[0].metrics[&Metric::Mse]);
    // The same configuration measured on the whole image has another error.
    assert_ne!(m[0].metrics, whole.results.measurements[0].metrics);
}
