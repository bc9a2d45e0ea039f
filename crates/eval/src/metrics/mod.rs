//! Image error metrics: an image under test against a reference, both linear Rec.709 RGB.
//!
//! [`compute`] gives one number per metric, [`error_map`] its per-pixel counterpart. The
//! definitions (each documented on its [`Metric`] variant) follow the papers this project
//! reproduces and the reference implementations the tests check against
//! (`tools/metrics/README.md`): scikit-image for SSIM, NVIDIA's FLIP for FLIP and
//! colour-science for CIELUV.
//!
//! Input rules, the same for every metric:
//! - the two images must have the same, non-zero size ([`MetricError`] otherwise);
//! - every reference pixel must be finite ([`MetricError::NonFiniteReference`]);
//! - a pixel of the image under test with any non-finite channel (NaN or ±inf) is replaced
//!   by black (0, 0, 0) before measuring, so it counts as an error against the reference
//!   instead of turning the whole metric into NaN or infinity.
//!
//! Sums are accumulated in f64, row by row and then in row order, so results do not depend
//! on the thread count.

mod flicker;
mod flip;
mod luv;
mod mse;
mod psnr;
mod relmse;
mod ssim;

use std::borrow::Cow;
use std::fmt;
use std::str::FromStr;

use glam::Vec3;
use rayon::prelude::*;

use crate::image::Image;

/// An image error metric.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "lowercase")]
pub enum Metric {
    /// Mean squared error on linear values: the mean over pixels and the three channels of
    /// `(img - ref)^2`.
    Mse,
    /// Root mean squared error: `sqrt(mse)`.
    Rmse,
    /// Relative MSE as seed 002 (texture-space caching) defines it: the mean over pixels of
    /// `sum_c (img_c - ref_c)^2 / (gray(ref)^2 + 0.001)`, with `gray` the Rec.709 luminance
    /// of the reference pixel. A sum over the channels, not a mean.
    Relmse,
    /// Peak signal-to-noise ratio in dB on sRGB-encoded values clamped to [0, 1] (peak 1):
    /// `10 log10(1 / mse_srgb)`, infinite for identical encodings.
    Psnr,
    /// Structural similarity (Wang et al. 2004) on sRGB-encoded values clamped to [0, 1]:
    /// Gaussian window σ = 1.5 truncated at 3.5σ (11x11), K1 = 0.01, K2 = 0.03, data range
    /// 1, population covariances, per channel, then the mean of the three channels; as
    /// `skimage.metrics.structural_similarity(gaussian_weights=True, sigma=1.5,
    /// use_sample_covariance=False, data_range=1.0, channel_axis=2)`, including its border
    /// handling (filtering with mirrored borders, scipy's `reflect`, and averaging only
    /// pixels at least 5 away from the border).
    Ssim,
    /// NVIDIA FLIP, LDR (Andersson et al. 2020), at 67 pixels per degree, on the images
    /// encoded as 8-bit sRGB (clamped to [0, 1], rounded to nearest): the mean of the FLIP
    /// error map.
    Flip,
    /// Mean squared error in CIE 1976 L*u*v*, as seed 001 (RPF) measures: linear Rec.709 to
    /// XYZ (IEC 61966-2-1 sRGB matrix, D65), then L*u*v* with the white point the XYZ of RGB
    /// (1, 1, 1) (so Yn = 1), without clamping; the mean over pixels and the three
    /// components of the squared differences.
    Luvmse,
    /// Flicker along a camera path (a temporal metric: [`compute_temporal`]): the change from
    /// the previous view's image to this one's that the references do not have, the mean over
    /// pixels and the three channels of `|(s(img) - s(img')) - (s(ref) - s(ref'))|`, `s` the
    /// sRGB encoding clamped to [0, 1], primes the previous view's. At a still view against a
    /// converged reference it is the mean absolute difference of consecutive frames (`pathlight
    /// play`'s flicker, there of their 8-bit encodings).
    Flicker,
}

impl Metric {
    /// Every metric of one image against its reference, in declaration order.
    pub const ALL: [Metric; 7] = [
        Metric::Mse,
        Metric::Rmse,
        Metric::Relmse,
        Metric::Psnr,
        Metric::Ssim,
        Metric::Flip,
        Metric::Luvmse,
    ];

    /// Every metric of two consecutive views' images against their references.
    pub const TEMPORAL: [Metric; 1] = [Metric::Flicker];

    /// Whether it compares consecutive views ([`compute_temporal`]) rather than one image.
    pub fn is_temporal(self) -> bool {
        Metric::TEMPORAL.contains(&self)
    }

    /// The lowercase name, as parsed by [`FromStr`] and written by serde and [`Display`](fmt::Display).
    pub fn name(self) -> &'static str {
        match self {
            Metric::Mse => "mse",
            Metric::Rmse => "rmse",
            Metric::Relmse => "relmse",
            Metric::Psnr => "psnr",
            Metric::Ssim => "ssim",
            Metric::Flip => "flip",
            Metric::Luvmse => "luvmse",
            Metric::Flicker => "flicker",
        }
    }

    /// Whether a smaller value means a better image (false for PSNR and SSIM).
    pub fn lower_is_better(self) -> bool {
        !matches!(self, Metric::Psnr | Metric::Ssim)
    }

    /// One line for plot axes and reports.
    pub fn description(self) -> &'static str {
        match self {
            Metric::Mse => "MSE (linear RGB)",
            Metric::Rmse => "RMSE (linear RGB)",
            Metric::Relmse => "relMSE (ε = 0.001, seed 002)",
            Metric::Psnr => "PSNR in dB (sRGB, clamped)",
            Metric::Ssim => "SSIM (sRGB, Gaussian σ = 1.5)",
            Metric::Flip => "ꟻLIP (LDR, 67 pixels per degree)",
            Metric::Luvmse => "MSE in CIELUV (seed 001)",
            Metric::Flicker => "flicker: |change - the reference's change| between views (sRGB)",
        }
    }
}

impl fmt::Display for Metric {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A metric name that [`Metric::from_str`] does not know.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error(
    "unknown metric `{name}`; valid metrics: mse, rmse, relmse, psnr, ssim, flip, luvmse, flicker"
)]
pub struct ParseMetricError {
    pub name: String,
}

impl FromStr for Metric {
    type Err = ParseMetricError;

    /// Parses a metric name, ignoring ASCII case and surrounding whitespace.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let wanted = s.trim();
        Metric::ALL
            .into_iter()
            .chain(Metric::TEMPORAL)
            .find(|m| m.name().eq_ignore_ascii_case(wanted))
            .ok_or_else(|| ParseMetricError {
                name: s.to_string(),
            })
    }
}

/// Why a metric cannot be computed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MetricError {
    #[error(
        "image size mismatch: the image is {image_width}x{image_height}, \
         the reference {reference_width}x{reference_height}"
    )]
    SizeMismatch {
        image_width: u32,
        image_height: u32,
        reference_width: u32,
        reference_height: u32,
    },
    #[error("empty image ({width}x{height})")]
    Empty { width: u32, height: u32 },
    #[error("the {which} is {width}x{height} but holds {len} pixels")]
    PixelCount {
        which: &'static str,
        width: u32,
        height: u32,
        len: usize,
    },
    #[error("non-finite reference pixel at ({x}, {y}): ({r}, {g}, {b})")]
    NonFiniteReference {
        x: u32,
        y: u32,
        r: f32,
        g: f32,
        b: f32,
    },
    #[error(
        "the two views' images differ in size: {width}x{height}, the previous \
         {previous_width}x{previous_height}"
    )]
    ViewSizeMismatch {
        width: u32,
        height: u32,
        previous_width: u32,
        previous_height: u32,
    },
    #[error("{metric} compares two consecutive views' images, not one image")]
    Temporal { metric: Metric },
}

/// Computes `metric` of `image` against `reference` (see [`Metric`] for each definition and
/// the module documentation for the input rules).
pub fn compute(metric: Metric, image: &Image, reference: &Image) -> Result<f64, MetricError> {
    let pair = Pair::new(image, reference)?;
    Ok(match metric {
        Metric::Mse => pair.mean(&mse::squared_error_map(&pair)),
        Metric::Rmse => pair.mean(&mse::squared_error_map(&pair)).sqrt(),
        Metric::Relmse => pair.mean(&relmse::relative_squared_error_map(&pair)),
        Metric::Psnr => psnr::from_mse(pair.mean(&psnr::srgb_squared_error_map(&pair))),
        Metric::Ssim => ssim::SsimMap::new(&pair).mean_ssim(),
        Metric::Flip => {
            let map: Vec<f64> = flip::error_map(&pair).into_iter().map(f64::from).collect();
            pair.mean(&map)
        }
        Metric::Luvmse => pair.mean(&luv::squared_error_map(&pair)),
        Metric::Flicker => return Err(MetricError::Temporal { metric }),
    })
}

/// Computes temporal `metric` (see [`Metric::TEMPORAL`]) of `image` after `previous`, the
/// images of two consecutive views, against their references; the input rules of
/// [`compute`] hold for both pairs, and the two views' sizes must agree.
pub fn compute_temporal(
    metric: Metric,
    (image, reference): (&Image, &Image),
    (previous, previous_reference): (&Image, &Image),
) -> Result<f64, MetricError> {
    let now = Pair::new(image, reference)?;
    let before = Pair::new(previous, previous_reference)?;
    if (now.width, now.height) != (before.width, before.height) {
        return Err(MetricError::ViewSizeMismatch {
            width: image.width,
            height: image.height,
            previous_width: previous.width,
            previous_height: previous.height,
        });
    }
    match metric {
        Metric::Flicker => Ok(now.mean(&flicker::error_map(&now, &before))),
        _ => compute(metric, image, reference),
    }
}

/// Per-pixel error, `width * height` values, row-major, row 0 at the top: whose mean is the
/// metric (mse, relmse, luvmse, and flip up to f32 rounding of the map) or its natural
/// per-pixel counterpart:
/// - mse, rmse: squared error, mean over the channels (its mean is the MSE);
/// - relmse: relative squared error, summed over the channels;
/// - psnr: squared error of the clamped sRGB values, mean over the channels (its mean is
///   the MSE the PSNR is computed from);
/// - ssim: 1 - SSIM, mean over the channels, over the whole image (the SSIM value itself
///   averages only the pixels at least 5 from the border);
/// - flip: the FLIP error map;
/// - luvmse: squared error in L*u*v*, mean over the components.
pub fn error_map(
    metric: Metric,
    image: &Image,
    reference: &Image,
) -> Result<Vec<f32>, MetricError> {
    let pair = Pair::new(image, reference)?;
    let narrow = |v: Vec<f64>| v.into_iter().map(|e| e as f32).collect();
    Ok(match metric {
        Metric::Mse | Metric::Rmse => narrow(mse::squared_error_map(&pair)),
        Metric::Relmse => narrow(relmse::relative_squared_error_map(&pair)),
        Metric::Psnr => narrow(psnr::srgb_squared_error_map(&pair)),
        Metric::Ssim => narrow(ssim::SsimMap::new(&pair).one_minus_ssim()),
        Metric::Flip => flip::error_map(&pair),
        Metric::Luvmse => narrow(luv::squared_error_map(&pair)),
        Metric::Flicker => return Err(MetricError::Temporal { metric }),
    })
}

/// A validated image pair: same non-zero size, finite reference, and the image under test
/// with its non-finite pixels replaced by black.
struct Pair<'a> {
    width: usize,
    height: usize,
    image: Cow<'a, [Vec3]>,
    reference: &'a [Vec3],
}

impl<'a> Pair<'a> {
    fn new(image: &'a Image, reference: &'a Image) -> Result<Self, MetricError> {
        if (image.width, image.height) != (reference.width, reference.height) {
            return Err(MetricError::SizeMismatch {
                image_width: image.width,
                image_height: image.height,
                reference_width: reference.width,
                reference_height: reference.height,
            });
        }
        if image.width == 0 || image.height == 0 {
            return Err(MetricError::Empty {
                width: image.width,
                height: image.height,
            });
        }
        let (width, height) = (image.width as usize, image.height as usize);
        for (which, img) in [("image", image), ("reference", reference)] {
            if img.pixels.len() != width * height {
                return Err(MetricError::PixelCount {
                    which,
                    width: img.width,
                    height: img.height,
                    len: img.pixels.len(),
                });
            }
        }
        if let Some(i) = reference.pixels.iter().position(|p| !p.is_finite()) {
            let p = reference.pixels[i];
            return Err(MetricError::NonFiniteReference {
                x: (i % width) as u32,
                y: (i / width) as u32,
                r: p.x,
                g: p.y,
                b: p.z,
            });
        }
        let pixels = if image.pixels.iter().all(|p| p.is_finite()) {
            Cow::Borrowed(image.pixels.as_slice())
        } else {
            Cow::Owned(
                image
                    .pixels
                    .iter()
                    .map(|&p| if p.is_finite() { p } else { Vec3::ZERO })
                    .collect(),
            )
        };
        Ok(Self {
            width,
            height,
            image: pixels,
            reference: &reference.pixels,
        })
    }

    /// `f(image pixel, reference pixel)` for every pixel, row-major.
    fn per_pixel(&self, f: impl Fn(Vec3, Vec3) -> f64 + Sync) -> Vec<f64> {
        self.image
            .par_iter()
            .zip(self.reference.par_iter())
            .map(|(&i, &r)| f(i, r))
            .collect()
    }

    /// The mean of a per-pixel map: rows summed in parallel, then the row sums in order.
    fn mean(&self, map: &[f64]) -> f64 {
        mean_by_rows(map, self.width)
    }
}

/// The mean of `values`, summed per chunk of `row` values in parallel and then in order
/// (deterministic whatever the thread count).
fn mean_by_rows(values: &[f64], row: usize) -> f64 {
    let sums: Vec<f64> = values.par_chunks(row).map(|r| r.iter().sum()).collect();
    sums.iter().sum::<f64>() / values.len() as f64
}

/// Linear to sRGB-encoded (IEC 61966-2-1), clamped to [0, 1], per channel: the formula of
/// `pathlight_core::color::linear_to_srgb` evaluated in f64 (in f32 it encodes 1 as
/// 0.99999994, which would make PSNR and SSIM of saturated pixels slightly off).
fn srgb(c: Vec3) -> [f64; 3] {
    channels(c).map(|v| {
        let v = v.clamp(0.0, 1.0);
        if v <= 0.003_130_8 {
            12.92 * v
        } else {
            1.055 * v.powf(1.0 / 2.4) - 0.055
        }
    })
}

fn channels(c: Vec3) -> [f64; 3] {
    [c.x, c.y, c.z].map(f64::from)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(width: u32, height: u32, f: impl Fn(u32, u32) -> Vec3) -> Image {
        let pixels = (0..height)
            .flat_map(|y| (0..width).map(move |x| (x, y)))
            .map(|(x, y)| f(x, y))
            .collect();
        Image::new(width, height, pixels)
    }

    fn pattern(width: u32, height: u32) -> Image {
        image(width, height, |x, y| {
            Vec3::new(
                x as f32 / width as f32,
                0.3 + 0.5 * ((x * 7 + y * 3) % 5) as f32 / 5.0,
                y as f32 / height as f32 * 2.0,
            )
        })
    }

    #[test]
    fn identical_images_are_perfect() {
        let a = pattern(23, 17);
        for metric in Metric::ALL {
            let value = compute(metric, &a, &a).unwrap();
            match metric {
                Metric::Psnr => assert_eq!(value, f64::INFINITY),
                Metric::Ssim => assert!((value - 1.0).abs() < 1e-12, "ssim {value}"),
                _ => assert_eq!(value, 0.0, "{metric}"),
            }
            let map = error_map(metric, &a, &a).unwrap();
            assert_eq!(map.len(), 23 * 17);
            assert!(map.iter().all(|&e| e.abs() < 1e-6), "{metric} map");
        }
    }

    #[test]
    fn size_mismatch_names_both_sizes() {
        let a = pattern(4, 3);
        let b = pattern(3, 4);
        for metric in Metric::ALL {
            let err = compute(metric, &a, &b).unwrap_err();
            assert!(matches!(err, MetricError::SizeMismatch { .. }));
            let msg = err.to_string();
            assert!(msg.contains("4x3") && msg.contains("3x4"), "{msg}");
            assert!(error_map(metric, &a, &b).is_err());
        }
    }

    #[test]
    fn empty_images_are_an_error() {
        let e = Image::new(0, 5, vec![]);
        let err = compute(Metric::Mse, &e, &e).unwrap_err();
        assert_eq!(
            err,
            MetricError::Empty {
                width: 0,
                height: 5
            }
        );
        assert!(err.to_string().contains("empty"));
    }

    #[test]
    fn inconsistent_pixel_count_is_an_error() {
        let a = pattern(4, 3);
        let mut b = a.clone();
        b.pixels.pop();
        let err = compute(Metric::Mse, &a, &b).unwrap_err();
        assert!(matches!(
            err,
            MetricError::PixelCount {
                which: "reference",
                len: 11,
                ..
            }
        ));
    }

    #[test]
    fn non_finite_reference_is_an_error_with_its_position() {
        let a = pattern(5, 4);
        let mut r = a.clone();
        r.pixels[2 * 5 + 3].y = f32::NAN;
        for metric in Metric::ALL {
            match compute(metric, &a, &r).unwrap_err() {
                MetricError::NonFiniteReference { x, y, .. } => assert_eq!((x, y), (3, 2)),
                e => panic!("{e}"),
            }
        }
        let msg = compute(Metric::Mse, &a, &r).unwrap_err().to_string();
        assert!(msg.contains("(3, 2)"), "{msg}");
    }

    #[test]
    fn non_finite_test_pixels_count_as_black() {
        let r = pattern(16, 12);
        let mut a = r.clone();
        a.pixels[7] = Vec3::new(f32::NAN, 0.5, 0.5);
        a.pixels[30] = Vec3::new(0.1, f32::INFINITY, 0.2);
        let mut black = r.clone();
        black.pixels[7] = Vec3::ZERO;
        black.pixels[30] = Vec3::ZERO;
        for metric in Metric::ALL {
            let v = compute(metric, &a, &r).unwrap();
            assert!(v.is_finite(), "{metric}: {v}");
            assert_eq!(v, compute(metric, &black, &r).unwrap(), "{metric}");
            assert!(error_map(metric, &a, &r)
                .unwrap()
                .iter()
                .all(|e| e.is_finite()));
        }
        assert!(compute(Metric::Mse, &a, &r).unwrap() > 0.0);
    }

    #[test]
    fn names_round_trip_and_parse_case_insensitively() {
        for metric in Metric::ALL.into_iter().chain(Metric::TEMPORAL) {
            assert_eq!(metric.name().parse::<Metric>().unwrap(), metric);
            assert_eq!(metric.to_string().parse::<Metric>().unwrap(), metric);
            assert_eq!(
                metric.name().to_uppercase().parse::<Metric>().unwrap(),
                metric
            );
            let json = serde_json::to_string(&metric).unwrap();
            assert_eq!(json, format!("\"{}\"", metric.name()));
            assert_eq!(serde_json::from_str::<Metric>(&json).unwrap(), metric);
            assert!(!metric.description().is_empty());
        }
        assert_eq!("RelMSE".parse::<Metric>().unwrap(), Metric::Relmse);
        let err = "l2".parse::<Metric>().unwrap_err();
        let msg = err.to_string();
        assert!(msg.contains("`l2`"), "{msg}");
        for metric in Metric::ALL.into_iter().chain(Metric::TEMPORAL) {
            assert!(msg.contains(metric.name()), "{msg}");
        }
    }

    #[test]
    fn direction() {
        let higher_is_better: Vec<_> = Metric::ALL
            .into_iter()
            .filter(|m| !m.lower_is_better())
            .collect();
        assert_eq!(higher_is_better, [Metric::Psnr, Metric::Ssim]);
    }

    #[test]
    fn error_maps_average_to_the_metric() {
        let r = pattern(20, 15);
        let a = image(20, 15, |x, y| {
            r.at(x, y) * (1.0 + 0.1 * ((x + 2 * y) % 3) as f32)
        });
        for metric in [Metric::Mse, Metric::Relmse, Metric::Luvmse, Metric::Flip] {
            let map = error_map(metric, &a, &r).unwrap();
            let mean = map.iter().map(|&e| f64::from(e)).sum::<f64>() / map.len() as f64;
            let value = compute(metric, &a, &r).unwrap();
            assert!(
                (mean - value).abs() <= 1e-6 * value.abs(),
                "{metric}: {mean} vs {value}"
            );
        }
        let map = error_map(Metric::Psnr, &a, &r).unwrap();
        let mse = map.iter().map(|&e| f64::from(e)).sum::<f64>() / map.len() as f64;
        let psnr = compute(Metric::Psnr, &a, &r).unwrap();
        assert!((10.0 * (1.0 / mse).log10() - psnr).abs() < 1e-5);
        let rmse = compute(Metric::Rmse, &a, &r).unwrap();
        assert!((rmse * rmse - compute(Metric::Mse, &a, &r).unwrap()).abs() < 1e-15);
    }
}
