//! A frame's filter inputs: the thesis's FilterVector and feature variances, per pixel in
//! row-major order.
//!
//! F0 `direct` (first-bounce direct light), F1 `indirect` (all later bounces), F2 `depth`
//! (along the view axis; infinite on the sky), F3 `normal`, F4 `albedo` (the "texture": the
//! albedo at the first hit), F5 `texture2` (the albedo at the first diffuse vertex after the
//! first bounce), each the mean over the pixel's samples; `variance` holds, per pixel, the
//! sample variance (n-1) of depth, normal, texture, first-bounce direction and texture2, each
//! summed over its components; `light_variance` the variance of the mean of the light's
//! luminance (or of its channels' mean); `roughness` and `metallic` the material's at the
//! first hit (means over the pixel's samples), which say how fast a glossy reflection turns
//! with the normal.

use glam::Vec3;

use crate::simd::F32xN;
use crate::FilterError;

/// Indices into [`Features::variance`].
pub const DEPTH: usize = 0;
pub const NORMAL: usize = 1;
pub const TEXTURE: usize = 2;
pub const DIRECTION: usize = 3;
pub const TEXTURE2: usize = 4;

#[derive(Debug, Clone, Copy)]
pub struct Features<'a> {
    pub width: usize,
    pub height: usize,
    pub direct: &'a [Vec3],
    pub indirect: &'a [Vec3],
    pub depth: &'a [f32],
    pub normal: &'a [Vec3],
    pub albedo: &'a [Vec3],
    pub texture2: &'a [Vec3],
    pub variance: &'a [[f32; 5]],
    /// The variance of the mean of the luminance of the direct and of the indirect light
    /// (not demodulated), or, with `colour_weights = "albedo"`, the mean over the channels of
    /// each one's; NaN where the caller does not know it (one sample). Read by the variance
    /// colour units only.
    pub light_variance: &'a [[f32; 2]],
    /// The first hit's roughness (perceptual: GGX alpha is its square) and metallic factor,
    /// means over the pixel's samples (1 and 0 where unknown: the thesis's normal test).
    pub roughness: &'a [f32],
    pub metallic: &'a [f32],
}

impl Features<'_> {
    /// Pixels in the frame.
    pub fn len(&self) -> usize {
        self.width * self.height
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Checks that every buffer holds one value per pixel.
    pub fn check(&self) -> Result<(), FilterError> {
        let n = self.len();
        for (name, len) in [
            ("direct", self.direct.len()),
            ("indirect", self.indirect.len()),
            ("depth", self.depth.len()),
            ("normal", self.normal.len()),
            ("albedo", self.albedo.len()),
            ("texture2", self.texture2.len()),
            ("variance", self.variance.len()),
            ("light_variance", self.light_variance.len()),
            ("roughness", self.roughness.len()),
            ("metallic", self.metallic.len()),
        ] {
            if len != n {
                return Err(FilterError::Size {
                    name,
                    len,
                    width: self.width,
                    height: self.height,
                });
            }
        }
        Ok(())
    }
}

/// What demodulation divides a pixel's light by: its albedo, each channel at least 0.01 (a
/// black surface's light is then filtered as it is, near enough).
pub(crate) fn demodulator(albedo: Vec3) -> Vec3 {
    albedo.max(Vec3::splat(0.01))
}

/// [`demodulator`] of one channel in lanes.
#[inline(always)]
pub(crate) fn demodulator_lanes<V: F32xN>(albedo: V) -> V {
    let floor = V::splat(0.01);
    V::select(albedo.ge(floor), albedo, floor)
}
