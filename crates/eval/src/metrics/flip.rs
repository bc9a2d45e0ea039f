//! NVIDIA ꟻLIP (LDR) through the `nv-flip` bindings of the reference C++ implementation.

use pathlight_core::color::linear_to_srgb8;

use super::Pair;

/// Pixels per degree of visual angle: FLIP's default (0.7 m from a 0.7 m wide 4K screen).
const PIXELS_PER_DEGREE: f32 = nv_flip::DEFAULT_PIXELS_PER_DEGREE;

/// The FLIP error map (values in [0, 1], row-major) of the image under test against the
/// reference, both encoded as 8-bit sRGB (clamped, rounded to nearest) as an LDR viewer
/// would show them.
pub(super) fn error_map(pair: &Pair) -> Vec<f32> {
    let (w, h) = (pair.width as u32, pair.height as u32);
    let reference = nv_flip::FlipImageRgb8::with_data(w, h, &srgb8(pair.reference));
    let test = nv_flip::FlipImageRgb8::with_data(w, h, &srgb8(&pair.image));
    nv_flip::flip(reference, test, PIXELS_PER_DEGREE).to_vec()
}

fn srgb8(pixels: &[glam::Vec3]) -> Vec<u8> {
    pixels
        .iter()
        .flat_map(|p| [p.x, p.y, p.z].map(linear_to_srgb8))
        .collect()
}
