//! `pathlight eval` end to end: the convergence experiment shows MSE falling as 1/spp with
//! independent samples, in its JSON and its plot; bad specs are refused naming the file.

mod common;

use std::path::{Path, PathBuf};

use common::{pathlight, s, stderr, stdout, temp_dir};

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The acceptance test of the evaluation harness and of the frame pipeline's accumulation:
/// `pathlight eval experiments/convergence.toml --out DIR` renders the Cornell box through the
/// real-time pipeline, one sample per pixel per frame, with a still camera, so the budgets of
/// 1 to 256 spp are 1 to 256 accumulated frames. With independent random samples the expected
/// MSE against the reference is exactly variance/frames, so the log-log slope is -1; the
/// measured one must be within 10% (the reference's own noise, at most 1/8 of the MSE at 256
/// frames, flattens it by about 0.02). The reference is rendered afresh (empty cache).
#[test]
fn convergence_experiment_shows_mse_falling_as_one_over_spp() {
    let dir = temp_dir("convergence");
    let out_dir = dir.join("out");
    let spec = repo().join("experiments/convergence.toml");
    let out = pathlight(&[
        "eval",
        s(&spec),
        "--out",
        s(&out_dir),
        "--cache",
        s(&dir.join("cache")),
        "--json",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let last = stdout(&out).lines().last().unwrap().to_owned();
    let summary: serde_json::Value = serde_json::from_str(&last).unwrap();
    let slope = |config: &str, metric: &str| -> f64 {
        summary["slopes"]
            .as_array()
            .unwrap()
            .iter()
            .find(|s| {
                s["configuration"] == config && s["metric"] == metric && s["against"] == "spp"
            })
            .unwrap_or_else(|| panic!("no {config} {metric} slope in {last}"))["slope"]
            .as_f64()
            .unwrap()
    };
    let independent = slope("independent", "mse");
    assert!(
        (independent + 1.0).abs() <= 0.1,
        "MSE slope {independent}, expected -1 within 10%"
    );
    // Owen-scrambled Sobol points converge faster than plain Monte Carlo.
    let sobol = slope("sobol", "mse");
    assert!(
        sobol < independent - 0.1,
        "sobol {sobol} vs independent {independent}"
    );

    // The JSON on disk says the same, with every measurement.
    let results: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out_dir.join("results.json")).unwrap()).unwrap();
    assert_eq!(results["complete"], true);
    // 2 configurations x 4 repetitions x (5 spp + 2 time budgets).
    assert_eq!(results["measurements"].as_array().unwrap().len(), 2 * 4 * 7);
    assert_eq!(results["slopes"], summary["slopes"]);
    assert_eq!(results["references"][0]["config"]["spp"], 2048);

    // The plot and the report exist.
    for f in ["plots/mse-vs-spp.png", "report.html"] {
        assert!(out_dir.join(f).is_file(), "{f}");
    }
    let png = image::open(out_dir.join("plots/mse-vs-spp.png")).unwrap();
    assert!(png.width() >= 600 && png.height() >= 400);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bad_specs_are_refused_naming_the_file() {
    let dir = temp_dir("bad");
    let missing = dir.join("missing.toml");
    let out = pathlight(&["eval", s(&missing), "--out", s(&dir.join("o"))]);
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr(&out).contains("missing.toml"), "{}", stderr(&out));

    for (name, text, needle) in [
        ("syntax.toml", "name = \"x\"\nwidth = [", "line 2"),
        ("range.toml", "name = \"x\"\nwidth = 0\nheight = 4\n[budget]\nspp = [1]\n[[configuration]]\nname = \"a\"\n", "width 0"),
        ("scene.toml", "name = \"x\"\nscene = \"nowhere.glb\"\nwidth = 4\nheight = 4\n[budget]\nspp = [1]\n[[configuration]]\nname = \"a\"\n", "nowhere.glb"),
    ] {
        let path = dir.join(name);
        std::fs::write(&path, text).unwrap();
        let out = pathlight(&["eval", s(&path), "--out", s(&dir.join("o")), "--cache", s(&dir.join("c"))]);
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(2), "{name}: {err}");
        assert!(err.contains(needle), "{name}: {needle:?} not in {err}");
        if name != "scene.toml" {
            assert!(err.contains(name), "{name} not named in {err}");
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `[[scenes]]`: one spec, two camera setups of the Cornell box; each entry writes its own
/// folder (with the display modes asked for), `--only` runs a subset, and an unknown name is
/// refused naming the spec.
#[test]
fn scenes_run_each_entry_into_its_folder() {
    let dir = temp_dir("scenes");
    let spec = dir.join("two.toml");
    std::fs::write(
        &spec,
        r#"
name = "two"
width = 16
height = 12
display_modes = ["samples", "probability"]
[budget]
spp = [1, 2]
[reference]
spp = 8
[[configuration]]
name = "plain"
[[scenes]]
name = "front"
[[scenes]]
name = "turned"
width = 12
[scenes.camera]
path = "rotation"
degrees = 10.0
step_degrees = 5.0
frames_per_view = 2
"#,
    )
    .unwrap();
    let cache = dir.join("cache");
    let run = |extra: &[&str], out: &Path| {
        let mut a = vec![
            "eval",
            s(&spec),
            "--out",
            s(out),
            "--cache",
            s(&cache),
            "--json",
        ];
        a.extend_from_slice(extra);
        pathlight(&a)
    };
    let all = dir.join("all");
    let out = run(&[], &all);
    assert!(out.status.success(), "{}", stderr(&out));
    let summary: serde_json::Value =
        serde_json::from_str(stdout(&out).lines().last().unwrap()).unwrap();
    assert_eq!(summary["entries"].as_array().unwrap().len(), 2);
    for (name, width) in [("front", 16), ("turned", 12)] {
        let results: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(all.join(name).join("results.json")).unwrap(),
        )
        .unwrap();
        assert_eq!(results["spec"]["name"], format!("two/{name}"));
        assert_eq!(results["spec"]["width"], width);
        let report = std::fs::read_to_string(all.join(name).join("report.html")).unwrap();
        for mode in ["samples", "probability"] {
            let file = format!("images/0-plain-{mode}.png");
            assert!(all.join(name).join(&file).exists(), "{file}");
            assert!(report.contains(&file), "{file} not in the report");
        }
    }

    let some = dir.join("some");
    let out = run(&["--only", "turned"], &some);
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(some.join("turned/results.json").exists());
    assert!(!some.join("front").exists());

    let out = run(&["--only", "sideways"], &dir.join("none"));
    assert!(!out.status.success());
    let e = stderr(&out);
    assert!(e.contains("two.toml") && e.contains("sideways"), "{e}");
}

/// References rendered elsewhere (`--missing-references`, then `render --samples A..B` with
/// the listed arguments and configuration, then `--import-references`, as `pathlight-farm` does
/// on a cluster) are the references `eval` renders itself, to float rounding, and the run then
/// finds them in the cache. Parts of another render are refused, naming the file.
#[test]
fn references_rendered_in_parts_import_into_the_cache() {
    let dir = temp_dir("import");
    let spec = dir.join("spec.toml");
    std::fs::write(
        &spec,
        r#"
name = "import"
width = 20
height = 16
metrics = ["mse"]
point_lights = 3
measure = "every"
[camera]
path = "orbit"
steps = 1
degrees = 15
[budget]
spp = [1]
[reference]
spp = 24
[reference.config]
max_bounces = 3
[[configuration]]
name = "plain"
"#,
    )
    .unwrap();
    let (cache, local) = (dir.join("cache"), dir.join("local"));
    let eval = |extra: &[&str], cache: &Path| {
        let mut args = vec!["eval", s(&spec), "--cache", s(cache)];
        args.extend_from_slice(extra);
        pathlight(&args)
    };
    let listed = eval(&["--missing-references"], &cache);
    assert!(listed.status.success(), "{}", stderr(&listed));
    let listed: serde_json::Value = serde_json::from_str(stdout(&listed).trim()).unwrap();
    let references = listed["references"].as_array().unwrap().clone();
    assert_eq!(references.len(), 2, "{listed}");
    for (i, r) in references.iter().enumerate() {
        let config = dir.join(format!("reference-{i}.toml"));
        std::fs::write(&config, r["config"].as_str().unwrap()).unwrap();
        let mut parts = Vec::new();
        for (a, b) in [(0, 7), (7, 24)] {
            let part = dir.join(format!("{i}-{a}.part"));
            let mut args: Vec<String> = vec!["render".into()];
            args.extend(
                r["render_args"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|a| a.as_str().unwrap().to_owned()),
            );
            args.extend(
                [
                    "--config",
                    s(&config),
                    "--samples",
                    &format!("{a}..{b}"),
                    "--out",
                    s(&part),
                    "--quiet",
                ]
                .map(str::to_owned),
            );
            let args: Vec<&str> = args.iter().map(String::as_str).collect();
            let out = pathlight(&args);
            assert!(out.status.success(), "{}", stderr(&out));
            parts.push(part);
        }
        if i == 1 {
            // Parts of two references are not one reference.
            let mixed = eval(
                &[
                    "--import-references",
                    s(&dir.join("0-0.part")),
                    s(&parts[1]),
                ],
                &cache,
            );
            assert!(!mixed.status.success());
            assert!(
                stderr(&mixed).contains("1-7.part: a part of another render"),
                "{}",
                stderr(&mixed)
            );
        }
        let mut args = vec!["--import-references"];
        args.extend(parts.iter().map(|p| s(p)));
        let imported = eval(&args, &cache);
        assert!(imported.status.success(), "{}", stderr(&imported));
        assert!(stderr(&imported).contains(r["key"].as_str().unwrap()));
    }
    // Nothing is missing any more, and a part of a render of another spec is refused.
    let listed = eval(&["--missing-references"], &cache);
    assert_eq!(stdout(&listed).trim(), r#"{"references":[]}"#);
    let stranger = dir.join("stranger.part");
    let out = pathlight(&[
        "render",
        "--width",
        "20",
        "--height",
        "16",
        "--spp",
        "4",
        "--samples",
        "0..4",
        "--out",
        s(&stranger),
        "--quiet",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let refused = eval(&["--import-references", s(&stranger)], &cache);
    assert!(!refused.status.success());
    assert!(
        stderr(&refused).contains("stranger.part: not a part of any reference"),
        "{}",
        stderr(&refused)
    );

    // The run finds both references in the cache; a run with an empty cache renders them
    // itself, and they agree to float rounding.
    let results = |out: &Path| -> serde_json::Value {
        serde_json::from_slice(&std::fs::read(out.join("results.json")).unwrap()).unwrap()
    };
    for (cache, out) in [(&cache, "out"), (&local, "out-local")] {
        let out_dir = dir.join(out);
        let run = eval(&["--out", s(&out_dir), "--quiet"], cache);
        assert!(run.status.success(), "{}", stderr(&run));
    }
    let (imported, rendered) = (results(&dir.join("out")), results(&dir.join("out-local")));
    for v in 0..2 {
        let info = |r: &serde_json::Value| r["references"][v].clone();
        assert_eq!(info(&imported)["cached"], true);
        assert_eq!(info(&rendered)["cached"], false);
        assert_eq!(info(&imported)["key"], info(&rendered)["key"]);
        let read = |r: &serde_json::Value| {
            pathlight_render::output::read_exr_rgb(Path::new(info(r)["path"].as_str().unwrap()))
                .unwrap()
                .2
        };
        let (a, b) = (read(&imported), read(&rendered));
        assert_eq!(a.len(), 20 * 16);
        for (p, q) in a.iter().zip(&b) {
            let d = (*p - *q).abs().max_element();
            assert!(d <= 1e-5 * q.abs().max_element().max(1e-3), "{p} vs {q}");
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
