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
