//! Command-line options shared by every command that loads a scene.

use std::path::PathBuf;

use clap::Args;
use pathlight_render::World;
use pathlight_scene::{Limits, LoadOptions};

/// Which scene to load, and what to add to it. Flatten this into a command's arguments with
/// `#[command(flatten)]`.
#[derive(Debug, Clone, PartialEq, Args)]
#[command(next_help_heading = "Scene")]
pub struct SceneArgs {
    /// Scene file: glTF 2.0 (.gltf, .glb) or OBJ/MTL (.obj). Without it, the built-in Cornell box.
    #[arg(value_name = "SCENE")]
    pub scene: Option<PathBuf>,

    /// Environment map lighting the scene: equirectangular .hdr or .exr.
    #[arg(long, value_name = "FILE")]
    pub env: Option<PathBuf>,

    /// Rotation of the environment map about +Y, in degrees (counter-clockwise seen from above).
    #[arg(
        long,
        value_name = "DEGREES",
        default_value_t = 0.0,
        allow_negative_numbers = true
    )]
    pub env_rotation: f32,

    /// Multiplier of the environment map's radiance.
    #[arg(long, value_name = "X", default_value_t = 1.0)]
    pub env_intensity: f32,

    /// Add N random point lights inside the scene's bounds.
    #[arg(long, value_name = "N", default_value_t = 0)]
    pub point_lights: usize,

    /// Seed of the random point lights' positions.
    #[arg(long, value_name = "S", default_value_t = 0)]
    pub point_light_seed: u64,

    /// Multiplier of the random point lights' intensity (1: a surface a quarter of the scene's
    /// diagonal away receives 1 lux from each).
    #[arg(long, value_name = "X", default_value_t = 1.0)]
    pub point_light_intensity: f32,

    /// Refuse scenes with more triangles than this, counted over instances
    /// [default: 100000000].
    #[arg(long, value_name = "N")]
    pub max_triangles: Option<u64>,

    /// Refuse textures and environment maps with more pixels (width x height) than this
    /// [default: 268435456 = 16384^2].
    #[arg(long, value_name = "N")]
    pub max_texture_pixels: Option<u64>,
}

impl SceneArgs {
    /// The loader's limits: [`Limits::default`] with the command-line overrides.
    pub fn limits(&self) -> Limits {
        let mut limits = Limits::default();
        if let Some(n) = self.max_triangles {
            limits.max_triangles = n;
        }
        if let Some(n) = self.max_texture_pixels {
            limits.max_texture_pixels = n;
        }
        limits
    }

    pub fn load_options(&self) -> LoadOptions {
        LoadOptions {
            limits: self.limits(),
            environment: self.env.clone(),
            environment_rotation: self.env_rotation,
            environment_intensity: self.env_intensity,
            point_lights: self.point_lights,
            point_light_seed: self.point_light_seed,
            point_light_intensity: self.point_light_intensity,
        }
    }
}

impl SceneArgs {
    /// The arguments that load `scene` (none: the built-in Cornell box) with `options`
    /// (default limits).
    pub fn new(scene: Option<PathBuf>, options: &LoadOptions) -> Self {
        Self {
            scene,
            env: options.environment.clone(),
            env_rotation: options.environment_rotation,
            env_intensity: options.environment_intensity,
            point_lights: options.point_lights,
            point_light_seed: options.point_light_seed,
            point_light_intensity: options.point_light_intensity,
            max_triangles: None,
            max_texture_pixels: None,
        }
    }

    /// The command-line arguments that give these arguments back (limits left out).
    pub fn to_args(&self) -> Vec<String> {
        let mut args: Vec<String> = self.scene.iter().map(|s| s.display().to_string()).collect();
        if let Some(env) = &self.env {
            args.extend(["--env".to_owned(), env.display().to_string()]);
        }
        args.extend([
            "--env-rotation".to_owned(),
            self.env_rotation.to_string(),
            "--env-intensity".to_owned(),
            self.env_intensity.to_string(),
            "--point-lights".to_owned(),
            self.point_lights.to_string(),
            "--point-light-seed".to_owned(),
            self.point_light_seed.to_string(),
            "--point-light-intensity".to_owned(),
            self.point_light_intensity.to_string(),
        ]);
        args
    }

    /// Loads the scene and builds its world (accelerator, lights) for `light_selection`,
    /// saying on standard error what it loads and, once done, what it loaded in how long: a
    /// large scene takes seconds, and the window or the first frame waits for it.
    pub fn load_world(
        &self,
        light_selection: pathlight_render::light::LightSelection,
    ) -> anyhow::Result<World> {
        let start = std::time::Instant::now();
        let name = self.scene.as_ref().map_or_else(
            || "the built-in Cornell box".to_owned(),
            |p| p.display().to_string(),
        );
        eprintln!("loading {name}...");
        let scene = pathlight_scene::load(self.scene.as_deref(), &self.load_options())?;
        let world = World::new(scene, light_selection);
        let s = world.scene.stats();
        eprintln!(
            "loaded {name}: {} triangles, {} textures, {} lights in {:.0} ms",
            s.triangles,
            s.textures,
            world.lights.len(),
            start.elapsed().as_secs_f64() * 1e3
        );
        Ok(world)
    }

    /// A short identity of the loaded scene for checkpoints and partial renders.
    pub fn identity(&self, world: &World) -> String {
        let s = world.scene.stats();
        format!(
            "{} | {:?} | env {:?} x{} rot {} | +{} lights seed {} x{} | {} triangles, {} materials, {} textures, {} lights",
            world.scene.name,
            self.scene,
            self.env,
            self.env_intensity,
            self.env_rotation,
            self.point_lights,
            self.point_light_seed,
            self.point_light_intensity,
            s.triangles,
            s.materials,
            s.textures,
            world.lights.len()
        )
    }
}

impl From<&SceneArgs> for LoadOptions {
    fn from(args: &SceneArgs) -> Self {
        args.load_options()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Debug, Parser)]
    struct Wrapper {
        #[command(flatten)]
        scene: SceneArgs,
    }

    fn parse(args: &[&str]) -> SceneArgs {
        Wrapper::try_parse_from(std::iter::once("test").chain(args.iter().copied()))
            .unwrap()
            .scene
    }

    #[test]
    fn defaults_match_load_options_defaults() {
        let args = parse(&[]);
        assert!(args.scene.is_none());
        assert_eq!(args.load_options(), LoadOptions::default());
    }

    #[test]
    fn every_option_reaches_load_options() {
        let args = parse(&[
            "room.glb",
            "--env",
            "sky.hdr",
            "--env-rotation",
            "-90",
            "--env-intensity",
            "2.5",
            "--point-lights",
            "16",
            "--point-light-seed",
            "7",
            "--max-triangles",
            "1000",
            "--max-texture-pixels",
            "4096",
        ]);
        assert_eq!(
            args.scene.as_deref(),
            Some(std::path::Path::new("room.glb"))
        );
        let options = LoadOptions::from(&args);
        assert_eq!(options.environment, Some(PathBuf::from("sky.hdr")));
        assert_eq!(options.environment_rotation, -90.0);
        assert_eq!(options.environment_intensity, 2.5);
        assert_eq!(options.point_lights, 16);
        assert_eq!(options.point_light_seed, 7);
        assert_eq!(options.limits.max_triangles, 1000);
        assert_eq!(options.limits.max_texture_pixels, 4096);
        // Limits without a flag keep their defaults.
        let defaults = Limits::default();
        assert_eq!(options.limits.max_vertices, defaults.max_vertices);
        assert_eq!(options.limits.max_file_bytes, defaults.max_file_bytes);
    }

    #[test]
    fn to_args_gives_the_same_arguments_back() {
        for args in [
            parse(&[]),
            parse(&[
                "/scenes/room.glb",
                "--env",
                "/sky.hdr",
                "--env-rotation",
                "-33.3",
                "--env-intensity",
                "0.1",
                "--point-lights",
                "500",
                "--point-light-seed",
                "3",
            ]),
        ] {
            let line = args.to_args();
            let words: Vec<&str> = line.iter().map(String::as_str).collect();
            assert_eq!(parse(&words), args, "{line:?}");
        }
    }

    #[test]
    fn documented_limit_defaults_are_current() {
        // The help text states these defaults; keep it honest if Limits changes.
        let defaults = Limits::default();
        assert_eq!(defaults.max_triangles, 100_000_000);
        assert_eq!(defaults.max_texture_pixels, 16384 * 16384);
    }
}
