//! Evaluation: image metrics against references, cached reference renders, experiments
//! described as data (TOML), plots and an HTML report.
//!
//! `pathlight eval SPEC.toml --out DIR` is [`experiment::Runner`] followed by
//! [`publish::publish`].

use std::path::PathBuf;

pub mod experiment;
pub mod image;
pub mod metrics;
pub mod plot;
pub mod publish;
pub mod reference;
pub mod report;
pub mod results;
pub mod spec;

/// Anything that stops an experiment, naming the file at fault where there is one.
#[derive(Debug, thiserror::Error)]
pub enum EvalError {
    #[error(transparent)]
    Spec(#[from] spec::SpecError),
    #[error(transparent)]
    Scene(#[from] pathlight_scene::SceneError),
    #[error("{}: {error}", path.display())]
    Io {
        path: PathBuf,
        error: std::io::Error,
    },
    #[error(transparent)]
    Output(#[from] pathlight_render::output::OutputError),
    #[error(transparent)]
    Checkpoint(#[from] pathlight_render::checkpoint::CheckpointError),
    #[error(transparent)]
    Metric(#[from] metrics::MetricError),
    #[error(transparent)]
    Plot(#[from] plot::PlotError),
    #[error("configuration {configuration}: {error}")]
    Filter {
        configuration: String,
        error: pathlight_render::denoise::FilterError,
    },
}

impl EvalError {
    /// An I/O error on `path`.
    pub fn io(path: impl Into<PathBuf>, error: std::io::Error) -> Self {
        Self::Io {
            path: path.into(),
            error,
        }
    }
}
