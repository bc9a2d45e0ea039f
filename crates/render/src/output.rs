//! Writing images: tone-mapped sRGB PNG, linear HDR OpenEXR (with the AOV layers), always
//! atomically (a temporary file in the same folder, renamed over the target).

use std::io::{Cursor, Write};
use std::path::{Path, PathBuf};

use glam::Vec3;
use image::ImageEncoder;
use pathlight_core::color::linear_to_srgb8;

use crate::film::Film;
use crate::frame::display::{tonemap, DisplayConfig};

#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    #[error("{file}: {problem}")]
    Write { file: PathBuf, problem: String },
}

fn error(file: &Path, problem: impl ToString) -> OutputError {
    OutputError::Write {
        file: file.to_owned(),
        problem: problem.to_string(),
    }
}

/// Writes `bytes` to `path` atomically: a temporary file beside it, flushed and synced, then
/// renamed over `path`. A reader never sees a half-written file.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), OutputError> {
    let dir = path.parent().filter(|d| !d.as_os_str().is_empty());
    let name = path
        .file_name()
        .ok_or_else(|| error(path, "not a file name"))?;
    let mut tmp_name = std::ffi::OsString::from(".");
    tmp_name.push(name);
    tmp_name.push(format!(".tmp-{}", std::process::id()));
    let tmp = dir.map_or_else(|| PathBuf::from(&tmp_name), |d| d.join(&tmp_name));
    let result = (|| {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    result.map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        error(path, e)
    })
}

/// The image format chosen by the file extension.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    Png,
    Exr,
}

impl Format {
    pub fn from_path(path: &Path) -> Result<Self, OutputError> {
        match path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase)
            .as_deref()
        {
            Some("png") => Ok(Self::Png),
            Some("exr") => Ok(Self::Exr),
            _ => Err(error(path, "unknown image format: use .png or .exr")),
        }
    }
}

/// Encodes linear RGB as an 8-bit sRGB PNG after the display's exposure and tone mapping
/// (non-finite values as black).
pub fn encode_png(width: u32, height: u32, rgb: &[Vec3], display: &DisplayConfig) -> Vec<u8> {
    let bytes: Vec<u8> = rgb
        .iter()
        .flat_map(|c| {
            tonemap(*c * display.exposure, display.tonemap)
                .to_array()
                .map(linear_to_srgb8)
        })
        .collect();
    encode_rgb8_png(width, height, &bytes)
}

/// Writes linear RGB to `path`: .png tone-mapped and sRGB-encoded as `display` says, .exr as
/// linear 32-bit float RGB; atomically.
pub fn write_rgb(
    path: &Path,
    width: u32,
    height: u32,
    rgb: &[Vec3],
    display: &DisplayConfig,
) -> Result<(), OutputError> {
    let bytes = match Format::from_path(path)? {
        Format::Png => encode_png(width, height, rgb, display),
        Format::Exr => {
            let mut ch = Channels::new(width, height);
            ch.add_rgb("", ["R", "G", "B"], rgb);
            ch.encode_exr().map_err(|e| error(path, e))?
        }
    };
    write_atomic(path, &bytes)
}

/// Encodes 8-bit RGBA (row-major, 4 bytes per pixel) as a PNG.
pub fn encode_rgba8_png(width: u32, height: u32, rgba8: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    image::codecs::png::PngEncoder::new(&mut out)
        .write_image(rgba8, width, height, image::ExtendedColorType::Rgba8)
        .expect("encoding a PNG into memory cannot fail");
    out
}

/// Encodes 8-bit RGB (row-major, 3 bytes per pixel) as a PNG.
pub fn encode_rgb8_png(width: u32, height: u32, rgb8: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    image::codecs::png::PngEncoder::new(&mut out)
        .write_image(rgb8, width, height, image::ExtendedColorType::Rgb8)
        .expect("encoding a PNG into memory cannot fail");
    out
}

/// Named float channels of one image.
pub struct Channels {
    pub width: u32,
    pub height: u32,
    pub channels: Vec<(String, Vec<f32>)>,
}

impl Channels {
    pub fn new(width: u32, height: u32) -> Self {
        Self {
            width,
            height,
            channels: Vec::new(),
        }
    }

    /// Adds a three-channel layer: `prefix` "" gives R, G, B; "albedo" gives albedo.R, ...
    pub fn add_rgb(&mut self, prefix: &str, names: [&str; 3], values: &[Vec3]) {
        for (c, name) in names.iter().enumerate() {
            let full = if prefix.is_empty() {
                (*name).to_owned()
            } else {
                format!("{prefix}.{name}")
            };
            self.channels
                .push((full, values.iter().map(|v| v[c]).collect()));
        }
    }

    pub fn add(&mut self, name: &str, values: Vec<f32>) {
        self.channels.push((name.to_owned(), values));
    }

    /// Encodes as a single-part OpenEXR with 32-bit float channels (ZIP compression).
    pub fn encode_exr(self) -> Result<Vec<u8>, String> {
        use exr::prelude::*;
        let list: SmallVec<[AnyChannel<FlatSamples>; 4]> = self
            .channels
            .into_iter()
            .map(|(name, v)| AnyChannel::new(name.as_str(), FlatSamples::F32(v)))
            .collect();
        let layer = Layer::new(
            (self.width as usize, self.height as usize),
            LayerAttributes::default(),
            Encoding::FAST_LOSSLESS,
            AnyChannels::sort(list),
        );
        let mut out = Cursor::new(Vec::new());
        Image::from_layer(layer)
            .write()
            .to_buffered(&mut out)
            .map_err(|e| e.to_string())?;
        Ok(out.into_inner())
    }
}

/// Writes the film's mean radiance to `path` (.png: tone-mapped sRGB as `display` says; .exr:
/// linear RGB, plus with `aovs` the layers albedo, normal (X, Y, Z), depth (Z), direct,
/// indirect and variance (per-sample variance of radiance, n - 1 estimator) and spp).
pub fn write_film(
    path: &Path,
    film: &Film,
    aovs: bool,
    display: &DisplayConfig,
) -> Result<(), OutputError> {
    let bytes = match Format::from_path(path)? {
        Format::Png => encode_png(film.width, film.height, &film.layer(|p| p.mean), display),
        Format::Exr => {
            let mut ch = Channels::new(film.width, film.height);
            ch.add_rgb("", ["R", "G", "B"], &film.layer(|p| p.mean));
            if aovs {
                const RGB: [&str; 3] = ["R", "G", "B"];
                ch.add_rgb("albedo", RGB, &film.layer(|p| p.albedo));
                ch.add_rgb("normal", ["X", "Y", "Z"], &film.layer(|p| p.normal));
                ch.add("depth.Z", film.pixels.iter().map(|p| p.depth).collect());
                ch.add_rgb("direct", RGB, &film.layer(|p| p.direct));
                ch.add_rgb("indirect", RGB, &film.layer(|p| p.indirect));
                ch.add_rgb("variance", RGB, &film.layer(|p| p.variance()));
                ch.add("spp.Y", film.pixels.iter().map(|p| p.n as f32).collect());
            }
            ch.encode_exr().map_err(|e| error(path, e))?
        }
    };
    write_atomic(path, &bytes)
}

/// Reads the RGB channels of an OpenEXR file (for tests and comparisons).
pub fn read_exr_rgb(path: &Path) -> Result<(u32, u32, Vec<Vec3>), OutputError> {
    read_exr_layer(path, "")
}

/// Reads channels `prefix.R/G/B` (or R, G, B for an empty prefix; X, Y, Z as fallback) of an
/// OpenEXR file.
pub fn read_exr_layer(path: &Path, prefix: &str) -> Result<(u32, u32, Vec<Vec3>), OutputError> {
    use exr::prelude::*;
    let image = read_all_flat_layers_from_file(path).map_err(|e| error(path, e))?;
    let layer = image
        .layer_data
        .first()
        .ok_or_else(|| error(path, "no layers"))?;
    let (w, h) = (layer.size.width(), layer.size.height());
    let find = |names: [&str; 2]| {
        layer.channel_data.list.iter().find(|c| {
            let n = c.name.to_string();
            names.iter().any(|want| {
                let full = if prefix.is_empty() {
                    (*want).to_owned()
                } else {
                    format!("{prefix}.{want}")
                };
                n == full
            })
        })
    };
    let mut out = vec![Vec3::ZERO; w * h];
    for (c, names) in [["R", "X"], ["G", "Y"], ["B", "Z"]].into_iter().enumerate() {
        let ch =
            find(names).ok_or_else(|| error(path, format!("no channel {prefix} {names:?}")))?;
        for (i, v) in ch.sample_data.values_as_f32().enumerate().take(w * h) {
            out[i][c] = v;
        }
    }
    Ok((w as u32, h as u32, out))
}
