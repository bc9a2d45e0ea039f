//! The display pass: one of the pipeline's buffers (the final image, the noisy input, a
//! G-buffer feature, a statistic) as 8-bit RGBA for the screen or a PNG, tone-mapped where it
//! is radiance; or as linear values for EXR files.

use glam::{Vec3, Vec4};
use pathlight_core::color::{luminance, Srgb8Encoder};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::config::{DisplayConfig, Tonemap};

use super::accumulation::PixelStats;
use super::gbuffer::GBuffer;
use super::lighting::LightSample;
use super::reprojection::Reprojection;
use super::restir::Reservoir;

/// What is shown.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum DisplayMode {
    /// The image: the accumulated mean radiance over the frames so far, filtered when the
    /// reconstruction filter (seed 001) is on.
    #[default]
    Final,
    /// The accumulated image before the reconstruction filter (its input light).
    Accumulated,
    /// This frame's radiance alone (the pipeline's noisy input).
    Noisy,
    /// Accumulated direct light (from emitters straight to the first surface).
    Direct,
    /// Accumulated indirect light (everything that bounced more).
    Indirect,
    /// Relative standard error of the accumulated mean (luminance), as a heat map 0 to 1.
    Variance,
    /// Samples per pixel accumulated, from black (none) to white (the most).
    Samples,
    /// G-buffer: base colour at the first hit.
    Albedo,
    /// G-buffer: shading normal (x, y, z mapped from [-1, 1] to [0, 1]).
    Normal,
    /// G-buffer: depth, near white to far black; the sky black.
    Depth,
    /// G-buffer: motion since the previous frame (red: x, green: y; grey is still; 32 pixels
    /// to full scale).
    Motion,
    /// G-buffer: perceptual roughness (grey).
    Roughness,
    /// G-buffer: metallic (grey).
    Metallic,
    /// Lighting: base colour at the first non-specular vertex after the first hit (seed 001's
    /// "texture2").
    BounceAlbedo,
    /// Lighting: the direction chosen at the first hit (mapped from [-1, 1] to [0, 1]).
    BounceDirection,
    /// Adaptive sampling: each pixel's fixed probability P of a sample per frame, as a heat
    /// map 0 to 1 (dark grey before the schedule fixes it).
    Probability,
    /// Reprojection: which pixels kept their history at the last camera move (white: all
    /// their states, grey: some of the 4, black: none).
    Reprojected,
    /// Reprojection: what happened at the last camera move, per pixel: kept (green), newly
    /// seen (black), occluded (red), view-dependency error (yellow), specular (blue), aliasing
    /// depth test (magenta).
    Rejection,
    /// Lighting: this frame's direct light alone (with ReSTIR, what the reservoirs gave).
    FrameDirect,
    /// ReSTIR: the candidates behind each pixel's reservoir (M), as a heat map from 0 to the
    /// image's largest (dark grey: no reservoir).
    ReservoirM,
    /// ReSTIR: each reservoir's contribution weight W, as a heat map of its logarithm over the
    /// image's range (dark grey: W = 0, no sample or an occluded one).
    ReservoirWeight,
    /// Filter: the sample variance of the depth, relative to the depth squared, as a heat map
    /// 0 to 1 (dark grey when the filter is off).
    VarianceDepth,
    /// Filter: the variance of the normal (summed over x, y, z), heat map 0 to 1.
    VarianceNormal,
    /// Filter: the variance of the texture (albedo at the first hit), heat map 0 to 1.
    VarianceTexture,
    /// Filter: the variance of the first bounce's direction, heat map 0 to 1.
    VarianceDirection,
    /// Filter: the variance of texture2, heat map 0 to 1.
    VarianceTexture2,
    /// Data-driven filter, `sure`: each pixel's share of its own (unfiltered) light in the
    /// blend, direct light in red and indirect in green, 0 to 1 (blue where the pixel passed
    /// through; dark grey when the blend did not run).
    SureShare,
}

impl DisplayMode {
    /// Every mode with its pass, in menu order.
    pub const ALL: [DisplayMode; 27] = [
        DisplayMode::Final,
        DisplayMode::Accumulated,
        DisplayMode::Noisy,
        DisplayMode::Direct,
        DisplayMode::Indirect,
        DisplayMode::Variance,
        DisplayMode::Samples,
        DisplayMode::Albedo,
        DisplayMode::Normal,
        DisplayMode::Depth,
        DisplayMode::Motion,
        DisplayMode::Roughness,
        DisplayMode::Metallic,
        DisplayMode::BounceAlbedo,
        DisplayMode::BounceDirection,
        DisplayMode::Probability,
        DisplayMode::Reprojected,
        DisplayMode::Rejection,
        DisplayMode::FrameDirect,
        DisplayMode::ReservoirM,
        DisplayMode::ReservoirWeight,
        DisplayMode::VarianceDepth,
        DisplayMode::VarianceNormal,
        DisplayMode::VarianceTexture,
        DisplayMode::VarianceDirection,
        DisplayMode::VarianceTexture2,
        DisplayMode::SureShare,
    ];

    /// The name in configurations and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            DisplayMode::Final => "final",
            DisplayMode::Accumulated => "accumulated",
            DisplayMode::Noisy => "noisy",
            DisplayMode::Direct => "direct",
            DisplayMode::Indirect => "indirect",
            DisplayMode::Variance => "variance",
            DisplayMode::Samples => "samples",
            DisplayMode::Albedo => "albedo",
            DisplayMode::Normal => "normal",
            DisplayMode::Depth => "depth",
            DisplayMode::Motion => "motion",
            DisplayMode::Roughness => "roughness",
            DisplayMode::Metallic => "metallic",
            DisplayMode::BounceAlbedo => "bounce-albedo",
            DisplayMode::BounceDirection => "bounce-direction",
            DisplayMode::Probability => "probability",
            DisplayMode::Reprojected => "reprojected",
            DisplayMode::Rejection => "rejection",
            DisplayMode::FrameDirect => "frame-direct",
            DisplayMode::ReservoirM => "reservoir-m",
            DisplayMode::ReservoirWeight => "reservoir-weight",
            DisplayMode::VarianceDepth => "variance-depth",
            DisplayMode::VarianceNormal => "variance-normal",
            DisplayMode::VarianceTexture => "variance-texture",
            DisplayMode::VarianceDirection => "variance-direction",
            DisplayMode::VarianceTexture2 => "variance-texture2",
            DisplayMode::SureShare => "sure-share",
        }
    }

    /// The pass whose buffer the mode shows.
    pub fn pass(self) -> &'static str {
        use DisplayMode::*;
        match self {
            Accumulated | Direct | Indirect | Variance | Samples | Probability => super::ACCUMULATE,
            Final | VarianceDepth | VarianceNormal | VarianceTexture | VarianceDirection
            | VarianceTexture2 | SureShare => super::FILTER,
            Reprojected | Rejection => super::REPROJECT,
            Noisy | FrameDirect | BounceAlbedo | BounceDirection => super::LIGHTING,
            ReservoirM | ReservoirWeight => super::RESTIR,
            Albedo | Normal | Depth | Motion | Roughness | Metallic => super::PRIMARY,
        }
    }

    /// True for radiance, which exposure and tone mapping apply to.
    pub fn is_radiance(self) -> bool {
        matches!(
            self,
            DisplayMode::Final
                | DisplayMode::Accumulated
                | DisplayMode::Noisy
                | DisplayMode::Direct
                | DisplayMode::Indirect
                | DisplayMode::FrameDirect
        )
    }
}

impl std::str::FromStr for DisplayMode {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        DisplayMode::ALL
            .into_iter()
            .find(|m| m.name() == s)
            .ok_or_else(|| {
                let names: Vec<&str> = DisplayMode::ALL.iter().map(|m| m.name()).collect();
                format!("unknown display mode `{s}`; one of {}", names.join(", "))
            })
    }
}

/// The buffers a display mode reads.
pub struct Sources<'a> {
    pub gbuffer: &'a GBuffer,
    pub lighting: &'a [LightSample],
    pub history: &'a [PixelStats],
    /// Adaptive sampling's probabilities (empty when it never ran).
    pub probability: &'a [f32],
    pub reprojection: &'a Reprojection,
    /// ReSTIR's reservoirs of the last frame (empty when it never ran).
    pub reservoirs: &'a [Reservoir],
    /// The reconstruction filter's output (empty when it is off).
    pub filtered: &'a [Vec3],
    /// The feature variances the filter read (empty when it is off): depth, normal, texture,
    /// direction, texture2.
    pub feature_variance: &'a [[f32; 5]],
    /// The data-driven filter's `sure` shares of each pixel's own light, direct and indirect
    /// (empty when the blend did not run; NaN where the pixel passed through).
    pub sure_shares: &'a [[f32; 2]],
}

impl Sources<'_> {
    /// The linear value of `mode` at pixel `i`: radiance, the feature itself (normal and
    /// direction in [-1, 1], depth in scene units with the sky infinite, motion in pixels as
    /// (x, y, 0), albedo), the variance of the accumulated mean, the sample count, the
    /// probability (-1 before it is fixed), the fraction of states reprojected, or the
    /// [`Fate`](super::reprojection::Fate) as a number.
    pub fn value(&self, mode: DisplayMode, i: usize) -> Vec3 {
        let g = &self.gbuffer.pixels[i];
        let l = &self.lighting[i];
        let h = &self.history[i];
        let feature_variance = |k: usize| {
            let v = self.feature_variance.get(i).map_or(-1.0, |v| v[k]);
            if k == 0 && v >= 0.0 {
                // Relative to the depth squared, as the filter reads it.
                Vec3::splat(v / (g.depth * g.depth).max(1e-12))
            } else {
                Vec3::splat(v)
            }
        };
        match mode {
            DisplayMode::Final => self.filtered.get(i).copied().unwrap_or_else(|| h.mean()),
            DisplayMode::Accumulated => h.mean(),
            DisplayMode::Noisy => l.stats.mean(),
            DisplayMode::Direct => h.direct.mean,
            DisplayMode::Indirect => h.indirect.mean,
            DisplayMode::Variance => h.variance() / h.n.max(1) as f32,
            DisplayMode::Samples => Vec3::splat(h.n as f32),
            DisplayMode::Albedo => g.albedo,
            DisplayMode::Normal => g.normal,
            DisplayMode::Depth => Vec3::splat(g.depth),
            DisplayMode::Motion => g.motion.extend(0.0),
            DisplayMode::Roughness => Vec3::splat(g.roughness),
            DisplayMode::Metallic => Vec3::splat(g.metallic),
            DisplayMode::BounceAlbedo => l.bounce.albedo,
            DisplayMode::BounceDirection => l.bounce.direction,
            DisplayMode::Probability => {
                Vec3::splat(self.probability.get(i).copied().unwrap_or(-1.0))
            }
            DisplayMode::Reprojected => {
                let r = self.reprojection;
                let kept = r.kept.get(i).copied().unwrap_or(0);
                Vec3::splat(kept as f32 / r.samples.max(1) as f32)
            }
            DisplayMode::Rejection => Vec3::splat(self.reprojection.fate(i) as u8 as f32),
            DisplayMode::FrameDirect => l.stats.direct.mean,
            DisplayMode::ReservoirM => Vec3::splat(self.reservoirs.get(i).map_or(0.0, |r| r.m)),
            DisplayMode::ReservoirWeight => {
                Vec3::splat(self.reservoirs.get(i).map_or(0.0, |r| r.weight))
            }
            DisplayMode::VarianceDepth => feature_variance(0),
            DisplayMode::VarianceNormal => feature_variance(1),
            DisplayMode::VarianceTexture => feature_variance(2),
            DisplayMode::VarianceDirection => feature_variance(3),
            DisplayMode::VarianceTexture2 => feature_variance(4),
            // -1 when the blend did not run.
            DisplayMode::SureShare => self
                .sure_shares
                .get(i)
                .map_or(Vec3::splat(-1.0), |s| Vec3::new(s[0], s[1], 0.0)),
        }
    }

    /// The whole image of `mode` as linear values (see [`value`](Self::value)).
    pub fn linear(&self, mode: DisplayMode) -> Vec<Vec3> {
        (0..self.gbuffer.pixels.len())
            .into_par_iter()
            .map(|i| self.value(mode, i))
            .collect()
    }

    /// The image of `mode` as 8-bit RGBA (alpha 255) into `out`: radiance after exposure and
    /// tone mapping, sRGB-encoded; features mapped to [0, 1] as each mode says.
    pub fn rgba8(&self, mode: DisplayMode, display: &DisplayConfig, out: &mut Vec<u8>) {
        let n = self.gbuffer.pixels.len();
        out.resize(n * 4, 0);
        // Image-wide scales: the farthest finite depth, the most samples.
        let (max_depth, max_n) = match mode {
            DisplayMode::Depth => (
                self.gbuffer
                    .pixels
                    .par_iter()
                    .map(|g| g.depth)
                    .filter(|d| d.is_finite())
                    .reduce(|| 0.0, f32::max),
                0,
            ),
            DisplayMode::Samples => (0.0, self.history.par_iter().map(|h| h.n).max().unwrap_or(0)),
            _ => (0.0, 0),
        };
        let srgb = Srgb8Encoder::new();
        let radiance = |v: Vec3| srgb.encode3(tonemap(v * display.exposure, display.tonemap));
        match mode {
            // The usual mode, with its own loop.
            DisplayMode::Final if self.filtered.is_empty() => {
                fill(out, |i| radiance(self.history[i].mean()))
            }
            m if m.is_radiance() => fill(out, |i| radiance(self.value(mode, i))),
            DisplayMode::Albedo | DisplayMode::BounceAlbedo => {
                fill(out, |i| srgb.encode3(self.value(mode, i)))
            }
            DisplayMode::Normal | DisplayMode::BounceDirection => fill(out, |i| {
                let v = self.value(mode, i);
                unorm8(if v == Vec3::ZERO {
                    Vec3::ZERO
                } else {
                    v * 0.5 + 0.5
                })
            }),
            DisplayMode::Depth => fill(out, |i| {
                let d = self.value(mode, i).x;
                unorm8(Vec3::splat(if d.is_finite() && max_depth > 0.0 {
                    1.0 - 0.9 * d / max_depth
                } else {
                    0.0
                }))
            }),
            DisplayMode::Motion => fill(out, |i| {
                let v = self.value(mode, i);
                unorm8(Vec3::new(0.5 + v.x / 32.0, 0.5 + v.y / 32.0, 0.5))
            }),
            DisplayMode::Variance => fill(out, |i| {
                let v = self.value(mode, i);
                let relative = luminance(v).max(0.0).sqrt()
                    / (luminance(self.history[i].mean()).max(0.0) + 1e-3);
                viridis(relative)
            }),
            DisplayMode::Samples => fill(out, |i| {
                unorm8(Vec3::splat(self.value(mode, i).x / max_n.max(1) as f32))
            }),
            DisplayMode::Probability => fill(out, |i| {
                let p = self.value(mode, i).x;
                if p < 0.0 {
                    [40, 40, 40]
                } else {
                    viridis(p)
                }
            }),
            DisplayMode::Rejection => fill(out, |i| self.reprojection.fate(i).colour()),
            DisplayMode::VarianceDepth
            | DisplayMode::VarianceNormal
            | DisplayMode::VarianceTexture
            | DisplayMode::VarianceDirection
            | DisplayMode::VarianceTexture2 => fill(out, |i| {
                let v = self.value(mode, i).x;
                if v < 0.0 {
                    [40, 40, 40]
                } else {
                    viridis(v.min(1.0))
                }
            }),
            DisplayMode::SureShare => fill(out, |i| {
                let v = self.value(mode, i);
                if v.x < 0.0 {
                    [40, 40, 40]
                } else if v.x.is_nan() {
                    [0, 0, 160]
                } else {
                    unorm8(v)
                }
            }),
            DisplayMode::ReservoirM => {
                let max = self
                    .reservoirs
                    .par_iter()
                    .map(|r| r.m)
                    .reduce(|| 0.0, f32::max);
                fill(out, |i| {
                    let m = self.value(mode, i).x;
                    if m > 0.0 {
                        viridis(m / max)
                    } else {
                        [40, 40, 40]
                    }
                })
            }
            DisplayMode::ReservoirWeight => {
                let (lo, hi) = self
                    .reservoirs
                    .par_iter()
                    .filter(|r| r.weight > 0.0 && r.weight.is_finite())
                    .map(|r| (r.weight.ln(), r.weight.ln()))
                    .reduce(
                        || (f32::INFINITY, f32::NEG_INFINITY),
                        |a, b| (a.0.min(b.0), a.1.max(b.1)),
                    );
                fill(out, |i| {
                    let w = self.value(mode, i).x;
                    if w > 0.0 && w.is_finite() {
                        viridis((w.ln() - lo) / (hi - lo).max(1e-6))
                    } else {
                        [40, 40, 40]
                    }
                })
            }
            _ => fill(out, |i| unorm8(self.value(mode, i))),
        }
    }
}

/// Pixels per parallel task of the display pass.
const CHUNK: usize = 1024;

/// Writes `rgb(i)` and alpha 255 to each RGBA pixel `i` of `out`, in parallel.
fn fill(out: &mut [u8], rgb: impl Fn(usize) -> [u8; 3] + Sync) {
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
fn unorm8(v: Vec3) -> [u8; 3] {
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
    fn names_parse_back() {
        for m in DisplayMode::ALL {
            assert_eq!(m.name().parse::<DisplayMode>().unwrap(), m);
            let json = serde_json::to_string(&m).unwrap();
            assert_eq!(json, format!("\"{}\"", m.name()));
        }
        assert!("nope"
            .parse::<DisplayMode>()
            .unwrap_err()
            .contains("bounce-albedo"));
    }

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
