//! Partial renders: the statistics of sample indices `[start, end)` of every pixel of one
//! render (`pathlight render --samples A..B`), and their exact merging (`pathlight merge`).
//! The sampler is indexed by (seed, pixel, sample index), so ranges are independent: the
//! parts of any split of `0..spp`, merged, are the whole render to float rounding.
//!
//! File format (version 1), little-endian: the magic `PLPART01`; a u64 length; that many bytes
//! of JSON ([`PartHeader`]: `format` (1), `settings` (a hash of `render`, hex), `render` (the
//! whole render's [`Header`]: configuration with the total `spp`, scene identity, size), `start`
//! and `end`); then `width * height` pixels of [`crate::film::PIXEL_FLOATS`] (23) f32 each (sample count as the
//! bits of a u32, mean and M2 of radiance, direct, indirect, albedo, normal, depth: see
//! [`crate::film::Pixel::to_array`]). Every pixel of a part holds exactly `end - start`
//! samples.

use std::path::{Path, PathBuf};

use pathlight_core::rng::hash;
use serde::{Deserialize, Serialize};

use crate::checkpoint::{invalid, load_as, save_as, CheckpointError, Header};
use crate::film::Film;

const MAGIC: &[u8; 8] = b"PLPART01";
/// The format version this build writes and reads.
pub const FORMAT: u32 = 1;

/// What a partial render belongs to and which samples it holds.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PartHeader {
    pub format: u32,
    /// [`settings_hash`] of `render`, hex: parts of one render share it.
    pub settings: String,
    /// The whole render: its configuration (`spp` the total), scene and size.
    pub render: Header,
    pub start: u32,
    pub end: u32,
}

/// The hash of a render's settings (its header without the sample range), as 16 hex digits.
pub fn settings_hash(render: &Header) -> String {
    let whole = Header {
        samples: None,
        ..render.clone()
    };
    let json = serde_json::to_vec(&whole).expect("a header serialises");
    let words: Vec<u64> = json
        .chunks(8)
        .map(|c| {
            let mut b = [0u8; 8];
            b[..c.len()].copy_from_slice(c);
            u64::from_le_bytes(b)
        })
        .chain([json.len() as u64])
        .collect();
    format!("{:016x}", hash(&words))
}

impl PartHeader {
    /// The header of samples `[start, end)` of `render`.
    pub fn new(render: &Header, start: u32, end: u32) -> Self {
        Self {
            format: FORMAT,
            settings: settings_hash(render),
            render: Header {
                samples: None,
                ..render.clone()
            },
            start,
            end,
        }
    }
}

/// Writes a partial render atomically.
pub fn save(path: &Path, header: &PartHeader, film: &Film) -> Result<(), CheckpointError> {
    save_as(path, MAGIC, header, film)
}

/// Reads a partial render and checks it on its own: format version, settings hash, range,
/// size, and that every pixel holds the range's samples.
pub fn load(path: &Path) -> Result<(PartHeader, Film), CheckpointError> {
    let (header, film): (PartHeader, Film) = load_as(
        path,
        MAGIC,
        "a pathlight partial render (.part)",
        |h: &PartHeader| (h.render.width, h.render.height),
    )?;
    if header.format != FORMAT {
        return Err(invalid(
            path,
            format!(
                "format version {} (this build reads {FORMAT})",
                header.format
            ),
        ));
    }
    if header.settings != settings_hash(&header.render) {
        return Err(invalid(
            path,
            "corrupt header: its settings hash does not match its settings",
        ));
    }
    if !(header.start < header.end && header.end <= header.render.config.spp) {
        return Err(invalid(
            path,
            format!(
                "sample range {}..{} is not inside 0..{}",
                header.start, header.end, header.render.config.spp
            ),
        ));
    }
    let count = header.end - header.start;
    if let Some(i) = film.pixels.iter().position(|p| p.n != count) {
        return Err(invalid(
            path,
            format!(
                "incomplete or corrupt: pixel {i} holds {} samples where the range {}..{} has {count}",
                film.pixels[i].n, header.start, header.end
            ),
        ));
    }
    Ok((header, film))
}

/// The largest JSON header a part may have (a guard against a corrupt length).
const MAX_HEADER: u64 = 1 << 20;

/// Reads only the header of a partial render (the pixels are checked by [`load`]).
pub fn load_header(path: &Path) -> Result<PartHeader, CheckpointError> {
    use std::io::Read;
    let mut file = std::fs::File::open(path).map_err(|e| invalid(path, e))?;
    let mut start = [0u8; 16];
    file.read_exact(&mut start)
        .map_err(|_| invalid(path, "not a pathlight partial render (.part)"))?;
    if &start[..8] != MAGIC {
        return Err(invalid(path, "not a pathlight partial render (.part)"));
    }
    let len = u64::from_le_bytes(start[8..].try_into().unwrap());
    if len > MAX_HEADER {
        return Err(invalid(path, format!("corrupt header length {len}")));
    }
    let mut json = vec![0u8; len as usize];
    file.read_exact(&mut json)
        .map_err(|_| invalid(path, "truncated header"))?;
    serde_json::from_slice(&json).map_err(|e| invalid(path, e))
}

/// Merges the partial renders in `paths` (any order): they must share one render's settings
/// and cover its `0..spp` exactly once (checked from their headers before any pixel is read),
/// and each must be whole ([`load`]). Holds two films at a time, whatever the number of
/// parts. Returns the render's header and its film.
pub fn merge(paths: &[PathBuf]) -> Result<(Header, Film), CheckpointError> {
    let Some(first_path) = paths.first() else {
        return Err(invalid(Path::new("merge"), "no parts to merge"));
    };
    let headers = paths
        .iter()
        .map(|p| load_header(p))
        .collect::<Result<Vec<_>, _>>()?;
    let first = &headers[0];
    for (path, h) in paths.iter().zip(&headers) {
        if h.settings != first.settings || h.render != first.render {
            return Err(invalid(
                path,
                format!(
                    "belongs to another render than {} (settings {} against {})",
                    first_path.display(),
                    h.settings,
                    first.settings
                ),
            ));
        }
    }
    let mut order: Vec<usize> = (0..paths.len()).collect();
    order.sort_by_key(|&i| (headers[i].start, headers[i].end));
    let mut covered = 0;
    let mut previous: Option<&Path> = None;
    for &i in &order {
        let (path, h) = (&paths[i], &headers[i]);
        if h.start > covered {
            return Err(invalid(
                path,
                format!(
                    "samples {covered}..{} are missing before its range {}..{}",
                    h.start, h.start, h.end
                ),
            ));
        }
        if h.start < covered {
            return Err(invalid(
                path,
                format!(
                    "its range {}..{} overlaps {} (which ends at {covered})",
                    h.start,
                    h.end,
                    previous.map_or("another part".into(), |p| p.display().to_string())
                ),
            ));
        }
        covered = h.end;
        previous = Some(path);
    }
    let spp = first.render.config.spp;
    if covered != spp {
        return Err(invalid(
            &paths[*order.last().unwrap()],
            format!("samples {covered}..{spp} are missing after it (the render has {spp})"),
        ));
    }
    let mut film = Film::new(first.render.width, first.render.height);
    for &i in &order {
        let (header, part) = load(&paths[i])?;
        if header != headers[i] {
            return Err(invalid(&paths[i], "changed while it was being merged"));
        }
        for (p, q) in film.pixels.iter_mut().zip(&part.pixels) {
            p.merge(q);
        }
    }
    Ok((first.render.clone(), film))
}
