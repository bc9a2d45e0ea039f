//! The one configuration type behind `render` (and, as they arrive, the real-time pipeline,
//! the viewer, the player, the benchmarks and the experiments). Serialisable, so experiments and
//! checkpoints can store it.

use serde::{Deserialize, Serialize};

use crate::bsdf::Microfacet;
use crate::camera::Camera;
use crate::frame::adaptive::AdaptiveConfig;
use crate::frame::reprojection::ReprojectionConfig;
use crate::frame::restir::RestirConfig;
use crate::frame::texture_cache::TextureCacheConfig;
use crate::frame::upsample::UpsampleConfig;
use crate::light::LightSelection;
use crate::path::PathSettings;
use crate::sampler::SamplerKind;
use crate::world::World;
use pathlight_denoise::FilterConfig;

pub use crate::camera::CameraConfig;
pub use crate::error::ConfigError;
pub use crate::frame::display::{DisplayConfig, Tonemap};
pub use crate::path::MAX_PATH_VERTICES;

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Config {
    pub width: u32,
    pub height: u32,
    /// Samples per pixel: of the whole image for `render` and references, of each frame in
    /// the frame pipeline.
    pub spp: u32,
    /// Seeds every random decision of the image.
    pub seed: u64,
    /// Sample values: Owen-scrambled Sobol points or independent random numbers.
    pub sampler: SamplerKind,
    /// Maximum number of scattering events along a path; `None`: unlimited (Russian roulette
    /// ends paths, with a hard stop at [`MAX_PATH_VERTICES`]).
    pub max_bounces: Option<u32>,
    /// First bounce at which Russian roulette may end a path.
    pub rr_start: u32,
    pub microfacet: Microfacet,
    pub light_selection: LightSelection,
    pub camera: CameraConfig,
    /// The real-time frame pipeline's passes (`view`, `play`, `bench frame`, `eval`).
    pub frame: FrameConfig,
    /// How images are shown and written as 8-bit pictures.
    pub display: DisplayConfig,
}

/// Makes [`FrameConfig`]: accumulation's two settings, then each stage's settings (its own
/// module's type, checked by its `validate()`) by field, with their defaults and their check.
macro_rules! frame_config {
    ($($(#[$doc:meta])* $field:ident: $settings:ty,)*) => {
        /// The passes of the real-time frame pipeline ([`crate::frame`]) and their parameters.
        /// A frame traces `spp` samples per pixel (the first through the G-buffer), then
        /// accumulates them with the earlier frames while nothing changes. Each technique's
        /// settings are its own module's type, gathered here by field.
        #[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
        #[serde(default, deny_unknown_fields)]
        pub struct FrameConfig {
            /// Progressive accumulation: average the frames while the camera and the settings
            /// stay the same; any change starts afresh. Off: every frame stands alone.
            pub accumulate: bool,
            /// Accumulation stops adding samples after this many frames (0: never).
            pub max_frames: u32,
            /// The frame time to hold, in milliseconds, by the render scale
            /// ([`crate::frame::target`]); 0: none (the frames are the same whatever the
            /// machine's speed).
            pub target_ms: f32,
            $($(#[$doc])* pub $field: $settings,)*
        }

        impl Default for FrameConfig {
            fn default() -> Self {
                Self {
                    accumulate: true,
                    max_frames: 0,
                    target_ms: 0.0,
                    $($field: Default::default(),)*
                }
            }
        }

        impl FrameConfig {
            /// Checks each stage's settings.
            fn validate_stages(&self) -> Result<(), ConfigError> {
                $(self.$field.validate()?;)*
                Ok(())
            }
        }
    };
}

frame_config! {
    /// Seed 000's adaptive sampling.
    adaptive: AdaptiveConfig,
    /// Seed 000's forward reprojection (with `adaptive`: their combination).
    reprojection: ReprojectionConfig,
    /// Seed 004's ReSTIR direct illumination at the first hit.
    restir: RestirConfig,
    /// Seed 001's reconstruction filter of the accumulated image.
    filter: FilterConfig,
    /// Seed 002's texture-space shading cache.
    texture_cache: TextureCacheConfig,
    /// Temporal upsampling: the frame traced at a fraction of the output's size.
    upsample: UpsampleConfig,
}

/// Largest image side accepted.
pub const MAX_SIDE: u32 = 16384;
/// Largest sample count accepted.
pub const MAX_SPP: u32 = 1 << 24;

impl Default for Config {
    fn default() -> Self {
        let path = PathSettings::default();
        Self {
            width: 640,
            height: 360,
            spp: 1,
            seed: path.seed,
            sampler: path.sampler,
            max_bounces: path.max_bounces,
            rr_start: path.rr_start,
            microfacet: path.microfacet,
            light_selection: LightSelection::Power,
            camera: CameraConfig::default(),
            frame: FrameConfig::default(),
            display: DisplayConfig::default(),
        }
    }
}

impl Config {
    /// What the path tracer reads of this configuration.
    pub fn path_settings(&self) -> PathSettings {
        PathSettings {
            seed: self.seed,
            sampler: self.sampler,
            max_bounces: self.max_bounces,
            rr_start: self.rr_start,
            microfacet: self.microfacet,
            mis_at_last: false,
        }
    }

    /// The render camera of this configuration's view and image size in `world`
    /// ([`World::camera`]).
    pub fn render_camera(&self, world: &World) -> Camera {
        world.camera(&self.camera, self.width, self.height)
    }

    /// The default real-time configuration (`view`, `play`, `bench frame`): one sample per
    /// pixel per frame and two scattering events per path (next event estimation at both, so
    /// direct light and one bounce of indirect light), accumulated while the camera is still.
    pub fn realtime() -> Self {
        Self {
            max_bounces: Some(2),
            ..Self::default()
        }
    }

    /// A preset (a TOML text of any subset of the fields) as a whole configuration: the
    /// defaults with the fields it sets, and this configuration's own view of the scene kept
    /// (its camera, image size, display settings, seed and frame-time target: where the user
    /// is looking and how, not how the frame is made). Applied after another, a preset gives
    /// what it gives alone: nothing of the first remains. Not checked: see
    /// [`validate`](Self::validate).
    pub fn with_preset(&self, text: &str) -> Result<Config, String> {
        let mut c = Config::default().with_toml(text)?;
        c.keep_view(self);
        Ok(c)
    }

    /// Whether this configuration is `preset` (made by [`with_preset`](Self::with_preset)),
    /// its view of the scene aside: false once a setting of its own was changed.
    pub fn is_preset(&self, preset: &Config) -> bool {
        let mut p = preset.clone();
        p.keep_view(self);
        p == *self
    }

    /// Takes `from`'s view of the scene: camera, image size, display, seed and frame-time
    /// target (the frame rate the user asked for, which a preset does not choose).
    fn keep_view(&mut self, from: &Config) {
        self.camera = from.camera.clone();
        (self.width, self.height) = (from.width, from.height);
        self.display = from.display.clone();
        self.seed = from.seed;
        self.frame.target_ms = from.frame.target_ms;
    }

    /// This configuration with the fields a TOML text sets (any subset of the fields; those
    /// it leaves out keep their values here). Not checked: see [`validate`](Self::validate).
    pub fn with_toml(&self, text: &str) -> Result<Config, String> {
        /// Merges `over` into `base`, table by table.
        fn merge(base: &mut toml::Value, over: toml::Value) {
            match (base, over) {
                (toml::Value::Table(b), toml::Value::Table(o)) => {
                    for (k, v) in o {
                        match b.get_mut(&k) {
                            Some(slot) => merge(slot, v),
                            None => {
                                b.insert(k, v);
                            }
                        }
                    }
                }
                (slot, v) => *slot = v,
            }
        }
        let mut merged = toml::Value::try_from(self).map_err(|e| e.to_string())?;
        let file: toml::Value = toml::from_str(text).map_err(|e| e.to_string())?;
        merge(&mut merged, file);
        merged
            .try_into()
            .map_err(|e: toml::de::Error| e.to_string())
    }

    /// Checks every value's range: image sides in 1..=[`MAX_SIDE`], spp in 1..=[`MAX_SPP`],
    /// field of view in (0, 180), finite non-negative lens radius, finite positive focus
    /// distance, finite camera vectors, and each technique's settings.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let err = |field, value: &dyn std::fmt::Display, requirement: String| ConfigError {
            field,
            value: value.to_string(),
            requirement,
        };
        for (field, v) in [("width", self.width), ("height", self.height)] {
            if v == 0 || v > MAX_SIDE {
                return Err(err(field, &v, format!("between 1 and {MAX_SIDE}")));
            }
        }
        if self.spp == 0 || self.spp > MAX_SPP {
            return Err(err("spp", &self.spp, format!("between 1 and {MAX_SPP}")));
        }
        if !(self.display.exposure.is_finite() && self.display.exposure >= 0.0) {
            return Err(err(
                "exposure",
                &self.display.exposure,
                "finite and >= 0".into(),
            ));
        }
        let cam = &self.camera;
        if let Some(f) = cam.fov_y {
            if !(f > 0.0 && f < 180.0) {
                return Err(err("fov_y", &f, "between 0 and 180 degrees".into()));
            }
        }
        if !(cam.lens_radius.is_finite() && cam.lens_radius >= 0.0) {
            return Err(err(
                "lens_radius",
                &cam.lens_radius,
                "finite and >= 0".into(),
            ));
        }
        if let Some(d) = cam.focus_distance {
            if !(d.is_finite() && d > 0.0) {
                return Err(err("focus_distance", &d, "finite and > 0".into()));
            }
        }
        for (field, v) in [
            ("look_from", cam.look_from),
            ("look_at", cam.look_at),
            ("up", cam.up),
        ] {
            if let Some(v) = v.filter(|v| !v.iter().all(|c| c.is_finite())) {
                return Err(err(field, &format!("{v:?}"), "finite".into()));
            }
        }
        if crate::frame::views::find(self.display.mode.name()).is_none() {
            return Err(err(
                "mode",
                &self.display.mode,
                format!("one of {}", crate::frame::views::names().join(", ")),
            ));
        }
        // Seed 000's techniques spread samples over the frames of an epoch and carry the
        // accumulated history into a new view: without accumulation every frame is an epoch
        // of its own, which samples every pixel afresh and has no history to carry.
        for (field, on) in [
            ("frame.adaptive.enabled", self.frame.adaptive.enabled),
            (
                "frame.reprojection.enabled",
                self.frame.reprojection.enabled,
            ),
        ] {
            if on && !self.frame.accumulate {
                return Err(err(
                    field,
                    &true,
                    "false when frame.accumulate is false (seed 000 works on the history that \
                     frames accumulate; without accumulation every frame starts afresh)"
                        .into(),
                ));
            }
        }
        let (t, range) = (self.frame.target_ms, crate::frame::target::TARGET_MS);
        if !range.contains(&t) {
            let want = format!(
                "between {} and {} (0: no target)",
                range.start(),
                range.end()
            );
            return Err(err("frame.target_ms", &t, want));
        }
        self.frame.validate_stages()?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A key the configuration does not have (a misspelling, or a removed one such as the
    /// data-driven filter's `sigma_direction`, which nothing read) is refused, naming it; a
    /// moved one names where it is now.
    #[test]
    fn unknown_and_removed_keys_are_refused_by_name() {
        for (text, key) in [
            (
                "[frame.filter]\nsigma_direction = 0.75\n",
                "sigma_direction",
            ),
            ("spp = 1\nmax_bounce = 2\n", "max_bounce"),
            // A filter key of before the per-method tables: its message names the new key.
            ("[frame.filter]\nholes = true\n", "data_driven.holes"),
        ] {
            let e = Config::default().with_toml(text).unwrap_err();
            assert!(e.contains(key), "{e}");
        }
    }

    #[test]
    fn toml_fields_merge_over_a_configuration() {
        let base = Config {
            width: 99,
            ..Config::realtime()
        };
        let c = base
            .with_toml("spp = 3\n[frame.reprojection]\nenabled = true\n")
            .unwrap();
        assert_eq!((c.width, c.spp, c.max_bounces), (99, 3, Some(2)));
        assert!(c.frame.reprojection.enabled && !c.frame.adaptive.enabled);
        assert_eq!(c.frame.reprojection.samples, 1);
        let e = base
            .with_toml("[frame.reprojection]\nsampels = 4\n")
            .unwrap_err();
        assert!(e.contains("sampels"), "{e}");
        assert!(base.with_toml("spp = ").is_err());
    }

    #[test]
    fn the_realtime_preset_is_a_valid_configuration() {
        let c = Config::realtime()
            .with_toml(include_str!("../../../experiments/realtime.toml"))
            .unwrap();
        c.validate().unwrap();
        assert_eq!(c.frame.filter.method, pathlight_denoise::Method::Svgf);
        assert!(!c.frame.reprojection.enabled);
        // The still camera's handover to the data-driven filter needs the accumulated image.
        assert!(c.frame.filter.svgf.still_handover > 0 && c.frame.accumulate);
        // The many-lights preset is the same with ReSTIR.
        let m = Config::realtime()
            .with_toml(include_str!(
                "../../../experiments/realtime-many-lights.toml"
            ))
            .unwrap();
        m.validate().unwrap();
        assert!(m.frame.restir.enabled && !c.frame.restir.enabled);
        let restir = Default::default();
        let without = Config {
            frame: FrameConfig {
                restir,
                ..m.frame.clone()
            },
            ..m
        };
        assert_eq!(without, c);
        // The sun preset: the texture cache holding all but the sun, temporal antialiasing.
        let s = Config::realtime()
            .with_toml(include_str!("../../../experiments/realtime-sun.toml"))
            .unwrap();
        s.validate().unwrap();
        let t = &s.frame.texture_cache;
        assert!(t.enabled && t.terms == crate::frame::texture_cache::CachedTerms::Sky);
        assert_eq!(s.frame.filter.method, pathlight_denoise::Method::Taa);
    }
}
