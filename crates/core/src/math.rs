//! Fast approximations of trigonometric functions for hot loops (environment map lookups),
//! accurate to a few millionths of a radian: far below a texel of any environment map.

use std::f32::consts::{FRAC_PI_2, PI};

/// `acos(x)` for `x` in [-1, 1] (clamped): Abramowitz and Stegun 4.4.46, absolute error below
/// 1e-6.
#[inline]
pub fn fast_acos(x: f32) -> f32 {
    let a = x.abs().min(1.0);
    let p = FRAC_PI_2
        + a * (-0.214_598_8
            + a * (0.088_978_99
                + a * (-0.050_174_3
                    + a * (0.030_891_88
                        + a * (-0.017_088_126 + a * (0.006_670_09 + a * -0.001_262_491))))));
    let r = p * (1.0 - a).sqrt();
    if x < 0.0 {
        PI - r
    } else {
        r
    }
}

/// `atan2(y, x)` in (-pi, pi]: a minimax polynomial for atan on [0, 1] with octant reduction,
/// absolute error below 2e-6. `fast_atan2(0, 0)` is 0.
#[inline]
pub fn fast_atan2(y: f32, x: f32) -> f32 {
    let (ax, ay) = (x.abs(), y.abs());
    let (lo, hi) = if ax > ay { (ay, ax) } else { (ax, ay) };
    if hi == 0.0 {
        return 0.0;
    }
    let z = lo / hi;
    let z2 = z * z;
    let mut a = z
        * (0.999_977_26
            + z2 * (-0.332_623_47
                + z2 * (0.193_543_46
                    + z2 * (-0.116_432_87 + z2 * (0.052_653_32 + z2 * -0.011_721_2)))));
    if ay > ax {
        a = FRAC_PI_2 - a;
    }
    if x < 0.0 {
        a = PI - a;
    }
    if y < 0.0 {
        -a
    } else {
        a
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn acos_is_close_to_std() {
        let mut worst = 0.0f32;
        for i in 0..=200_000 {
            let x = -1.0 + i as f32 / 100_000.0;
            worst = worst.max((fast_acos(x) - x.acos()).abs());
        }
        assert!(worst < 1e-6, "worst {worst}");
        assert_eq!(fast_acos(2.0), 0.0);
        assert!((fast_acos(-2.0) - PI).abs() < 1e-6);
    }

    #[test]
    fn atan2_is_close_to_std_in_every_octant() {
        let mut worst = 0.0f32;
        for i in 0..100_000 {
            let a = i as f32 / 100_000.0 * 2.0 * PI - PI;
            for r in [1e-3f32, 1.0, 7.5] {
                let (y, x) = (r * a.sin(), r * a.cos());
                worst = worst.max((fast_atan2(y, x) - y.atan2(x)).abs());
            }
        }
        assert!(worst < 2e-6, "worst {worst}");
        assert_eq!(fast_atan2(0.0, 0.0), 0.0);
        assert!((fast_atan2(0.0, -1.0) - PI).abs() < 1e-6);
        assert!((fast_atan2(1.0, 0.0) - FRAC_PI_2).abs() < 1e-6);
    }
}
