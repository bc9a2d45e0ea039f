//! Evaluation: image metrics against references, cached reference renders, experiments
//! described as data (TOML), plots and an HTML report.

pub mod image;
pub mod metrics;
pub mod plot;
pub mod report;
