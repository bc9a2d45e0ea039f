//! Environment maps: equirectangular `.hdr` (Radiance RGBE) and `.exr` (OpenEXR) images of
//! radiance arriving from infinitely far away.
//!
//! Mapping (the common "lat-long" convention, as in Mitsuba and Blender): the image's top row is
//! straight up (+Y), its middle row the horizon; the column at u = 0.5 looks along -Z, u = 0.75
//! along +X. `rotation` turns the map about +Y (positive: counter-clockwise seen from above).

use std::f32::consts::PI;
use std::path::Path;

use glam::{Vec2, Vec3};

use crate::error::{Result, SceneError};
use crate::limits::Limits;
use crate::source::read_file_limited;
use crate::texture::check_pixels;

#[derive(Debug, Clone, PartialEq)]
pub struct Environment {
    pub name: String,
    pub width: u32,
    pub height: u32,
    /// Linear RGB radiance, row-major, top row first (before `intensity`).
    pub texels: Vec<Vec3>,
    /// Rotation about +Y in radians.
    pub rotation: f32,
    /// Multiplies every texel.
    pub intensity: f32,
}

impl Environment {
    /// Loads an equirectangular `.hdr` or `.exr` file. Negative, NaN and infinite texels are set
    /// to 0 with a warning in the log.
    pub fn load(
        path: &Path,
        rotation_degrees: f32,
        intensity: f32,
        limits: &Limits,
    ) -> Result<Self> {
        let bytes = read_file_limited(path, limits.max_file_bytes)?;
        Self::decode(&bytes, path, rotation_degrees, intensity, limits)
    }

    /// Decodes `.hdr` or `.exr` bytes; `path` gives the format (by extension) and names the
    /// file in messages.
    pub fn decode(
        bytes: &[u8],
        path: &Path,
        rotation_degrees: f32,
        intensity: f32,
        limits: &Limits,
    ) -> Result<Self> {
        use image::{ImageFormat, ImageReader};
        if !rotation_degrees.is_finite() || !intensity.is_finite() || intensity < 0.0 {
            return Err(SceneError::new(
                path,
                format!("environment rotation {rotation_degrees} and intensity {intensity} must be finite, intensity >= 0"),
            ));
        }
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase)
            .unwrap_or_default();
        let format = match ext.as_str() {
            "hdr" | "pic" | "rgbe" => ImageFormat::Hdr,
            "exr" => ImageFormat::OpenExr,
            _ => {
                return Err(SceneError::new(
                    path,
                    "unknown environment map format: expected .hdr or .exr",
                ))
            }
        };
        let reader = || ImageReader::with_format(std::io::Cursor::new(bytes), format);
        let (width, height) = reader()
            .into_dimensions()
            .map_err(|e| SceneError::new(path, format!("not a valid {ext} image: {e}")))?;
        check_pixels(path, width, height, limits.max_texture_pixels)?;
        let mut image_limits = image::Limits::default();
        image_limits.max_image_width = Some(width);
        image_limits.max_image_height = Some(height);
        image_limits.max_alloc = Some((width as u64 * height as u64 * 48).max(1 << 20));
        let mut r = reader();
        r.limits(image_limits);
        let decoded = r
            .decode()
            .map_err(|e| SceneError::new(path, format!("cannot decode the {ext} image: {e}")))?
            .into_rgb32f();
        // The decoded size, not the header's, describes `texels`.
        let (width, height) = decoded.dimensions();
        let mut bad = 0usize;
        let texels = decoded
            .as_raw()
            .chunks_exact(3)
            .map(|c| {
                let v = Vec3::new(c[0], c[1], c[2]);
                if v.is_finite() && v.min_element() >= 0.0 {
                    v
                } else {
                    bad += 1;
                    v.max(Vec3::ZERO).select_finite()
                }
            })
            .collect();
        if bad > 0 {
            log::warn!(
                "{}: {bad} texels were negative, NaN or infinite and were set to 0",
                path.display()
            );
        }
        Ok(Self {
            name: path
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default(),
            width,
            height,
            texels,
            rotation: rotation_degrees.to_radians(),
            intensity,
        })
    }

    /// A constant environment (tests, white furnace).
    pub fn constant(radiance: Vec3) -> Self {
        Self {
            name: "constant".into(),
            width: 1,
            height: 1,
            texels: vec![radiance],
            rotation: 0.0,
            intensity: 1.0,
        }
    }

    /// The image coordinate in [0,1]^2 seen in world direction `dir` (unit length).
    pub fn direction_to_uv(&self, dir: Vec3) -> Vec2 {
        // Fast approximations (error under 2e-6 radians, far below a texel).
        let phi = pathlight_core::math::fast_atan2(dir.x, -dir.z) - self.rotation;
        let theta = pathlight_core::math::fast_acos(dir.y);
        Vec2::new((0.5 + phi / (2.0 * PI)).rem_euclid(1.0), theta / PI)
    }

    /// The world direction of image coordinate `uv` (inverse of [`direction_to_uv`](Self::direction_to_uv)).
    pub fn uv_to_direction(&self, uv: Vec2) -> Vec3 {
        let phi = (uv.x - 0.5) * 2.0 * PI + self.rotation;
        let theta = uv.y * PI;
        let (sp, cp) = phi.sin_cos();
        let (st, ct) = theta.sin_cos();
        Vec3::new(st * sp, ct, -st * cp)
    }

    /// Radiance arriving from direction `dir` (nearest texel, times `intensity`).
    pub fn radiance(&self, dir: Vec3) -> Vec3 {
        self.radiance_at_uv(self.direction_to_uv(dir))
    }

    /// Radiance at image coordinate `uv` (nearest texel, times `intensity`).
    pub fn radiance_at_uv(&self, uv: Vec2) -> Vec3 {
        let x = ((uv.x * self.width as f32) as u32).min(self.width - 1);
        let y = ((uv.y * self.height as f32) as u32).min(self.height - 1);
        self.texels[(y * self.width + x) as usize] * self.intensity
    }

    pub fn heap_bytes(&self) -> usize {
        self.texels.len() * 12
    }
}

trait SelectFinite {
    fn select_finite(self) -> Self;
}

impl SelectFinite for Vec3 {
    fn select_finite(self) -> Self {
        Vec3::new(
            if self.x.is_finite() { self.x } else { 0.0 },
            if self.y.is_finite() { self.y } else { 0.0 },
            if self.z.is_finite() { self.z } else { 0.0 },
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn direction_and_uv_are_inverse() {
        for rotation in [0.0f32, 1.0, -2.5] {
            let env = Environment {
                rotation,
                ..Environment::constant(Vec3::ONE)
            };
            for (u, v) in [(0.1, 0.2), (0.5, 0.5), (0.9, 0.7), (0.3, 0.95)] {
                let uv = Vec2::new(u, v);
                let back = env.direction_to_uv(env.uv_to_direction(uv));
                assert!((back - uv).length() < 1e-4, "{uv} -> {back}");
            }
        }
    }

    #[test]
    fn documented_orientation() {
        let env = Environment::constant(Vec3::ONE);
        assert!(env.direction_to_uv(Vec3::Y).y < 1e-6);
        assert!((env.direction_to_uv(Vec3::NEG_Z) - Vec2::new(0.5, 0.5)).length() < 1e-6);
        assert!((env.direction_to_uv(Vec3::X) - Vec2::new(0.75, 0.5)).length() < 1e-6);
    }
}
