//! The binary glTF container (`.glb`): a 12-byte header, a JSON chunk, an optional BIN chunk.

use std::path::Path;

use crate::error::{Result, SceneError};

const MAGIC: u32 = 0x4654_6C67; // "glTF"
const CHUNK_JSON: u32 = 0x4E4F_534A; // "JSON"
const CHUNK_BIN: u32 = 0x004E_4942; // "BIN\0"

/// The chunks of a GLB file.
#[derive(Debug)]
pub struct Glb<'a> {
    pub json: &'a [u8],
    pub bin: Option<&'a [u8]>,
}

/// True when the bytes start with the GLB magic.
pub fn is_glb(bytes: &[u8]) -> bool {
    bytes.len() >= 4 && read_u32(bytes, 0) == Some(MAGIC)
}

fn read_u32(bytes: &[u8], at: usize) -> Option<u32> {
    let b = bytes.get(at..at.checked_add(4)?)?;
    Some(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
}

/// Splits a GLB file into its chunks, checking every length against the real data.
pub fn parse<'a>(bytes: &'a [u8], file: &Path) -> Result<Glb<'a>> {
    let bad = |what: String| SceneError::new(file, format!("invalid GLB: {what}"));
    if bytes.len() < 12 {
        return Err(bad(format!(
            "the file is {} bytes, shorter than the 12-byte header",
            bytes.len()
        )));
    }
    if read_u32(bytes, 0) != Some(MAGIC) {
        return Err(bad("it does not start with the magic \"glTF\"".into()));
    }
    let version = read_u32(bytes, 4).unwrap_or(0);
    if version != 2 {
        return Err(bad(format!(
            "version {version}; only glTF 2.0 is supported"
        )));
    }
    let declared = read_u32(bytes, 8).unwrap_or(0) as usize;
    if declared > bytes.len() {
        return Err(bad(format!(
            "the header declares {declared} bytes but the file has only {} (truncated?)",
            bytes.len()
        )));
    }
    if declared < 12 {
        return Err(bad(format!(
            "the header declares a length of {declared} bytes"
        )));
    }
    let body = &bytes[..declared];
    let mut at = 12usize;
    let mut json = None;
    let mut bin = None;
    let mut index = 0;
    while at < body.len() {
        let (Some(len), Some(kind)) = (read_u32(body, at), read_u32(body, at + 4)) else {
            return Err(bad(format!(
                "chunk {index} has a truncated header at byte {at}"
            )));
        };
        let start = at + 8;
        let end = start
            .checked_add(len as usize)
            .filter(|&e| e <= body.len())
            .ok_or_else(|| {
                bad(format!(
                    "chunk {index} declares {len} bytes at byte {start}, past the end of the file ({} bytes)",
                    body.len()
                ))
            })?;
        let data = &body[start..end];
        match (index, kind) {
            (0, CHUNK_JSON) => json = Some(data),
            (0, _) => {
                return Err(bad(format!(
                    "the first chunk has type 0x{kind:08x}, not JSON"
                )))
            }
            (_, CHUNK_JSON) => return Err(bad("a second JSON chunk".into())),
            (1, CHUNK_BIN) => bin = Some(data),
            _ => {} // Unknown chunks are ignored, as the specification requires.
        }
        // Chunks are 4-byte aligned; tolerate writers that forgot the padding of the last one.
        at = end.div_ceil(4) * 4;
        index += 1;
    }
    let json = json.ok_or_else(|| bad("no JSON chunk".into()))?;
    Ok(Glb { json, bin })
}

/// Writes a GLB file from a JSON document and an optional binary chunk (tests, tools).
pub fn write(json: &[u8], bin: Option<&[u8]>) -> Vec<u8> {
    let pad = |v: &[u8], fill: u8| {
        let mut v = v.to_vec();
        while v.len() & 3 != 0 {
            v.push(fill);
        }
        v
    };
    let json = pad(json, b' ');
    let mut out = Vec::new();
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&0u32.to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(&CHUNK_JSON.to_le_bytes());
    out.extend_from_slice(&json);
    if let Some(bin) = bin {
        let bin = pad(bin, 0);
        out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
        out.extend_from_slice(&CHUNK_BIN.to_le_bytes());
        out.extend_from_slice(&bin);
    }
    let n = out.len() as u32;
    out[8..12].copy_from_slice(&n.to_le_bytes());
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_chunks() {
        let f = write(b"{}", Some(&[1, 2, 3, 4]));
        let g = parse(&f, Path::new("a.glb")).unwrap();
        assert_eq!(g.json, b"{}  ");
        assert_eq!(g.bin, Some(&[1u8, 2, 3, 4][..]));
    }

    #[test]
    fn lying_headers_are_refused() {
        let f = write(b"{}", Some(&[1, 2, 3, 4]));
        // Truncated file.
        for cut in [0, 5, 11, 12, 20, f.len() - 1] {
            let e = parse(&f[..cut], Path::new("a.glb")).expect_err("refused");
            assert!(e.to_string().starts_with("a.glb: invalid GLB"), "{e}");
        }
        // Header length larger than the file, or absurd.
        let mut g = f.clone();
        g[8..12].copy_from_slice(&u32::MAX.to_le_bytes());
        assert!(parse(&g, Path::new("a.glb"))
            .unwrap_err()
            .problem
            .contains("declares"));
        // Chunk length past the end.
        let mut g = f.clone();
        g[12..16].copy_from_slice(&(u32::MAX - 3).to_le_bytes());
        assert!(parse(&g, Path::new("a.glb"))
            .unwrap_err()
            .problem
            .contains("chunk 0"));
        // Wrong version.
        let mut g = f.clone();
        g[4] = 1;
        assert!(parse(&g, Path::new("a.glb"))
            .unwrap_err()
            .problem
            .contains("version 1"));
        // BIN first.
        let mut g = f;
        g[16..20].copy_from_slice(&CHUNK_BIN.to_le_bytes());
        assert!(parse(&g, Path::new("a.glb"))
            .unwrap_err()
            .problem
            .contains("not JSON"));
    }
}
