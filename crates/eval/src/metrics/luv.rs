//! Squared error in CIE 1976 L*u*v* (CIELUV), as seed 001 (RPF) measures MSE.

use super::{channels, Pair};

/// Linear Rec.709 RGB to CIE XYZ, D65: the IEC 61966-2-1 (sRGB) matrix, whose Y row is the
/// Rec.709 luminance weights. colour-science uses the same matrix for its `sRGB` colourspace.
const RGB_TO_XYZ: [[f64; 3]; 3] = [
    [0.4124, 0.3576, 0.1805],
    [0.2126, 0.7152, 0.0722],
    [0.0193, 0.1192, 0.9505],
];

/// CIELUV of a linear Rec.709 colour, relative to the white point XYZ of RGB (1, 1, 1)
/// (Yn = 1). No clamping: values above 1 (HDR) and below 0 go through the CIE formulas
/// (L* = 116 cbrt(Y/Yn) - 16 above (6/29)^3, (29/3)^3 Y/Yn below; u* = 13 L* (u' - u'n),
/// v* = 13 L* (v' - v'n)). Where X + 15Y + 3Z is 0, u' and v' are taken as 0 (as
/// colour-science does).
pub(super) fn rgb_to_luv(rgb: [f64; 3]) -> [f64; 3] {
    let [x, y, z] = xyz(rgb);
    let [xn, yn, zn] = xyz([1.0; 3]);
    let (un, vn) = uv_prime(xn, yn, zn);
    let t = y / yn;
    let l = if t > (6.0f64 / 29.0).powi(3) {
        116.0 * t.cbrt() - 16.0
    } else {
        24389.0 / 27.0 * t
    };
    let (u, v) = uv_prime(x, y, z);
    [l, 13.0 * l * (u - un), 13.0 * l * (v - vn)]
}

fn xyz(rgb: [f64; 3]) -> [f64; 3] {
    RGB_TO_XYZ.map(|row| row[0] * rgb[0] + row[1] * rgb[1] + row[2] * rgb[2])
}

/// CIE 1976 UCS chromaticity (u', v'), (0, 0) where X + 15Y + 3Z is 0.
fn uv_prime(x: f64, y: f64, z: f64) -> (f64, f64) {
    let d = x + 15.0 * y + 3.0 * z;
    if d == 0.0 {
        (0.0, 0.0)
    } else {
        (4.0 * x / d, 9.0 * y / d)
    }
}

/// Per pixel: the mean over L*, u*, v* of the squared differences.
pub(super) fn squared_error_map(pair: &Pair) -> Vec<f64> {
    pair.per_pixel(|i, r| {
        let (i, r) = (rgb_to_luv(channels(i)), rgb_to_luv(channels(r)));
        (0..3).map(|c| (i[c] - r[c]).powi(2)).sum::<f64>() / 3.0
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn white_and_black() {
        let white = rgb_to_luv([1.0; 3]);
        assert!((white[0] - 100.0).abs() < 1e-12);
        assert!(white[1].abs() < 1e-12 && white[2].abs() < 1e-12);
        assert_eq!(rgb_to_luv([0.0; 3]), [0.0; 3]);
        // Grey is achromatic at every level, HDR included.
        for g in [0.001, 0.18, 4.0] {
            let [_, u, v] = rgb_to_luv([g; 3]);
            assert!(u.abs() < 1e-9 && v.abs() < 1e-9);
        }
    }

    #[test]
    fn lightness_is_continuous_at_the_knee() {
        let knee = (6.0f64 / 29.0).powi(3);
        let below = rgb_to_luv([knee * (1.0 - 1e-12); 3])[0];
        let above = rgb_to_luv([knee * (1.0 + 1e-12); 3])[0];
        assert!((below - 8.0).abs() < 1e-9 && (above - 8.0).abs() < 1e-9);
    }
}
