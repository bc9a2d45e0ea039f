//! Reconstruction filters over screen-sized buffers (seed 001), with no dependency on the path
//! tracer: they read a frame's noisy light and its features ([`Features`]) and write a clean
//! image, so they can be tested on synthetic images with a known answer.
//!
//! - [`data_driven`]: the thesis's data-driven filter, a cross-bilateral filter guided by the
//!   features, with direct and indirect light filtered apart (thesis Eqs. 6.8-6.21).
//! - [`svgf`]: a spatio-temporal variance-guided filter in the manner of SVGF, and [`taa`],
//!   the temporal antialiasing its paper applies after it.
//! - [`rpf`]: Random Parameter Filtering, the offline baseline (every sample filtered apart).
//!
//! One settings type, [`FilterConfig`] (`[frame.filter]` of pathlight's `Config`), chooses the
//! method and holds its parameters.

mod atrous;
pub mod config;
pub mod data_driven;
mod exp;
pub mod features;
mod history;
mod neighbourhood;
pub mod rpf;
mod simd;
mod sure;
pub mod svgf;
pub mod taa;

pub use config::{
    ranges, ColourUnits, ColourWeights, DataDrivenConfig, DepthUnits, ErrorPair, FilterConfig,
    Method, SvgfConfig, TaaConfig,
};
pub use data_driven::DataDriven;
pub use features::Features;
pub use svgf::{Svgf, SvgfFrame, SvgfParams};

/// What a filter refuses, naming the parameter or buffer at fault.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FilterError {
    /// A parameter out of range, named by its place in pathlight's configuration
    /// (`frame.filter.kernel`).
    #[error("{field} {value}: must be {requirement}")]
    Parameter {
        field: &'static str,
        value: String,
        requirement: String,
    },
    #[error("filter: buffer `{name}` holds {len} values for a {width}x{height} frame")]
    Size {
        name: &'static str,
        len: usize,
        width: usize,
        height: usize,
    },
}

impl FilterError {
    /// The refusal of `field`'s `value`, which must be `requirement`, as an `Err`.
    pub fn parameter<T>(
        field: &'static str,
        value: impl std::fmt::Display,
        requirement: impl Into<String>,
    ) -> Result<T, Self> {
        Err(Self::Parameter {
            field,
            value: value.to_string(),
            requirement: requirement.into(),
        })
    }
}
