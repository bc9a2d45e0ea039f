//! Where a scene's files come from: a folder on disk that the scene may not leave, or memory.
//!
//! Every URI or path found inside a scene file is resolved here. Absolute paths, URL schemes and
//! paths that escape the scene's folder (by `..` or by a symbolic link) are refused.

use std::collections::HashMap;
use std::io::Read;
use std::path::{Component, Path, PathBuf};

use crate::error::{Result, SceneError};

/// The files a scene may read, relative to the folder of its main file.
#[derive(Debug, Clone)]
pub enum SceneSource {
    /// A folder on disk: the canonical path of the folder holding the main scene file.
    Folder(PathBuf),
    /// Files held in memory (the built-in scenes and tests), by relative name.
    Memory(HashMap<String, Vec<u8>>),
}

impl SceneSource {
    /// The source for the folder that holds `scene_file`.
    pub fn for_file(scene_file: &Path) -> Result<Self> {
        let dir = scene_file
            .parent()
            .filter(|p| !p.as_os_str().is_empty())
            .unwrap_or(Path::new("."));
        let dir = dir.canonicalize().map_err(|e| {
            SceneError::new(scene_file, format!("cannot open the scene's folder: {e}"))
        })?;
        Ok(Self::Folder(dir))
    }

    /// Resolves a relative reference (already percent-decoded) found in `referrer`, refusing
    /// anything that would leave the scene's folder. Returns the path to show in messages and
    /// the path to open.
    pub fn resolve(&self, referrer: &Path, reference: &str) -> Result<PathBuf> {
        let refuse = |why: &str| {
            Err(SceneError::new(
                referrer,
                format!(
                    "refused the reference \"{}\": {why}",
                    reference.escape_debug()
                ),
            ))
        };
        if reference.is_empty() {
            return refuse("it is empty");
        }
        if reference.contains('\0') {
            return refuse("it contains a NUL character");
        }
        if has_scheme(reference) {
            return refuse("only relative paths inside the scene's folder are allowed, not URLs");
        }
        let normalised = reference.replace('\\', "/");
        let path = Path::new(&normalised);
        if path.is_absolute() || normalised.starts_with('/') {
            return refuse("absolute paths are not allowed; use a path relative to the scene file");
        }
        // Resolve `.` and `..` lexically; going above the folder is an escape.
        let mut clean = PathBuf::new();
        for component in path.components() {
            match component {
                Component::Normal(part) => clean.push(part),
                Component::CurDir => {}
                Component::ParentDir => {
                    if !clean.pop() {
                        return refuse("it leads outside the scene's folder");
                    }
                }
                Component::RootDir | Component::Prefix(_) => {
                    return refuse("absolute paths are not allowed")
                }
            }
        }
        if clean.as_os_str().is_empty() {
            return refuse("it names the scene's folder itself, not a file");
        }
        match self {
            Self::Folder(dir) => Ok(dir.join(clean)),
            Self::Memory(_) => Ok(clean),
        }
    }

    /// Reads a whole file found by [`resolve`](Self::resolve), refusing files larger than
    /// `max_bytes` and files that symbolic links place outside the scene's folder.
    pub fn read(&self, path: &Path, max_bytes: u64) -> Result<Vec<u8>> {
        match self {
            Self::Memory(files) => {
                let key = path.to_string_lossy().replace('\\', "/");
                files
                    .get(&key)
                    .cloned()
                    .ok_or_else(|| SceneError::new(path, "no such file"))
            }
            Self::Folder(dir) => {
                let real = path
                    .canonicalize()
                    .map_err(|e| SceneError::new(path, format!("cannot open: {e}")))?;
                if !real.starts_with(dir) {
                    return Err(SceneError::new(
                        path,
                        "refused: a symbolic link leads outside the scene's folder",
                    ));
                }
                read_file_limited(&real, max_bytes).map_err(|e| SceneError::new(path, e.problem))
            }
        }
    }
}

/// Reads a file from disk, refusing it if it holds more than `max_bytes` bytes.
pub fn read_file_limited(path: &Path, max_bytes: u64) -> Result<Vec<u8>> {
    let file = std::fs::File::open(path)
        .map_err(|e| SceneError::new(path, format!("cannot open: {e}")))?;
    let meta = file
        .metadata()
        .map_err(|e| SceneError::new(path, format!("cannot read: {e}")))?;
    if meta.is_dir() {
        return Err(SceneError::new(path, "is a folder, not a file"));
    }
    if meta.len() > max_bytes {
        return Err(SceneError::new(
            path,
            format!(
                "is {} bytes, over the limit of {max_bytes} bytes",
                meta.len()
            ),
        ));
    }
    let mut bytes = Vec::with_capacity(meta.len() as usize);
    // `take` bounds the read even if the file grows while we read it.
    file.take(max_bytes + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| SceneError::new(path, format!("cannot read: {e}")))?;
    if bytes.len() as u64 > max_bytes {
        return Err(SceneError::new(
            path,
            format!("is over the limit of {max_bytes} bytes"),
        ));
    }
    Ok(bytes)
}

/// True when `s` starts with a URL scheme (`http:`, `file:`, `data:`) or a Windows drive (`C:`).
fn has_scheme(s: &str) -> bool {
    match s.find(':') {
        Some(i) => {
            let scheme = &s[..i];
            !scheme.is_empty()
                && scheme
                    .chars()
                    .next()
                    .is_some_and(|c| c.is_ascii_alphabetic())
                && scheme
                    .chars()
                    .all(|c| c.is_ascii_alphanumeric() || matches!(c, '+' | '-' | '.'))
        }
        None => false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn folder() -> SceneSource {
        SceneSource::Folder(PathBuf::from("/scenes/box"))
    }

    #[test]
    fn relative_paths_resolve_inside_the_folder() {
        let s = folder();
        let r = Path::new("scene.gltf");
        assert_eq!(
            s.resolve(r, "a/b.bin").unwrap(),
            Path::new("/scenes/box/a/b.bin")
        );
        assert_eq!(
            s.resolve(r, "a/../b.bin").unwrap(),
            Path::new("/scenes/box/b.bin")
        );
        assert_eq!(
            s.resolve(r, "./tex\\x.png").unwrap(),
            Path::new("/scenes/box/tex/x.png")
        );
    }

    #[test]
    fn escapes_and_absolute_paths_are_refused() {
        let s = folder();
        let r = Path::new("scene.gltf");
        for bad in [
            "../secret.bin",
            "a/../../secret.bin",
            "/etc/passwd",
            "\\\\server\\share\\x.bin",
            "C:\\Windows\\x.bin",
            "c:/x.bin",
            "file:///etc/passwd",
            "http://example.com/x.bin",
            "",
            ".",
            "a\0b",
        ] {
            let err = s.resolve(r, bad).unwrap_err();
            assert!(err.problem.starts_with("refused"), "{bad:?}: {err}");
            assert_eq!(err.file, r);
        }
    }
}
