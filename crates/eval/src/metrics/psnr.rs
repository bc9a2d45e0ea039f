//! Peak signal-to-noise ratio on clamped sRGB-encoded values.

use super::{srgb, Pair};

/// Per pixel: the mean over the three channels of the squared difference of the sRGB
/// encodings (each clamped to [0, 1] first).
pub(super) fn srgb_squared_error_map(pair: &Pair) -> Vec<f64> {
    pair.per_pixel(|i, r| {
        let (i, r) = (srgb(i), srgb(r));
        (0..3).map(|c| (i[c] - r[c]).powi(2)).sum::<f64>() / 3.0
    })
}

/// PSNR in dB for a peak value of 1: `10 log10(1 / mse)`, infinite when `mse` is 0.
pub(super) fn from_mse(mse: f64) -> f64 {
    if mse == 0.0 {
        f64::INFINITY
    } else {
        -10.0 * mse.log10()
    }
}
