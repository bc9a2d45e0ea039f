//! Checkpoints of a long render: the film's per-pixel statistics with the configuration and the
//! scene they belong to, written atomically, so a stopped render resumes where it stopped.
//!
//! Layout: the magic `PLCKPT01`, a little-endian u64 length, that many bytes of JSON
//! ([`Header`]), then `width * height * PIXEL_FLOATS` little-endian f32.

use std::path::{Path, PathBuf};

use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};

use crate::config::Config;
use crate::film::{Film, Pixel, PIXEL_FLOATS};
use crate::output::write_atomic;

const MAGIC: &[u8; 8] = b"PLCKPT01";

#[derive(Debug, thiserror::Error)]
pub enum CheckpointError {
    #[error("{file}: {problem}")]
    Invalid { file: PathBuf, problem: String },
}

pub(crate) fn invalid(file: &Path, problem: impl ToString) -> CheckpointError {
    CheckpointError::Invalid {
        file: file.to_owned(),
        problem: problem.to_string(),
    }
}

/// What a checkpoint belongs to.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Header {
    /// The configuration of the render (its `spp` is the target; the film says what is done).
    pub config: Config,
    /// Identifies the scene (name, counts, file): resuming with another scene is refused.
    pub scene: String,
    pub width: u32,
    pub height: u32,
    /// A render of sample indices `[start, end)` only (`render --samples`), whose output is a
    /// partial render ([`crate::part`]); `None`: the whole `0..spp`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub samples: Option<[u32; 2]>,
}

impl Header {
    /// True when a render with `other` may continue this checkpoint: everything but the sample
    /// count must match.
    pub fn compatible(&self, other: &Header) -> bool {
        let strip = |h: &Header| Header {
            config: Config {
                spp: 0,
                display: Default::default(),
                ..h.config.clone()
            },
            ..h.clone()
        };
        strip(self) == strip(other)
    }
}

/// Writes `film` with `header` to `path` atomically.
pub fn save(path: &Path, header: &Header, film: &Film) -> Result<(), CheckpointError> {
    save_as(path, MAGIC, header, film)
}

/// Reads a checkpoint, checking its size against its own header.
pub fn load(path: &Path) -> Result<(Header, Film), CheckpointError> {
    load_as(path, MAGIC, "a pathlight checkpoint", |h: &Header| {
        (h.width, h.height)
    })
}

/// The file layout of checkpoints and partial renders: `magic`, a little-endian u64 length,
/// that many bytes of JSON (`header`), then the film's pixels as [`PIXEL_FLOATS`]
/// little-endian f32 each. Written atomically.
pub(crate) fn save_as<H: Serialize>(
    path: &Path,
    magic: &[u8; 8],
    header: &H,
    film: &Film,
) -> Result<(), CheckpointError> {
    let json = serde_json::to_vec(header).map_err(|e| invalid(path, e))?;
    let mut bytes = Vec::with_capacity(16 + json.len() + film.pixels.len() * PIXEL_FLOATS * 4);
    bytes.extend_from_slice(magic);
    bytes.extend_from_slice(&(json.len() as u64).to_le_bytes());
    bytes.extend_from_slice(&json);
    for p in &film.pixels {
        for v in p.to_array() {
            bytes.extend_from_slice(&v.to_le_bytes());
        }
    }
    write_atomic(path, &bytes).map_err(|e| invalid(path, e))
}

/// Reads a file written by [`save_as`] with `magic` (`what` names the kind in errors), its
/// size checked against the dimensions `dims` finds in its header.
pub(crate) fn load_as<H: DeserializeOwned>(
    path: &Path,
    magic: &[u8; 8],
    what: &str,
    dims: impl Fn(&H) -> (u32, u32),
) -> Result<(H, Film), CheckpointError> {
    let bytes = std::fs::read(path).map_err(|e| invalid(path, e))?;
    if bytes.len() < 16 || &bytes[..8] != magic {
        return Err(invalid(path, format!("not {what}")));
    }
    let len = u64::from_le_bytes(bytes[8..16].try_into().unwrap());
    let json_end = 16u64
        .checked_add(len)
        .filter(|&e| e <= bytes.len() as u64)
        .ok_or_else(|| invalid(path, "truncated header"))? as usize;
    let header: H = serde_json::from_slice(&bytes[16..json_end]).map_err(|e| invalid(path, e))?;
    let (width, height) = dims(&header);
    let pixels = width as u64 * height as u64;
    let expected = pixels * (PIXEL_FLOATS as u64 * 4);
    if (bytes.len() - json_end) as u64 != expected {
        return Err(invalid(
            path,
            format!(
                "expected {expected} bytes of pixel data for {width}x{height}, found {}",
                bytes.len() - json_end
            ),
        ));
    }
    let mut film = Film::new(width, height);
    for (p, chunk) in film
        .pixels
        .iter_mut()
        .zip(bytes[json_end..].chunks_exact(PIXEL_FLOATS * 4))
    {
        let mut a = [0f32; PIXEL_FLOATS];
        for (v, b) in a.iter_mut().zip(chunk.chunks_exact(4)) {
            *v = f32::from_le_bytes(b.try_into().unwrap());
        }
        *p = Pixel::from_array(&a);
    }
    Ok((header, film))
}
