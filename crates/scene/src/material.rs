//! The one material model: glTF 2.0 metallic-roughness with the extensions pathlight reads.
//!
//! Other models are mapped onto it by their loaders:
//! - `KHR_materials_pbrSpecularGlossiness`: see `gltf::material`;
//! - OBJ/MTL: see `obj`; a material with only `Kd` becomes exactly Lambertian
//!   (`specular = 0`, so the dielectric specular layer vanishes).

use glam::{Affine2, Vec2, Vec3, Vec4};

/// How a texture is addressed outside [0, 1].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Wrap {
    #[default]
    Repeat,
    MirroredRepeat,
    ClampToEdge,
}

/// Texture filtering: glTF's magnification filter and whether minification uses mip-maps.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Sampler {
    pub wrap_s: Wrap,
    pub wrap_t: Wrap,
    /// Nearest-neighbour magnification (glTF `NEAREST`); otherwise bilinear.
    pub nearest: bool,
    /// Mip-mapped minification (the default); `false` for glTF's `NEAREST`/`LINEAR` min filters.
    pub mipmaps: bool,
}

impl Default for Sampler {
    fn default() -> Self {
        Self {
            wrap_s: Wrap::Repeat,
            wrap_t: Wrap::Repeat,
            nearest: false,
            mipmaps: true,
        }
    }
}

/// A material's use of a texture: which texture, which UV set, how UVs are transformed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TextureRef {
    /// Index into [`Scene::textures`](crate::Scene::textures).
    pub texture: u32,
    /// 0 for `uv0`, 1 for `uv1`.
    pub texcoord: u32,
    /// `KHR_texture_transform`: uv' = transform * uv (identity when absent).
    pub transform: Affine2,
    pub sampler: Sampler,
}

impl TextureRef {
    pub fn new(texture: u32) -> Self {
        Self {
            texture,
            texcoord: 0,
            transform: Affine2::IDENTITY,
            sampler: Sampler::default(),
        }
    }

    /// The UV at which to look up the texture.
    #[inline]
    pub fn apply(&self, uv: Vec2) -> Vec2 {
        self.transform.transform_point2(uv)
    }
}

/// Builds the `KHR_texture_transform` matrix: translation * rotation * scale, rotation in radians
/// counter-clockwise in UV space as the extension defines it.
pub fn uv_transform(offset: Vec2, rotation: f32, scale: Vec2) -> Affine2 {
    let (s, c) = rotation.sin_cos();
    // The extension's matrix: [c, s; -s, c] (column-major rows as written in the spec).
    let rot = glam::Mat2::from_cols(Vec2::new(c, -s), Vec2::new(s, c));
    Affine2::from_mat2_translation(rot * glam::Mat2::from_diagonal(scale), offset)
}

#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum AlphaMode {
    #[default]
    Opaque,
    /// Cut out where alpha < cutoff.
    Mask { cutoff: f32 },
    /// Blend by alpha (a path tracer treats alpha as stochastic coverage).
    Blend,
}

/// `KHR_materials_volume`: a homogeneous absorbing medium behind a transmissive surface.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Volume {
    /// Thickness in object units (for rasterisers; a path tracer uses the real geometry).
    pub thickness: f32,
    /// Green channel multiplies `thickness`.
    pub thickness_texture: Option<TextureRef>,
    /// Distance at which light has the attenuation colour; infinite when no attenuation.
    pub attenuation_distance: f32,
    pub attenuation_color: Vec3,
}

/// A surface material (glTF 2.0 metallic-roughness plus extensions). All colours are linear.
#[derive(Debug, Clone, PartialEq)]
pub struct Material {
    pub name: String,
    /// Linear RGBA; alpha is coverage.
    pub base_color: Vec4,
    /// sRGB texture, multiplies `base_color`.
    pub base_color_texture: Option<TextureRef>,
    pub metallic: f32,
    /// Perceptual roughness; GGX alpha = roughness^2.
    pub roughness: f32,
    /// Linear texture: green multiplies roughness, blue multiplies metallic.
    pub metallic_roughness_texture: Option<TextureRef>,
    /// Weight of the dielectric specular layer (`KHR_materials_specular`'s `specular`;
    /// 1 by default, 0 for a purely diffuse material).
    pub specular: f32,
    /// Alpha channel multiplies `specular`.
    pub specular_texture: Option<TextureRef>,
    /// Tint of the dielectric F0: F0 = min(((ior-1)/(ior+1))^2 * specular_color, 1).
    pub specular_color: Vec3,
    /// sRGB texture, multiplies `specular_color`.
    pub specular_color_texture: Option<TextureRef>,
    /// Index of refraction (1.5 by default).
    pub ior: f32,
    /// Tangent-space normal map (linear), with its scale.
    pub normal_texture: Option<TextureRef>,
    pub normal_scale: f32,
    /// Ambient occlusion (red channel), with its strength. Not used by a path tracer's lighting.
    pub occlusion_texture: Option<TextureRef>,
    pub occlusion_strength: f32,
    /// Emitted radiance: emissive factor times `KHR_materials_emissive_strength`.
    pub emissive: Vec3,
    /// sRGB texture, multiplies `emissive`.
    pub emissive_texture: Option<TextureRef>,
    /// `KHR_materials_transmission`: fraction of light transmitted by the dielectric base.
    pub transmission: f32,
    /// Red channel multiplies `transmission`.
    pub transmission_texture: Option<TextureRef>,
    pub volume: Option<Volume>,
    pub alpha_mode: AlphaMode,
    pub double_sided: bool,
    /// Whether emission leaves the back face too. glTF: `double_sided` (the material is the same
    /// on both sides); OBJ: false, the emitter shines from its front face only (the winding's
    /// side), as area lights do in Mitsuba and pbrt.
    pub emits_from_back: bool,
}

impl Default for Material {
    /// The glTF default material: white base colour, metallic 1, roughness 1, single-sided,
    /// opaque, as the glTF 2.0 specification defines it.
    fn default() -> Self {
        Self {
            name: String::new(),
            base_color: Vec4::ONE,
            base_color_texture: None,
            metallic: 1.0,
            roughness: 1.0,
            metallic_roughness_texture: None,
            specular: 1.0,
            specular_texture: None,
            specular_color: Vec3::ONE,
            specular_color_texture: None,
            ior: 1.5,
            normal_texture: None,
            normal_scale: 1.0,
            occlusion_texture: None,
            occlusion_strength: 1.0,
            emissive: Vec3::ZERO,
            emissive_texture: None,
            transmission: 0.0,
            transmission_texture: None,
            volume: None,
            alpha_mode: AlphaMode::Opaque,
            double_sided: false,
            emits_from_back: false,
        }
    }
}

impl Material {
    /// A two-sided Lambertian material of the given linear albedo.
    pub fn lambertian(name: &str, albedo: Vec3) -> Self {
        Self {
            name: name.to_owned(),
            base_color: albedo.extend(1.0),
            metallic: 0.0,
            specular: 0.0,
            double_sided: true,
            ..Self::default()
        }
    }

    /// True when the material emits light anywhere.
    pub fn is_emissive(&self) -> bool {
        self.emissive.max_element() > 0.0
    }

    /// Dielectric F0 before textures: min(((ior-1)/(ior+1))^2 * specular_color, 1) * specular.
    pub fn dielectric_f0(&self) -> Vec3 {
        let r = (self.ior - 1.0) / (self.ior + 1.0);
        (self.specular_color * (r * r)).min(Vec3::ONE) * self.specular
    }

    /// Calls `f` on every texture slot of the material (used or not).
    pub fn for_each_texture_slot(&mut self, mut f: impl FnMut(&mut Option<TextureRef>)) {
        f(&mut self.base_color_texture);
        f(&mut self.metallic_roughness_texture);
        f(&mut self.specular_texture);
        f(&mut self.specular_color_texture);
        f(&mut self.normal_texture);
        f(&mut self.occlusion_texture);
        f(&mut self.emissive_texture);
        f(&mut self.transmission_texture);
        if let Some(v) = &mut self.volume {
            f(&mut v.thickness_texture);
        }
    }

    /// Every texture the material uses, with the slot's name.
    pub fn texture_refs(&self) -> Vec<(&'static str, TextureRef)> {
        [
            ("baseColor", self.base_color_texture),
            ("metallicRoughness", self.metallic_roughness_texture),
            ("specular", self.specular_texture),
            ("specularColor", self.specular_color_texture),
            ("normal", self.normal_texture),
            ("occlusion", self.occlusion_texture),
            ("emissive", self.emissive_texture),
            ("transmission", self.transmission_texture),
            ("thickness", self.volume.and_then(|v| v.thickness_texture)),
        ]
        .into_iter()
        .filter_map(|(name, t)| t.map(|t| (name, t)))
        .collect()
    }
}
