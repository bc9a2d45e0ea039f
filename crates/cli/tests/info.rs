//! End-to-end tests of `pathlight info`: they run the built binary.

use std::collections::BTreeMap;
use std::path::Path;
use std::process::Output;

use serde_json::Value;

mod common;

use common::*;

/// Keys `info --json` promises.
const REQUIRED_KEYS: &[&str] = &[
    "file",
    "triangles",
    "unique_triangles",
    "dropped_triangles",
    "vertices",
    "meshes",
    "instances",
    "materials",
    "textures",
    "emissive_triangles",
    "punctual_lights",
    "cameras",
    "environment",
    "bounds",
    "load_ms",
    "peak_rss_bytes",
    "warnings",
];

/// Runs `pathlight info --json <args>`, checks it succeeded and parses its last stdout line.
fn info_json(args: &[&str]) -> Value {
    let mut all = vec!["info", "--json"];
    all.extend_from_slice(args);
    let out = pathlight(&all);
    assert!(
        out.status.success(),
        "pathlight {all:?} failed ({}):\nstdout:\n{}\nstderr:\n{}",
        out.status,
        stdout(&out),
        stderr(&out)
    );
    let text = stdout(&out);
    let last = text.lines().last().expect("some output on stdout");
    let json: Value = serde_json::from_str(last)
        .unwrap_or_else(|e| panic!("last stdout line is not JSON ({e}): {last}"));
    assert!(json.is_object(), "not a JSON object: {last}");
    json
}

fn assert_failed_with_code_2(out: &Output) {
    assert_eq!(
        out.status.code(),
        Some(2),
        "expected exit code 2, got {}; stderr:\n{}",
        out.status,
        stderr(out)
    );
    let err = stderr(out);
    assert!(err.contains("error: "), "no `error: ` on stderr:\n{err}");
    assert!(!err.contains("panicked"), "the binary panicked:\n{err}");
}

#[test]
fn json_of_the_built_in_scene_has_the_required_keys() {
    let json = info_json(&[]);
    for key in REQUIRED_KEYS {
        assert!(json.get(key).is_some(), "missing key `{key}` in {json}");
    }
    assert!(json["triangles"].is_u64());
    assert!(json["environment"].is_boolean());
    assert!(json["warnings"].is_array());
    assert!(json["file"].is_null(), "the built-in scene has no file");
}

#[test]
fn table_of_the_built_in_scene() {
    let out = pathlight(&["info"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let text = stdout(&out);
    for row in [
        "triangles",
        "materials",
        "load time",
        "peak memory",
        "warnings",
    ] {
        assert!(text.contains(row), "no `{row}` row in:\n{text}");
    }
}

#[test]
fn cornell_box_has_36_triangles() {
    let json = info_json(&[]);
    assert_eq!(json["triangles"], 36, "{json}");
    assert!(json["emissive_triangles"].as_u64().unwrap() > 0, "{json}");
    assert!(json["bounds"].is_object(), "{json}");
}

#[test]
fn a_missing_file_fails_with_code_2_and_names_it() {
    let path = Path::new(env!("CARGO_TARGET_TMPDIR")).join("no-such-dir/missing-scene.glb");
    let path = path.to_str().unwrap();
    let out = pathlight(&["info", path]);
    assert_failed_with_code_2(&out);
    assert!(
        stderr(&out).contains(path),
        "the message does not name {path}:\n{}",
        stderr(&out)
    );
    // Same with --json: errors never go to stdout as JSON.
    let out = pathlight(&["info", "--json", path]);
    assert_failed_with_code_2(&out);
}

#[test]
fn an_unknown_extension_fails_with_code_2() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("info-unknown-extension");
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("scene.txt");
    std::fs::write(&path, "not a scene\n").unwrap();
    let out = pathlight(&["info", path.to_str().unwrap()]);
    assert_failed_with_code_2(&out);
    assert!(stderr(&out).contains("scene.txt"), "{}", stderr(&out));
}

#[test]
fn a_missing_environment_map_fails_with_code_2() {
    let path = Path::new(env!("CARGO_TARGET_TMPDIR")).join("no-such-dir/sky.hdr");
    let out = pathlight(&["info", "--env", path.to_str().unwrap()]);
    assert_failed_with_code_2(&out);
}

#[test]
fn a_bad_flag_is_a_usage_error_with_code_2() {
    let out = pathlight(&["info", "--point-lights", "many"]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
}

/// Expected triangle counts per scene file from the scene table of `SOURCES.md`: the table whose
/// header starts with a `file` column and has a `triangles` column; rows whose file cell is a
/// backticked `folder/file.{obj,gltf,glb}` and whose triangle cell is a number.
fn expected_triangles(sources_md: &str) -> BTreeMap<String, u64> {
    fn cells(line: &str) -> Vec<&str> {
        let inner = line.trim().trim_start_matches('|').trim_end_matches('|');
        inner.split('|').map(str::trim).collect()
    }
    let mut map = BTreeMap::new();
    let mut columns: Option<(usize, usize)> = None; // (cell count, triangles column)
    for line in sources_md.lines() {
        let line = line.trim();
        if !line.starts_with('|') {
            columns = None;
            continue;
        }
        let row = cells(line);
        match columns {
            None => {
                if row.first().is_some_and(|c| c.starts_with("file")) {
                    if let Some(t) = row.iter().position(|c| *c == "triangles") {
                        columns = Some((row.len(), t));
                    }
                }
            }
            Some((n, t)) => {
                let Some(file) = row[0].strip_prefix('`').and_then(|f| f.strip_suffix('`')) else {
                    continue; // the |---| separator
                };
                let is_scene = file.contains('/')
                    && [".obj", ".gltf", ".glb"]
                        .iter()
                        .any(|ext| file.to_ascii_lowercase().ends_with(ext));
                if !is_scene {
                    continue;
                }
                assert_eq!(
                    row.len(),
                    n,
                    "SOURCES.md row with {} cells: {line}",
                    row.len()
                );
                let count: u64 = row[t]
                    .replace(',', "")
                    .parse()
                    .unwrap_or_else(|e| panic!("triangles `{}` of {file}: {e}", row[t]));
                map.insert(file.to_string(), count);
            }
        }
    }
    map
}

#[test]
fn parses_the_sources_table() {
    let md = "\
intro | not a table
| need | scene |
|---|---|
| tests | `CornellBox/CornellBox-Original.obj` |

| file (folder/…) | what | bytes | triangles | emissive |
|---|---|---:|---:|---:|
| `CornellBox/CornellBox-Original.obj` | box | 4,079 | 36 | 1 |
| `extras_meshopt/dream-apartment.glb` | flat | 4,710,164 | 177,934 | 0 |
| `hdri/noon_grass_1k.hdr` | sky | 1,545,906 | - | - |
";
    let map = expected_triangles(md);
    assert_eq!(map.len(), 2, "{map:?}");
    assert_eq!(map["CornellBox/CornellBox-Original.obj"], 36);
    assert_eq!(map["extras_meshopt/dream-apartment.glb"], 177_934);
}

#[test]
fn shared_scenes_have_the_triangle_counts_of_sources_md() {
    let scenes = pathlight_core::shared_data::dir(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let sources = scenes.join("SOURCES.md");
    if !pathlight_core::shared_data::present(&sources) {
        return;
    }
    let md = std::fs::read_to_string(&sources).unwrap();
    let expected = expected_triangles(&md);
    println!(
        "expected triangles from {}: {expected:#?}",
        sources.display()
    );
    assert!(
        expected.len() >= 10,
        "only {} scenes parsed from SOURCES.md",
        expected.len()
    );
    let mut failures = Vec::new();
    for (file, &triangles) in &expected {
        let path = scenes.join(file);
        let out = pathlight(&["info", "--json", path.to_str().unwrap()]);
        if !out.status.success() {
            failures.push(format!("{file}: failed: {}", stderr(&out).trim()));
            continue;
        }
        let text = stdout(&out);
        let json: Value = match text.lines().last().map(serde_json::from_str) {
            Some(Ok(json)) => json,
            _ => {
                failures.push(format!("{file}: last stdout line is not JSON: {text}"));
                continue;
            }
        };
        println!(
            "{file}: {} triangles, {} ms",
            json["triangles"], json["load_ms"]
        );
        // SOURCES.md counts the triangles in the file; the loader drops degenerate ones and
        // says how many.
        let kept = json["triangles"].as_u64().unwrap_or(0);
        let dropped = json["dropped_triangles"].as_u64().unwrap_or(0);
        if kept + dropped != triangles || dropped * 1000 > triangles {
            failures.push(format!(
                "{file}: {kept} triangles + {dropped} dropped, SOURCES.md says {triangles}"
            ));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// `info` says whether the environment has a sun (as the sun preset and the texture cache's
/// `terms = "sky"` split it): none without an environment or in a studio's lamps; the suns of
/// the interior's and the garden's skies are small and hold most of their power.
#[test]
fn info_says_whether_the_environment_has_a_sun() {
    assert!(info_json(&[]).get("sun").is_some_and(Value::is_null));
    let hdri = pathlight_core::shared_data::dir(env!("CARGO_MANIFEST_DIR")).join("scenes/hdri");
    for (file, sun) in [
        ("noon_grass_1k.hdr", true),
        ("kloppenheim_05_1k.hdr", true),
        ("brown_photostudio_02_1k.hdr", false),
    ] {
        let path = hdri.join(file);
        if !pathlight_core::shared_data::present(&path) {
            continue;
        }
        let v = info_json(&["--env", path.to_str().unwrap()]);
        match sun {
            true => {
                let texels = v["sun"]["texels"].as_u64().unwrap();
                let share = v["sun"]["share"].as_f64().unwrap();
                assert!(
                    (1..=200).contains(&texels) && share > 0.5,
                    "{file}: {}",
                    v["sun"]
                );
            }
            false => assert!(v["sun"].is_null(), "{file}: {}", v["sun"]),
        }
    }
}
