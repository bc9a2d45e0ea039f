//! Cameras as scenes define them. The camera looks down its local -Z axis with +Y up (glTF).

use glam::{Mat4, Vec3};

#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Projection {
    /// Vertical field of view in radians; `aspect` (width / height) when the file fixes it.
    Perspective {
        yfov: f32,
        aspect: Option<f32>,
        znear: f32,
    },
    /// Half-width and half-height of the view volume.
    Orthographic { xmag: f32, ymag: f32, znear: f32 },
}

#[derive(Debug, Clone, PartialEq)]
pub struct Camera {
    pub name: String,
    /// Camera to world (rotation and translation only; loaders remove scale).
    pub transform: Mat4,
    pub projection: Projection,
}

impl Camera {
    /// A perspective camera at `from` looking at `at`, `up` roughly up, vertical field of view
    /// in degrees.
    pub fn look_at(name: &str, from: Vec3, at: Vec3, up: Vec3, yfov_degrees: f32) -> Self {
        let forward = (at - from).normalize();
        let right = forward.cross(up).normalize();
        let true_up = right.cross(forward);
        Self {
            name: name.to_owned(),
            transform: Mat4::from_cols(
                right.extend(0.0),
                true_up.extend(0.0),
                (-forward).extend(0.0),
                from.extend(1.0),
            ),
            projection: Projection::Perspective {
                yfov: yfov_degrees.to_radians(),
                aspect: None,
                znear: 0.0,
            },
        }
    }

    pub fn position(&self) -> Vec3 {
        self.transform.w_axis.truncate()
    }

    /// The unit direction the camera looks along.
    pub fn forward(&self) -> Vec3 {
        (-self.transform.z_axis.truncate()).normalize()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn look_at_points_the_camera() {
        let c = Camera::look_at(
            "c",
            Vec3::new(0.0, 1.0, 3.5),
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::Y,
            40.0,
        );
        assert!((c.position() - Vec3::new(0.0, 1.0, 3.5)).length() < 1e-6);
        assert!((c.forward() - Vec3::NEG_Z).length() < 1e-6);
        assert!((c.transform.y_axis.truncate() - Vec3::Y).length() < 1e-6);
    }
}
