//! The render camera: pinhole or thin lens (seed 001's depth of field) or orthographic, with
//! ray differentials for one-pixel steps in x and y.

use glam::{Mat4, Vec2, Vec3, Vec4};
use pathlight_accel::Ray;
use pathlight_scene::{Camera as SceneCamera, Projection};
use serde::{Deserialize, Serialize};

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
            Projection::Perspective { yfov, .. } => yfov.to_degrees(),
            _ => 45.0,
        });
        SceneCamera::look_at(&base.name, from, at, up, fov)
    }
}

/// How the camera projects.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Kind {
    /// `tan(yfov / 2)`.
    Perspective { tan_half_fov_y: f32 },
    /// Half the view height in scene units.
    Orthographic { half_height: f32 },
}

/// A camera ray with its differentials: the rays through the pixel one step right and one step
/// down (same lens point), as pbrt's `RayDifferential`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraRay {
    pub ray: Ray,
    pub dx_origin: Vec3,
    pub dx_direction: Vec3,
    pub dy_origin: Vec3,
    pub dy_direction: Vec3,
}

/// A camera set up for an image of `width` x `height` pixels.
#[derive(Debug, Clone, PartialEq)]
pub struct Camera {
    to_world: Mat4,
    /// The inverse of `to_world` (world to camera space, for projections).
    to_camera: Mat4,
    kind: Kind,
    width: f32,
    height: f32,
    /// Thin-lens radius in scene units (0: pinhole).
    lens_radius: f32,
    /// Distance of the plane in focus along the view direction.
    focus_distance: f32,
    /// The pinhole's world direction (not unit) through film position (0, 0), and its change
    /// per pixel in x and y: the film as an affine map, so a camera ray costs one normalise.
    film_direction: [Vec3; 3],
    /// World point to homogeneous film coordinates: film = (r0 . p, r1 . p) / (r2 . p), with
    /// r2 . p > 0 in front of a perspective camera (the projection as one matrix).
    projection: [Vec4; 3],
}

impl Camera {
    /// The scene camera `camera` (its aspect ratio is replaced by the image's) as a pinhole.
    pub fn new(camera: &SceneCamera, width: u32, height: u32) -> Self {
        let kind = match camera.projection {
            Projection::Perspective { yfov, .. } => Kind::Perspective {
                tan_half_fov_y: (0.5 * yfov.clamp(1e-4, 3.1)).tan(),
            },
            Projection::Orthographic { ymag, .. } => Kind::Orthographic {
                half_height: ymag.abs().max(1e-6),
            },
        };
        let mut c = Self {
            to_world: camera.transform,
            to_camera: camera.transform.inverse(),
            kind,
            width: width.max(1) as f32,
            height: height.max(1) as f32,
            lens_radius: 0.0,
            focus_distance: 1.0,
            film_direction: [Vec3::ZERO; 3],
            projection: [Vec4::ZERO; 3],
        };
        // `film_point` is affine in the film position: its value at (0, 0) and its steps per
        // pixel, written out (differences of film points would cancel digits away).
        let (half, aspect) = (c.half_height(), c.width / c.height);
        let world = |v: Vec3| c.to_world.transform_vector3(v);
        c.film_direction = [
            world(Vec3::new(-aspect * half, half, -1.0)),
            world(Vec3::new(2.0 * aspect * half / c.width, 0.0, 0.0)),
            world(Vec3::new(0.0, -2.0 * half / c.height, 0.0)),
        ];
        // The perspective projection: film = ((sx + 1) W / 2, (1 - sy) H / 2)
        // with (sx, sy) = (x / (aspect half), y / half) / -z, as rows over camera space,
        // composed with world to camera.
        let rows = c.to_camera.transpose();
        let (kx, ky) = (0.5 * c.width / (aspect * half), 0.5 * c.height / half);
        let depth = -rows.z_axis;
        c.projection = [
            rows.x_axis * kx + depth * (0.5 * c.width),
            rows.y_axis * -ky + depth * (0.5 * c.height),
            depth,
        ];
        c
    }

    /// Adds a thin lens of radius `lens_radius` focused at `focus_distance` (depth of field).
    pub fn with_lens(mut self, lens_radius: f32, focus_distance: f32) -> Self {
        self.lens_radius = lens_radius.max(0.0);
        self.focus_distance = focus_distance.max(1e-4);
        self
    }

    pub fn position(&self) -> Vec3 {
        self.to_world.w_axis.truncate()
    }

    /// The unit view direction.
    pub fn forward(&self) -> Vec3 {
        (-self.to_world.z_axis.truncate()).normalize()
    }

    /// The point on the image plane at distance 1 (camera space) of film position `film` in
    /// pixels ((0, 0) the top-left corner of the image, (width, height) the bottom-right).
    #[inline]
    fn film_point(&self, film: Vec2) -> Vec3 {
        let aspect = self.width / self.height;
        let sx = 2.0 * film.x / self.width - 1.0;
        let sy = 1.0 - 2.0 * film.y / self.height;
        let half = self.half_height();
        Vec3::new(sx * aspect * half, sy * half, -1.0)
    }

    /// Half the film's height on the image plane at distance 1 (perspective) or in scene units
    /// (orthographic).
    fn half_height(&self) -> f32 {
        match self.kind {
            Kind::Perspective { tan_half_fov_y } => tan_half_fov_y,
            Kind::Orthographic { half_height } => half_height,
        }
    }

    /// The camera-space ray through film point `film` and lens sample `lens` in [0,1)^2.
    #[inline]
    fn local_ray(&self, film: Vec2, lens: Vec2) -> (Vec3, Vec3) {
        let p = self.film_point(film);
        let (mut origin, mut dir) = match self.kind {
            Kind::Perspective { .. } => (Vec3::ZERO, p),
            Kind::Orthographic { .. } => (Vec3::new(p.x, p.y, 0.0), Vec3::NEG_Z),
        };
        if self.lens_radius > 0.0 {
            let d = concentric_disk(lens) * self.lens_radius;
            // The ray through the lens centre meets the focal plane at `focus`; every lens
            // point's ray goes there too.
            let focus = origin + dir * (self.focus_distance / -dir.z);
            origin += Vec3::new(d.x, d.y, 0.0);
            dir = focus - origin;
        }
        (origin, dir.normalize())
    }

    /// The world-space ray through film position `film` (pixels) with lens sample `lens`,
    /// without differentials.
    #[inline]
    pub fn primary_ray(&self, film: Vec2, lens: Vec2) -> Ray {
        if self.lens_radius == 0.0 && matches!(self.kind, Kind::Perspective { .. }) {
            let [d0, dx, dy] = self.film_direction;
            return Ray::new(
                self.position(),
                (d0 + dx * film.x + dy * film.y).normalize(),
            );
        }
        let (o, d) = self.local_ray(film, lens);
        Ray::new(
            self.to_world.transform_point3(o),
            self.to_world.transform_vector3(d).normalize(),
        )
    }

    /// The world-space ray through film position `film` (pixels) with lens sample `lens`.
    #[inline]
    pub fn ray(&self, film: Vec2, lens: Vec2) -> CameraRay {
        let world = |(o, d): (Vec3, Vec3)| {
            (
                self.to_world.transform_point3(o),
                self.to_world.transform_vector3(d).normalize(),
            )
        };
        let (origin, direction) = world(self.local_ray(film, lens));
        let (dx_origin, dx_direction) = world(self.local_ray(film + Vec2::X, lens));
        let (dy_origin, dy_direction) = world(self.local_ray(film + Vec2::Y, lens));
        CameraRay {
            ray: Ray::new(origin, direction),
            dx_origin,
            dx_direction,
            dy_origin,
            dy_direction,
        }
    }

    /// The film position (pixels) where world point `p` projects, if it is in front of the
    /// camera (pinhole geometry; used for motion vectors and reprojection).
    #[inline]
    pub fn project(&self, p: Vec3) -> Option<Vec2> {
        match self.kind {
            Kind::Perspective { .. } => self.project_homogeneous(p.extend(1.0)),
            Kind::Orthographic { .. } => {
                self.project_orthographic(self.to_camera.transform_point3(p))
            }
        }
    }

    /// The film position (pixels) where points infinitely far in world direction `d` project
    /// (the environment), if they are in front of the camera.
    #[inline]
    pub fn project_direction(&self, d: Vec3) -> Option<Vec2> {
        match self.kind {
            Kind::Perspective { .. } => self.project_homogeneous(d.extend(0.0)),
            Kind::Orthographic { .. } => None,
        }
    }

    /// Perspective projection of homogeneous world point `h` (a direction when `h.w == 0`).
    #[inline]
    fn project_homogeneous(&self, h: Vec4) -> Option<Vec2> {
        let [a, b, w] = self.projection.map(|r| r.dot(h));
        (w > 0.0).then(|| Vec2::new(a, b) / w)
    }

    /// Orthographic projection of camera-space point `local`.
    fn project_orthographic(&self, local: Vec3) -> Option<Vec2> {
        let half = self.half_height();
        let aspect = self.width / self.height;
        let sx = local.x / (aspect * half);
        let sy = local.y / half;
        Some(Vec2::new(
            (sx + 1.0) * 0.5 * self.width,
            (1.0 - sy) * 0.5 * self.height,
        ))
    }
}

/// Shirley and Chiu's concentric map from the unit square to the unit disk.
#[inline]
pub fn concentric_disk(u: Vec2) -> Vec2 {
    let o = 2.0 * u - Vec2::ONE;
    if o == Vec2::ZERO {
        return Vec2::ZERO;
    }
    let (r, theta) = if o.x.abs() > o.y.abs() {
        (o.x, std::f32::consts::FRAC_PI_4 * (o.y / o.x))
    } else {
        (
            o.y,
            std::f32::consts::FRAC_PI_2 - std::f32::consts::FRAC_PI_4 * (o.x / o.y),
        )
    };
    let (s, c) = theta.sin_cos();
    Vec2::new(r * c, r * s)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cornell(width: u32, height: u32) -> Camera {
        let cam = SceneCamera::look_at(
            "c",
            Vec3::new(0.0, 1.0, 3.5),
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::Y,
            40.107,
        );
        Camera::new(&cam, width, height)
    }

    #[test]
    fn centre_and_edges_follow_the_field_of_view() {
        let c = cornell(256, 128);
        let centre = c.ray(Vec2::new(128.0, 64.0), Vec2::splat(0.5)).ray;
        assert!((centre.direction - Vec3::NEG_Z).length() < 1e-6);
        assert!((centre.origin - Vec3::new(0.0, 1.0, 3.5)).length() < 1e-6);
        // Top edge centre: 20.05 degrees above the axis.
        let top = c.ray(Vec2::new(128.0, 0.0), Vec2::ZERO).ray.direction;
        let angle = top.y.atan2(-top.z).to_degrees();
        assert!((angle - 40.107 / 2.0).abs() < 1e-3, "{angle}");
        // Right edge: horizontal half-angle atan(aspect * tan(vfov / 2)).
        let right = c.ray(Vec2::new(256.0, 64.0), Vec2::ZERO).ray.direction;
        let expected = (2.0 * (20.0535f32).to_radians().tan()).atan();
        assert!((right.x.atan2(-right.z) - expected).abs() < 1e-4);
    }

    #[test]
    fn projection_inverts_the_ray() {
        let c = cornell(320, 200);
        for film in [Vec2::new(10.5, 20.5), Vec2::new(300.0, 150.25)] {
            let r = c.ray(film, Vec2::ZERO).ray;
            let back = c.project(r.at(2.7)).unwrap();
            assert!((back - film).length() < 1e-3, "{film} -> {back}");
        }
    }

    /// The pinhole's precomputed film map and projection matrix agree with the general camera
    /// model (`ray`, which goes through camera space) and invert each other.
    #[test]
    fn fast_pinhole_paths_agree_with_the_camera_model() {
        let c = cornell(640, 360);
        for film in [
            Vec2::ZERO,
            Vec2::new(640.0, 360.0),
            Vec2::new(17.25, 300.5),
            Vec2::new(600.0, 3.0),
        ] {
            let fast = c.primary_ray(film, Vec2::splat(0.3));
            let model = c.ray(film, Vec2::splat(0.3)).ray;
            assert!((fast.origin - model.origin).length() < 1e-6);
            let err = (fast.direction - model.direction).length();
            assert!(err < 1e-6, "{film}: {err}");
            let back = c.project(fast.at(3.3)).unwrap();
            assert!((back - film).length() < 1e-3, "{film} -> {back}");
            let sky = c.project_direction(fast.direction).unwrap();
            assert!((sky - film).length() < 1e-3, "{film} -> {sky}");
        }
        // Behind the camera: no projection.
        assert_eq!(c.project(Vec3::new(0.0, 1.0, 5.0)), None);
        assert_eq!(c.project_direction(Vec3::Z), None);
    }

    #[test]
    fn thin_lens_rays_meet_on_the_focal_plane() {
        let c = cornell(64, 64).with_lens(0.1, 2.5);
        let film = Vec2::new(20.0, 40.0);
        let a = c.ray(film, Vec2::new(0.1, 0.9)).ray;
        let b = c.ray(film, Vec2::new(0.8, 0.3)).ray;
        assert!((a.origin - b.origin).length() > 0.01);
        // Both reach the same point at depth 2.5 along the view axis.
        let at_depth = |r: Ray| r.at((2.5 - (3.5 - r.origin.z)) / -r.direction.z);
        assert!((at_depth(a) - at_depth(b)).length() < 1e-5);
    }

    #[test]
    fn differentials_step_one_pixel() {
        let c = cornell(100, 100);
        let r = c.ray(Vec2::new(50.0, 50.0), Vec2::ZERO);
        let right = c.ray(Vec2::new(51.0, 50.0), Vec2::ZERO).ray;
        assert!((r.dx_direction - right.direction).length() < 1e-6);
        assert!(r.dy_direction.y < r.ray.direction.y);
    }

    #[test]
    fn concentric_disk_stays_inside_and_is_area_preserving() {
        let n = 64;
        let mut inner = 0;
        for i in 0..n {
            for j in 0..n {
                let u = Vec2::new((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
                let d = concentric_disk(u);
                assert!(d.length() <= 1.0 + 1e-6);
                inner += (d.length() < 0.5) as u32;
            }
        }
        // A quarter of the area lies within radius 1/2.
        let frac = inner as f32 / (n * n) as f32;
        assert!((frac - 0.25).abs() < 0.02, "{frac}");
    }
}
