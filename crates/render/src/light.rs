//! The scene's lights as the path tracer samples them: emissive triangles, punctual lights
//! (glTF `KHR_lights_punctual`) and the environment, chosen in proportion to power (or
//! uniformly) with an alias table.

use glam::{Vec2, Vec3};
use pathlight_scene::Scene;
use serde::{Deserialize, Serialize};

/// How a light is picked for next event estimation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum LightSelection {
    /// In proportion to emitted power (luminance).
    #[default]
    Power,
    Uniform,
}

/// A light sample seen from a shading point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LightSample {
    /// Unit direction from the shading point toward the light.
    pub wi: Vec3,
    /// Distance to the sampled point (`f32::INFINITY` for the environment and directional
    /// lights). The shadow ray tests `(epsilon, distance * (1 - 1e-4))`.
    pub distance: f32,
    /// Radiance arriving along `-wi` (for punctual lights: intensity / distance^2 with the
    /// spot and range falloffs; directional: its illuminance).
    pub radiance: Vec3,
    /// Solid-angle density including the selection probability; for a punctual light the
    /// selection probability alone.
    pub pdf: f32,
    /// True for punctual lights (no MIS with BSDF sampling).
    pub delta: bool,
}

/// Every light of a scene, ready to sample.
pub struct Lights {
    count: usize,
}

impl Lights {
    pub fn new(scene: &Scene, selection: LightSelection) -> Self {
        let _ = (scene, selection);
        todo!("lights")
    }

    /// Number of lights (emissive triangles + punctual lights + the environment).
    pub fn len(&self) -> usize {
        self.count
    }

    pub fn is_empty(&self) -> bool {
        self.count == 0
    }

    /// Samples a light and a point on it as seen from `p`: `u_select` picks the light, `u` the
    /// point. `None` when nothing can be sampled (no light, or the point is behind a one-sided
    /// emitter).
    pub fn sample(&self, p: Vec3, u_select: f32, u: Vec2) -> Option<LightSample> {
        let _ = (p, u_select, u);
        todo!("lights")
    }

    /// Radiance emitted toward `wo` (unit, pointing away from the surface toward the viewer)
    /// from the point with barycentrics `bary` (the hit's u, v) of `triangle` of `instance`;
    /// zero on the back of a one-sided emitter and on non-emitters.
    pub fn emitted(
        &self,
        scene: &Scene,
        instance: u32,
        triangle: u32,
        bary: Vec2,
        wo: Vec3,
    ) -> Vec3 {
        let _ = (scene, instance, triangle, bary, wo);
        todo!("lights")
    }

    /// The solid-angle density (selection included) with which [`sample`](Self::sample), called
    /// at `p`, returns the point `q` of emissive `triangle` of `instance`; 0 when it is not a
    /// light.
    pub fn pdf_triangle(&self, p: Vec3, instance: u32, triangle: u32, q: Vec3) -> f32 {
        let _ = (p, instance, triangle, q);
        todo!("lights")
    }

    /// Radiance of the environment along `dir` (toward the sky); zero without one.
    pub fn environment_radiance(&self, dir: Vec3) -> Vec3 {
        let _ = dir;
        todo!("lights")
    }

    /// The solid-angle density (selection included) of sampling environment direction `dir`.
    pub fn pdf_environment(&self, dir: Vec3) -> f32 {
        let _ = dir;
        todo!("lights")
    }
}
