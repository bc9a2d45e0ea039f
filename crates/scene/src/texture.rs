//! Textures: 8-bit RGBA images with a full mip chain, decoded from PNG or JPEG.
//!
//! Texels are stored as the file encodes them (sRGB or linear), 4 bytes each; [`Texture::texel`]
//! decodes to linear. Mip levels are box-filtered in linear space, so sRGB textures keep their
//! brightness when minified.

use std::path::Path;

use glam::{Vec2, Vec4};
use pathlight_core::color::{linear_to_srgb8, srgb8_to_linear};
use rayon::prelude::*;

use crate::error::{Result, SceneError};
use crate::material::{Sampler, Wrap};

/// How a texture's colour channels are encoded. Alpha is always linear.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ColorSpace {
    /// Base colour, emissive, specular colour, diffuse: sRGB-encoded (glTF 2.0 spec).
    Srgb,
    /// Data textures: metallic-roughness, normal, occlusion, transmission, thickness.
    Linear,
}

/// One level of a mip chain.
#[derive(Debug, Clone, PartialEq)]
pub struct MipLevel {
    pub width: u32,
    pub height: u32,
    /// Row-major, top row first, as in the image file.
    pub texels: Vec<[u8; 4]>,
}

/// A texture with its mip chain (level 0 is the full image; the last level is 1x1).
#[derive(Debug, Clone, PartialEq)]
pub struct Texture {
    pub name: String,
    pub color_space: ColorSpace,
    pub levels: Vec<MipLevel>,
}

impl Texture {
    /// Builds a texture and its mip chain from level-0 texels.
    ///
    /// # Panics
    /// If `texels.len() != width * height` or a dimension is 0 (callers check decoded images).
    pub fn new(
        name: impl Into<String>,
        width: u32,
        height: u32,
        texels: Vec<[u8; 4]>,
        color_space: ColorSpace,
    ) -> Self {
        assert!(width > 0 && height > 0 && texels.len() == width as usize * height as usize);
        let mut levels = vec![MipLevel {
            width,
            height,
            texels,
        }];
        while let Some(last) = levels.last().filter(|l| l.width > 1 || l.height > 1) {
            let next = downsample(last, color_space);
            levels.push(next);
        }
        Self {
            name: name.into(),
            color_space,
            levels,
        }
    }

    /// A 1x1 texture of one linear colour (fallbacks, tests).
    pub fn constant(name: impl Into<String>, linear: Vec4, color_space: ColorSpace) -> Self {
        Self::new(name, 1, 1, vec![encode(linear, color_space)], color_space)
    }

    pub fn width(&self) -> u32 {
        self.levels[0].width
    }

    pub fn height(&self) -> u32 {
        self.levels[0].height
    }

    /// The linear value of texel (x, y) of a mip level (coordinates clamped to the level).
    #[inline]
    pub fn texel(&self, level: usize, x: u32, y: u32) -> Vec4 {
        let l = &self.levels[level.min(self.levels.len() - 1)];
        let x = x.min(l.width - 1);
        let y = y.min(l.height - 1);
        decode(l.texels[(y * l.width + x) as usize], self.color_space)
    }

    /// Bilinear (or nearest) lookup at level 0, with the sampler's wrap modes. `uv` (0, 0) is the
    /// top-left corner of the image, as in glTF.
    pub fn sample(&self, uv: Vec2, sampler: &Sampler) -> Vec4 {
        let l = &self.levels[0];
        let (w, h) = (l.width as f32, l.height as f32);
        let (u, v) = (uv.x * w - 0.5, uv.y * h - 0.5);
        if !u.is_finite() || !v.is_finite() {
            return self.texel(0, 0, 0);
        }
        if sampler.nearest {
            let x = wrap_index(u.round() as i64, l.width, sampler.wrap_s);
            let y = wrap_index(v.round() as i64, l.height, sampler.wrap_t);
            return self.texel(0, x, y);
        }
        let (x0, y0) = (u.floor(), v.floor());
        let (fx, fy) = (u - x0, v - y0);
        let (x0, y0) = (x0 as i64, y0 as i64);
        let xs = [
            wrap_index(x0, l.width, sampler.wrap_s),
            wrap_index(x0 + 1, l.width, sampler.wrap_s),
        ];
        let ys = [
            wrap_index(y0, l.height, sampler.wrap_t),
            wrap_index(y0 + 1, l.height, sampler.wrap_t),
        ];
        let top = self
            .texel(0, xs[0], ys[0])
            .lerp(self.texel(0, xs[1], ys[0]), fx);
        let bottom = self
            .texel(0, xs[0], ys[1])
            .lerp(self.texel(0, xs[1], ys[1]), fx);
        top.lerp(bottom, fy)
    }

    /// The mean linear value over the whole texture (its 1x1 mip level).
    pub fn average(&self) -> Vec4 {
        self.texel(self.levels.len() - 1, 0, 0)
    }

    pub fn heap_bytes(&self) -> usize {
        self.levels.iter().map(|l| l.texels.len() * 4).sum()
    }
}

/// Maps an integer texel coordinate into [0, size) by a wrap mode.
#[inline]
pub fn wrap_index(i: i64, size: u32, wrap: Wrap) -> u32 {
    let n = size as i64;
    let i = match wrap {
        Wrap::Repeat => i.rem_euclid(n),
        Wrap::ClampToEdge => i.clamp(0, n - 1),
        Wrap::MirroredRepeat => {
            let m = i.rem_euclid(2 * n);
            if m < n {
                m
            } else {
                2 * n - 1 - m
            }
        }
    };
    i as u32
}

#[inline]
fn decode(t: [u8; 4], color_space: ColorSpace) -> Vec4 {
    let a = t[3] as f32 / 255.0;
    match color_space {
        ColorSpace::Srgb => Vec4::new(
            srgb8_to_linear(t[0]),
            srgb8_to_linear(t[1]),
            srgb8_to_linear(t[2]),
            a,
        ),
        ColorSpace::Linear => Vec4::new(t[0] as f32, t[1] as f32, t[2] as f32, t[3] as f32) / 255.0,
    }
}

#[inline]
fn encode(v: Vec4, color_space: ColorSpace) -> [u8; 4] {
    let lin = |c: f32| (c.clamp(0.0, 1.0) * 255.0 + 0.5) as u8;
    match color_space {
        ColorSpace::Srgb => [
            linear_to_srgb8(v.x),
            linear_to_srgb8(v.y),
            linear_to_srgb8(v.z),
            lin(v.w),
        ],
        ColorSpace::Linear => [lin(v.x), lin(v.y), lin(v.z), lin(v.w)],
    }
}

/// Halves a level with a 2x2 box filter in linear space (odd edges repeat their last texel).
fn downsample(src: &MipLevel, color_space: ColorSpace) -> MipLevel {
    let width = (src.width / 2).max(1);
    let height = (src.height / 2).max(1);
    let mut texels = vec![[0u8; 4]; width as usize * height as usize];
    texels
        .par_chunks_mut(width as usize)
        .enumerate()
        .for_each(|(y, row)| {
            let y0 = (2 * y as u32).min(src.height - 1);
            let y1 = (2 * y as u32 + 1).min(src.height - 1);
            for (x, out) in row.iter_mut().enumerate() {
                let x0 = (2 * x as u32).min(src.width - 1);
                let x1 = (2 * x as u32 + 1).min(src.width - 1);
                let at =
                    |x: u32, y: u32| decode(src.texels[(y * src.width + x) as usize], color_space);
                let sum = at(x0, y0) + at(x1, y0) + at(x0, y1) + at(x1, y1);
                *out = encode(sum * 0.25, color_space);
            }
        });
    MipLevel {
        width,
        height,
        texels,
    }
}

/// The format and the size (width, height) that a PNG or JPEG image declares in its header,
/// read without decoding any pixel.
pub fn image_header(bytes: &[u8], file: &Path) -> Result<(image::ImageFormat, u32, u32)> {
    use image::{ImageFormat, ImageReader};
    let fail = |what: String| SceneError::new(file, what);
    let format =
        image::guess_format(bytes).map_err(|_| fail("is not a PNG or JPEG image".into()))?;
    if !matches!(format, ImageFormat::Png | ImageFormat::Jpeg) {
        return Err(fail(format!(
            "is a {format:?} image; textures must be PNG or JPEG"
        )));
    }
    let (w, h) = ImageReader::with_format(std::io::Cursor::new(bytes), format)
        .into_dimensions()
        .map_err(|e| fail(format!("is not a valid image: {e}")))?;
    Ok((format, w, h))
}

/// Decodes a PNG or JPEG image to 8-bit RGBA, refusing images over `max_pixels` before any
/// pixel memory is allocated. `file` names the image (or the scene file holding it) in errors.
pub fn decode_image(
    bytes: &[u8],
    file: &Path,
    max_pixels: u64,
) -> Result<(u32, u32, Vec<[u8; 4]>)> {
    use image::ImageReader;
    let fail = |what: String| SceneError::new(file, what);
    let (format, w, h) = image_header(bytes, file)?;
    let reader = || ImageReader::with_format(std::io::Cursor::new(bytes), format);
    check_pixels(file, w, h, max_pixels)?;
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(w);
    limits.max_image_height = Some(h);
    // Room for the decoded image at 16 bits per channel plus the RGBA8 copy.
    limits.max_alloc = Some((w as u64 * h as u64 * 16).max(1 << 20));
    let mut r = reader();
    r.limits(limits);
    let img = r
        .decode()
        .map_err(|e| fail(format!("cannot decode the image: {e}")))?;
    let rgba = img.into_rgba8();
    // The decoded size, not the header's: `Texture::new` asserts they match the texel count.
    let (w, h) = rgba.dimensions();
    let texels = rgba
        .as_raw()
        .chunks_exact(4)
        .map(|c| [c[0], c[1], c[2], c[3]])
        .collect();
    Ok((w, h, texels))
}

/// Refuses an image of zero size or with more than `max_pixels` pixels.
pub fn check_pixels(file: &Path, width: u32, height: u32, max_pixels: u64) -> Result<()> {
    let pixels = width as u64 * height as u64;
    if pixels == 0 {
        return Err(SceneError::new(
            file,
            format!("the image is empty ({width}x{height})"),
        ));
    }
    if pixels > max_pixels {
        return Err(SceneError::new(
            file,
            format!(
                "the image is {width}x{height} = {pixels} pixels, over the limit of {max_pixels}"
            ),
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mip_chain_ends_at_one_texel_and_keeps_linear_mean() {
        // A 4x2 sRGB checker of black and white: the mean in linear space is 0.5, which is
        // sRGB code 188, not the naive 128.
        let b = [0, 0, 0, 255];
        let w = [255, 255, 255, 255];
        let t = Texture::new("c", 4, 2, vec![b, w, b, w, w, b, w, b], ColorSpace::Srgb);
        assert_eq!(t.levels.len(), 3);
        assert_eq!((t.levels[2].width, t.levels[2].height), (1, 1));
        assert_eq!(t.levels[2].texels[0], [188, 188, 188, 255]);
        assert!((t.average().x - 0.5).abs() < 0.003);
        let l = Texture::new("c", 4, 2, vec![b, w, b, w, w, b, w, b], ColorSpace::Linear);
        assert_eq!(l.levels[2].texels[0][0], 128);
    }

    #[test]
    fn odd_sizes_downsample_to_one() {
        let t = Texture::new("o", 5, 3, vec![[10, 20, 30, 40]; 15], ColorSpace::Linear);
        let sizes: Vec<_> = t.levels.iter().map(|l| (l.width, l.height)).collect();
        assert_eq!(sizes, vec![(5, 3), (2, 1), (1, 1)]);
        assert_eq!(t.levels[2].texels[0], [10, 20, 30, 40]);
    }

    #[test]
    fn wrap_modes() {
        assert_eq!(wrap_index(-1, 4, Wrap::Repeat), 3);
        assert_eq!(wrap_index(5, 4, Wrap::Repeat), 1);
        assert_eq!(wrap_index(-1, 4, Wrap::ClampToEdge), 0);
        assert_eq!(wrap_index(9, 4, Wrap::ClampToEdge), 3);
        assert_eq!(wrap_index(4, 4, Wrap::MirroredRepeat), 3);
        assert_eq!(wrap_index(-1, 4, Wrap::MirroredRepeat), 0);
        assert_eq!(wrap_index(8, 4, Wrap::MirroredRepeat), 0);
    }

    #[test]
    fn bilinear_sample_between_texels() {
        let t = Texture::new(
            "g",
            2,
            1,
            vec![[0, 0, 0, 255], [255, 255, 255, 255]],
            ColorSpace::Linear,
        );
        let s = Sampler {
            wrap_s: Wrap::ClampToEdge,
            ..Sampler::default()
        };
        assert!((t.sample(Vec2::new(0.5, 0.5), &s).x - 0.5).abs() < 1e-6);
        assert_eq!(t.sample(Vec2::new(0.25, 0.5), &s).x, 0.0);
        assert_eq!(t.sample(Vec2::new(f32::NAN, 0.5), &s).x, 0.0);
    }

    #[test]
    fn images_over_the_pixel_limit_are_refused_before_decoding() {
        let mut png = Vec::new();
        image::RgbaImage::from_pixel(64, 64, image::Rgba([1, 2, 3, 4]))
            .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
            .unwrap();
        let (w, h, px) = decode_image(&png, Path::new("t.png"), 4096).unwrap();
        assert_eq!((w, h, px[0]), (64, 64, [1, 2, 3, 4]));
        let err = decode_image(&png, Path::new("t.png"), 4095).unwrap_err();
        assert!(err.problem.contains("over the limit"), "{err}");
        let err = decode_image(&png[..100], Path::new("t.png"), 4096).unwrap_err();
        assert!(err.to_string().starts_with("t.png: "), "{err}");
        let err = decode_image(b"not an image", Path::new("t.png"), 4096).unwrap_err();
        assert!(err.problem.contains("not a PNG or JPEG"), "{err}");
    }
}
