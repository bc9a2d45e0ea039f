//! Experiments as data: a TOML file names the scene, the camera path, the resolution, the
//! configurations to compare, the budgets (equal samples, equal time or both), the metrics and
//! the number of repetitions. See `experiments/README.md` for the format.

use std::path::{Path, PathBuf};

use glam::{Quat, Vec3};
use pathlight_render::config::{CameraConfig, Config, MAX_SPP};
use pathlight_scene::{Camera as SceneCamera, LoadOptions, Projection};
use serde::{Deserialize, Serialize};

use crate::metrics::Metric;

/// Largest spec file read.
const MAX_SPEC_BYTES: u64 = 1 << 20;
/// Bounds on counts, so that a typo cannot ask for years of rendering by accident.
const MAX_CONFIGURATIONS: usize = 64;
const MAX_REPETITIONS: u32 = 1000;
const MAX_STEPS: u32 = 10_000;
const MAX_BUDGETS: usize = 64;
const MAX_TIME_MS: f64 = 3_600_000.0;

/// One experiment.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Spec {
    pub name: String,
    #[serde(default)]
    pub description: String,
    /// Scene file, relative to the spec's folder; none: the built-in Cornell box.
    #[serde(default)]
    pub scene: Option<PathBuf>,
    /// Environment map (.hdr, .exr), relative to the spec's folder.
    #[serde(default)]
    pub environment: Option<PathBuf>,
    #[serde(default)]
    pub environment_rotation: f32,
    #[serde(default = "one_f32")]
    pub environment_intensity: f32,
    /// Random point lights added to the scene.
    #[serde(default)]
    pub point_lights: usize,
    pub width: u32,
    pub height: u32,
    /// Metrics measured at every budget; the first one is drawn in the error maps.
    #[serde(default = "default_metrics")]
    pub metrics: Vec<Metric>,
    /// Runs of each configuration with different seeds; plots show their mean.
    #[serde(default = "one_u32")]
    pub repetitions: u32,
    #[serde(default)]
    pub camera: CameraPath,
    pub budget: Budget,
    #[serde(default)]
    pub reference: ReferenceSpec,
    #[serde(rename = "configuration")]
    pub configurations: Vec<Configuration>,
}

fn one_f32() -> f32 {
    1.0
}
fn one_u32() -> u32 {
    1
}
fn default_metrics() -> Vec<Metric> {
    vec![Metric::Mse, Metric::Relmse]
}

/// How the camera moves before (or while) error is measured.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CameraPath {
    pub path: PathKind,
    /// The first view (overrides of the scene camera, as in a configuration's `camera`).
    pub look_from: Option<[f32; 3]>,
    pub look_at: Option<[f32; 3]>,
    pub up: Option<[f32; 3]>,
    pub fov_y: Option<f32>,
    /// Rotation: total angle about the vertical axis through the camera (counter-clockwise
    /// seen from above), in steps of `step_degrees` (seed 000: 100 degrees in 5 degree steps).
    pub degrees: f32,
    pub step_degrees: f32,
    /// Translation: total offset of the camera, in `steps` equal steps.
    pub offset: [f32; 3],
    pub steps: u32,
    /// Samples per pixel rendered at each view before the measured one (seed 000: 32 or 64).
    pub samples_per_step: u32,
    /// Which views are measured against their references.
    pub measure: Measure,
}

impl Default for CameraPath {
    fn default() -> Self {
        Self {
            path: PathKind::Still,
            look_from: None,
            look_at: None,
            up: None,
            fov_y: None,
            degrees: 100.0,
            step_degrees: 5.0,
            offset: [0.0; 3],
            steps: 10,
            samples_per_step: 32,
            measure: Measure::Final,
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum PathKind {
    Still,
    Rotation,
    Translation,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Measure {
    /// Only the last view: error against time after the final step (seed 000's protocol).
    Final,
    /// Every view of the path.
    Every,
}

/// When images are measured.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Budget {
    /// Equal samples: measure when every pixel has this many samples (ascending).
    #[serde(default)]
    pub spp: Vec<u32>,
    /// Equal time: measure after this much render time, in milliseconds (ascending).
    #[serde(default)]
    pub time_ms: Vec<f64>,
}

/// How references are rendered (by the reference path tracer).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReferenceSpec {
    pub spp: u32,
    /// Settings of the reference render; its width, height, spp and camera come from the spec.
    #[serde(default = "reference_config")]
    pub config: Config,
}

/// The reference's default settings: unlimited bounces, and a seed no configuration uses by
/// default (a reference must not share its noise with the images it judges).
fn reference_config() -> Config {
    Config {
        seed: 0x5eed_0f4e_f000,
        ..Config::default()
    }
}

impl Default for ReferenceSpec {
    fn default() -> Self {
        Self {
            spp: 2048,
            config: reference_config(),
        }
    }
}

/// A named set of settings to compare.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Configuration {
    pub name: String,
    /// Settings; width, height and spp come from the spec and its budgets, the view from the
    /// camera path.
    #[serde(default)]
    pub config: Config,
}

/// A spec that cannot be used, naming the file.
#[derive(Debug, thiserror::Error)]
#[error("{}: {message}", path.display())]
pub struct SpecError {
    pub path: PathBuf,
    pub message: String,
}

impl Spec {
    /// Reads and checks a spec file.
    pub fn load(path: &Path) -> Result<Self, SpecError> {
        let error = |message: String| SpecError {
            path: path.to_owned(),
            message,
        };
        let meta = std::fs::metadata(path).map_err(|e| error(e.to_string()))?;
        if meta.len() > MAX_SPEC_BYTES {
            return Err(error(format!(
                "{} bytes: an experiment spec is at most {MAX_SPEC_BYTES} bytes",
                meta.len()
            )));
        }
        let text = std::fs::read_to_string(path).map_err(|e| error(e.to_string()))?;
        Self::parse(&text).map_err(error)
    }

    /// Parses and checks a spec's text.
    pub fn parse(text: &str) -> Result<Self, String> {
        let spec: Spec = toml::from_str(text).map_err(|e| e.to_string())?;
        spec.validate()?;
        Ok(spec)
    }

    /// Checks every count and range, and that each configuration's settings are valid.
    pub fn validate(&self) -> Result<(), String> {
        if self.name.trim().is_empty() {
            return Err("name: must not be empty".into());
        }
        if self.configurations.is_empty() {
            return Err("no [[configuration]]: nothing to compare".into());
        }
        if self.configurations.len() > MAX_CONFIGURATIONS {
            return Err(format!(
                "{} configurations: at most {MAX_CONFIGURATIONS}",
                self.configurations.len()
            ));
        }
        let mut names = std::collections::HashSet::new();
        for c in &self.configurations {
            if c.name.trim().is_empty() {
                return Err("configuration name: must not be empty".into());
            }
            if !names.insert(c.name.as_str()) {
                return Err(format!(
                    "configuration {:?}: the name is used twice",
                    c.name
                ));
            }
        }
        if self.metrics.is_empty() {
            return Err("metrics: name at least one".into());
        }
        if !(1..=MAX_REPETITIONS).contains(&self.repetitions) {
            return Err(format!(
                "repetitions {}: must be between 1 and {MAX_REPETITIONS}",
                self.repetitions
            ));
        }
        let b = &self.budget;
        if b.spp.is_empty() && b.time_ms.is_empty() {
            return Err("budget: give spp = [...] or time_ms = [...] (or both)".into());
        }
        if b.spp.len() > MAX_BUDGETS || b.time_ms.len() > MAX_BUDGETS {
            return Err(format!("budget: at most {MAX_BUDGETS} values per list"));
        }
        if b.spp.iter().any(|&n| n == 0 || n > MAX_SPP) || !b.spp.is_sorted_by(|a, b| a < b) {
            return Err(format!(
                "budget.spp {:?}: must ascend strictly, each between 1 and {MAX_SPP}",
                b.spp
            ));
        }
        if b.time_ms
            .iter()
            .any(|t| !(t.is_finite() && *t > 0.0 && *t <= MAX_TIME_MS))
            || !b.time_ms.is_sorted_by(|a, b| a < b)
        {
            return Err(format!(
                "budget.time_ms {:?}: must ascend strictly, each in (0, {MAX_TIME_MS}]",
                b.time_ms
            ));
        }
        if !(self.environment_rotation.is_finite()
            && self.environment_intensity.is_finite()
            && self.environment_intensity >= 0.0)
        {
            return Err("environment_rotation and environment_intensity: must be finite, the intensity >= 0".into());
        }
        self.camera.validate()?;
        for view in self.views(&SceneCamera::look_at(
            "check",
            Vec3::ZERO,
            Vec3::NEG_Z,
            Vec3::Y,
            45.0,
        )) {
            for c in &self.configurations {
                let config = self.configuration_config(&c.config, &view, 1);
                config
                    .validate()
                    .map_err(|e| format!("configuration {:?}: {e}", c.name))?;
            }
        }
        if self.reference.spp == 0 || self.reference.spp > MAX_SPP {
            return Err(format!(
                "reference.spp {}: must be between 1 and {MAX_SPP}",
                self.reference.spp
            ));
        }
        Ok(())
    }

    /// `config` with the spec's resolution, `spp` and the view's camera.
    pub fn configuration_config(&self, config: &Config, view: &CameraConfig, spp: u32) -> Config {
        let mut c = config.clone();
        c.width = self.width;
        c.height = self.height;
        c.spp = spp;
        c.camera = CameraConfig {
            lens_radius: c.camera.lens_radius,
            focus_distance: c.camera.focus_distance,
            ..view.clone()
        };
        c
    }

    /// The reference's settings for `view`.
    pub fn reference_config(&self, view: &CameraConfig) -> Config {
        self.configuration_config(&self.reference.config, view, self.reference.spp)
    }

    /// The scene loader's options (paths relative to `spec_dir`).
    pub fn load_options(&self, spec_dir: &Path) -> LoadOptions {
        LoadOptions {
            environment: self.environment.as_ref().map(|e| spec_dir.join(e)),
            environment_rotation: self.environment_rotation,
            environment_intensity: self.environment_intensity,
            point_lights: self.point_lights,
            ..LoadOptions::default()
        }
    }

    /// The scene file (relative to `spec_dir`), or none for the built-in Cornell box.
    pub fn scene_path(&self, spec_dir: &Path) -> Option<PathBuf> {
        self.scene.as_ref().map(|s| spec_dir.join(s))
    }

    /// The camera of every view along the path, starting from `scene_camera` with the path's
    /// overrides.
    pub fn views(&self, scene_camera: &SceneCamera) -> Vec<CameraConfig> {
        self.camera.views(scene_camera)
    }

    /// Indices of the measured views among [`views`](Self::views).
    pub fn measured_views(&self, count: usize) -> Vec<usize> {
        match self.camera.measure {
            Measure::Final => vec![count - 1],
            Measure::Every => (0..count).collect(),
        }
    }
}

impl CameraPath {
    fn validate(&self) -> Result<(), String> {
        let finite = |v: [f32; 3]| v.iter().all(|c| c.is_finite());
        if [self.look_from, self.look_at, self.up]
            .iter()
            .flatten()
            .any(|v| !finite(*v))
            || !finite(self.offset)
        {
            return Err("camera: vectors must be finite".into());
        }
        if let Some(f) = self.fov_y {
            if !(f > 0.0 && f < 180.0) {
                return Err(format!("camera.fov_y {f}: must be between 0 and 180"));
            }
        }
        if self.samples_per_step > MAX_SPP {
            return Err(format!(
                "camera.samples_per_step {}: at most {MAX_SPP}",
                self.samples_per_step
            ));
        }
        let steps = match self.path {
            PathKind::Still => 0.0,
            PathKind::Rotation => {
                if !(self.degrees.is_finite() && self.step_degrees.is_finite())
                    || self.step_degrees <= 0.0
                {
                    return Err(format!(
                        "camera: degrees {} and step_degrees {}: must be finite, the step > 0",
                        self.degrees, self.step_degrees
                    ));
                }
                (self.degrees.abs() / self.step_degrees).ceil()
            }
            PathKind::Translation => self.steps as f32,
        };
        if steps > MAX_STEPS as f32 {
            return Err(format!("camera: {steps} steps, at most {MAX_STEPS}"));
        }
        Ok(())
    }

    /// The views: the first, then one per step.
    pub fn views(&self, scene_camera: &SceneCamera) -> Vec<CameraConfig> {
        let base = CameraConfig {
            look_from: self.look_from,
            look_at: self.look_at,
            up: self.up,
            fov_y: self.fov_y,
            ..CameraConfig::default()
        }
        .apply(scene_camera);
        let from = base.position();
        let forward = base.forward();
        let up = base.transform.y_axis.truncate().normalize();
        let fov = match base.projection {
            Projection::Perspective { yfov, .. } => yfov.to_degrees(),
            Projection::Orthographic { .. } => 45.0,
        };
        let view = |from: Vec3, forward: Vec3, up: Vec3| CameraConfig {
            look_from: Some(from.to_array()),
            look_at: Some((from + forward).to_array()),
            up: Some(up.to_array()),
            fov_y: Some(fov),
            ..CameraConfig::default()
        };
        match self.path {
            PathKind::Still => vec![view(from, forward, up)],
            PathKind::Rotation => {
                let steps = (self.degrees.abs() / self.step_degrees).ceil() as u32;
                (0..=steps)
                    .map(|i| {
                        let angle = (i as f32 * self.step_degrees).min(self.degrees.abs())
                            * self.degrees.signum();
                        let q = Quat::from_rotation_y(angle.to_radians());
                        view(from, q * forward, q * up)
                    })
                    .collect()
            }
            PathKind::Translation => (0..=self.steps)
                .map(|i| {
                    let t = i as f32 / self.steps.max(1) as f32;
                    view(from + Vec3::from(self.offset) * t, forward, up)
                })
                .collect(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MINIMAL: &str = r#"
        name = "t"
        width = 8
        height = 6
        [budget]
        spp = [1, 4]
        [[configuration]]
        name = "a"
    "#;

    #[test]
    fn minimal_spec_gets_defaults() {
        let s = Spec::parse(MINIMAL).unwrap();
        assert_eq!(s.metrics, vec![Metric::Mse, Metric::Relmse]);
        assert_eq!(s.repetitions, 1);
        assert_eq!(s.camera.path, PathKind::Still);
        assert_eq!(s.reference.spp, 2048);
        assert_eq!(s.configurations[0].config, Config::default());
        let cam = SceneCamera::look_at("c", Vec3::ZERO, Vec3::NEG_Z, Vec3::Y, 40.0);
        assert_eq!(s.views(&cam).len(), 1);
        assert_eq!(s.measured_views(1), vec![0]);
    }

    #[test]
    fn configuration_settings_are_read() {
        let s = Spec::parse(&format!(
            "{MINIMAL}\n[configuration.config]\nsampler = \"independent\"\nmax_bounces = 2\n"
        ))
        .unwrap();
        let c = &s.configurations[0].config;
        assert_eq!(
            c.sampler,
            pathlight_render::sampler::SamplerKind::Independent
        );
        assert_eq!(c.max_bounces, Some(2));
    }

    #[test]
    fn bad_specs_are_refused_with_the_reason() {
        let cases = [
            (MINIMAL.replace("spp = [1, 4]", "spp = [4, 1]"), "ascend"),
            (MINIMAL.replace("spp = [1, 4]", "spp = [0]"), "between 1"),
            (MINIMAL.replace("spp = [1, 4]", ""), "give spp"),
            (MINIMAL.replace("width = 8", "width = 0"), "width 0"),
            (MINIMAL.replace("width = 8", "width = 99999"), "width 99999"),
            (MINIMAL.replace("name = \"a\"", "name = \"a\"\ncolour = 1"), "colour"),
            (MINIMAL.replace("[[configuration]]\n        name = \"a\"", ""), "configuration"),
            (format!("{MINIMAL}\n[[configuration]]\nname = \"a\""), "used twice"),
            (format!("metrics = []\n{MINIMAL}"), "metrics"),
            (format!("repetitions = 0\n{MINIMAL}"), "repetitions 0"),
            (format!("metrics = [\"psnr\", \"nope\"]\n{MINIMAL}"), "nope"),
            (format!("{MINIMAL}\n[camera]\npath = \"rotation\"\nstep_degrees = 0\n"), "step"),
            (format!("{MINIMAL}\n[camera]\npath = \"rotation\"\ndegrees = 1e9\nstep_degrees = 1e-3\n"), "steps"),
            (format!("{MINIMAL}\n[camera]\nfov_y = 500\n"), "fov_y"),
            (format!("{MINIMAL}\n[reference]\nspp = 0\n"), "reference.spp"),
            (format!("{MINIMAL}\n[configuration.config]\nspp = \"many\"\n"), "spp"),
            ("name = ".to_owned(), "TOML"),
        ];
        for (text, needle) in cases {
            let e = Spec::parse(&text).expect_err(&text);
            assert!(
                e.to_lowercase().contains(&needle.to_lowercase())
                    || (needle == "TOML" && !e.is_empty()),
                "{needle:?} not in {e:?} for\n{text}"
            );
        }
    }

    #[test]
    fn rotation_views_turn_about_the_camera() {
        let mut s = Spec::parse(MINIMAL).unwrap();
        s.camera.path = PathKind::Rotation;
        s.camera.degrees = 100.0;
        s.camera.step_degrees = 30.0;
        let cam = SceneCamera::look_at(
            "c",
            Vec3::new(1.0, 2.0, 3.0),
            Vec3::new(1.0, 2.0, 2.0),
            Vec3::Y,
            40.0,
        );
        let views = s.views(&cam);
        // 0, 30, 60, 90, 100 degrees.
        assert_eq!(views.len(), 5);
        for v in &views {
            assert_eq!(v.look_from, Some([1.0, 2.0, 3.0]));
        }
        let dir =
            |v: &CameraConfig| Vec3::from(v.look_at.unwrap()) - Vec3::from(v.look_from.unwrap());
        assert!(dir(&views[0]).abs_diff_eq(Vec3::NEG_Z, 1e-5));
        // Counter-clockwise seen from above: -Z turns towards -X.
        let d = 100f32.to_radians();
        assert!(dir(&views[4]).abs_diff_eq(Vec3::new(-d.sin(), 0.0, -d.cos()), 1e-5));
        assert_eq!(s.measured_views(views.len()), vec![4]);
    }

    #[test]
    fn translation_views_move_in_equal_steps() {
        let mut s = Spec::parse(MINIMAL).unwrap();
        s.camera.path = PathKind::Translation;
        s.camera.offset = [2.0, 0.0, 0.0];
        s.camera.steps = 4;
        s.camera.measure = Measure::Every;
        let cam = SceneCamera::look_at("c", Vec3::ZERO, Vec3::NEG_Z, Vec3::Y, 40.0);
        let xs: Vec<f32> = s
            .views(&cam)
            .iter()
            .map(|v| v.look_from.unwrap()[0])
            .collect();
        assert_eq!(xs, vec![0.0, 0.5, 1.0, 1.5, 2.0]);
        assert_eq!(s.measured_views(5), vec![0, 1, 2, 3, 4]);
    }
}
