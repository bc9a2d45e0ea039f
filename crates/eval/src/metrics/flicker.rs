//! Flicker along a camera path: the change between consecutive views' images that their
//! references do not have.

use super::{srgb, Pair};

/// Per pixel: the mean over the three channels of `|(s(img) - s(img')) - (s(ref) -
/// s(ref'))|`, `s` the clamped sRGB encoding, `now` this view's pair, `before` the previous
/// view's (the same size).
pub(super) fn error_map(now: &Pair, before: &Pair) -> Vec<f64> {
    now.image
        .iter()
        .zip(now.reference)
        .zip(before.image.iter().zip(before.reference))
        .map(|((&i, &r), (&i0, &r0))| {
            let (i, r, i0, r0) = (srgb(i), srgb(r), srgb(i0), srgb(r0));
            (0..3)
                .map(|c| ((i[c] - i0[c]) - (r[c] - r0[c])).abs())
                .sum::<f64>()
                / 3.0
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use crate::image::Image;
    use crate::metrics::{compute, compute_temporal, Metric, MetricError};

    fn flat(w: u32, h: u32, v: f32) -> Image {
        Image::new(w, h, vec![Vec3::splat(v); (w * h) as usize])
    }

    /// sRGB of a linear value, by the standard's formula (independent of the module's).
    fn encode(v: f32) -> f64 {
        let v = f64::from(v);
        if v <= 0.0031308 {
            12.92 * v
        } else {
            1.055 * v.powf(1.0 / 2.4) - 0.055
        }
    }

    #[test]
    fn a_still_view_against_a_converged_reference_is_the_frames_difference() {
        let r = flat(4, 3, 0.2);
        let (a, b) = (flat(4, 3, 0.25), flat(4, 3, 0.18));
        let f = compute_temporal(Metric::Flicker, (&b, &r), (&a, &r)).unwrap();
        assert!((f - (encode(0.25) - encode(0.18))).abs() < 1e-12, "{f}");
    }

    #[test]
    fn following_the_references_change_is_no_flicker() {
        // The scene brightens from one view to the next, and the images follow it.
        let (r0, r1) = (flat(5, 2, 0.1), flat(5, 2, 0.4));
        let (i0, i1) = (r0.clone(), r1.clone());
        assert_eq!(
            compute_temporal(Metric::Flicker, (&i1, &r1), (&i0, &r0)).unwrap(),
            0.0
        );
        // A frame that lags: the image stays as it was while the reference changes.
        let f = compute_temporal(Metric::Flicker, (&i0, &r1), (&i0, &r0)).unwrap();
        assert!((f - (encode(0.4) - encode(0.1))).abs() < 1e-12, "{f}");
        // Noise that differs per pixel: the mean of the pixels' absolute changes.
        let mut n = i0.clone();
        n.pixels[3] = Vec3::new(0.1, 0.1, 0.5);
        let f = compute_temporal(Metric::Flicker, (&n, &r0), (&i0, &r0)).unwrap();
        let want = (encode(0.5) - encode(0.1)) / 3.0 / 10.0;
        assert!((f - want).abs() < 1e-12, "{f} vs {want}");
    }

    #[test]
    fn temporal_metrics_need_two_views_of_one_size() {
        let a = flat(4, 3, 0.2);
        assert_eq!(
            compute(Metric::Flicker, &a, &a).unwrap_err(),
            MetricError::Temporal {
                metric: Metric::Flicker
            }
        );
        let b = flat(3, 4, 0.2);
        let err = compute_temporal(Metric::Flicker, (&a, &a), (&b, &b)).unwrap_err();
        assert!(err.to_string().contains("4x3") && err.to_string().contains("3x4"));
        assert!(Metric::Flicker.is_temporal() && !Metric::Relmse.is_temporal());
    }
}
