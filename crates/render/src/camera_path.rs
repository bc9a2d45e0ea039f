//! Scripted camera motion: the views that `pathlight play` renders frame by frame and that
//! experiments measure, from keyframes or from built-in protocols (seed 000's rotation in
//! steps, a translation, an orbit).
//!
//! A path is data (TOML): see `experiments/README.md` and the README's `play` section.

use glam::{Quat, Vec3};
use pathlight_scene::{Camera as SceneCamera, Projection};
use serde::{Deserialize, Serialize};

use crate::camera::CameraConfig;

/// Most views a path may produce (a typo must not ask for years of frames).
pub const MAX_VIEWS: usize = 100_000;

/// A camera path.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CameraPath {
    pub path: PathKind,
    /// The first view: overrides of the scene's camera (as `--look-from` etc.).
    pub look_from: Option<[f32; 3]>,
    pub look_at: Option<[f32; 3]>,
    pub up: Option<[f32; 3]>,
    pub fov_y: Option<f32>,
    /// Rotation: total angle about the vertical axis through the camera (counter-clockwise
    /// seen from above) in steps of `step_degrees` (seed 000: 100 degrees in 5 degree steps).
    /// Orbit: total angle of the camera around the pivot, in `steps` steps.
    pub degrees: f32,
    pub step_degrees: f32,
    /// Translation: total offset of the camera, in `steps` equal steps.
    pub offset: [f32; 3],
    /// Translation and orbit: the number of steps (views after the first).
    pub steps: u32,
    /// Orbit: the point circled (default: the point of the view axis nearest the scene's
    /// centre).
    pub pivot: Option<[f32; 3]>,
    /// Keyframes: views at given times, interpolated linearly at `fps` views per second.
    pub keyframes: Vec<Keyframe>,
    pub fps: f32,
    /// Frames rendered at each view (seed 000's samples per step, at one sample per frame).
    pub frames_per_view: u32,
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
            pivot: None,
            keyframes: Vec::new(),
            fps: 30.0,
            frames_per_view: 1,
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum PathKind {
    Still,
    Rotation,
    Translation,
    Orbit,
    Keyframes,
}

/// A view at a time (seconds).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Keyframe {
    pub time: f32,
    pub look_from: [f32; 3],
    pub look_at: [f32; 3],
    #[serde(default = "y_up")]
    pub up: [f32; 3],
    /// Vertical field of view in degrees (default: the scene camera's).
    #[serde(default)]
    pub fov_y: Option<f32>,
}

fn y_up() -> [f32; 3] {
    [0.0, 1.0, 0.0]
}

impl CameraPath {
    /// Checks every value, so that [`views`](Self::views) cannot fail or run away.
    pub fn validate(&self) -> Result<(), String> {
        let finite = |v: [f32; 3]| v.iter().all(|c| c.is_finite());
        if [self.look_from, self.look_at, self.up, self.pivot]
            .iter()
            .flatten()
            .any(|v| !finite(*v))
            || !finite(self.offset)
        {
            return Err("camera path: vectors must be finite".into());
        }
        let fov_ok = |f: f32| f > 0.0 && f < 180.0;
        if let Some(f) = self.fov_y.filter(|f| !fov_ok(*f)) {
            return Err(format!("fov_y {f}: must be between 0 and 180"));
        }
        if self.frames_per_view > 1 << 20 {
            return Err(format!(
                "frames_per_view {}: at most {}",
                self.frames_per_view,
                1 << 20
            ));
        }
        let views = match self.path {
            PathKind::Still => 1.0,
            PathKind::Rotation => {
                if !(self.degrees.is_finite() && self.step_degrees.is_finite())
                    || self.step_degrees <= 0.0
                {
                    return Err(format!(
                        "degrees {} and step_degrees {}: must be finite, the step > 0",
                        self.degrees, self.step_degrees
                    ));
                }
                (self.degrees.abs() / self.step_degrees).ceil() + 1.0
            }
            PathKind::Translation | PathKind::Orbit => {
                if !self.degrees.is_finite() {
                    return Err(format!("degrees {}: must be finite", self.degrees));
                }
                self.steps as f32 + 1.0
            }
            PathKind::Keyframes => {
                if self.keyframes.is_empty() {
                    return Err("keyframes: give at least one [[keyframes]]".into());
                }
                if !(self.fps.is_finite() && self.fps > 0.0) {
                    return Err(format!("fps {}: must be finite and > 0", self.fps));
                }
                for (i, k) in self.keyframes.iter().enumerate() {
                    let ok = k.time.is_finite()
                        && k.time >= 0.0
                        && finite(k.look_from)
                        && finite(k.look_at)
                        && finite(k.up)
                        && k.fov_y.is_none_or(fov_ok);
                    if !ok {
                        return Err(format!(
                            "keyframe {i}: time must be finite and >= 0, vectors finite, fov_y in (0, 180)"
                        ));
                    }
                    if i > 0 && k.time <= self.keyframes[i - 1].time {
                        return Err(format!("keyframe {i}: times must increase"));
                    }
                    if (Vec3::from(k.look_at) - Vec3::from(k.look_from)).length_squared() == 0.0 {
                        return Err(format!("keyframe {i}: look_from equals look_at"));
                    }
                }
                self.keyframes.last().expect("not empty").time * self.fps + 1.0
            }
        };
        if views > MAX_VIEWS as f32 {
            return Err(format!("{views} views: at most {MAX_VIEWS}"));
        }
        Ok(())
    }

    /// The views in order: the first (the scene camera with this path's overrides), then one
    /// per step. `scene_centre` places the orbit's default pivot.
    pub fn views(&self, scene_camera: &SceneCamera, scene_centre: Vec3) -> Vec<CameraConfig> {
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
        let view = |from: Vec3, forward: Vec3, up: Vec3, fov: f32| CameraConfig {
            look_from: Some(from.to_array()),
            look_at: Some((from + forward).to_array()),
            up: Some(up.to_array()),
            fov_y: Some(fov),
            ..CameraConfig::default()
        };
        match self.path {
            PathKind::Still => vec![view(from, forward, up, fov)],
            PathKind::Rotation => {
                let steps = (self.degrees.abs() / self.step_degrees).ceil() as u32;
                (0..=steps)
                    .map(|i| {
                        let angle = (i as f32 * self.step_degrees).min(self.degrees.abs())
                            * self.degrees.signum();
                        let q = Quat::from_rotation_y(angle.to_radians());
                        view(from, q * forward, q * up, fov)
                    })
                    .collect()
            }
            PathKind::Translation => (0..=self.steps)
                .map(|i| {
                    let t = i as f32 / self.steps.max(1) as f32;
                    view(from + Vec3::from(self.offset) * t, forward, up, fov)
                })
                .collect(),
            PathKind::Orbit => {
                let pivot = self.pivot.map(Vec3::from).unwrap_or_else(|| {
                    // The point of the view axis nearest the scene's centre (in front of the
                    // camera).
                    from + forward * (scene_centre - from).dot(forward).max(1e-3)
                });
                (0..=self.steps)
                    .map(|i| {
                        let t = i as f32 / self.steps.max(1) as f32;
                        let q = Quat::from_rotation_y((self.degrees * t).to_radians());
                        let p = pivot + q * (from - pivot);
                        view(p, q * forward, q * up, fov)
                    })
                    .collect()
            }
            PathKind::Keyframes => {
                let k = &self.keyframes;
                let last = k.last().expect("validated: not empty").time;
                let count = (last * self.fps).floor() as usize + 1;
                (0..count)
                    .map(|i| {
                        let t = i as f32 / self.fps;
                        let j = k.partition_point(|f| f.time <= t).clamp(1, k.len()) - 1;
                        let a = &k[j];
                        let b = k.get(j + 1).unwrap_or(a);
                        let s = if b.time > a.time {
                            ((t - a.time) / (b.time - a.time)).clamp(0.0, 1.0)
                        } else {
                            0.0
                        };
                        let lerp = |x: [f32; 3], y: [f32; 3]| Vec3::from(x).lerp(Vec3::from(y), s);
                        let from = lerp(a.look_from, b.look_from);
                        let at = lerp(a.look_at, b.look_at);
                        let up = lerp(a.up, b.up).normalize_or(Vec3::Y);
                        let fa = a.fov_y.unwrap_or(fov);
                        let fb = b.fov_y.unwrap_or(fov);
                        view(from, at - from, up, fa + (fb - fa) * s)
                    })
                    .collect()
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera() -> SceneCamera {
        SceneCamera::look_at(
            "c",
            Vec3::new(1.0, 2.0, 3.0),
            Vec3::new(1.0, 2.0, 2.0),
            Vec3::Y,
            40.0,
        )
    }

    fn dir(v: &CameraConfig) -> Vec3 {
        Vec3::from(v.look_at.unwrap()) - Vec3::from(v.look_from.unwrap())
    }

    #[test]
    fn rotation_turns_about_the_camera_in_steps() {
        let p = CameraPath {
            path: PathKind::Rotation,
            degrees: 100.0,
            step_degrees: 30.0,
            ..CameraPath::default()
        };
        p.validate().unwrap();
        let views = p.views(&camera(), Vec3::ZERO);
        // 0, 30, 60, 90, 100 degrees.
        assert_eq!(views.len(), 5);
        assert!(views.iter().all(|v| v.look_from == Some([1.0, 2.0, 3.0])));
        assert!(dir(&views[0]).abs_diff_eq(Vec3::NEG_Z, 1e-5));
        // Counter-clockwise seen from above: -Z turns towards -X.
        let d = 100f32.to_radians();
        assert!(dir(&views[4]).abs_diff_eq(Vec3::new(-d.sin(), 0.0, -d.cos()), 1e-5));
    }

    #[test]
    fn translation_moves_in_equal_steps() {
        let p = CameraPath {
            path: PathKind::Translation,
            offset: [2.0, 0.0, 0.0],
            steps: 4,
            ..CameraPath::default()
        };
        let xs: Vec<f32> = p
            .views(&camera(), Vec3::ZERO)
            .iter()
            .map(|v| v.look_from.unwrap()[0])
            .collect();
        assert_eq!(xs, vec![1.0, 1.5, 2.0, 2.5, 3.0]);
    }

    #[test]
    fn orbit_keeps_its_distance_and_looks_at_the_pivot() {
        let p = CameraPath {
            path: PathKind::Orbit,
            degrees: 90.0,
            steps: 3,
            ..CameraPath::default()
        };
        // The scene's centre at (1, 2, 0): the pivot is (1, 2, 0), 3 in front of the camera.
        let views = p.views(&camera(), Vec3::new(1.0, 0.0, 0.0));
        assert_eq!(views.len(), 4);
        let pivot = Vec3::new(1.0, 2.0, 0.0);
        for v in &views {
            let from = Vec3::from(v.look_from.unwrap());
            assert!(((from - pivot).length() - 3.0).abs() < 1e-4);
            assert!(dir(v)
                .normalize()
                .abs_diff_eq((pivot - from).normalize(), 1e-4));
        }
        // A quarter turn counter-clockwise from +Z of the pivot ends at +X.
        let last = Vec3::from(views[3].look_from.unwrap());
        assert!(last.abs_diff_eq(Vec3::new(4.0, 2.0, 0.0), 1e-4), "{last}");
    }

    #[test]
    fn keyframes_interpolate_at_the_frame_rate() {
        let p = CameraPath {
            path: PathKind::Keyframes,
            fps: 4.0,
            keyframes: vec![
                Keyframe {
                    time: 0.0,
                    look_from: [0.0, 0.0, 0.0],
                    look_at: [0.0, 0.0, -1.0],
                    up: y_up(),
                    fov_y: Some(40.0),
                },
                Keyframe {
                    time: 1.0,
                    look_from: [4.0, 0.0, 0.0],
                    look_at: [4.0, 0.0, -1.0],
                    up: y_up(),
                    fov_y: Some(60.0),
                },
            ],
            ..CameraPath::default()
        };
        p.validate().unwrap();
        let views = p.views(&camera(), Vec3::ZERO);
        assert_eq!(views.len(), 5);
        let xs: Vec<f32> = views.iter().map(|v| v.look_from.unwrap()[0]).collect();
        assert_eq!(xs, vec![0.0, 1.0, 2.0, 3.0, 4.0]);
        assert_eq!(views[2].fov_y, Some(50.0));
    }

    #[test]
    fn bad_paths_are_refused() {
        let bad = [
            CameraPath {
                path: PathKind::Rotation,
                step_degrees: 0.0,
                ..CameraPath::default()
            },
            CameraPath {
                path: PathKind::Rotation,
                degrees: 1e9,
                step_degrees: 1e-3,
                ..CameraPath::default()
            },
            CameraPath {
                path: PathKind::Keyframes,
                ..CameraPath::default()
            },
            CameraPath {
                fov_y: Some(500.0),
                ..CameraPath::default()
            },
            CameraPath {
                offset: [f32::NAN, 0.0, 0.0],
                ..CameraPath::default()
            },
            CameraPath {
                path: PathKind::Keyframes,
                fps: 1e9,
                keyframes: vec![Keyframe {
                    time: 100.0,
                    look_from: [0.0; 3],
                    look_at: [0.0, 0.0, 1.0],
                    up: y_up(),
                    fov_y: None,
                }],
                ..CameraPath::default()
            },
        ];
        for p in bad {
            assert!(p.validate().is_err(), "{p:?}");
        }
    }
}
