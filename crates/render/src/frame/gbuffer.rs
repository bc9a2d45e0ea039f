//! The G-buffer and the primary visibility pass that fills it: per pixel, the first surface
//! that the frame's first camera sample sees, its features (position, normal, albedo,
//! roughness, metallic, material, depth) and its motion since the previous frame; and, for the
//! lighting pass, where the path goes on from there.

use glam::{Vec2, Vec3};
use pathlight_accel::{Hit, Ray};
use pathlight_core::rng::Rng;

use crate::camera::Camera;
use crate::path::{CameraSample, PathTracer, Vertex};
use crate::sampler::PixelSampler;

/// Material index of a pixel whose camera ray escaped.
pub const NO_MATERIAL: u32 = u32::MAX;

/// One pixel of the G-buffer.
#[derive(Debug, Clone)]
pub struct GPixel {
    /// World position of the first hit (zero where the ray escaped).
    pub position: Vec3,
    /// Unit world shading normal at the first hit, facing the camera (zero where the ray
    /// escaped).
    pub normal: Vec3,
    /// Base colour at the first hit (zero where the ray escaped).
    pub albedo: Vec3,
    pub roughness: f32,
    pub metallic: f32,
    /// Index into the scene's materials, [`NO_MATERIAL`] where the ray escaped.
    pub material: u32,
    /// Distance along the view axis to the first hit; infinite where the ray escaped.
    pub depth: f32,
    /// Where this pixel's first surface (or, for the sky, its direction) was on the previous
    /// frame's film, minus where it is now, in pixels (zero on the first frame, and where the
    /// point was behind the previous camera).
    pub motion: Vec2,
    /// The first hit is on a light source (an emissive triangle of the light list).
    pub emitter: bool,
    /// Where the pixel's first camera sample lies on the film, in pixels.
    pub film: Vec2,
}

/// Where a camera path goes on after its first hit: what the primary pass hands the lighting
/// pass for one pixel (kept per band of rows, not for the whole screen).
#[derive(Debug, Clone)]
pub struct PrimaryHit {
    pub ray: Ray,
    pub first: Option<Vertex>,
    pub sampler: PixelSampler,
    pub rng: Rng,
}

impl Default for GPixel {
    fn default() -> Self {
        Self {
            position: Vec3::ZERO,
            normal: Vec3::ZERO,
            albedo: Vec3::ZERO,
            roughness: 0.0,
            metallic: 0.0,
            material: NO_MATERIAL,
            depth: f32::INFINITY,
            motion: Vec2::ZERO,
            emitter: false,
            film: Vec2::ZERO,
        }
    }
}

impl GPixel {
    /// True where the camera ray escaped (the environment is seen).
    pub fn is_sky(&self) -> bool {
        self.material == NO_MATERIAL
    }
}

/// The G-buffer: one [`GPixel`] per pixel, row-major, row 0 at the top.
#[derive(Debug, Clone, Default)]
pub struct GBuffer {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<GPixel>,
}

/// Two first hits lie on one surface if each lies within this fraction of the nearer one's
/// depth of the other's tangent plane ([`GBuffer::on_edge`]; a pixel's footprint is about
/// 0.008 of its depth at 320x180 and 70 degrees)...
const EDGE_PLANE: f32 = 0.01;
/// ... and their normals' cosine is at least this.
const EDGE_COSINE: f32 = 0.8;

impl GBuffer {
    /// Whether pixel (`x`, `y`)'s first hit and one of its four neighbours' lie on different
    /// surfaces (one escaped and the other not, normals at an angle, or either point off the
    /// other's tangent plane by more than [`EDGE_PLANE`] of the nearer depth: a crease or a
    /// silhouette, not a plane seen at a grazing angle), where a single camera sample's
    /// coverage aliases.
    pub fn on_edge(&self, x: u32, y: u32) -> bool {
        let (w, h) = (self.width as i64, self.height as i64);
        let g = &self.pixels[(y as i64 * w + x as i64) as usize];
        [(-1, 0), (1, 0), (0, -1), (0, 1)].iter().any(|&(dx, dy)| {
            let (nx, ny) = (x as i64 + dx, y as i64 + dy);
            if nx < 0 || ny < 0 || nx >= w || ny >= h {
                return false;
            }
            let n = &self.pixels[(ny * w + nx) as usize];
            match (g.depth.is_finite(), n.depth.is_finite()) {
                (true, true) => {
                    let d = n.position - g.position;
                    let off = g.normal.dot(d).abs().max(n.normal.dot(d).abs());
                    g.normal.dot(n.normal) < EDGE_COSINE || off > EDGE_PLANE * g.depth.min(n.depth)
                }
                (a, b) => a != b,
            }
        })
    }

    /// Resizes to `width` x `height` (contents undefined until the next pass).
    pub fn resize(&mut self, width: u32, height: u32) {
        self.width = width;
        self.height = height;
        self.pixels
            .resize(width as usize * height as usize, GPixel::default());
    }
}

/// The primary visibility pass for one pixel: follows `sample`, the pixel's camera sample
/// ([`PathTracer::camera_sample`]), to its first surface; `hit` is the closest hit of its ray
/// (the caller traces a run's camera rays together). `previous` is the camera of the previous
/// frame (motion vectors). Returns the G-buffer pixel, the hit for the lighting pass and the
/// rays traced.
#[inline(always)]
pub fn primary(
    tracer: &PathTracer,
    sample: CameraSample,
    hit: Option<Hit>,
    previous: Option<&Camera>,
) -> (GPixel, PrimaryHit, u32) {
    let camera = tracer.camera;
    let CameraSample {
        ray,
        film,
        mut rng,
        sampler,
        ..
    } = sample;
    let mut rays = 0;
    let first = tracer.intersect_from(ray, hit, &mut rng, &mut rays);
    let now_and_then = |at: &dyn Fn(&Camera) -> Option<Vec2>| {
        previous
            .and_then(|prev| Some(at(prev)? - at(camera)?))
            .unwrap_or(Vec2::ZERO)
    };
    let g = match &first {
        Some(v) => GPixel {
            position: v.surface.p,
            normal: v.surface.ns,
            albedo: v.shading.params.base_color,
            roughness: v.shading.params.roughness,
            metallic: v.shading.params.metallic,
            material: v.surface.material,
            depth: v.hit.t * ray.direction.dot(camera.forward()),
            motion: now_and_then(&|c| c.project(v.surface.p)),
            emitter: tracer
                .world
                .lights
                .triangle_light(v.surface.instance, v.surface.triangle)
                .is_some(),
            film,
        },
        None => GPixel {
            motion: now_and_then(&|c| c.project_direction(ray.direction)),
            film,
            ..GPixel::default()
        },
    };
    (
        g,
        PrimaryHit {
            ray,
            first,
            sampler,
            rng,
        },
        rays,
    )
}
