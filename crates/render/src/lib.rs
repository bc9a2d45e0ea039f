//! Rendering in pathlight: BSDFs, light sampling, cameras, low-discrepancy samplers and the
//! reference path tracer. The real-time passes of later issues build on the same pieces.

pub mod alias;
pub mod bsdf;
pub mod camera;
pub mod checkpoint;
pub mod config;
pub mod distribution;
pub mod film;
pub mod light;
pub mod output;
pub mod path;
pub mod renderer;
pub mod sampler;
pub mod surface;
pub mod world;

pub use camera::Camera;
pub use config::Config;
pub use film::Film;
pub use world::World;
