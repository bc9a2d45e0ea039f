//! Smoke tests of `pathlight bench rays`: they run the built binary on the built-in Cornell box.

use std::collections::BTreeSet;

use serde_json::Value;

mod common;

use common::*;

const KEYS: &[&str] = &[
    "backend",
    "kind",
    "rays",
    "mrays_per_s",
    "threads",
    "build_ms",
    "memory_bytes",
    "mismatches",
];

fn expected_backends() -> BTreeSet<&'static str> {
    let mut b = BTreeSet::from(["native"]);
    if cfg!(feature = "embree") {
        b.insert("embree");
    }
    b
}

#[test]
fn bench_rays_json_on_the_cornell_box() {
    let out = pathlight(&[
        "bench",
        "rays",
        "--width",
        "64",
        "--height",
        "64",
        "--repeat",
        "1",
        "--threads",
        "2",
        "--json",
    ]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{}\n{stdout}\n{stderr}", out.status);
    let lines: Vec<Value> = stdout
        .lines()
        .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("{e}: {l:?}")))
        .collect();
    assert!(lines.len() >= 3, "{stdout}");
    let mut seen = BTreeSet::new();
    for v in &lines {
        let obj = v.as_object().expect("an object");
        let keys: BTreeSet<&str> = obj.keys().map(String::as_str).collect();
        assert_eq!(keys, KEYS.iter().copied().collect(), "{v}");
        assert_eq!(v["mismatches"], 0, "{v}");
        assert_eq!(v["threads"], 2, "{v}");
        assert!(v["mrays_per_s"].as_f64().unwrap() > 0.0, "{v}");
        assert!(v["rays"].as_u64().unwrap() > 0, "{v}");
        let kind = v["kind"].as_str().unwrap();
        assert!(["primary", "bounce", "shadow"].contains(&kind), "{v}");
        if kind == "primary" {
            assert_eq!(v["rays"], 64 * 64);
        }
        seen.insert((v["backend"].as_str().unwrap().to_owned(), kind.to_owned()));
    }
    let backends: BTreeSet<&str> = seen.iter().map(|(b, _)| b.as_str()).collect();
    assert_eq!(backends, expected_backends());
    assert_eq!(seen.len(), 3 * expected_backends().len());
}

#[test]
fn bench_rays_table_and_backend_choice() {
    let out = pathlight(&[
        "bench",
        "rays",
        "--width",
        "16",
        "--height",
        "16",
        "--repeat",
        "1",
        "--backend",
        "native",
    ]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{stdout}");
    assert!(
        stdout.contains("native") && stdout.contains("shadow"),
        "{stdout}"
    );

    let out = pathlight(&[
        "bench",
        "rays",
        "--width",
        "16",
        "--height",
        "16",
        "--backend",
        "embree",
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    if cfg!(feature = "embree") {
        assert!(out.status.success(), "{stderr}");
    } else {
        assert_eq!(out.status.code(), Some(2));
        assert!(
            stderr.contains("built without the embree feature"),
            "{stderr}"
        );
    }
}

/// `bench frame --json`: the last line has the median frame time, Mrays/s and each pass.
#[test]
fn bench_frame_json_on_the_cornell_box() {
    let out = pathlight(&[
        "bench", "frame", "--width", "64", "--height", "36", "--frames", "3", "--json",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let last = stdout(&out).lines().last().unwrap().to_owned();
    let v: Value = serde_json::from_str(&last).unwrap();
    for key in [
        "ms_per_frame",
        "fps",
        "mrays_per_s",
        "rays_per_frame",
        "setup_ms",
    ] {
        assert!(v[key].as_f64().unwrap() > 0.0, "{key} in {last}");
    }
    assert_eq!(v["frames"], 3);
    assert_eq!(
        (v["width"].as_u64(), v["height"].as_u64()),
        (Some(64), Some(36))
    );
    // The default real-time configuration: one sample, two bounces.
    assert_eq!(
        (v["spp"].as_u64(), v["max_bounces"].as_u64()),
        (Some(1), Some(2))
    );
    for pass in ["primary", "lighting", "accumulate", "display"] {
        assert!(
            v["passes"][pass].as_f64().unwrap() >= 0.0,
            "{pass} in {last}"
        );
    }
    // At least a camera ray per pixel.
    assert!(v["rays_per_frame"].as_f64().unwrap() >= 64.0 * 36.0 * 0.5);
}
