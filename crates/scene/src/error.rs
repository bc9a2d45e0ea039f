//! The one error type of scene loading: which file, and what is wrong with it.

use std::fmt;
use std::path::{Path, PathBuf};

/// A scene file could not be loaded. The message names the file and the problem.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SceneError {
    /// The file at fault (the scene file itself, or a buffer, image or material library it uses).
    pub file: PathBuf,
    /// What is wrong, for a person to read.
    pub problem: String,
}

impl SceneError {
    pub fn new(file: impl AsRef<Path>, problem: impl Into<String>) -> Self {
        Self {
            file: file.as_ref().to_path_buf(),
            problem: problem.into(),
        }
    }
}

impl fmt::Display for SceneError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.file.display(), self.problem)
    }
}

impl std::error::Error for SceneError {}

pub type Result<T, E = SceneError> = std::result::Result<T, E>;

/// Collects the warnings of one load (a dropped triangle count, a missing texture, ...):
/// kept on the scene for `pathlight info` and logged as they come.
#[derive(Debug, Default, Clone)]
pub struct Warnings {
    pub messages: Vec<String>,
}

impl Warnings {
    pub fn push(&mut self, file: &Path, message: impl Into<String>) {
        let text = format!("{}: {}", file.display(), message.into());
        log::warn!("{text}");
        self.messages.push(text);
    }
}
