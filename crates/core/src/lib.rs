//! Shared foundations of pathlight: maths (re-exported from `glam`) and colour.

pub mod color;

pub use glam;
