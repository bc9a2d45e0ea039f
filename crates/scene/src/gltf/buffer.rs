//! Buffers and buffer views: the binary data of a glTF file, loaded with every length checked.

use std::path::{Path, PathBuf};

use ::gltf::json;
use base64::Engine;

use crate::error::{Result, SceneError};
use crate::limits::Limits;
use crate::source::SceneSource;

/// The decoded bytes of every buffer of a document.
pub struct Buffers {
    pub data: Vec<Vec<u8>>,
}

/// Decodes a `data:` URI with base64 payload. Returns `None` when `uri` is not a data URI.
pub fn decode_data_uri(uri: &str, file: &Path) -> Option<Result<Vec<u8>>> {
    let rest = uri.strip_prefix("data:")?;
    let Some((header, payload)) = rest.split_once(',') else {
        return Some(Err(SceneError::new(
            file,
            "a data URI has no ',' before its data",
        )));
    };
    if !header.ends_with(";base64") {
        return Some(Err(SceneError::new(
            file,
            format!(
                "data URI \"{}\" is not base64-encoded",
                header.escape_debug()
            ),
        )));
    }
    Some(
        base64::engine::general_purpose::STANDARD
            .decode(payload.trim_end())
            .map_err(|e| SceneError::new(file, format!("a data URI has invalid base64: {e}"))),
    )
}

/// Resolves a URI of the document (percent-decoded) to a path inside the scene's folder.
pub fn resolve_uri(source: &SceneSource, file: &Path, uri: &str) -> Result<PathBuf> {
    let decoded = percent_encoding::percent_decode_str(uri)
        .decode_utf8()
        .map_err(|_| {
            SceneError::new(
                file,
                format!(
                    "URI \"{}\" is not valid UTF-8 once decoded",
                    uri.escape_debug()
                ),
            )
        })?;
    source.resolve(file, &decoded)
}

impl Buffers {
    /// Loads every buffer: the GLB's BIN chunk, data URIs, or files beside the scene.
    pub fn load(
        root: &json::Root,
        bin: Option<&[u8]>,
        source: &SceneSource,
        file: &Path,
        limits: &Limits,
    ) -> Result<Self> {
        let mut data = Vec::with_capacity(root.buffers.len());
        for (i, buffer) in root.buffers.iter().enumerate() {
            let declared = buffer.byte_length.0;
            let (bytes, from) = match &buffer.uri {
                None => match bin {
                    Some(bin) if i == 0 => (bin.to_vec(), file.to_path_buf()),
                    _ => {
                        return Err(SceneError::new(
                            file,
                            format!(
                                "buffer {i} has no URI and there is no GLB binary chunk for it"
                            ),
                        ))
                    }
                },
                Some(uri) => match decode_data_uri(uri, file) {
                    Some(bytes) => (bytes?, file.to_path_buf()),
                    None => {
                        let path = resolve_uri(source, file, uri)?;
                        (source.read(&path, limits.max_file_bytes)?, path)
                    }
                },
            };
            if (bytes.len() as u64) < declared {
                return Err(SceneError::new(
                    from,
                    format!(
                        "buffer {i} declares {declared} bytes but has only {} (truncated or short file)",
                        bytes.len()
                    ),
                ));
            }
            data.push(bytes);
        }
        Ok(Self { data })
    }

    /// The bytes of buffer view `index`, checked to lie inside its buffer.
    pub fn view(&self, root: &json::Root, index: usize, file: &Path) -> Result<&[u8]> {
        let view = root
            .buffer_views
            .get(index)
            .ok_or_else(|| SceneError::new(file, format!("bufferView {index} does not exist")))?;
        let buffer = view.buffer.value();
        let bytes = self.data.get(buffer).ok_or_else(|| {
            SceneError::new(
                file,
                format!("bufferView {index} names buffer {buffer}, which does not exist"),
            )
        })?;
        let offset = view.byte_offset.map_or(0, |o| o.0);
        let length = view.byte_length.0;
        let end = offset.saturating_add(length);
        if end > bytes.len() as u64 {
            return Err(SceneError::new(
                file,
                format!(
                    "bufferView {index} (bytes {offset}..{end}) lies outside buffer {buffer} ({} bytes)",
                    bytes.len()
                ),
            ));
        }
        Ok(&bytes[offset as usize..end as usize])
    }
}
