//! Shared foundations of pathlight: maths (re-exported from `glam`, fast trigonometry), colour and
//! deterministic random numbers.

pub mod color;
pub mod math;
pub mod prefetch;
pub mod rng;
pub mod shared_data;

pub use glam;
