//! Camera control: orbit around a target or fly, from the mouse and the keys. The camera
//! keeps +Y up (roll is not controlled).

use glam::Vec3;
use pathlight_render::config::CameraConfig;
use pathlight_scene::{Camera as SceneCamera, Projection};

/// How mouse and keys move the camera.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    /// Drag: turn around the target; right-drag or shift-drag: pan; wheel: closer or farther.
    Orbit,
    /// W/A/S/D: move; Q/E: down/up; drag: look around; shift: faster.
    Fly,
}

/// The camera's position and orientation, and the controls' state.
#[derive(Debug, Clone, PartialEq)]
pub struct Navigation {
    pub mode: Mode,
    pub position: Vec3,
    /// Heading about +Y (0: looking along -Z; positive turns left) and elevation, radians.
    pub yaw: f32,
    pub pitch: f32,
    /// Distance from the position to the orbit's target along the view direction.
    pub distance: f32,
    /// Vertical field of view, degrees.
    pub fov_y: f32,
    /// Flying speed, scene units per second.
    pub speed: f32,
    home: Box<(Vec3, f32, f32, f32, f32)>,
}

/// Largest elevation: just short of straight up or down (the view must not flip).
const MAX_PITCH: f32 = 1.55;
/// Radians per pixel of mouse drag.
const TURN_PER_PIXEL: f32 = 0.005;

impl Navigation {
    /// Starts at `camera`, orbiting the point of its view axis nearest `scene_centre`; flies
    /// at a speed that crosses a scene of size `scene_size` in four seconds.
    pub fn new(camera: &SceneCamera, scene_centre: Vec3, scene_size: f32) -> Self {
        let position = camera.position();
        let forward = camera.forward().normalize_or(Vec3::NEG_Z);
        let yaw = (-forward.x).atan2(-forward.z);
        let pitch = forward
            .y
            .clamp(-1.0, 1.0)
            .asin()
            .clamp(-MAX_PITCH, MAX_PITCH);
        let distance = (scene_centre - position)
            .dot(forward)
            .max(1e-3 * scene_size.max(1e-3));
        let fov_y = match camera.projection {
            Projection::Perspective { yfov, .. } => yfov.to_degrees(),
            Projection::Orthographic { .. } => 45.0,
        };
        let speed = (scene_size / 4.0).max(1e-3);
        Self {
            mode: Mode::Orbit,
            position,
            yaw,
            pitch,
            distance,
            fov_y,
            speed,
            home: Box::new((position, yaw, pitch, distance, fov_y)),
        }
    }

    /// The unit view direction.
    pub fn forward(&self) -> Vec3 {
        let (sy, cy) = self.yaw.sin_cos();
        let (sp, cp) = self.pitch.sin_cos();
        Vec3::new(-sy * cp, sp, -cy * cp)
    }

    /// The unit direction to the right of the view.
    pub fn right(&self) -> Vec3 {
        let (sy, cy) = self.yaw.sin_cos();
        Vec3::new(cy, 0.0, -sy)
    }

    /// The orbit's target.
    pub fn target(&self) -> Vec3 {
        self.position + self.forward() * self.distance
    }

    /// Back to the starting view.
    pub fn home(&mut self) {
        let (p, y, pi, d, f) = *self.home;
        (
            self.position,
            self.yaw,
            self.pitch,
            self.distance,
            self.fov_y,
        ) = (p, y, pi, d, f);
    }

    fn turn(&mut self, dx: f32, dy: f32) {
        self.yaw -= dx * TURN_PER_PIXEL;
        self.pitch = (self.pitch - dy * TURN_PER_PIXEL).clamp(-MAX_PITCH, MAX_PITCH);
    }

    /// A drag of (`dx`, `dy`) pixels: orbit around the target, or look around when flying.
    pub fn drag(&mut self, dx: f32, dy: f32) {
        match self.mode {
            Mode::Orbit => {
                let target = self.target();
                self.turn(dx, dy);
                self.position = target - self.forward() * self.distance;
            }
            Mode::Fly => self.turn(dx, dy),
        }
    }

    /// A pan of (`dx`, `dy`) pixels in an image `height` pixels high: the target follows the
    /// mouse.
    pub fn pan(&mut self, dx: f32, dy: f32, height: f32) {
        let up = self.right().cross(self.forward());
        let per_pixel =
            2.0 * self.distance * (0.5 * self.fov_y.to_radians()).tan() / height.max(1.0);
        self.position += (-self.right() * dx + up * dy) * per_pixel;
    }

    /// Mouse wheel: `steps` (positive: closer) move towards the target (orbit) or forward (fly).
    pub fn zoom(&mut self, steps: f32) {
        match self.mode {
            Mode::Orbit => {
                let target = self.target();
                self.distance = (self.distance * (-0.1 * steps).exp()).max(1e-4);
                self.position = target - self.forward() * self.distance;
            }
            Mode::Fly => self.position += self.forward() * (0.1 * steps * self.speed),
        }
    }

    /// Flies `seconds` with keys held: `mv` = (right, up, forward) in -1..=1 each.
    pub fn fly(&mut self, mv: Vec3, seconds: f32) {
        let step = self.speed * seconds;
        self.position += (self.right() * mv.x + Vec3::Y * mv.y + self.forward() * mv.z) * step;
    }

    /// The camera settings of this view (the lens is the configuration's own).
    pub fn camera(&self, base: &CameraConfig) -> CameraConfig {
        CameraConfig {
            look_from: Some(self.position.to_array()),
            look_at: Some((self.position + self.forward()).to_array()),
            up: Some([0.0, 1.0, 0.0]),
            fov_y: Some(self.fov_y),
            ..base.clone()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cornell_camera() -> SceneCamera {
        SceneCamera::look_at(
            "c",
            Vec3::new(0.0, 1.0, 3.5),
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::Y,
            40.0,
        )
    }

    #[test]
    fn starts_at_the_scene_camera() {
        let n = Navigation::new(&cornell_camera(), Vec3::new(0.0, 1.0, 0.0), 2.0);
        assert!(n.forward().abs_diff_eq(Vec3::NEG_Z, 1e-6));
        assert!((n.distance - 3.5).abs() < 1e-5);
        assert!(n.target().abs_diff_eq(Vec3::new(0.0, 1.0, 0.0), 1e-5));
        let c = n.camera(&CameraConfig::default());
        assert_eq!(c.look_from, Some([0.0, 1.0, 3.5]));
        assert!((c.fov_y.unwrap() - 40.0).abs() < 1e-4);
        // Turned 90 degrees to the left, the camera looks along -X; right is then -Z.
        let n = Navigation {
            yaw: std::f32::consts::FRAC_PI_2,
            ..n
        };
        assert!(n.forward().abs_diff_eq(Vec3::NEG_X, 1e-6));
        assert!(n.right().abs_diff_eq(Vec3::NEG_Z, 1e-6));
    }

    #[test]
    fn orbit_keeps_the_target_and_the_distance() {
        let mut n = Navigation::new(&cornell_camera(), Vec3::new(0.0, 1.0, 0.0), 2.0);
        let target = n.target();
        n.drag(120.0, -40.0);
        assert!(n.target().abs_diff_eq(target, 1e-4));
        assert!(((n.position - target).length() - 3.5).abs() < 1e-4);
        n.zoom(3.0);
        assert!(n.target().abs_diff_eq(target, 1e-4));
        assert!(n.distance < 3.5);
        // Pitch stays short of the poles.
        n.drag(0.0, -1e6);
        assert!(n.pitch <= MAX_PITCH);
        n.home();
        assert!(n.forward().abs_diff_eq(Vec3::NEG_Z, 1e-6));
    }

    #[test]
    fn flying_moves_along_the_view() {
        let mut n = Navigation::new(&cornell_camera(), Vec3::new(0.0, 1.0, 0.0), 4.0);
        n.mode = Mode::Fly;
        let start = n.position;
        n.fly(Vec3::new(0.0, 0.0, 1.0), 2.0);
        // Speed: a 4-unit scene in 4 seconds, so 2 units in 2 seconds, along -Z.
        assert!((n.position - (start + Vec3::new(0.0, 0.0, -2.0))).length() < 1e-5);
        n.fly(Vec3::new(1.0, 0.0, 0.0), 1.0);
        assert!((n.position.x - 1.0).abs() < 1e-5);
        // Looking around does not move.
        let p = n.position;
        n.drag(50.0, 10.0);
        assert_eq!(n.position, p);
    }

    #[test]
    fn panning_moves_camera_and_target_together() {
        let mut n = Navigation::new(&cornell_camera(), Vec3::new(0.0, 1.0, 0.0), 2.0);
        let (p0, t0) = (n.position, n.target());
        n.pan(100.0, 0.0, 360.0);
        let moved = n.position - p0;
        assert!(moved.abs_diff_eq(n.target() - t0, 1e-5));
        assert!(moved.x < 0.0 && moved.y.abs() < 1e-6, "{moved}");
    }
}
