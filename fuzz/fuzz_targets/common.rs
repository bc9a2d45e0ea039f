// Shared by the fuzz targets (included with `#[path]`, so each target can use a subset).
#![allow(dead_code)]

use std::collections::HashMap;

use pathlight_scene::source::SceneSource;
use pathlight_scene::Limits;

/// Small limits: legitimately big counts are refused early instead of making the fuzzer run
/// out of memory (the loaders must still check them before allocating).
pub fn limits() -> Limits {
    Limits {
        max_triangles: 100_000,
        max_vertices: 100_000,
        max_texture_pixels: 1 << 20,
        max_total_texture_pixels: 1 << 22,
        max_file_bytes: 1 << 24,
        max_instances: 10_000,
    }
}

/// A valid buffer (the Cornell box glTF's .bin, 2808 bytes).
pub const A_BIN: &[u8] = include_bytes!("../side/a.bin");
/// A valid 8x8 RGBA PNG.
pub const T_PNG: &[u8] = include_bytes!("../side/t.png");
/// The Cornell box material library.
pub const A_MTL: &[u8] = include_bytes!("../side/a.mtl");

pub fn memory(files: &[(&str, &[u8])]) -> SceneSource {
    let map: HashMap<String, Vec<u8>> = files
        .iter()
        .map(|(name, bytes)| (name.to_string(), bytes.to_vec()))
        .collect();
    SceneSource::Memory(map)
}
