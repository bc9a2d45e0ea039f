//! pathlight's scene model and its loaders.
//!
//! [`load`] reads glTF 2.0 (`.gltf`, `.glb`) and OBJ/MTL (`.obj`) scenes, adds an optional
//! environment map (`.hdr`, `.exr`) and random point lights, and returns a [`Scene`]. With no
//! path it returns the built-in Cornell box. Malformed or hostile files give a [`SceneError`]
//! naming the file and the problem; loading never panics, never reads outside the scene's
//! folder, and checks [`Limits`] before allocating.

pub mod camera;
pub mod cornell;
pub mod environment;
pub mod error;
pub mod gltf;
pub mod light;
pub mod limits;
pub mod material;
pub mod mesh;
pub mod obj;
pub mod scene;
pub mod source;
pub mod tangent;
pub mod texture;

use std::path::{Path, PathBuf};

pub use camera::{Camera, Projection};
pub use environment::Environment;
pub use error::{Result, SceneError, Warnings};
pub use light::{Bounds, EmissiveTriangle, PunctualKind, PunctualLight};
pub use limits::Limits;
pub use material::{AlphaMode, Material, Sampler, TextureRef, Volume, Wrap};
pub use mesh::{Instance, Mesh};
pub use scene::{Scene, SceneStats};
pub use texture::{ColorSpace, Texture};

/// Number of point lights added, with a warning, to a scene that has no light at all.
pub const DEFAULT_POINT_LIGHTS: usize = 16;

/// What to load besides the scene file itself.
#[derive(Debug, Clone, PartialEq)]
pub struct LoadOptions {
    pub limits: Limits,
    /// An environment map (`--env`).
    pub environment: Option<PathBuf>,
    /// Rotation of the environment about +Y, in degrees.
    pub environment_rotation: f32,
    /// Multiplier of the environment's radiance.
    pub environment_intensity: f32,
    /// Add this many random point lights (`--point-lights N`).
    pub point_lights: usize,
    /// Seed of the random point lights' positions.
    pub point_light_seed: u64,
    /// Multiplier of the random point lights' intensity.
    pub point_light_intensity: f32,
}

impl Default for LoadOptions {
    fn default() -> Self {
        Self {
            limits: Limits::default(),
            environment: None,
            environment_rotation: 0.0,
            environment_intensity: 1.0,
            point_lights: 0,
            point_light_seed: 0,
            point_light_intensity: 1.0,
        }
    }
}

/// Loads a scene file (or the built-in Cornell box when `path` is `None`) with its options.
pub fn load(path: Option<&Path>, options: &LoadOptions) -> Result<Scene> {
    let mut scene = match path {
        None => cornell::cornell_box(),
        Some(path) => load_file(path, &options.limits)?,
    };
    if let Some(env) = &options.environment {
        scene.environment = Some(Environment::load(
            env,
            options.environment_rotation,
            options.environment_intensity,
            &options.limits,
        )?);
    }
    if options.point_lights > 0 {
        scene.add_random_point_lights(
            options.point_lights,
            options.point_light_seed,
            options.point_light_intensity,
        );
    }
    if scene.is_unlit() && !scene.instances.is_empty() {
        let message = format!(
            "the scene has no light (no emissive material, punctual light or environment); \
             added {DEFAULT_POINT_LIGHTS} random point lights (use --point-lights N or --env FILE)"
        );
        let mut w = Warnings::default();
        w.push(path.unwrap_or(Path::new(&scene.name)), message);
        scene.warnings.extend(w.messages);
        scene.add_random_point_lights(DEFAULT_POINT_LIGHTS, options.point_light_seed, 1.0);
    }
    Ok(scene)
}

/// Loads one scene file by its extension, without environment or added lights.
pub fn load_file(path: &Path, limits: &Limits) -> Result<Scene> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .unwrap_or_default();
    let mut scene = match ext.as_str() {
        "gltf" | "glb" => gltf::load(path, limits)?,
        "obj" => obj::load(path, limits)?,
        _ => {
            return Err(SceneError::new(
                path,
                "unknown scene format: expected .gltf, .glb or .obj",
            ))
        }
    };
    scene.path = Some(path.to_path_buf());
    scene.collect_emissive_triangles();
    Ok(scene)
}
