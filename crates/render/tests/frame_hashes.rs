//! Frames that cannot change while the frame pipeline is restructured: a matrix of
//! configurations (each technique alone, the real-time preset as it stood, reprojection with
//! adaptive sampling, ReSTIR with SVGF, the texture-space cache alone and with ReSTIR, ...),
//! on the built-in Cornell box and a textured glTF scene, with a still camera and a moving
//! one, rendered on 1 and 2 threads. Every frame's image, history and report, and at the end
//! every display mode, are hashed, and the hashes must equal those recorded in
//! `tests/data/frame-hashes.txt`.
//!
//! The recorded hashes are bit-exact results of floating-point code whose instruction set is
//! chosen at run time (AVX-512, AVX2 and FMA paths in the filters and in ReSTIR), so they are
//! kept per instruction-set fingerprint. On a processor whose fingerprint has no record the
//! test still checks that 1 and 2 threads agree, and says that it could not compare (under
//! CI, with `CI` set, it fails instead). On a processor with AVX-512 it also checks the AVX2
//! record, with the filters' lanes capped.
//! `PATHLIGHT_BLESS=1 cargo test -p pathlight-render --test frame_hashes` (1, no other value)
//! records the hashes of this processor's fingerprint (only for a change meant to alter
//! frames: say so in its commit).
//!
//! The configurations are spelled out here rather than read from `experiments/` or the
//! defaults, so that a later change of a preset or of a default does not move these hashes.

mod common;

use std::collections::BTreeMap;
use std::path::PathBuf;

use common::{cornell, in_pool, textured, textured_view};
use glam::Vec3;
use pathlight_render::camera_path::{CameraPath, PathKind};
use pathlight_render::config::CameraConfig;
use pathlight_render::frame::{FrameReport, Pipeline};
use pathlight_render::{Config, World};

/// The display modes hashed at the end of each sequence, by name.
const MODES: [&str; 27] = [
    "final",
    "accumulated",
    "noisy",
    "direct",
    "indirect",
    "variance",
    "samples",
    "albedo",
    "normal",
    "depth",
    "motion",
    "roughness",
    "metallic",
    "bounce-albedo",
    "bounce-direction",
    "probability",
    "reprojected",
    "rejection",
    "frame-direct",
    "reservoir-m",
    "reservoir-weight",
    "variance-depth",
    "variance-normal",
    "variance-texture",
    "variance-direction",
    "variance-texture2",
    "sure-share",
];

/// The texture cache's display modes hashed at the end of its cases' sequences too: not
/// `cache-hits` and `cache-shaded`, which show which pixel's thread shaded a block first (the
/// light does not depend on it, the order does).
const CACHE_MODES: [&str; 3] = ["cache-light", "cache-texels", "cache-level"];

/// Every setting of the texture cache as its defaults were when its cases were added.
const CACHE: &str = "[frame.texture_cache]\nenabled = true\nbudget_mb = 64.0\nlod_bias = 1.0\n\
     filter = \"gaussian\"\nkernel = 9\ntemporal_alpha = 0.7\nterms = \"sky\"\n\
     temporal = \"mean\"\nmax_count = 256\nreshade = 2.0\nshrink = 0.5\nlod = \"area\"\n\
     interpolate = true\nmin_roughness = 0.3\nedge_spp = 1\nfresh_spp = 16\n\
     fresh_budget = 0.5\ncold_budget = 1.0\nclamp = 1.0\nsun_ratio = true\n";

/// The configurations, as TOML over [`Config::realtime`] at the test's size (the cache's
/// cases start with [`CACHE`]).
const CASES: [(&str, &str); 14] = [
    ("plain", ""),
    ("plain-no-accumulate", "[frame]\naccumulate = false\n"),
    ("two-spp", "spp = 2\n"),
    (
        "adaptive",
        "[frame.adaptive]\nenabled = true\nmin_spp = 2\nmax_spp = 8\nmeasure = \"luminance\"\n\
         budget = false\nskip_empty = true\ncap = false\n",
    ),
    (
        "adaptive-error-budget",
        "[frame.adaptive]\nenabled = true\nmin_spp = 2\nmax_spp = 8\nmeasure = \"error\"\n\
         budget = true\ncap = false\n",
    ),
    ("reprojection", "[frame.reprojection]\nenabled = true\n"),
    (
        "reprojection-4-fresh",
        "[frame.reprojection]\nenabled = true\nsamples = 4\nfresh_spp = 4\n",
    ),
    (
        "reprojection-adaptive",
        "[frame.reprojection]\nenabled = true\n[frame.adaptive]\nenabled = true\nmin_spp = 2\n\
         max_spp = 8\nmeasure = \"error\"\nbudget = true\ncap = true\n",
    ),
    ("restir", "[frame.restir]\nenabled = true\n"),
    (
        "data-driven",
        "[frame.filter]\nmethod = \"data-driven\"\n[frame.filter.data_driven]\nkernel = 7\nholes = true\nsure = true\n",
    ),
    (
        "restir-svgf",
        "[frame.restir]\nenabled = true\n[frame.filter]\nmethod = \"svgf\"\n[frame.filter.svgf]\natrous_kernel = 5\n\
         taa = false\nconverge = false\n",
    ),
    // `experiments/realtime.toml`'s settings when this test was written.
    (
        "preset",
        "[frame]\naccumulate = true\n[frame.filter]\nmethod = \"svgf\"\n[frame.filter.svgf]\natrous_kernel = 3\n\
         taa = true\nconverge = true\nstill_handover = 4\n[frame.filter.data_driven]\nholes = true\n\
         sure = true\nrefresh_growth = 1.25\n",
    ),
    ("texture-cache", ""),
    (
        "texture-cache-indirect-restir",
        "[frame.texture_cache]\nterms = \"indirect\"\nfilter = \"linear\"\nedge_spp = 2\n\
         fresh_budget = 2.0\n[frame.restir]\nenabled = true\n",
    ),
];

const WIDTH: u32 = 40;
const HEIGHT: u32 = 24;
/// Frames of the still camera (past the preset's handover and a refresh).
const STILL_FRAMES: u32 = 9;
/// Views of the moving camera (one frame each).
const MOVING_VIEWS: u32 = 5;

/// The case's configuration.
fn config(case: &str, toml: &str) -> Config {
    let base = Config {
        width: WIDTH,
        height: HEIGHT,
        seed: 11,
        ..Config::realtime()
    };
    let base = match case.starts_with("texture-cache") {
        true => base.with_toml(CACHE).unwrap(),
        false => base,
    };
    let c = base.with_toml(toml).unwrap();
    c.validate().unwrap();
    c
}

/// 64-bit FNV-1a, written out so that the hashes do not depend on a library's choice.
#[derive(Clone, Copy)]
struct Fnv(u64);

impl Fnv {
    fn new() -> Self {
        Self(0xcbf2_9ce4_8422_2325)
    }

    fn bytes(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0 ^ b as u64).wrapping_mul(0x0000_0100_0000_01b3);
        }
    }

    fn f32(&mut self, v: f32) {
        self.bytes(&v.to_bits().to_le_bytes());
    }

    fn vec3(&mut self, v: Vec3) {
        v.to_array().into_iter().for_each(|c| self.f32(c));
    }

    fn u64(&mut self, v: u64) {
        self.bytes(&v.to_le_bytes());
    }
}

/// A frame's hash: its final image (linear), the history's statistics, the displayed bytes
/// and the deterministic parts of its report.
fn frame_hash(pipeline: &Pipeline, report: &FrameReport) -> u64 {
    let mut h = Fnv::new();
    for v in pipeline.image() {
        h.vec3(v);
    }
    for s in &pipeline.frame.history {
        h.u64(s.n as u64);
        h.vec3(s.direct.mean);
        h.vec3(s.indirect.mean);
        h.vec3(s.direct.m2);
        h.vec3(s.indirect.m2);
    }
    h.bytes(&pipeline.rgba);
    for v in [
        report.frame,
        report.epoch,
        report.accumulated as u64,
        report.spp as u64,
        report.samples,
        report.traced as u64,
        report.rays,
        report.tau.map_or(u64::MAX, |t| t.to_bits() as u64),
        report.probability_above_one.unwrap_or(u64::MAX),
    ] {
        h.u64(v);
    }
    h.0
}

/// The hashes of one case on one scene and camera: one per frame, then one per display mode
/// at the last frame.
fn sequence(
    world: &World,
    base: &Config,
    views: &[CameraConfig],
    frames: u32,
    lanes: Option<&str>,
) -> Vec<u64> {
    let at = |view: &CameraConfig| Config {
        camera: view.clone(),
        ..base.clone()
    };
    let mut pipeline = Pipeline::new(at(&views[0]));
    if let Some(lanes) = lanes {
        pipeline.stages.filter.set_lanes(lanes);
    }
    let mut hashes = Vec::new();
    let mut report = None;
    for f in 0..frames {
        let view = &views[(f as usize).min(views.len() - 1)];
        pipeline.set_config(&at(view));
        let mut r = pipeline.render_frame(world);
        pipeline.display(&mut r);
        hashes.push(frame_hash(&pipeline, &r));
        report = Some(r);
    }
    // The display settings change no frame: each mode of the last one.
    let (last, mut report) = (at(&views[views.len() - 1]), report.unwrap());
    let cache_modes = match base.frame.texture_cache.enabled {
        true => &CACHE_MODES[..],
        false => &[],
    };
    for &name in MODES.iter().chain(cache_modes) {
        let mut c = last.clone();
        c.display.mode = name.parse().unwrap();
        pipeline.set_config(&c);
        pipeline.display(&mut report);
        let mut h = Fnv::new();
        h.bytes(&pipeline.rgba);
        for v in pipeline.linear(&c.display.mode) {
            h.vec3(v);
        }
        hashes.push(h.0);
    }
    hashes
}

/// Every (case, scene, camera) with its hashes, rendered on `threads` threads.
/// (`lanes`: the filters' lanes capped, as `Filter::set_lanes` says.)
fn matrix(threads: usize, lanes: Option<&str>) -> BTreeMap<String, Vec<u64>> {
    let scenes: [(&str, World, CameraConfig); 2] = [
        ("cornell", cornell(), CameraConfig::default()),
        ("textured", textured(), textured_view()),
    ];
    let mut out = BTreeMap::new();
    in_pool(threads, || {
        for (scene, world, first) in &scenes {
            let orbit = world.path_views(&CameraPath {
                path: PathKind::Orbit,
                degrees: 12.0,
                steps: MOVING_VIEWS - 1,
                look_from: first.look_from,
                look_at: first.look_at,
                fov_y: first.fov_y,
                ..CameraPath::default()
            });
            let still = vec![orbit[0].clone()];
            for (case, toml) in CASES {
                let base = config(case, toml);
                for (camera, views, frames) in [
                    ("still", &still, STILL_FRAMES),
                    ("moving", &orbit, MOVING_VIEWS),
                ] {
                    let key = format!("{case} {scene} {camera}");
                    out.insert(key, sequence(world, &base, views, frames, lanes));
                }
            }
        }
    });
    out
}

/// The instruction sets the frames' floating-point code may choose at run time.
fn fingerprint() -> String {
    #[cfg(target_arch = "x86_64")]
    {
        let mut parts = vec!["x86_64"];
        if std::arch::is_x86_feature_detected!("avx2") {
            parts.push("avx2");
        }
        if std::arch::is_x86_feature_detected!("fma") {
            parts.push("fma");
        }
        if std::arch::is_x86_feature_detected!("avx512f") {
            parts.push("avx512f");
        }
        parts.join("+")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        std::env::consts::ARCH.to_owned()
    }
}

fn record_path() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/frame-hashes.txt")
}

/// The recorded hashes: `fingerprint`, then `case scene camera: hash hash ...` lines per key.
fn read_records() -> BTreeMap<String, BTreeMap<String, Vec<u64>>> {
    let mut records: BTreeMap<String, BTreeMap<String, Vec<u64>>> = BTreeMap::new();
    let Ok(text) = std::fs::read_to_string(record_path()) else {
        return records;
    };
    let mut current = None;
    for line in text
        .lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
    {
        if let Some(fp) = line.strip_prefix("[").and_then(|l| l.strip_suffix("]")) {
            current = Some(fp.to_owned());
            continue;
        }
        let (key, hashes) = line.split_once(':').expect("a `key: hashes` line");
        let hashes = hashes
            .split_whitespace()
            .map(|h| u64::from_str_radix(h, 16).expect("a hex hash"))
            .collect();
        let fp = current.clone().expect("a [fingerprint] line first");
        records
            .entry(fp)
            .or_default()
            .insert(key.to_owned(), hashes);
    }
    records
}

fn write_records(records: &BTreeMap<String, BTreeMap<String, Vec<u64>>>) {
    let mut text = String::from(
        "# Frame hashes of tests/frame_hashes.rs, per instruction-set fingerprint.\n\
         # Written by `PATHLIGHT_BLESS=1 cargo test -p pathlight-render --test frame_hashes`.\n",
    );
    for (fp, keys) in records {
        text.push_str(&format!("[{fp}]\n"));
        for (key, hashes) in keys {
            let hex: Vec<String> = hashes.iter().map(|h| format!("{h:016x}")).collect();
            text.push_str(&format!("{key}: {}\n", hex.join(" ")));
        }
    }
    let path = record_path();
    let tmp = path.with_extension("txt.tmp");
    std::fs::write(&tmp, text).unwrap();
    std::fs::rename(tmp, path).unwrap();
}

#[test]
fn frames_keep_their_recorded_hashes_on_one_and_two_threads() {
    let one = matrix(1, None);
    let two = matrix(2, None);
    for (key, hashes) in &one {
        let first = (hashes.iter().zip(&two[key])).position(|(a, b)| a != b);
        assert!(
            first.is_none(),
            "{key}: 1 and 2 threads differ (first at entry {first:?})"
        );
    }
    // A case whose switches changed nothing would repeat the plain pipeline's frames. Some
    // do by design: without accumulation a moving camera's frames (a new epoch at every
    // move either way), reprojection with a still camera (nothing to carry).
    let same_as_plain: Vec<String> = one
        .iter()
        .filter(|(k, v)| {
            let (case, rest) = k.split_once(' ').unwrap();
            case != "plain" && one[&format!("plain {rest}")] == **v
        })
        .map(|(k, _)| k.clone())
        .collect();
    assert_eq!(
        same_as_plain,
        [
            "plain-no-accumulate cornell moving",
            "plain-no-accumulate textured moving",
            "reprojection cornell still",
            "reprojection textured still",
        ]
    );
    // On a processor with AVX-512, the filters' lanes capped at AVX2 give the frames of one
    // without it (ReSTIR's AVX-512 and AVX2 lanes agree bit for bit: the two records differ
    // only where a filter runs), so both records are checked here.
    let fp = fingerprint();
    let mut runs = vec![(fp.clone(), one)];
    if let Some(avx2) = fp.strip_suffix("+avx512f") {
        runs.push((avx2.to_owned(), matrix(2, Some("avx2"))));
    }
    let mut records = read_records();
    if std::env::var("PATHLIGHT_BLESS").as_deref() == Ok("1") {
        records.extend(runs);
        write_records(&records);
        return;
    }
    let mut differ = Vec::new();
    let mut compared = 0;
    for (fp, run) in &runs {
        let Some(recorded) = records.get(fp) else {
            // Under CI a processor without a record is a failure, not a note: the matrix
            // would compare nothing.
            assert!(
                std::env::var_os("CI").is_none(),
                "no frame hashes recorded for {fp} (CI is set): record them with \
                 PATHLIGHT_BLESS=1 on such a processor"
            );
            eprintln!(
                "note: no frame hashes recorded for {fp}; 1 and 2 threads agree, the recorded \
                 frames were not compared"
            );
            continue;
        };
        for (key, hashes) in run {
            compared += 1;
            match recorded.get(key) {
                Some(r) if r == hashes => {}
                Some(r) => {
                    let frames = r.len().min(hashes.len());
                    let first = (0..frames).find(|&i| r[i] != hashes[i]);
                    differ.push(format!("{fp}: {key} (first at entry {first:?})"));
                }
                None => differ.push(format!("{fp}: {key} (not recorded)")),
            }
        }
    }
    assert!(
        differ.is_empty(),
        "frames changed ({} of {compared}):\n{}",
        differ.len(),
        differ.join("\n")
    );
}
