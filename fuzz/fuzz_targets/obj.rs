//! OBJ text plus a material library: the input is split at its first NUL byte into the OBJ
//! (before) and "a.mtl" (after; without a NUL, "a.mtl" is the Cornell box's library).
//! "t.png" (a valid PNG) is there too for map_Kd and friends.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;

#[path = "common.rs"]
mod common;

fuzz_target!(|data: &[u8]| {
    let (obj, mtl) = match data.iter().position(|&b| b == 0) {
        Some(i) => (&data[..i], &data[i + 1..]),
        None => (data, common::A_MTL),
    };
    let source = common::memory(&[("a.mtl", mtl), ("t.png", common::T_PNG)]);
    let limits = common::limits();
    if let Ok(mut scene) = pathlight_scene::obj::parse(obj, Path::new("fuzz.obj"), &source, &limits) {
        scene.collect_emissive_triangles();
        let _ = scene.stats();
        let _ = scene.bounds();
    }
});
