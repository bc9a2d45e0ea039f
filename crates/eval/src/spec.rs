//! Experiments as data: a TOML file names the scene, the camera path, the resolution, the
//! configurations to compare, the budgets (equal samples, equal time or both), the metrics and
//! the number of repetitions. See `experiments/README.md` for the format.

use std::path::{Path, PathBuf};

use glam::Vec3;
use pathlight_render::camera_path::CameraPath;
use pathlight_render::config::{CameraConfig, Config, MAX_SPP};
use pathlight_render::frame::display::DisplayMode;
use pathlight_scene::{Camera as SceneCamera, LoadOptions};
use serde::{Deserialize, Serialize};

use crate::metrics::Metric;

/// Largest spec file read.
const MAX_SPEC_BYTES: u64 = 1 << 20;
/// Bounds on counts, so that a typo cannot ask for years of rendering by accident.
const MAX_CONFIGURATIONS: usize = 64;
const MAX_REPETITIONS: u32 = 1000;
const MAX_BUDGETS: usize = 64;
const MAX_TIME_MS: f64 = 3_600_000.0;
const MAX_SCENES: usize = 256;

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
    /// Multiplier of their intensity.
    #[serde(default = "one_f32")]
    pub point_light_intensity: f32,
    pub width: u32,
    pub height: u32,
    /// Metrics measured at every budget; the first one is drawn in the error maps.
    #[serde(default = "default_metrics")]
    pub metrics: Vec<Metric>,
    /// Runs of each configuration with different seeds; plots show their mean.
    #[serde(default = "one_u32")]
    pub repetitions: u32,
    /// How the camera moves (`pathlight_render::camera_path`); the views before a measured
    /// one are rendered for `frames_per_view` frames each.
    #[serde(default)]
    pub camera: CameraPath,
    /// Which views along the path are measured.
    #[serde(default = "final_view")]
    pub measure: Measure,
    /// With `measure = "every"`: the first view measured (the views before it are rendered,
    /// the history they build kept, but not measured: they need no reference).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub measure_from: usize,
    pub budget: Budget,
    #[serde(default)]
    pub reference: ReferenceSpec,
    /// What is compared against the reference: the image (`final`, the default) or the
    /// indirect light alone (`indirect`: the history's indirect light against the reference
    /// path tracer's, paths through at least two surfaces).
    #[serde(default, skip_serializing_if = "Layer::is_final")]
    pub layer: Layer,
    /// Display modes of the frame pipeline written beside each configuration's image (first
    /// repetition, last budget point of the last measured view), e.g. `probability`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub display_modes: Vec<DisplayMode>,
    #[serde(rename = "configuration")]
    pub configurations: Vec<Configuration>,
    /// Several scenes or camera setups in one experiment: each entry runs the whole
    /// experiment with the fields it sets in place of the spec's (see [`Spec::entries`]).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub scenes: Vec<SceneEntry>,
}

/// One entry of `[[scenes]]`: a name, and the scene and camera fields it replaces.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SceneEntry {
    /// Names its output folder and its results: letters, digits, `-`, `_` and `.` (required).
    pub name: String,
    pub scene: Option<PathBuf>,
    pub environment: Option<PathBuf>,
    pub environment_rotation: Option<f32>,
    pub environment_intensity: Option<f32>,
    pub point_lights: Option<usize>,
    pub point_light_intensity: Option<f32>,
    pub width: Option<u32>,
    pub height: Option<u32>,
    pub camera: Option<CameraPath>,
    /// The reference's samples per pixel (`[reference] spp`).
    pub reference_spp: Option<u32>,
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

fn is_zero(n: &usize) -> bool {
    *n == 0
}

fn final_view() -> Measure {
    Measure::Final
}

/// The light an experiment compares.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Layer {
    /// The image.
    #[default]
    Final,
    /// The indirect light alone.
    Indirect,
}

impl Layer {
    pub fn is_final(&self) -> bool {
        *self == Layer::Final
    }

    /// The reference EXR's layer of it (its channels' prefix).
    pub fn exr_prefix(&self) -> &'static str {
        match self {
            Layer::Final => "",
            Layer::Indirect => "indirect",
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Measure {
    /// Only the last view: error against time after the final step (seed 000's protocol).
    Final,
    /// Every view of the path.
    Every,
}

/// When images are measured: one progressive run of frames at the measured view, measured as
/// it passes each point of either list.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Budget {
    /// Equal samples: measure once this many samples per pixel have been traced at the view
    /// (ascending).
    #[serde(default)]
    pub spp: Vec<u32>,
    /// Equal time: measure once this much render time has passed at the view, in
    /// milliseconds (ascending).
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
    /// Settings of the frame pipeline (`spp` is samples per frame); width and height come
    /// from the spec, the view from the camera path. With `preset`, over that preset.
    #[serde(default)]
    pub config: Config,
    /// A preset ([`pathlight_render::preset::Preset::name`]) the configuration starts from,
    /// its `config` table applied over it (resolved when the spec is read); or `"auto"`: the
    /// preset the rule chooses for each scene from its lights, as `view`, `play` and `bench
    /// frame` run without a configuration (resolved per scene; it takes no `config` table).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub preset: Option<String>,
}

pub use pathlight_render::preset::AUTO;

impl Configuration {
    /// Its settings for a scene lit by `lights`: `config`, or with `preset = "auto"` the
    /// preset the rule chooses for them.
    pub fn config_for(&self, lights: &pathlight_render::light::Lights) -> Config {
        match self.preset.as_deref() {
            Some(AUTO) => pathlight_render::preset::choose(lights)
                .preset
                .config(&Config::default()),
            _ => self.config.clone(),
        }
    }
}

/// Resolves each `[[configuration]]`'s named `preset` (its `config` table applied over the
/// preset) in a spec's TOML; `"auto"` is left for the run. `Ok(None)`: no preset named.
fn resolve_presets(text: &str) -> Result<Option<toml::Table>, String> {
    use pathlight_render::preset::Preset;
    let mut table: toml::Table = text.parse().map_err(|e: toml::de::Error| e.to_string())?;
    let Some(toml::Value::Array(list)) = table.get_mut("configuration") else {
        return Ok(None);
    };
    let mut any = false;
    for c in list.iter_mut() {
        let Some(c) = c.as_table_mut() else { continue };
        let name = c
            .get("name")
            .and_then(|n| n.as_str())
            .unwrap_or("")
            .to_owned();
        let preset = match c.get("preset") {
            None => continue,
            Some(toml::Value::String(p)) => p.clone(),
            Some(v) => return Err(format!("configuration {name}: preset = {v}: a string")),
        };
        any = true;
        let own = match c.get("config") {
            Some(toml::Value::Table(t)) => Some(t.clone()),
            None => None,
            Some(_) => return Err(format!("configuration {name}: config must be a table")),
        };
        if preset == AUTO {
            if own.is_some() {
                return Err(format!(
                    "configuration {name}: preset = \"auto\" takes no config table (the rule's \
                     preset is used as it is)"
                ));
            }
            continue;
        }
        let Some(p) = Preset::named(&preset) else {
            return Err(format!(
                "configuration {name}: preset = \"{preset}\": one of {}",
                pathlight_render::preset::names()
            ));
        };
        let base = p.config(&Config::default());
        let merged = match own {
            Some(t) => base.with_toml(&t.to_string()),
            None => Ok(base),
        }
        .map_err(|e| format!("configuration {name}: {e}"))?;
        let merged = toml::Table::try_from(&merged).map_err(|e| e.to_string())?;
        c.insert("config".into(), toml::Value::Table(merged));
    }
    Ok(any.then_some(table))
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

    /// Parses and checks a spec's text (each of its `[[scenes]]` entries too).
    pub fn parse(text: &str) -> Result<Self, String> {
        let spec: Spec = match resolve_presets(text)? {
            None => toml::from_str(text).map_err(|e| e.to_string())?,
            Some(table) => table
                .try_into()
                .map_err(|e: toml::de::Error| e.to_string())?,
        };
        if spec.scenes.is_empty() {
            spec.validate()?;
        } else {
            spec.entries()?;
        }
        Ok(spec)
    }

    /// The experiments this spec runs: itself (unnamed) without `[[scenes]]`; else one per
    /// entry, named after it, with the fields the entry sets in place of the spec's (each
    /// field it leaves out is the spec's). Each is checked.
    pub fn entries(&self) -> Result<Vec<(Option<String>, Spec)>, String> {
        if self.scenes.is_empty() {
            return Ok(vec![(None, self.clone())]);
        }
        if self.scenes.len() > MAX_SCENES {
            return Err(format!(
                "{} [[scenes]]: at most {MAX_SCENES}",
                self.scenes.len()
            ));
        }
        let mut names = std::collections::HashSet::new();
        let mut out = Vec::with_capacity(self.scenes.len());
        for e in &self.scenes {
            let safe = !e.name.is_empty()
                && e.name.len() <= 64
                && !e.name.starts_with('.')
                && e.name
                    .chars()
                    .all(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.'));
            if !safe {
                return Err(format!(
                    "[[scenes]] name {:?}: 1 to 64 letters, digits, '-', '_' or '.', not starting with '.'",
                    e.name
                ));
            }
            if !names.insert(e.name.as_str()) {
                return Err(format!("[[scenes]] name {:?}: used twice", e.name));
            }
            let spec = Spec {
                name: format!("{}/{}", self.name, e.name),
                scene: e.scene.clone().or_else(|| self.scene.clone()),
                environment: e.environment.clone().or_else(|| self.environment.clone()),
                environment_rotation: e.environment_rotation.unwrap_or(self.environment_rotation),
                environment_intensity: e
                    .environment_intensity
                    .unwrap_or(self.environment_intensity),
                point_lights: e.point_lights.unwrap_or(self.point_lights),
                point_light_intensity: e
                    .point_light_intensity
                    .unwrap_or(self.point_light_intensity),
                width: e.width.unwrap_or(self.width),
                height: e.height.unwrap_or(self.height),
                camera: e.camera.clone().unwrap_or_else(|| self.camera.clone()),
                reference: ReferenceSpec {
                    spp: e.reference_spp.unwrap_or(self.reference.spp),
                    ..self.reference.clone()
                },
                scenes: Vec::new(),
                ..self.clone()
            };
            spec.validate()
                .map_err(|m| format!("[[scenes]] {:?}: {m}", e.name))?;
            out.push((Some(e.name.clone()), spec));
        }
        Ok(out)
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
            if self.layer == Layer::Indirect
                && c.config.frame.filter.method == pathlight_render::denoise::Method::Rpf
            {
                return Err(format!(
                    "configuration {:?}: layer = \"indirect\" compares the frame pipeline's indirect light; RPF filters the whole image",
                    c.name
                ));
            }
        }
        if self.metrics.is_empty() {
            return Err("metrics: name at least one".into());
        }
        if let Some(m) = self.metrics.iter().find(|m| m.is_temporal()) {
            if self.metrics[0].is_temporal() {
                return Err(format!(
                    "metrics: {m} compares consecutive views and has no error map; name another first (the first is drawn in the error maps)"
                ));
            }
            if self.measure != Measure::Every {
                return Err(format!(
                    "metrics: {m} compares consecutive views; it needs measure = \"every\""
                ));
            }
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
        if !(self.point_light_intensity.is_finite() && self.point_light_intensity >= 0.0) {
            return Err(format!(
                "point_light_intensity {}: must be finite and >= 0",
                self.point_light_intensity
            ));
        }
        if !(self.environment_rotation.is_finite()
            && self.environment_intensity.is_finite()
            && self.environment_intensity >= 0.0)
        {
            return Err("environment_rotation and environment_intensity: must be finite, the intensity >= 0".into());
        }
        self.camera.validate().map_err(|e| format!("camera: {e}"))?;
        let check = SceneCamera::look_at("check", Vec3::ZERO, Vec3::NEG_Z, Vec3::Y, 45.0);
        let first = &self.views(&check, Vec3::NEG_Z)[0];
        for c in &self.configurations {
            self.configuration_config(&c.config, first)
                .validate()
                .map_err(|e| format!("configuration {:?}: {e}", c.name))?;
        }
        if self.reference.spp == 0 || self.reference.spp > MAX_SPP {
            return Err(format!(
                "reference.spp {}: must be between 1 and {MAX_SPP}",
                self.reference.spp
            ));
        }
        Ok(())
    }

    /// `config` with the spec's resolution and the view's camera.
    pub fn configuration_config(&self, config: &Config, view: &CameraConfig) -> Config {
        let mut c = config.clone();
        c.width = self.width;
        c.height = self.height;
        c.camera = CameraConfig {
            lens_radius: c.camera.lens_radius,
            focus_distance: c.camera.focus_distance,
            ..view.clone()
        };
        c
    }

    /// The reference's settings for `view`.
    pub fn reference_config(&self, view: &CameraConfig) -> Config {
        Config {
            spp: self.reference.spp,
            ..self.configuration_config(&self.reference.config, view)
        }
    }

    /// The scene loader's options (paths relative to `spec_dir`).
    pub fn load_options(&self, spec_dir: &Path) -> LoadOptions {
        LoadOptions {
            environment: self.environment.as_ref().map(|e| spec_dir.join(e)),
            environment_rotation: self.environment_rotation,
            environment_intensity: self.environment_intensity,
            point_lights: self.point_lights,
            point_light_intensity: self.point_light_intensity,
            ..LoadOptions::default()
        }
    }

    /// The scene file (relative to `spec_dir`), or none for the built-in Cornell box.
    pub fn scene_path(&self, spec_dir: &Path) -> Option<PathBuf> {
        self.scene.as_ref().map(|s| spec_dir.join(s))
    }

    /// The camera of every view along the path, starting from `scene_camera` with the path's
    /// overrides (`scene_centre` places an orbit's default pivot).
    pub fn views(&self, scene_camera: &SceneCamera, scene_centre: Vec3) -> Vec<CameraConfig> {
        self.camera.views(scene_camera, scene_centre)
    }

    /// Indices of the measured views among [`views`](Self::views).
    pub fn measured_views(&self, count: usize) -> Vec<usize> {
        match self.measure {
            Measure::Final => vec![count - 1],
            Measure::Every => (self.measure_from.min(count - 1)..count).collect(),
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
    fn scenes_entries_take_the_specs_fields_they_leave_out() {
        // (Top-level fields go before MINIMAL's [[configuration]], which would take them.)
        let text = format!(
            "point_lights = 3\n{MINIMAL}\n[[scenes]]\nname = \"a\"\n[[scenes]]\nname = \"b-2.x\"\nscene = \"room.glb\"\nwidth = 4\n[scenes.camera]\npath = \"orbit\"\n"
        );
        let spec = Spec::parse(&text).unwrap();
        let entries = spec.entries().unwrap();
        assert_eq!(entries.len(), 2);
        let (a, b) = (&entries[0], &entries[1]);
        assert_eq!(a.0.as_deref(), Some("a"));
        assert_eq!(a.1.name, "t/a");
        assert_eq!(
            (a.1.width, a.1.scene.clone(), a.1.point_lights),
            (8, None, 3)
        );
        assert_eq!(b.1.name, "t/b-2.x");
        assert_eq!(b.1.width, 4);
        assert_eq!(b.1.height, 6);
        assert_eq!(b.1.scene, Some(PathBuf::from("room.glb")));
        assert_eq!(b.1.point_lights, 3);
        assert_eq!((a.1.reference.spp, b.1.reference.spp), (2048, 2048));
        assert_eq!(
            b.1.camera.path,
            pathlight_render::camera_path::PathKind::Orbit
        );
        assert!(b.1.scenes.is_empty());
        // Without [[scenes]]: the spec itself, unnamed.
        let plain = Spec::parse(MINIMAL).unwrap();
        assert_eq!(plain.entries().unwrap(), vec![(None, plain.clone())]);
        // Bad names and bad entries are refused.
        let base = MINIMAL;
        for (entries, expect) in [
            ("[[scenes]]\nname = \"../up\"\n", "../up"),
            ("[[scenes]]\nname = \"\"\n", "name"),
            (
                "[[scenes]]\nname = \"x\"\n[[scenes]]\nname = \"x\"\n",
                "twice",
            ),
            ("[[scenes]]\nname = \"x\"\nwidth = 0\n", "\"x\""),
        ] {
            let e = Spec::parse(&format!("{base}{entries}")).unwrap_err();
            assert!(e.contains(expect), "{e}");
        }
    }

    /// A configuration's `preset` is its base, its `config` table applied over it; `"auto"`
    /// is left to each scene's lights and takes no table; other names are refused.
    #[test]
    fn a_configuration_starts_from_its_preset() {
        let spec = |tail: &str| {
            Spec::parse(&format!(
                "name = \"p\"\nwidth = 8\nheight = 8\n[budget]\nspp = [1]\n{tail}"
            ))
        };
        let s = spec(
            "[[configuration]]\nname = \"sun\"\npreset = \"realtime-sun\"\n\
             [configuration.config.frame.texture_cache]\nlod_bias = 3.0\n",
        )
        .unwrap();
        let c = &s.configurations[0].config;
        let sun = pathlight_render::preset::Preset::Sun.config(&Config::default());
        assert!(c.frame.texture_cache.enabled);
        assert_eq!(c.frame.texture_cache.lod_bias, 3.0);
        assert_eq!(c.frame.filter, sun.frame.filter);
        let auto = spec("[[configuration]]\nname = \"d\"\npreset = \"auto\"\n").unwrap();
        let lights = pathlight_render::light::Lights::new(
            &pathlight_scene::cornell::cornell_box(),
            Default::default(),
        );
        assert_eq!(auto.configurations[0].config_for(&lights), sun);
        let e = spec(
            "[[configuration]]\nname = \"d\"\npreset = \"auto\"\n\
             [configuration.config]\nspp = 2\n",
        )
        .unwrap_err();
        assert!(e.contains("takes no config"), "{e}");
        let e = spec("[[configuration]]\nname = \"x\"\npreset = \"sunny\"\n").unwrap_err();
        assert!(e.contains("sunny") && e.contains("realtime-sun"), "{e}");
    }

    #[test]
    fn minimal_spec_gets_defaults() {
        let s = Spec::parse(MINIMAL).unwrap();
        assert_eq!(s.metrics, vec![Metric::Mse, Metric::Relmse]);
        assert_eq!(s.repetitions, 1);
        assert_eq!(
            s.camera.path,
            pathlight_render::camera_path::PathKind::Still
        );
        assert_eq!(s.reference.spp, 2048);
        assert_eq!(s.configurations[0].config, Config::default());
        let cam = SceneCamera::look_at("c", Vec3::ZERO, Vec3::NEG_Z, Vec3::Y, 40.0);
        assert_eq!(s.views(&cam, Vec3::ZERO).len(), 1);
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
            (format!("metrics = [\"mse\", \"flicker\"]\n{MINIMAL}"), "measure = \"every\""),
            (
                format!("measure = \"every\"\nmetrics = [\"flicker\", \"mse\"]\n{MINIMAL}"),
                "name another first",
            ),
            (format!("{MINIMAL}\n[camera]\npath = \"rotation\"\nstep_degrees = 0\n"), "step"),
            (format!("{MINIMAL}\n[camera]\npath = \"rotation\"\ndegrees = 1e9\nstep_degrees = 1e-3\n"), "views"),
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
    fn camera_paths_are_read_and_measured_views_chosen() {
        let s = Spec::parse(&format!(
            "measure = \"every\"\n{MINIMAL}\n[camera]\npath = \"rotation\"\ndegrees = 20\nstep_degrees = 10\nframes_per_view = 4\n"
        ))
        .unwrap();
        let cam = SceneCamera::look_at("c", Vec3::ZERO, Vec3::NEG_Z, Vec3::Y, 40.0);
        assert_eq!(s.views(&cam, Vec3::ZERO).len(), 3);
        assert_eq!(s.camera.frames_per_view, 4);
        assert_eq!(s.measured_views(3), vec![0, 1, 2]);
        let s = Spec::parse(&format!(
            "measure = \"every\"\nmeasure_from = 2\n{MINIMAL}\n[camera]\npath = \"rotation\"\ndegrees = 30\nstep_degrees = 10\n"
        ))
        .unwrap();
        assert_eq!(s.measured_views(4), vec![2, 3]);
        assert_eq!(s.measured_views(2), vec![1]);
        let s = Spec::parse(MINIMAL).unwrap();
        assert_eq!(s.measured_views(3), vec![2]);
    }
}
