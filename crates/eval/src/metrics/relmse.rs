//! Relative squared error, as seed 002 (texture-space caching) defines relMSE.

use super::{channels, Pair};

/// The ε in the denominator, which keeps dark reference pixels from dominating.
const EPSILON: f64 = 0.001;

/// Per pixel: `sum_c (img_c - ref_c)^2 / (gray(ref)^2 + ε)`, with `gray` the Rec.709
/// luminance of the reference pixel (0.2126 R + 0.7152 G + 0.0722 B) and ε = 0.001.
/// A sum over the channels, not a mean.
pub(super) fn relative_squared_error_map(pair: &Pair) -> Vec<f64> {
    pair.per_pixel(|i, r| {
        let (i, r) = (channels(i), channels(r));
        let gray = 0.2126 * r[0] + 0.7152 * r[1] + 0.0722 * r[2];
        let denominator = gray * gray + EPSILON;
        (0..3).map(|c| (i[c] - r[c]).powi(2)).sum::<f64>() / denominator
    })
}
