//! Shared foundations of pathlight: maths (re-exported from `glam`), colour and
//! deterministic random numbers.

pub mod color;
pub mod rng;

pub use glam;
