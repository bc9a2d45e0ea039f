//! The shared scene pack (`../shared` beside the repository, or `$PATHLIGHT_SHARED`) as tests
//! and benchmarks find it.
//!
//! A test that needs a file of the pack skips with a note on a developer's machine without
//! it, but fails under CI (`CI` set), which always has the pack beside the clone: a missing
//! pack there is a broken set-up, not a test to skip.

use std::path::{Path, PathBuf};

/// The shared folder: `$PATHLIGHT_SHARED`, else `shared` beside the workspace of the crate
/// whose manifest folder is `manifest_dir` (a crate under `crates/`; pass
/// `env!("CARGO_MANIFEST_DIR")`).
pub fn dir(manifest_dir: &str) -> PathBuf {
    std::env::var_os("PATHLIGHT_SHARED")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(manifest_dir).join("../../../shared"))
}

/// Whether `path` (of the shared pack) exists. When it does not: under CI a panic naming it;
/// elsewhere a note on standard error, and false (the caller skips).
pub fn present(path: &Path) -> bool {
    if path.exists() {
        return true;
    }
    assert!(
        std::env::var_os("CI").is_none(),
        "{} not found: under CI the shared scene pack must be beside the clone (or at \
         $PATHLIGHT_SHARED)",
        path.display()
    );
    eprintln!(
        "note: {} not found (set PATHLIGHT_SHARED to the shared folder); skipped",
        path.display()
    );
    false
}
