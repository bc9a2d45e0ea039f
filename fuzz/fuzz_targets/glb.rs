//! The GLB container alone: header and chunk lengths.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(glb) = pathlight_scene::gltf::glb::parse(data, Path::new("fuzz.glb")) {
        // The chunks must be views into the input.
        let range = data.as_ptr_range();
        for chunk in std::iter::once(glb.json).chain(glb.bin) {
            let r = chunk.as_ptr_range();
            assert!(range.start <= r.start && r.end <= range.end);
        }
    }
});
