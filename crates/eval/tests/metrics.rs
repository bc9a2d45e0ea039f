//! Image metrics against facts that do not come from this crate: values computed by hand,
//! and values from the reference implementations (scikit-image, NVIDIA flip-evaluator,
//! colour-science) stored by `tools/metrics/reference_values.py` under
//! `tests/data/metrics/` (see `tools/metrics/README.md`).

use std::path::{Path, PathBuf};

use glam::Vec3;
use pathlight_eval::image::Image;
use pathlight_eval::metrics::{compute, error_map, Metric};

fn v(x: f32, y: f32, z: f32) -> Vec3 {
    Vec3::new(x, y, z)
}

fn assert_close(what: &str, got: f64, want: f64, abs: f64, rel: f64) {
    let diff = (got - want).abs();
    assert!(
        diff <= abs + rel * want.abs(),
        "{what}: got {got}, want {want} (difference {diff:e}, tolerance {abs:e} + {rel:e} relative)"
    );
}

// ------------------------------------------------------------------ hand-computed values

/// A 2x2 pair whose MSE and relMSE are computed by hand.
///
/// reference           image               squared errors (sum over channels)
/// (0.5, 0.5, 0.5)     (0.6, 0.5, 0.5)     0.01
/// (0, 0, 0)           (0.1, 0.1, 0.1)     0.03
/// (1, 1, 1)           (1, 1, 1)           0
/// (0.25,0.25,0.25)    (0.25, 0.05, 0.25)  0.04
fn hand_pair() -> (Image, Image) {
    let reference = Image::new(
        2,
        2,
        vec![
            v(0.5, 0.5, 0.5),
            v(0.0, 0.0, 0.0),
            v(1.0, 1.0, 1.0),
            v(0.25, 0.25, 0.25),
        ],
    );
    let image = Image::new(
        2,
        2,
        vec![
            v(0.6, 0.5, 0.5),
            v(0.1, 0.1, 0.1),
            v(1.0, 1.0, 1.0),
            v(0.25, 0.05, 0.25),
        ],
    );
    (image, reference)
}

#[test]
fn mse_and_rmse_by_hand() {
    let (image, reference) = hand_pair();
    // (0.01 + 0.03 + 0 + 0.04) / (4 pixels * 3 channels) = 0.08 / 12.
    let mse = 0.08 / 12.0;
    // The inputs are f32 (0.6, 0.1, 0.05 are not exact), hence the 1e-6 relative tolerance.
    assert_close(
        "mse",
        compute(Metric::Mse, &image, &reference).unwrap(),
        mse,
        0.0,
        1e-6,
    );
    assert_close(
        "rmse",
        compute(Metric::Rmse, &image, &reference).unwrap(),
        mse.sqrt(),
        0.0,
        1e-6,
    );
    let map = error_map(Metric::Mse, &image, &reference).unwrap();
    let want = [0.01 / 3.0, 0.03 / 3.0, 0.0, 0.04 / 3.0];
    for (got, want) in map.iter().zip(want) {
        assert_close("mse map", f64::from(*got), want, 1e-9, 1e-5);
    }
}

#[test]
fn relmse_by_hand() {
    let (image, reference) = hand_pair();
    // gray(ref) per pixel: 0.5, 0, 1, 0.25 (Rec.709 weights sum to 1 on grey).
    // Per pixel sum_c (img - ref)^2 / (gray^2 + 0.001):
    //   0.01 / (0.25 + 0.001), 0.03 / (0 + 0.001) = 30, 0 / 1.001 = 0, 0.04 / (0.0625 + 0.001)
    let per_pixel = [0.01 / 0.251, 30.0, 0.0, 0.04 / 0.0635];
    let relmse = per_pixel.iter().sum::<f64>() / 4.0; // = 7.667440...
    assert_close(
        "relmse",
        compute(Metric::Relmse, &image, &reference).unwrap(),
        relmse,
        0.0,
        1e-5,
    );
    let map = error_map(Metric::Relmse, &image, &reference).unwrap();
    for (got, want) in map.iter().zip(per_pixel) {
        assert_close("relmse map", f64::from(*got), want, 1e-9, 1e-5);
    }
}

#[test]
fn psnr_by_hand_clamps_before_encoding() {
    // sRGB encodes 0 -> 0 and 1 -> 1; values outside [0, 1] clamp first.
    let reference = Image::new(
        2,
        2,
        vec![
            v(0.0, 0.0, 0.0),
            v(1.0, 1.0, 1.0),
            v(0.0, 0.0, 0.0),
            v(1.0, 1.0, 1.0),
        ],
    );
    let image = Image::new(
        2,
        2,
        vec![
            v(1.0, 0.0, 0.0),  // sRGB error 1 in one channel
            v(1.0, 1.0, 1.0),  // exact
            v(0.0, 0.0, 0.0),  // exact
            v(1.0, 3.0, -0.5), // clamps to (1, 1, 0): error 1 in one channel
        ],
    );
    // mse_srgb = 2 / 12 = 1/6, PSNR = 10 log10(6) = 7.781512503836436 dB.
    assert_close(
        "psnr",
        compute(Metric::Psnr, &image, &reference).unwrap(),
        10.0 * 6f64.log10(),
        1e-12,
        0.0,
    );
    // The linear MSE does not clamp: (1 + (3-1)^2 + (-0.5-1)^2) / 12 = 7.25 / 12.
    assert_close(
        "mse",
        compute(Metric::Mse, &image, &reference).unwrap(),
        7.25 / 12.0,
        1e-12,
        0.0,
    );
    let map = error_map(Metric::Psnr, &image, &reference).unwrap();
    assert_eq!(map, [1.0 / 3.0, 0.0, 0.0, 1.0 / 3.0]);
}

#[test]
fn ssim_of_constant_images_by_hand() {
    // Constant images: every local variance and covariance is 0, so
    // S = (2 x y + C1) / (x^2 + y^2 + C1) with C1 = 0.01^2, everywhere.
    let white = Image::new(12, 12, vec![Vec3::ONE; 144]);
    let black = Image::new(12, 12, vec![Vec3::ZERO; 144]);
    let want = 1e-4 / (1.0 + 1e-4);
    assert_close(
        "ssim",
        compute(Metric::Ssim, &black, &white).unwrap(),
        want,
        1e-15,
        0.0,
    );
    // Linear 0.2158605 is sRGB 128/255 (IEC 61966-2-1).
    let grey = Image::new(12, 12, vec![Vec3::splat(0.215_860_5); 144]);
    let g = 128.0 / 255.0;
    let want = (2.0 * g + 1e-4) / (g * g + 1.0 + 1e-4);
    assert_close(
        "ssim",
        compute(Metric::Ssim, &grey, &white).unwrap(),
        want,
        1e-6,
        0.0,
    );
}

#[test]
fn luvmse_of_greys_by_hand() {
    // Greys are achromatic (u* = v* = 0); L* of white is 100, of Y = 0.125 it is
    // 116 * 0.5 - 16 = 42, and below (6/29)^3 it is (29/3)^3 Y: Y = 0.001 gives 0.903296...
    let white = Image::new(1, 3, vec![Vec3::ONE; 3]);
    let image = Image::new(
        1,
        3,
        vec![Vec3::ZERO, Vec3::splat(0.125), Vec3::splat(0.001)],
    );
    let l_dark = 24389.0 / 27.0 * 0.001f32 as f64;
    let want = (100f64.powi(2) + 58f64.powi(2) + (100.0 - l_dark).powi(2)) / 9.0;
    assert_close(
        "luvmse",
        compute(Metric::Luvmse, &image, &white).unwrap(),
        want,
        0.0,
        1e-9,
    );
}

// ------------------------------------------------------------------ reference implementations

fn data_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/metrics")
}

fn read_f32(name: &str) -> Vec<f32> {
    let path = data_dir().join(name);
    let bytes = std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    assert_eq!(bytes.len() % 4, 0, "{}", path.display());
    bytes
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect()
}

fn read_image(name: &str, width: u32, height: u32) -> Image {
    let values = read_f32(name);
    assert_eq!(values.len(), (width * height * 3) as usize, "{name}");
    let pixels = values
        .chunks_exact(3)
        .map(|c| v(c[0], c[1], c[2]))
        .collect();
    Image::new(width, height, pixels)
}

struct Case {
    name: String,
    image: Image,
    reference: Image,
    expected: serde_json::Value,
}

impl Case {
    fn want(&self, key: &str) -> f64 {
        self.expected[key]
            .as_f64()
            .unwrap_or_else(|| panic!("{}: no {key}", self.name))
    }
}

fn cases() -> Vec<Case> {
    let text = std::fs::read_to_string(data_dir().join("expected.json")).unwrap();
    let json: serde_json::Value = serde_json::from_str(&text).unwrap();
    let pairs = json["pairs"].as_object().unwrap();
    assert_eq!(pairs.len(), 4);
    pairs
        .iter()
        .map(|(name, pair)| {
            let w = pair["width"].as_u64().unwrap() as u32;
            let h = pair["height"].as_u64().unwrap() as u32;
            Case {
                name: name.clone(),
                image: read_image(&format!("{name}_image.f32"), w, h),
                reference: read_image(&format!("{name}_reference.f32"), w, h),
                expected: pair["values"].clone(),
            }
        })
        .collect()
}

/// Checks one metric on every stored pair; returns the largest absolute and relative
/// differences seen (printed with `--nocapture`).
fn check(metric: Metric, abs: f64, rel: f64) {
    let (mut max_abs, mut max_rel) = (0f64, 0f64);
    for case in cases() {
        let got = compute(metric, &case.image, &case.reference).unwrap();
        let want = case.want(metric.name());
        assert_close(&format!("{} {metric}", case.name), got, want, abs, rel);
        max_abs = max_abs.max((got - want).abs());
        max_rel = max_rel.max((got - want).abs() / want.abs());
    }
    println!("{metric}: max abs difference {max_abs:e}, max relative {max_rel:e}");
}

/// Compares an error map with a stored one; returns the largest absolute difference.
fn check_map(metric: Metric, file_suffix: &str, abs: f32) {
    let mut max_abs = 0f32;
    for case in cases() {
        let got = error_map(metric, &case.image, &case.reference).unwrap();
        let want = read_f32(&format!("{}_{file_suffix}", case.name));
        assert_eq!(got.len(), want.len(), "{}", case.name);
        for (i, (g, w)) in got.iter().zip(&want).enumerate() {
            let d = (g - w).abs();
            let (x, y) = (i as u32 % case.image.width, i as u32 / case.image.width);
            assert!(
                d <= abs,
                "{} {metric} map at ({x}, {y}): got {g}, want {w}",
                case.name
            );
            max_abs = max_abs.max(d);
        }
    }
    println!("{metric} map: max abs difference {max_abs:e}");
}

#[test]
fn mse_family_matches_numpy_and_scikit_image() {
    // Same f32 inputs, f64 arithmetic on both sides: only the summation order differs
    // (measured: 7e-16 relative at most).
    check(Metric::Mse, 0.0, 1e-12);
    check(Metric::Rmse, 0.0, 1e-12);
    check(Metric::Relmse, 0.0, 1e-12);
    // Measured: 4e-15 dB.
    check(Metric::Psnr, 1e-9, 0.0);
}

#[test]
fn ssim_matches_scikit_image() {
    // Both in f64 with the same window and borders: measured 3e-15, and the maps (stored
    // as f32) agree exactly. Checked by mutation: σ = 1.4, radius 4, no border crop, or
    // scipy's `nearest` borders instead of `reflect` each fail this test (the border mode
    // only through the map: the cropped mean never reaches past the border).
    check(Metric::Ssim, 1e-10, 0.0);
    check_map(Metric::Ssim, "ssim_map.f32", 1e-6);
}

#[test]
fn flip_matches_flip_evaluator() {
    // The same FLIP C++ code on the same 8-bit images: the maps agree exactly here and the
    // means to 2e-7 (flip-evaluator averages in f32). The tolerances leave room for
    // another compiler's floating-point contraction, not for a different algorithm.
    check(Metric::Flip, 1e-5, 0.0);
    check_map(Metric::Flip, "flip_map.f32", 1e-4);
}

#[test]
fn luvmse_matches_colour_science() {
    // Same matrix, white point and formulas in f64: measured 2e-15 relative.
    check(Metric::Luvmse, 0.0, 1e-9);
}

#[test]
fn stored_pairs_are_what_the_generator_describes() {
    // Guards against a stale or truncated data directory: the HDR pair really is HDR and
    // the checkerboard really differs.
    let cases = cases();
    let hdr = cases.iter().find(|c| c.name == "hdr").unwrap();
    assert_eq!((hdr.image.width, hdr.image.height), (64, 48));
    assert!(hdr.reference.pixels.iter().any(|p| p.max_element() > 10.0));
    assert!(hdr.image.pixels.iter().any(|p| p.min_element() < 0.0));
    for case in &cases {
        assert!(case.want("mse") > 0.0, "{}", case.name);
        assert!(case.want("ssim") < 1.0, "{}", case.name);
    }
}
