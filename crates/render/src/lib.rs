//! Rendering in pathlight: BSDFs, light sampling, cameras, low-discrepancy samplers and the
//! reference path tracer. The real-time passes of later issues build on the same pieces.

pub mod alias;
pub mod bsdf;
pub mod distribution;
pub mod light;
