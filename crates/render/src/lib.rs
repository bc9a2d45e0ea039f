//! Rendering in pathlight: BSDFs, light sampling, cameras, low-discrepancy samplers, the
//! reference path tracer and the real-time frame pipeline ([`frame`]), whose passes the
//! techniques plug into.

pub mod alias;
pub mod bsdf;
pub mod camera;
pub mod camera_path;
pub mod checkpoint;
pub mod config;
pub mod distribution;
pub mod error;
pub mod film;
pub mod frame;
pub mod light;
pub mod output;
pub mod part;
pub mod path;
pub mod preset;
pub mod renderer;
pub mod rpf;
pub mod sampler;
pub mod surface;
pub mod world;

pub use camera::Camera;
pub use config::Config;
pub use film::Film;
pub use frame::Pipeline;
/// Seed 001's reconstruction filters (the `frame.filter` settings and the filters).
pub use pathlight_denoise as denoise;
pub use world::World;
