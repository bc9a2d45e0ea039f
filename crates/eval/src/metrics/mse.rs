//! Squared error on linear values (MSE, RMSE).

use super::{channels, Pair};

/// Per pixel: the mean over the three channels of `(img - ref)^2`, linear values.
pub(super) fn squared_error_map(pair: &Pair) -> Vec<f64> {
    pair.per_pixel(|i, r| {
        let (i, r) = (channels(i), channels(r));
        (0..3).map(|c| (i[c] - r[c]).powi(2)).sum::<f64>() / 3.0
    })
}
