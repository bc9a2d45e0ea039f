//! glTF 2.0 JSON or GLB (the loader picks by the GLB magic) with side files in memory:
//! "a.bin" (a valid buffer) and "t.png" (a valid PNG), so mutations reach buffer, accessor,
//! material and texture code.
#![no_main]

use std::path::Path;
use std::sync::OnceLock;

use libfuzzer_sys::fuzz_target;
use pathlight_scene::source::SceneSource;

#[path = "common.rs"]
mod common;

static SOURCE: OnceLock<SceneSource> = OnceLock::new();

fuzz_target!(|data: &[u8]| {
    let source = SOURCE.get_or_init(|| {
        common::memory(&[("a.bin", common::A_BIN), ("t.png", common::T_PNG)])
    });
    let limits = common::limits();
    if let Ok(mut scene) = pathlight_scene::gltf::parse(data, Path::new("fuzz.gltf"), source, &limits)
    {
        // What `load_file` does after parsing, and what the CLI prints.
        scene.collect_emissive_triangles();
        let _ = scene.stats();
        let _ = scene.bounds();
    }
});
