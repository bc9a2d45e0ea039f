//! The display pass and its settings: one of the stages' views (the final image, the noisy
//! input, a G-buffer feature, a statistic, a technique's state) as 8-bit RGBA for the screen or
//! a PNG, tone-mapped where it is radiance; or as linear values for EXR files.
//!
//! A view belongs to its stage ([`super::stage::Stage::views`]): the stage names it, says how
//! its values are shown ([`ViewKind`]) and gives its values. This module knows no stage: it
//! holds the settings ([`DisplayConfig`]), the name of the view shown ([`DisplayMode`]; the
//! names are checked against the stages' in [`super::views`]), and the colour maps.

use std::borrow::Cow;

use glam::{Vec3, Vec4};
use pathlight_core::color::Srgb8Encoder;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// The display pass's name (timings).
pub const DISPLAY: &str = "display";

/// Tone mapping and the picture shown.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DisplayConfig {
    /// Multiplier of linear radiance before tone mapping.
    pub exposure: f32,
    pub tonemap: Tonemap,
    /// What the viewer shows and the player writes: a stage's view, by name.
    pub mode: DisplayMode,
}

impl Default for DisplayConfig {
    fn default() -> Self {
        Self {
            exposure: 1.0,
            tonemap: Tonemap::Clamp,
            mode: DisplayMode::FINAL,
        }
    }
}

/// Linear radiance (after exposure) to display values in [0, 1], then sRGB-encoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Tonemap {
    /// Clamp to [0, 1] (what `pathlight render` writes to PNG).
    #[default]
    Clamp,
    /// The ACES filmic curve (Narkowicz's fit): highlights roll off instead of clipping.
    Aces,
}

/// The view shown, by its name (`final`, `normal`, `reservoir-m`, ...): one of the stages'
/// views ([`super::views::all`]). Parsing (`FromStr`, and a configuration file's
/// `display.mode`) refuses a name no stage has.
#[derive(Debug, Clone, PartialEq, Eq, Hash, Serialize)]
#[serde(into = "String")]
pub struct DisplayMode(Cow<'static, str>);

impl DisplayMode {
    /// The image: the accumulated mean radiance, filtered when a reconstruction filter is on.
    pub const FINAL: DisplayMode = DisplayMode(Cow::Borrowed("final"));

    /// The view named `name` (not checked: see [`super::views::find`]).
    pub const fn named(name: &'static str) -> Self {
        Self(Cow::Borrowed(name))
    }

    /// The name in configurations and on the command line.
    pub fn name(&self) -> &str {
        &self.0
    }
}

impl Default for DisplayMode {
    fn default() -> Self {
        Self::FINAL
    }
}

impl From<DisplayMode> for String {
    fn from(m: DisplayMode) -> String {
        m.0.into_owned()
    }
}

impl std::fmt::Display for DisplayMode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

/// One of a stage's named images.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct View {
    /// Its name ([`DisplayMode`]).
    pub name: &'static str,
    /// What it shows, in a line (the viewer's tooltip, `--display`'s help).
    pub about: &'static str,
    pub kind: ViewKind,
}

/// How a view's linear values become colours.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ViewKind {
    /// Radiance: exposure, tone mapping, sRGB encoding.
    Radiance,
    /// A colour (an albedo), sRGB-encoded.
    Colour,
    /// A direction in [-1, 1] mapped to [0, 1] (zero stays black).
    Direction,
    /// Values in [0, 1] as they are, clamped.
    Unit,
    /// A depth: near white to far black over the image's farthest finite depth; infinite (the
    /// sky) black.
    Depth,
    /// Motion in pixels (x, y): grey is still, 32 pixels to full scale.
    Motion,
    /// A count: black (none) to white (the image's most).
    Count,
    /// A heat map of [0, 1] (clamped); negative is "none" (dark grey).
    Heat,
    /// A heat map from 0 to the image's largest value; 0 and below dark grey.
    HeatOfLargest,
    /// A heat map of the logarithm over the image's range of positive finite values; others
    /// dark grey.
    HeatOfLog,
    /// Coloured by its stage ([`super::stage::Stage::paint`]).
    Painted,
}

/// The colour of "nothing here" in heat maps.
pub const NONE: [u8; 3] = [40, 40, 40];

/// Pixels per parallel task of the display pass.
const CHUNK: usize = 1024;

/// The image of a view of kind `kind` over `n` pixels as 8-bit RGBA (alpha 255) into `out`:
/// `value(i)` is the view's linear value at pixel `i`, `paint(i)` its colour when the kind is
/// [`ViewKind::Painted`].
pub fn encode(
    kind: ViewKind,
    n: usize,
    value: impl Fn(usize) -> Vec3 + Sync,
    paint: impl Fn(usize) -> [u8; 3] + Sync,
    display: &DisplayConfig,
    out: &mut Vec<u8>,
) {
    out.resize(n * 4, 0);
    // Image-wide scales.
    let largest = |keep: fn(f32) -> bool| {
        (0..n)
            .into_par_iter()
            .map(|i| value(i).x)
            .filter(|&v| keep(v))
            .reduce(|| 0.0, f32::max)
    };
    let srgb = Srgb8Encoder::new();
    match kind {
        ViewKind::Radiance => fill(out, |i| {
            srgb.encode3(tonemap(value(i) * display.exposure, display.tonemap))
        }),
        ViewKind::Colour => fill(out, |i| srgb.encode3(value(i))),
        ViewKind::Direction => fill(out, |i| {
            let v = value(i);
            unorm8(if v == Vec3::ZERO {
                Vec3::ZERO
            } else {
                v * 0.5 + 0.5
            })
        }),
        ViewKind::Unit => fill(out, |i| unorm8(value(i))),
        ViewKind::Depth => {
            let far = largest(f32::is_finite);
            fill(out, |i| {
                let d = value(i).x;
                unorm8(Vec3::splat(if d.is_finite() && far > 0.0 {
                    1.0 - 0.9 * d / far
                } else {
                    0.0
                }))
            })
        }
        ViewKind::Motion => fill(out, |i| {
            let v = value(i);
            unorm8(Vec3::new(0.5 + v.x / 32.0, 0.5 + v.y / 32.0, 0.5))
        }),
        ViewKind::Count => {
            let most = largest(|_| true);
            fill(out, |i| unorm8(Vec3::splat(value(i).x / most.max(1.0))))
        }
        ViewKind::Heat => fill(out, |i| {
            let v = value(i).x;
            if v < 0.0 {
                NONE
            } else {
                viridis(v.min(1.0))
            }
        }),
        ViewKind::HeatOfLargest => {
            let most = largest(|_| true);
            fill(out, |i| {
                let v = value(i).x;
                if v > 0.0 {
                    viridis(v / most)
                } else {
                    NONE
                }
            })
        }
        ViewKind::HeatOfLog => {
            let positive = |v: f32| v > 0.0 && v.is_finite();
            let (lo, hi) = (0..n)
                .into_par_iter()
                .map(|i| value(i).x)
                .filter(|&v| positive(v))
                .map(|v| (v.ln(), v.ln()))
                .reduce(
                    || (f32::INFINITY, f32::NEG_INFINITY),
                    |a, b| (a.0.min(b.0), a.1.max(b.1)),
                );
            fill(out, |i| {
                let v = value(i).x;
                if positive(v) {
                    viridis((v.ln() - lo) / (hi - lo).max(1e-6))
                } else {
                    NONE
                }
            })
        }
        ViewKind::Painted => fill(out, paint),
    }
}

/// Writes `rgb(i)` and alpha 255 to each RGBA pixel `i` of `out`, in parallel.
pub fn fill(out: &mut [u8], rgb: impl Fn(usize) -> [u8; 3] + Sync) {
    out.par_chunks_mut(4 * CHUNK)
        .enumerate()
        .for_each(|(c, chunk)| {
            for (k, px) in chunk.chunks_exact_mut(4).enumerate() {
                let [r, g, b] = rgb(c * CHUNK + k);
                px.copy_from_slice(&[r, g, b, 255]);
            }
        });
}

/// A value in [0, 1] (clamped) to 8 bits, without encoding.
pub fn unorm8(v: Vec3) -> [u8; 3] {
    v.to_array()
        .map(|c| (c.clamp(0.0, 1.0) * 255.0 + 0.5) as u8)
}

/// Linear radiance to display-linear values in [0, 1].
pub fn tonemap(v: Vec3, tonemap: Tonemap) -> Vec3 {
    let v = if v.is_finite() {
        v.max(Vec3::ZERO)
    } else {
        Vec3::ZERO
    };
    match tonemap {
        Tonemap::Clamp => v.min(Vec3::ONE),
        // Narkowicz 2015, "ACES Filmic Tone Mapping Curve".
        Tonemap::Aces => {
            ((v * (2.51 * v + 0.03)) / (v * (2.43 * v + 0.59) + 0.14)).clamp(Vec3::ZERO, Vec3::ONE)
        }
    }
}

/// The viridis colour map at `t` in [0, 1] (clamped), as sRGB bytes: a degree-6 polynomial
/// fit of matplotlib's table (Matt Zucker's, error under 1/255).
pub fn viridis(t: f32) -> [u8; 3] {
    let t = if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        1.0
    };
    const C: [Vec4; 7] = [
        Vec4::new(0.277_727_33, 0.005_407_344_5, 0.334_099_8, 0.0),
        Vec4::new(0.105_093_04, 1.404_613_5, 1.384_590_2, 0.0),
        Vec4::new(-0.330_861_83, 0.214_847_56, 0.095_095_16, 0.0),
        Vec4::new(-4.634_230_6, -5.799_101, -19.332_441, 0.0),
        Vec4::new(6.228_27, 14.179_933, 56.690_55, 0.0),
        Vec4::new(4.776_385, -13.745_146, -65.353_03, 0.0),
        Vec4::new(-5.435_456, 4.645_852_6, 26.312_435, 0.0),
    ];
    let mut c = C[6];
    for k in (0..6).rev() {
        c = C[k] + t * c;
    }
    unorm8(c.truncate())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tonemaps_stay_in_range_and_keep_black() {
        for t in [Tonemap::Clamp, Tonemap::Aces] {
            assert_eq!(tonemap(Vec3::ZERO, t), Vec3::ZERO);
            assert_eq!(tonemap(Vec3::NAN, t), Vec3::ZERO);
            let big = tonemap(Vec3::splat(1e6), t);
            assert!(big.max_element() <= 1.0 && big.min_element() > 0.99);
        }
        // ACES is monotonic and rolls highlights off smoothly instead of clipping at 1.
        let ys: Vec<f32> = (0..200)
            .map(|i| tonemap(Vec3::splat(i as f32 * 0.05), Tonemap::Aces).x)
            .collect();
        assert!(ys.windows(2).all(|w| w[0] <= w[1]));
        assert!(tonemap(Vec3::ONE, Tonemap::Aces).x < 0.85);
    }

    #[test]
    fn viridis_ends_match_matplotlib() {
        // matplotlib: viridis(0) = #440154, viridis(1) = #fde725.
        let near = |a: [u8; 3], b: [u8; 3]| {
            a.iter()
                .zip(b)
                .all(|(x, y)| (*x as i32 - y as i32).abs() <= 4)
        };
        assert!(near(viridis(0.0), [0x44, 0x01, 0x54]), "{:?}", viridis(0.0));
        assert!(near(viridis(1.0), [0xfd, 0xe7, 0x25]), "{:?}", viridis(1.0));
        assert!(near(viridis(0.5), [0x21, 0x91, 0x8c]), "{:?}", viridis(0.5));
    }
}
