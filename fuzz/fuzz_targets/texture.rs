//! Texture decoding (PNG or JPEG, sniffed from the bytes) with a 1 Mpixel limit.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok((w, h, texels)) =
        pathlight_scene::texture::decode_image(data, Path::new("fuzz.png"), 1 << 20)
    {
        assert!(w as u64 * h as u64 <= 1 << 20);
        assert_eq!(texels.len() as u64, w as u64 * h as u64);
    }
});
