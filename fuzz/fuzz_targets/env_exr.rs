//! Environment map decoding, .exr format (by the path's extension).
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;

#[path = "common.rs"]
mod common;

fuzz_target!(|data: &[u8]| {
    let limits = common::limits();
    if let Ok(env) = pathlight_scene::Environment::decode(data, Path::new("fuzz.exr"), 30.0, 1.0, &limits) {
        assert_eq!(env.texels.len() as u64, env.width as u64 * env.height as u64);
        assert!(env.texels.iter().all(|t| t.is_finite() && t.min_element() >= 0.0));
    }
});
