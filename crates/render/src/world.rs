//! The scene as the renderer sees it: the scene model, its acceleration structure, its lights
//! and per-instance data the shading code needs on every hit.

use glam::{Mat3, Vec2, Vec4};
use pathlight_accel::{build_accel, Accel};
use pathlight_scene::{AlphaMode, Material, Scene};

use crate::bsdf::{Bsdf, BsdfParams, Microfacet};
use crate::camera::{Camera, CameraConfig};
use crate::camera_path::CameraPath;
use crate::light::{LightSelection, Lights};
use crate::surface::{shade_material, Shading, Surface};
use pathlight_accel::{Hit, Ray};

pub struct World {
    pub scene: Scene,
    pub accel: Box<dyn Accel>,
    pub lights: Lights,
    /// How `lights` chooses a light.
    light_selection: LightSelection,
    /// Object-to-world normal matrix (inverse transpose) per instance.
    pub(crate) normal_matrices: Vec<Mat3>,
    /// Object-to-world linear part per instance (tangents).
    pub(crate) linear: Vec<Mat3>,
    /// True when some material is alpha-masked or blended (rays then look through cut-outs).
    pub(crate) has_alpha: bool,
    /// Per material: its shading and BSDFs where no texture varies them over the surface
    /// (computed once here instead of at every hit).
    uniform: Vec<Option<UniformMaterial>>,
    /// The scene's bounds (its geometry is fixed once the accelerator is built over it).
    bounds: pathlight_scene::Bounds,
}

/// A material without textures: the same shading everywhere (on meshes without vertex
/// colours), and its BSDF for each microfacet distribution.
struct UniformMaterial {
    shading: Shading,
    /// Indexed by [`Microfacet`] (GGX, Beckmann).
    bsdf: [Bsdf; 2],
}

impl UniformMaterial {
    fn new(world_textures: &World, mat: &Material) -> Option<Self> {
        let textured = mat.base_color_texture.is_some()
            || mat.metallic_roughness_texture.is_some()
            || mat.specular_texture.is_some()
            || mat.specular_color_texture.is_some()
            || mat.transmission_texture.is_some();
        if textured {
            return None;
        }
        let shading = shade_material(
            &world_textures.scene,
            mat,
            [Vec2::ZERO; 2],
            Vec4::ONE,
            Microfacet::Ggx,
        );
        let bsdf = [Microfacet::Ggx, Microfacet::Beckmann].map(|distribution| {
            Bsdf::new(&BsdfParams {
                distribution,
                ..shading.params
            })
        });
        Some(Self { shading, bsdf })
    }
}

impl World {
    /// Builds the acceleration structure and the light sampler for `scene`.
    pub fn new(scene: Scene, selection: LightSelection) -> Self {
        let accel = build_accel(&scene);
        Self::with_accel(scene, accel, selection)
    }

    /// As [`new`](Self::new) with a given acceleration structure (e.g. Embree or brute force).
    pub fn with_accel(scene: Scene, accel: Box<dyn Accel>, selection: LightSelection) -> Self {
        let lights = Lights::new(&scene, selection);
        let normal_matrices = scene.instances.iter().map(|i| i.normal_matrix()).collect();
        let linear = scene
            .instances
            .iter()
            .map(|i| Mat3::from_mat4(i.transform))
            .collect();
        let has_alpha = scene
            .materials
            .iter()
            .any(|m| m.alpha_mode != AlphaMode::Opaque);
        let mut world = Self {
            scene,
            accel,
            lights,
            light_selection: selection,
            normal_matrices,
            linear,
            has_alpha,
            uniform: Vec::new(),
            bounds: pathlight_scene::Bounds::EMPTY,
        };
        world.bounds = world.scene.bounds();
        world.uniform = world
            .scene
            .materials
            .iter()
            .map(|m| UniformMaterial::new(&world, m))
            .collect();
        world
    }

    /// The shading of material `material` where it does not vary over the surface (no
    /// textures), with microfacet distribution `distribution`: what
    /// [`shade_material`] gives for any texture coordinates and a white vertex colour.
    #[inline]
    pub(crate) fn uniform_shading(
        &self,
        material: u32,
        distribution: Microfacet,
    ) -> Option<Shading> {
        let u = self.uniform.get(material as usize)?.as_ref()?;
        let mut shading = u.shading;
        shading.params.distribution = distribution;
        Some(shading)
    }

    /// The shading point of `hit` on `ray` ([`Surface::at`]).
    pub fn surface(&self, ray: &Ray, hit: &Hit) -> Surface {
        self.surface_at(ray, hit).0
    }

    /// [`Surface::at`] with this world's instance matrices.
    #[inline(always)]
    fn surface_at(&self, ray: &Ray, hit: &Hit) -> (Surface, [Vec2; 2], Vec4) {
        Surface::at(&self.scene, &self.normal_matrices, &self.linear, ray, hit)
    }

    /// The shading point of `hit` on `ray` and the material's values there.
    #[inline(always)]
    pub fn shaded(&self, ray: &Ray, hit: &Hit, distribution: Microfacet) -> (Surface, Shading) {
        let (surface, uv, color) = self.surface_at(ray, hit);
        if color == Vec4::ONE {
            if let Some(shading) = self.uniform_shading(surface.material, distribution) {
                return (surface, shading);
            }
        }
        let mat = &self.scene.materials[surface.material as usize];
        (
            surface,
            shade_material(&self.scene, mat, uv, color, distribution),
        )
    }

    /// The BSDF of `params` (`Bsdf::new`), taken from the material's precomputed one when
    /// `params` are that material's uniform parameters.
    #[inline]
    pub fn bsdf(&self, material: u32, params: &BsdfParams) -> Bsdf {
        if let Some(Some(u)) = self.uniform.get(material as usize) {
            let b = &u.bsdf[params.distribution as usize];
            if b.params() == params {
                return *b;
            }
        }
        Bsdf::new(params)
    }
}

impl World {
    /// How the light sampler chooses lights.
    pub fn light_selection(&self) -> LightSelection {
        self.light_selection
    }

    /// Rebuilds the light sampler for another way of choosing lights (when it differs).
    pub fn set_light_selection(&mut self, selection: LightSelection) {
        if selection != self.light_selection {
            self.lights = Lights::new(&self.scene, selection);
            self.light_selection = selection;
        }
    }

    /// The scene's first camera, or one that frames the whole scene from +Z when it has none.
    pub fn scene_camera(&self) -> pathlight_scene::Camera {
        if let Some(c) = self.scene.cameras.first() {
            return c.clone();
        }
        let b = self.bounds;
        let (centre, radius) = if b.is_empty() {
            (glam::Vec3::ZERO, 1.0)
        } else {
            (b.center(), (0.5 * b.diagonal().length()).max(1e-3))
        };
        let fov = 45.0f32;
        let distance = radius / (0.5 * fov.to_radians()).sin();
        pathlight_scene::Camera::look_at(
            "default",
            centre + glam::Vec3::Z * distance,
            centre,
            glam::Vec3::Y,
            fov,
        )
    }

    /// The centre of the scene's bounds (the origin for an empty scene).
    pub fn scene_centre(&self) -> glam::Vec3 {
        let b = self.bounds;
        if b.is_empty() {
            glam::Vec3::ZERO
        } else {
            b.center()
        }
    }

    /// The views of a camera path through this scene.
    pub fn path_views(&self, path: &CameraPath) -> Vec<CameraConfig> {
        path.views(&self.scene_camera(), self.scene_centre())
    }

    /// The render camera of `view` for a `width` x `height` image: the scene camera with the
    /// view's overrides, and its thin lens focused at `focus_distance` or, without one, on what
    /// the image centre sees.
    pub fn camera(&self, view: &CameraConfig, width: u32, height: u32) -> Camera {
        let cam = view.apply(&self.scene_camera());
        let camera = Camera::new(&cam, width, height);
        if view.lens_radius <= 0.0 {
            return camera;
        }
        let focus = view.focus_distance.unwrap_or_else(|| {
            let centre = glam::Vec2::new(width as f32, height as f32) * 0.5;
            let ray = camera.ray(centre, glam::Vec2::splat(0.5)).ray;
            self.accel
                .intersect(&ray)
                .map_or(1.0, |h| h.t * ray.direction.dot(camera.forward()))
        });
        camera.with_lens(view.lens_radius, focus)
    }
}
