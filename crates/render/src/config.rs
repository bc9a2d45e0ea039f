//! The one configuration type behind `render` (and, as they arrive, the real-time pipeline,
//! the viewer, the player, the benchmarks and the experiments). Serialisable, so experiments and
//! checkpoints can store it.

use glam::Vec3;
use pathlight_scene::Camera as SceneCamera;
use serde::{Deserialize, Serialize};

use crate::bsdf::Microfacet;
use crate::light::LightSelection;

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Config {
    pub width: u32,
    pub height: u32,
    /// Samples per pixel.
    pub spp: u32,
    /// Seeds every random decision of the image.
    pub seed: u64,
    /// Maximum number of scattering events along a path; `None`: unlimited (Russian roulette
    /// ends paths, with a hard stop at [`MAX_PATH_VERTICES`]).
    pub max_bounces: Option<u32>,
    /// First bounce at which Russian roulette may end a path.
    pub rr_start: u32,
    pub microfacet: Microfacet,
    pub light_selection: LightSelection,
    pub camera: CameraConfig,
}

/// Safety stop for paths of unlimited depth (reached only by pathological scenes, e.g. a
/// white furnace inside a perfect mirror).
pub const MAX_PATH_VERTICES: u32 = 1024;

impl Default for Config {
    fn default() -> Self {
        Self {
            width: 640,
            height: 360,
            spp: 64,
            seed: 0,
            max_bounces: None,
            rr_start: 3,
            microfacet: Microfacet::Ggx,
            light_selection: LightSelection::Power,
            camera: CameraConfig::default(),
        }
    }
}

/// The camera: the scene's first camera (or a view of the whole scene) unless overridden.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CameraConfig {
    pub look_from: Option<[f32; 3]>,
    pub look_at: Option<[f32; 3]>,
    pub up: Option<[f32; 3]>,
    /// Vertical field of view in degrees.
    pub fov_y: Option<f32>,
    /// Thin-lens radius in scene units; 0 is a pinhole.
    pub lens_radius: f32,
    /// Distance in focus; `None` focuses on what the image centre sees.
    pub focus_distance: Option<f32>,
}

impl CameraConfig {
    /// The scene camera with this configuration's overrides applied to `base`.
    pub fn apply(&self, base: &SceneCamera) -> SceneCamera {
        if self.look_from.is_none()
            && self.look_at.is_none()
            && self.up.is_none()
            && self.fov_y.is_none()
        {
            return base.clone();
        }
        let from = self.look_from.map_or(base.position(), Vec3::from);
        let at = self.look_at.map_or(from + base.forward(), Vec3::from);
        let up = self.up.map_or(base.transform.y_axis.truncate(), Vec3::from);
        let fov = self.fov_y.unwrap_or(match base.projection {
            pathlight_scene::Projection::Perspective { yfov, .. } => yfov.to_degrees(),
            _ => 45.0,
        });
        SceneCamera::look_at(&base.name, from, at, up, fov)
    }
}
