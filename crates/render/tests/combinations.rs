//! Every combination of the frame's switches runs: seed 000's adaptive sampling and forward
//! reprojection, seed 004's ReSTIR, seed 001's filters (none, the data-driven filter, SVGF
//! with its handover to the data-driven filter, temporal antialiasing alone), seed 002's
//! texture-space cache, with and without accumulation, on a small textured scene with a dozen lights and a sky, with a still camera
//! and a moving one. Every
//! configuration is valid but seed 000's without accumulation, which is refused with its
//! reason; every frame's image and history are finite, the frames are the same on 1 and 2
//! threads, and every switch changes the frames of each combination it is part of.

mod common;

use common::{in_pool, textured, textured_view};
use pathlight_render::camera_path::{CameraPath, PathKind};
use pathlight_render::config::CameraConfig;
use pathlight_render::frame::Pipeline;
use pathlight_render::{Config, World};

/// The switches' settings, as TOML over [`Config::realtime`].
const ADAPTIVE: [&str; 2] = [
    "",
    "[frame.adaptive]\nenabled = true\nmin_spp = 2\nmax_spp = 16\n",
];
const REPROJECTION: [&str; 2] = [
    "",
    "[frame.reprojection]\nenabled = true\nsamples = 4\nfresh_spp = 3\n",
];
const RESTIR: [&str; 2] = ["", "[frame.restir]\nenabled = true\ncandidates = 8\n"];
const FILTER: [&str; 4] = [
    "",
    "[frame.filter]\nmethod = \"data-driven\"\n[frame.filter.data_driven]\nkernel = 5\nholes = true\n",
    "[frame.filter]\nmethod = \"svgf\"\n[frame.filter.svgf]\natrous_kernel = 3\ntaa = true\n\
     still_handover = 2\n",
    "[frame.filter]\nmethod = \"taa\"\n",
];
const CACHE: [&str; 2] = [
    "",
    "[frame.texture_cache]\nenabled = true\nkernel = 5\nedge_spp = 2\nfresh_spp = 4\n",
];
const ACCUMULATE: [&str; 2] = ["", "[frame]\naccumulate = false\n"];

/// Every combination's name and configuration.
fn combinations() -> Vec<(String, Config)> {
    let mut out = Vec::new();
    for (a, adaptive) in ADAPTIVE.iter().enumerate() {
        for (r, reprojection) in REPROJECTION.iter().enumerate() {
            for (s, restir) in RESTIR.iter().enumerate() {
                for (f, filter) in FILTER.iter().enumerate() {
                    for ((t, cache), (n, accumulate)) in CACHE
                        .iter()
                        .enumerate()
                        .flat_map(|t| ACCUMULATE.iter().enumerate().map(move |n| (t, n)))
                    {
                        let toml =
                            [*adaptive, reprojection, restir, filter, cache, accumulate].concat();
                        let base = Config {
                            width: 24,
                            height: 16,
                            seed: 5,
                            ..Config::realtime()
                        };
                        let c = base.with_toml(&toml).unwrap();
                        let name = format!(
                            "adaptive {a} reprojection {r} restir {s} filter {f} cache {t} \
                             no-accumulate {n}"
                        );
                        match c.validate() {
                            Ok(()) => out.push((name, c)),
                            // Seed 000 works on the accumulated history: refused without it.
                            Err(e) if n == 1 && (a == 1 || r == 1) => {
                                assert!(e.to_string().contains("accumulate"), "{name}: {e}")
                            }
                            Err(e) => panic!("{name}: refused: {e}"),
                        }
                    }
                }
            }
        }
    }
    out
}

/// Every frame's image (bits), with the check that it and the history are finite.
fn frames(world: &World, name: &str, base: &Config, views: &[CameraConfig], n: usize) -> Vec<u32> {
    let at = |v: &CameraConfig| Config {
        camera: v.clone(),
        ..base.clone()
    };
    let mut pipeline = Pipeline::new(at(&views[0]));
    let mut bits = Vec::new();
    for f in 0..n {
        pipeline.set_config(&at(&views[f.min(views.len() - 1)]));
        let mut report = pipeline.render_frame(world);
        pipeline.display(&mut report);
        let image = pipeline.image();
        assert!(
            image.iter().all(|v| v.is_finite()),
            "{name}, frame {f}: the image is not finite"
        );
        assert!(
            pipeline.frame.history.iter().all(|h| h.mean().is_finite()),
            "{name}, frame {f}: the history is not finite"
        );
        assert!(report.samples > 0 || !report.traced, "{name}, frame {f}");
        bits.extend(image.iter().flat_map(|v| v.to_array().map(f32::to_bits)));
    }
    bits
}

#[test]
fn every_combination_runs_finite_whatever_the_thread_count() {
    let world = textured();
    let first = textured_view();
    let orbit = world.path_views(&CameraPath {
        path: PathKind::Orbit,
        degrees: 9.0,
        steps: 3,
        look_from: first.look_from,
        look_at: first.look_at,
        fov_y: first.fov_y,
        ..CameraPath::default()
    });
    let still = vec![orbit[0].clone()];
    let run = || {
        let mut out = Vec::new();
        for (name, c) in combinations() {
            out.push(frames(&world, &format!("{name}, still"), &c, &still, 8));
            out.push(frames(&world, &format!("{name}, moving"), &c, &orbit, 4));
        }
        out
    };
    let one = in_pool(1, run);
    let two = in_pool(2, run);
    let names: Vec<String> = combinations()
        .into_iter()
        .flat_map(|(n, _)| [format!("{n}, still"), format!("{n}, moving")])
        .collect();
    for ((a, b), name) in one.iter().zip(&two).zip(&names) {
        assert!(a == b, "{name}: 1 and 2 threads differ");
    }
    // 128 combinations, 48 of them seed 000's without accumulation; two cameras each.
    assert_eq!(one.len(), (128 - 48) * 2);
    // Every switch changes the frames of every combination it is part of (still or moving): a
    // technique its combination ignored would leave them as they were.
    let frames: std::collections::HashMap<&str, &Vec<u32>> =
        names.iter().map(String::as_str).zip(&one).collect();
    for name in names.iter().filter(|n| n.ends_with(", still")) {
        let combination = name.trim_end_matches(", still");
        for switch in [
            "adaptive",
            "reprojection",
            "restir",
            "filter",
            "cache",
            "no-accumulate",
        ] {
            let off = combination
                .split(' ')
                .collect::<Vec<_>>()
                .chunks(2)
                .map(|kv| {
                    if kv[0] == switch {
                        format!("{} 0", kv[0])
                    } else {
                        kv.join(" ")
                    }
                })
                .collect::<Vec<_>>()
                .join(" ");
            if off == combination || !frames.contains_key(format!("{off}, still").as_str()) {
                continue;
            }
            let same = |camera: &str| {
                frames[format!("{combination}, {camera}").as_str()]
                    == frames[format!("{off}, {camera}").as_str()]
            };
            assert!(
                !(same("still") && same("moving")),
                "{combination}: {switch} changed nothing"
            );
        }
    }
}
