//! Colour: sRGB transfer functions and luminance, in linear Rec.709 RGB.

use glam::Vec3;

/// The sRGB electro-optical transfer function: an encoded value in [0, 1] to linear.
#[inline]
pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// The inverse of [`srgb_to_linear`]: a linear value to sRGB encoding (input clamped to [0, 1]).
#[inline]
pub fn linear_to_srgb(c: f32) -> f32 {
    let c = c.clamp(0.0, 1.0);
    if c <= 0.003_130_8 {
        c * 12.92
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    }
}

/// Table of [`srgb_to_linear`] for every 8-bit code value.
pub fn srgb8_to_linear_table() -> &'static [f32; 256] {
    static TABLE: std::sync::OnceLock<[f32; 256]> = std::sync::OnceLock::new();
    TABLE.get_or_init(|| std::array::from_fn(|i| srgb_to_linear(i as f32 / 255.0)))
}

/// Decodes an 8-bit sRGB code value to linear.
#[inline]
pub fn srgb8_to_linear(c: u8) -> f32 {
    srgb8_to_linear_table()[c as usize]
}

/// Encodes a linear value as an 8-bit sRGB code value (rounded to nearest), by the formula.
#[inline]
fn linear_to_srgb8_formula(c: f32) -> u8 {
    (linear_to_srgb(c) * 255.0 + 0.5) as u8
}

/// For each code value `i` in 1..=255, the smallest linear value that encodes to `i` or more.
fn srgb8_thresholds() -> &'static [f32; 255] {
    static TABLE: std::sync::OnceLock<[f32; 255]> = std::sync::OnceLock::new();
    TABLE.get_or_init(|| {
        std::array::from_fn(|k| {
            let code = k as u8 + 1;
            // Bisection over the bit patterns of [0, 1] (ordered like the values).
            let (mut lo, mut hi) = (0u32, 1f32.to_bits());
            while lo < hi {
                let mid = lo + (hi - lo) / 2;
                if linear_to_srgb8_formula(f32::from_bits(mid)) >= code {
                    hi = mid;
                } else {
                    lo = mid + 1;
                }
            }
            f32::from_bits(lo)
        })
    })
}

/// For every value of the top 16 bits of a float in [0, 1): the code of the smallest value with
/// those bits. A bucket spans less than a code step above 1/256 and about one code below, so
/// encoding starts here and steps up at most a couple of thresholds.
fn srgb8_buckets() -> &'static [u8] {
    static TABLE: std::sync::OnceLock<Vec<u8>> = std::sync::OnceLock::new();
    TABLE.get_or_init(|| {
        (0..=(1f32.to_bits() >> 16))
            .map(|b| linear_to_srgb8_formula(f32::from_bits(b << 16)))
            .collect()
    })
}

/// Encodes a linear value as an 8-bit sRGB code value (rounded to nearest; clamped to [0, 1],
/// NaN as 0): the code of the value's bucket, then the code thresholds above it. The same
/// result as evaluating the transfer function, without a `powf` per value.
#[inline]
pub fn linear_to_srgb8(c: f32) -> u8 {
    Srgb8Encoder::new().encode(c)
}

/// [`linear_to_srgb8`] with its tables looked up once, for loops over many values.
#[derive(Clone, Copy)]
pub struct Srgb8Encoder {
    buckets: &'static [u8],
    thresholds: &'static [f32; 255],
}

impl Default for Srgb8Encoder {
    fn default() -> Self {
        Self::new()
    }
}

impl Srgb8Encoder {
    #[inline]
    pub fn new() -> Self {
        Self {
            buckets: srgb8_buckets(),
            thresholds: srgb8_thresholds(),
        }
    }

    /// [`linear_to_srgb8`] of `c`.
    #[inline]
    pub fn encode(&self, c: f32) -> u8 {
        // Zero, negative and NaN all encode as 0; 1 and above as 255.
        if c.is_nan() || c <= 0.0 {
            return 0;
        }
        if c >= 1.0 {
            return 255;
        }
        let mut code = self.buckets[(c.to_bits() >> 16) as usize];
        while code < 255 && c >= self.thresholds[code as usize] {
            code += 1;
        }
        code
    }

    /// [`encode`](Self::encode) of each channel.
    #[inline]
    pub fn encode3(&self, c: Vec3) -> [u8; 3] {
        [self.encode(c.x), self.encode(c.y), self.encode(c.z)]
    }
}

/// The ITU-R BT.709 weights of red, green and blue in [`luminance`].
pub const LUMINANCE: [f32; 3] = [0.2126, 0.7152, 0.0722];

/// Relative luminance of a linear Rec.709 colour (ITU-R BT.709 weights).
#[inline]
pub fn luminance(c: Vec3) -> f32 {
    LUMINANCE[0] * c.x + LUMINANCE[1] * c.y + LUMINANCE[2] * c.z
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_round_trips_every_code_value() {
        for i in 0..=255u8 {
            assert_eq!(linear_to_srgb8(srgb8_to_linear(i)), i);
        }
    }

    #[test]
    fn srgb_matches_published_values() {
        // IEC 61966-2-1: code 128 is 0.2158605 linear, 188 is ~0.5029.
        assert!((srgb8_to_linear(128) - 0.215_860_5).abs() < 1e-6);
        assert!((srgb8_to_linear(188) - 0.502_886).abs() < 1e-5);
        assert_eq!(srgb8_to_linear(0), 0.0);
        assert_eq!(srgb8_to_linear(255), 1.0);
        // The linear segment.
        assert!((srgb_to_linear(0.04) - 0.04 / 12.92).abs() < 1e-9);
    }

    #[test]
    fn encoding_by_table_equals_the_formula() {
        // Every code threshold and its neighbours, plus a dense sweep and the edges.
        for &t in srgb8_thresholds() {
            for v in [
                t,
                f32::from_bits(t.to_bits() - 1),
                f32::from_bits(t.to_bits() + 1),
            ] {
                assert_eq!(linear_to_srgb8(v), linear_to_srgb8_formula(v), "{v}");
            }
        }
        for i in 0..=1_000_000u32 {
            let v = i as f32 / 900_000.0;
            assert_eq!(linear_to_srgb8(v), linear_to_srgb8_formula(v), "{v}");
        }
        for v in [-1.0, -0.0, 0.0, 1e-30, 1.0, 2.0, f32::INFINITY, f32::NAN] {
            assert_eq!(linear_to_srgb8(v), linear_to_srgb8_formula(v), "{v}");
        }
    }

    #[test]
    fn luminance_of_white_is_one() {
        assert!((luminance(Vec3::ONE) - 1.0).abs() < 1e-6);
    }
}
