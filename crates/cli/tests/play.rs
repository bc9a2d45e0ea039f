//! `pathlight play` end to end: the frames of a camera path are deterministic for a fixed seed
//! (whatever the thread count), a different seed changes them, timings are written per frame
//! and per pass, built-in protocols and keyframe files work, and bad paths are refused naming
//! the file.

mod common;

use std::path::Path;

use common::{pathlight, s, stderr, stdout, temp_dir};

fn play(out: &Path, extra: &[&str]) {
    let mut args = vec![
        "play", "--path", "orbit", "--frames", "5", "--width", "48", "--height", "32", "--quiet",
        "--out",
    ];
    args.push(s(out));
    args.extend_from_slice(extra);
    let o = pathlight(&args);
    assert!(o.status.success(), "{}", stderr(&o));
}

fn frames(dir: &Path) -> Vec<Vec<u8>> {
    (0..5)
        .map(|i| std::fs::read(dir.join(format!("frame-{i:05}.png"))).unwrap())
        .collect()
}

#[test]
fn play_is_deterministic_for_a_fixed_seed() {
    let dir = temp_dir("determinism");
    let (a, b, c) = (dir.join("a"), dir.join("b"), dir.join("c"));
    // Without a configuration the frame-time target adapts the render scale to the machine's
    // speed; off, the frames are the settings' alone.
    let off = ["--target-ms", "0"];
    play(&a, &[&["--seed", "3", "--threads", "2"][..], &off].concat());
    play(&b, &[&["--seed", "3", "--threads", "1"][..], &off].concat());
    play(&c, &[&["--seed", "4"][..], &off].concat());
    assert_eq!(frames(&a), frames(&b), "same seed, different thread counts");
    assert_ne!(frames(&a), frames(&c), "the seed changes nothing");
    // Consecutive frames of the orbit differ (the camera moves).
    let fa = frames(&a);
    assert_ne!(fa[0], fa[1]);
    // --plain: the plain pipeline, its frames other than the preset's.
    let p = dir.join("p");
    play(&p, &["--seed", "3", "--plain"]);
    assert_ne!(frames(&p), fa, "--plain changes nothing");
    // ... and the plain pipeline's frames, bit for bit those of a configuration file that
    // sets nothing (the frame commands' configuration before the rule chose presets).
    let (empty, q) = (dir.join("empty.toml"), dir.join("q"));
    std::fs::write(&empty, "").unwrap();
    play(&q, &["--seed", "3", "--config", s(&empty)]);
    assert_eq!(frames(&p), frames(&q), "--plain is not the plain pipeline");
    // The defaults' frame-time target off: the chosen preset's frames, bit for bit those of a
    // configuration file that names it (which holds no target).
    let (named, r) = (dir.join("named.toml"), dir.join("r"));
    std::fs::write(&named, "preset = \"realtime-sun\"\n").unwrap();
    play(
        &r,
        &["--seed", "3", "--threads", "2", "--config", s(&named)],
    );
    assert_eq!(frames(&r), fa, "--target-ms 0 is not the preset's frames");

    // Timings per frame and per pass.
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(a.join("frames.json")).unwrap()).unwrap();
    let list = json.as_array().unwrap();
    assert_eq!(list.len(), 5);
    for (i, f) in list.iter().enumerate() {
        assert_eq!(f["index"], i);
        assert_eq!(f["file"], format!("frame-{i:05}.png"));
        let passes: Vec<&str> = f["passes"]
            .as_array()
            .unwrap()
            .iter()
            .map(|p| p["pass"].as_str().unwrap())
            .collect();
        // The preset the Cornell box's lamp calls for: the texture cache under TAA.
        let cache = [
            "primary",
            "lighting",
            "texture-cache",
            "accumulate",
            "filter",
            "display",
        ];
        assert_eq!(passes, cache);
        assert!(f["ms"].as_f64().unwrap() > 0.0);
        // Every frame is a new view of the orbit: one frame accumulated.
        assert_eq!(f["accumulated"], 1);
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn keyframes_still_views_accumulate_and_exr_frames() {
    let dir = temp_dir("keyframes");
    let path = dir.join("path.toml");
    std::fs::write(
        &path,
        "path = \"keyframes\"\nfps = 2\nframes_per_view = 2\n\
         [[keyframes]]\ntime = 0\nlook_from = [0, 1, 3.5]\nlook_at = [0, 1, 0]\n\
         [[keyframes]]\ntime = 1\nlook_from = [0.5, 1, 3.5]\nlook_at = [0, 1, 0]\n",
    )
    .unwrap();
    let out = dir.join("out");
    let o = pathlight(&[
        "play",
        "--path",
        s(&path),
        "--width",
        "32",
        "--height",
        "24",
        "--out",
        s(&out),
        "--format",
        "exr",
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    // What it loads, said before the wait and after it.
    let err = stderr(&o);
    assert!(err.contains("loading the built-in Cornell box..."), "{err}");
    assert!(err.contains("loaded the built-in Cornell box: "), "{err}");
    let last = stdout(&o).lines().last().unwrap().to_owned();
    let v: serde_json::Value = serde_json::from_str(&last).unwrap();
    // 3 views (t = 0, 0.5, 1) of 2 frames each.
    assert_eq!(v["frames"], 6);
    assert_eq!(v["views"], 3);
    assert!(v["ms_per_frame"].as_f64().unwrap() > 0.0);
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("frames.json")).unwrap()).unwrap();
    // The stalls: the first frame's time and the slowest later one's, against the median.
    let times: Vec<f64> = (json.as_array().unwrap().iter())
        .map(|f| f["ms"].as_f64().unwrap())
        .collect();
    assert_eq!(v["first_frame_ms"].as_f64().unwrap(), times[0]);
    // The stages' per-world set-up, made before the first frame (none here: no cache).
    assert!(v["prepare_ms"].as_f64().unwrap() >= 0.0);
    let median = v["ms_per_frame"].as_f64().unwrap();
    let worst = times[1..].iter().copied().fold(0.0, f64::max);
    assert!((v["worst_later_over_median"].as_f64().unwrap() - worst / median).abs() < 1e-9);
    assert!((v["first_over_median"].as_f64().unwrap() - times[0] / median).abs() < 1e-9);
    let accumulated: Vec<u64> = json
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f["accumulated"].as_u64().unwrap())
        .collect();
    assert_eq!(accumulated, [1, 2, 1, 2, 1, 2]);
    let (w, h, rgb) = pathlight_render::output::read_exr_rgb(&out.join("frame-00005.exr")).unwrap();
    assert_eq!((w, h), (32, 24));
    assert!(rgb.iter().all(|p| p.is_finite()) && rgb.iter().any(|p| p.x > 0.1));

    // A built-in protocol with fewer frames than it has.
    let o = pathlight(&[
        "play", "--path", "rotation", "--frames", "3", "--width", "16", "--height", "16", "--quiet",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("3 frames"), "{}", stderr(&o));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bad_paths_are_refused_naming_the_file() {
    let dir = temp_dir("bad");
    for (name, text, needle) in [
        ("missing.toml", None, "missing.toml"),
        ("syntax.toml", Some("path = "), "syntax.toml"),
        ("kind.toml", Some("path = \"spiral\""), "spiral"),
        ("empty.toml", Some("path = \"keyframes\""), "keyframes"),
        (
            "nan.toml",
            Some("path = \"rotation\"\nstep_degrees = -1"),
            "step",
        ),
    ] {
        let p = dir.join(name);
        if let Some(t) = text {
            std::fs::write(&p, t).unwrap();
        }
        let o = pathlight(&["play", "--path", s(&p), "--width", "8", "--height", "8"]);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{name}: {err}");
        assert!(err.contains(needle) && err.contains(name), "{name}: {err}");
    }
    let o = pathlight(&["play", "--path", "still", "--frames", "0"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("--frames 0"), "{}", stderr(&o));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn camera_flags_set_a_path_files_first_view_or_are_refused() {
    let dir = temp_dir("flags");
    let file = dir.join("still.toml");
    std::fs::write(&file, "path = \"still\"\nframes_per_view = 1\n").unwrap();
    let view = [
        "--look-from",
        "0.6,1.2,3.0",
        "--look-at",
        "0,0.8,0",
        "--fov-y",
        "55",
    ];
    let run = |out: &str, path: &str, extra: &[&str]| {
        let out = dir.join(out);
        let mut args = vec![
            "play", "--path", path, "--frames", "1", "--width", "48", "--height", "32", "--quiet",
            "--out",
        ];
        args.push(s(&out));
        args.extend_from_slice(extra);
        let o = pathlight(&args);
        assert!(o.status.success(), "{}", stderr(&o));
        std::fs::read(out.join("frame-00000.png")).unwrap()
    };
    let builtin = run("builtin", "still", &view);
    let from_file = run("file", s(&file), &view);
    let scene_camera = run("scene", s(&file), &[]);
    assert_eq!(builtin, from_file, "the flags set the file's first view");
    assert_ne!(from_file, scene_camera, "without flags, the scene's camera");

    // A flag that contradicts the file, and flags with keyframes, are refused.
    let conflict = dir.join("conflict.toml");
    std::fs::write(&conflict, "path = \"still\"\nlook_from = [0, 1, 3.5]\n").unwrap();
    let keyframes = dir.join("keys.toml");
    std::fs::write(
        &keyframes,
        "path = \"keyframes\"\n[[keyframes]]\ntime = 0\nlook_from = [0, 1, 3.5]\nlook_at = [0, 1, 0]\n",
    )
    .unwrap();
    for (p, flags, needles) in [
        (
            &conflict,
            &["--look-from", "1,1,3.5"][..],
            ["conflict.toml", "look_from", "--look-from"],
        ),
        (
            &keyframes,
            &["--fov-y", "30"][..],
            ["keys.toml", "keyframe", "--fov-y"],
        ),
    ] {
        let mut args = vec!["play", "--path", s(p), "--width", "8", "--height", "8"];
        args.extend_from_slice(flags);
        let o = pathlight(&args);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{err}");
        for n in needles {
            assert!(err.contains(n), "{n}: {err}");
        }
    }
    // The same value in both places is fine.
    run("same", s(&conflict), &["--look-from", "0,1,3.5"]);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The flicker measure: the mean absolute difference of consecutive shown frames at one view.
/// Frames that stop accumulating after the first are identical (flicker 0); single-sample
/// frames flicker; the data-driven filter on them flickers less; an orbit (no two frames at
/// one view) has none to measure.
#[test]
fn play_measures_flicker_at_a_still_view() {
    let flicker = |extra: &[&str]| -> serde_json::Value {
        let mut args = vec![
            "play", "--path", "still", "--frames", "6", "--width", "64", "--height", "48",
            "--quiet", "--json", "--plain",
        ];
        args.extend_from_slice(extra);
        let o = pathlight(&args);
        assert!(o.status.success(), "{}", stderr(&o));
        let last = stdout(&o).lines().last().unwrap().to_owned();
        serde_json::from_str::<serde_json::Value>(&last).unwrap()["flicker"].clone()
    };
    assert_eq!(flicker(&["--max-frames", "1"]).as_f64(), Some(0.0));
    let noisy = flicker(&["--no-accumulate"]).as_f64().unwrap();
    assert!(noisy > 0.01, "{noisy}");
    let filtered = flicker(&[
        "--no-accumulate",
        "--filter",
        "data-driven",
        "--kernel",
        "9",
    ])
    .as_f64()
    .unwrap();
    assert!(filtered < noisy, "{filtered} vs {noisy}");
    let o = pathlight(&[
        "play", "--path", "orbit", "--frames", "3", "--width", "16", "--height", "12", "--quiet",
        "--json",
    ]);
    let last = stdout(&o).lines().last().unwrap().to_owned();
    let v: serde_json::Value = serde_json::from_str(&last).unwrap();
    assert!(v["flicker"].is_null(), "{v}");
}

/// `--eye-separation`: each frame for a left and a right eye, written apart; with the texture
/// cache the right eye finds most of what the left one shaded at the same instant.
#[test]
fn a_stereo_pair_shares_the_texture_cache() {
    let dir = temp_dir("play-stereo");
    let o = pathlight(&[
        "play",
        "--path",
        "still",
        "--frames",
        "2",
        "--width",
        "64",
        "--height",
        "48",
        "--quiet",
        "--json",
        "--texture-cache",
        "--eye-separation",
        "0.05",
        "--out",
        s(&dir),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    for name in [
        "frame-00000-left.png",
        "frame-00000-right.png",
        "frame-00001-right.png",
    ] {
        assert!(dir.join(name).exists(), "{name}");
    }
    let last = stdout(&o).lines().last().unwrap().to_owned();
    let v: serde_json::Value = serde_json::from_str(&last).unwrap();
    // Seed 002's goal: the second eye filters at most 15% of the first's texels, and shades
    // at most 15% of its cells' samples (the pair's young cells topped up within one frame's
    // budget).
    let texels = v["second_eye_texel_blocks"].as_f64().unwrap();
    assert!(texels > 0.0 && texels <= 0.15, "{texels}");
    let share = v["second_eye_shading"].as_f64().unwrap();
    assert!(share > 0.0 && share <= 0.15, "{share}");
    let left = std::fs::read(dir.join("frame-00000-left.png")).unwrap();
    let right = std::fs::read(dir.join("frame-00000-right.png")).unwrap();
    assert_ne!(left, right, "the eyes see different views");
    let o = pathlight(&["play", "--path", "still", "--eye-separation", "-1"]);
    assert!(!o.status.success());
}

/// Without a configuration `play` runs the preset the scene's lights call for and reports it
/// (the Cornell box's one lamp: the texture cache's); `--plain`, a technique's flag and a
/// `--config` file run the plain pipeline, unless the file's `preset` key names a preset or
/// `"auto"`; a name that is none is refused, listing the names.
#[test]
fn play_chooses_a_preset_unless_told_otherwise() {
    let dir = temp_dir("preset");
    let run = |extra: &[&str]| {
        let mut args = vec![
            "play", "--path", "still", "--frames", "2", "--width", "32", "--height", "24",
            "--quiet", "--json",
        ];
        args.extend_from_slice(extra);
        pathlight(&args)
    };
    let report = |extra: &[&str]| -> serde_json::Value {
        let o = run(extra);
        assert!(o.status.success(), "{extra:?}: {}", stderr(&o));
        serde_json::from_str(stdout(&o).lines().last().unwrap()).unwrap()
    };
    let cache = |v: &serde_json::Value| v["passes"].get("texture-cache").is_some();
    let auto = report(&[]);
    assert_eq!(auto["preset"]["name"], "realtime-sun");
    let reason = auto["preset"]["reason"].as_str().unwrap();
    assert!(reason.contains("1 light source"), "{reason}");
    assert!(cache(&auto));
    // The defaults hold 33 ms a frame; a flag can turn that off.
    assert_eq!(auto["target"]["target_ms"], 33.0, "{auto}");
    assert!(report(&["--target-ms", "0"])["target"].is_null());
    for extra in [&["--plain"][..], &["--reprojection"]] {
        let v = report(extra);
        assert!(v["preset"].is_null() && !cache(&v), "{extra:?}: {v}");
        assert!(v["target"].is_null(), "{extra:?}: {v}");
    }
    let file = |name: &str, text: &str| {
        let f = dir.join(name);
        std::fs::write(&f, text).unwrap();
        f.to_str().unwrap().to_owned()
    };
    let own = file("own.toml", "spp = 1\n");
    let v = report(&["--config", &own]);
    assert!(v["preset"].is_null() && !cache(&v), "{v}");
    let svgf = file("svgf.toml", "preset = \"realtime\"\nspp = 1\n");
    let v = report(&["--config", &svgf]);
    assert!(v["passes"].get("filter").is_some() && !cache(&v), "{v}");
    let auto_file = file("auto.toml", "preset = \"auto\"\n");
    assert_eq!(
        report(&["--config", &auto_file])["preset"]["name"],
        "realtime-sun"
    );
    let bad = file("bad.toml", "preset = \"sunny\"\n");
    let o = run(&["--config", &bad]);
    assert!(!o.status.success());
    let e = stderr(&o);
    assert!(
        e.contains("sunny") && e.contains("realtime-sun") && e.contains("auto"),
        "{e}"
    );
}
