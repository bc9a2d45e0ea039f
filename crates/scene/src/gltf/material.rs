//! glTF materials and textures onto pathlight's [`Material`] model.
//!
//! Metallic-roughness materials map one to one, with `KHR_materials_emissive_strength`,
//! `KHR_materials_ior`, `KHR_materials_specular`, `KHR_materials_transmission`,
//! `KHR_materials_volume` and `KHR_texture_transform`.
//!
//! `KHR_materials_pbrSpecularGlossiness` is converted as glTF-Transform's `metalRough()` does,
//! with `KHR_materials_specular` carrying the specular colour so that nothing is lost:
//! - base colour = `diffuseFactor` (and `diffuseTexture`), metallic = 0;
//! - dielectric F0 = `specularFactor` x specular texture RGB: `specular = 1`,
//!   `specular_color = specularFactor / 0.04` (so `min(0.04 * specular_color, 1)` at ior 1.5
//!   equals `specularFactor`), `specular_color_texture` = the RGB of `specularGlossinessTexture`;
//! - roughness = 1 - `glossinessFactor` x texture alpha: the texture is baked into a derived
//!   metallic-roughness texture (green = roughness) at load time.
//!
//! What differs: the spec-gloss model scales diffuse by `1 - max(F0)`; the metal-rough model
//! with a specular layer scales it by `1 - F(view)`: equal at normal incidence for grey F0,
//! close elsewhere.

use std::borrow::Cow;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

use ::gltf::json;
use glam::{Vec2, Vec3, Vec4};
use json::validation::Checked;
use rayon::prelude::*;

use super::buffer::{decode_data_uri, resolve_uri, Buffers};
use crate::error::{SceneError, Warnings};
use crate::limits::Limits;
use crate::material::{uv_transform, AlphaMode, Material, Sampler, TextureRef, Volume, Wrap};
use crate::source::SceneSource;
use crate::texture::{check_pixels, decode_image, image_header, ColorSpace, Texture};

/// A change made to an image's texels before it becomes a texture.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
enum Derivation {
    None,
    /// Spec-gloss: green = 1 - glossiness factor x alpha; blue (metallic) = 0.
    GlossToRoughness {
        factor_bits: u32,
    },
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
struct Request {
    image: usize,
    color_space: ColorSpace,
    derivation: Derivation,
}

/// The bytes of an image to decode, the file they came from and the size its header declares.
struct Fetched<'b> {
    bytes: Cow<'b, [u8]>,
    from: PathBuf,
    width: u32,
    height: u32,
}

/// Converts materials, collecting the textures they need, then decodes those in parallel.
pub struct MaterialConverter<'a> {
    pub root: &'a json::Root,
    pub file: &'a Path,
    requests: Vec<Request>,
    request_ids: HashMap<Request, u32>,
}

impl<'a> MaterialConverter<'a> {
    pub fn new(root: &'a json::Root, file: &'a Path) -> Self {
        Self {
            root,
            file,
            requests: Vec::new(),
            request_ids: HashMap::new(),
        }
    }

    /// A texture slot: `TextureRef.texture` holds a request id until [`finish`](Self::finish).
    fn slot(
        &mut self,
        texture: usize,
        tex_coord: u32,
        transform: Option<&json::extensions::texture::TextureTransform>,
        color_space: ColorSpace,
        derivation: Derivation,
        warnings: &mut Warnings,
    ) -> Option<TextureRef> {
        let Some(t) = self.root.textures.get(texture) else {
            warnings.push(
                self.file,
                format!("texture {texture} does not exist; ignored"),
            );
            return None;
        };
        let image = t.source.value();
        if self.root.images.get(image).is_none() {
            warnings.push(
                self.file,
                format!("texture {texture} names image {image}, which does not exist; ignored"),
            );
            return None;
        }
        let request = Request {
            image,
            color_space,
            derivation,
        };
        let next = self.requests.len() as u32;
        let id = *self.request_ids.entry(request).or_insert_with(|| {
            self.requests.push(request);
            next
        });
        let mut r = TextureRef::new(id);
        r.texcoord = tex_coord;
        if let Some(tt) = transform {
            r.transform = uv_transform(
                Vec2::from(tt.offset.0),
                tt.rotation.0,
                Vec2::from(tt.scale.0),
            );
            if let Some(tc) = tt.tex_coord {
                r.texcoord = tc;
            }
        }
        if r.texcoord > 1 {
            warnings.push(
                self.file,
                format!(
                    "texture {texture} uses TEXCOORD_{}; only 0 and 1 are read, using 0",
                    r.texcoord
                ),
            );
            r.texcoord = 0;
        }
        if !r.transform.is_finite() {
            warnings.push(
                self.file,
                format!("texture {texture} has a non-finite KHR_texture_transform; ignored"),
            );
            r.transform = glam::Affine2::IDENTITY;
        }
        if let Some(s) = t.sampler.and_then(|s| self.root.samplers.get(s.value())) {
            r.sampler = sampler(s);
        }
        Some(r)
    }

    fn info(
        &mut self,
        info: &Option<json::texture::Info>,
        cs: ColorSpace,
        warnings: &mut Warnings,
    ) -> Option<TextureRef> {
        let info = info.as_ref()?;
        let tt = info
            .extensions
            .as_ref()
            .and_then(|e| e.texture_transform.as_ref());
        self.slot(
            info.index.value(),
            info.tex_coord,
            tt,
            cs,
            Derivation::None,
            warnings,
        )
    }

    /// Converts material `index`.
    pub fn convert(&mut self, index: usize, warnings: &mut Warnings) -> Material {
        let Some(m) = self.root.materials.get(index) else {
            return Material::default();
        };
        let pbr = &m.pbr_metallic_roughness;
        let mut out = Material {
            name: m
                .name
                .clone()
                .unwrap_or_else(|| format!("material {index}")),
            base_color: Vec4::from(pbr.base_color_factor.0),
            metallic: pbr.metallic_factor.0,
            roughness: pbr.roughness_factor.0,
            emissive: Vec3::from(m.emissive_factor.0),
            double_sided: m.double_sided,
            emits_from_back: m.double_sided,
            ..Material::default()
        };
        out.base_color_texture = self.info(&pbr.base_color_texture, ColorSpace::Srgb, warnings);
        out.metallic_roughness_texture = self.info(
            &pbr.metallic_roughness_texture,
            ColorSpace::Linear,
            warnings,
        );
        out.emissive_texture = self.info(&m.emissive_texture, ColorSpace::Srgb, warnings);
        if let Some(n) = &m.normal_texture {
            let tt = transform_from_others(n.extensions.as_ref().map(|e| &e.others));
            out.normal_texture = self.slot(
                n.index.value(),
                n.tex_coord,
                tt.as_ref(),
                ColorSpace::Linear,
                Derivation::None,
                warnings,
            );
            out.normal_scale = n.scale;
        }
        if let Some(o) = &m.occlusion_texture {
            let tt = transform_from_others(o.extensions.as_ref().map(|e| &e.others));
            out.occlusion_texture = self.slot(
                o.index.value(),
                o.tex_coord,
                tt.as_ref(),
                ColorSpace::Linear,
                Derivation::None,
                warnings,
            );
            out.occlusion_strength = o.strength.0;
        }
        out.alpha_mode = match m.alpha_mode {
            Checked::Valid(json::material::AlphaMode::Mask) => AlphaMode::Mask {
                cutoff: m.alpha_cutoff.map_or(0.5, |c| c.0),
            },
            Checked::Valid(json::material::AlphaMode::Blend) => AlphaMode::Blend,
            _ => AlphaMode::Opaque,
        };
        if let Some(ext) = &m.extensions {
            if let Some(s) = &ext.emissive_strength {
                out.emissive *= s.emissive_strength.0;
            }
            if let Some(ior) = &ext.ior {
                out.ior = ior.ior.0;
            }
            if let Some(s) = &ext.specular {
                out.specular = s.specular_factor.0;
                out.specular_texture = self.info(&s.specular_texture, ColorSpace::Linear, warnings);
                out.specular_color = Vec3::from(s.specular_color_factor.0);
                out.specular_color_texture =
                    self.info(&s.specular_color_texture, ColorSpace::Srgb, warnings);
            }
            if let Some(t) = &ext.transmission {
                out.transmission = t.transmission_factor.0;
                out.transmission_texture =
                    self.info(&t.transmission_texture, ColorSpace::Linear, warnings);
            }
            if let Some(v) = &ext.volume {
                out.volume = Some(Volume {
                    thickness: v.thickness_factor.0,
                    thickness_texture: self.info(
                        &v.thickness_texture,
                        ColorSpace::Linear,
                        warnings,
                    ),
                    attenuation_distance: v.attenuation_distance.0,
                    attenuation_color: Vec3::from(v.attenuation_color.0),
                });
            }
            if let Some(sg) = &ext.pbr_specular_glossiness {
                out.base_color = Vec4::from(sg.diffuse_factor.0);
                out.base_color_texture = self.info(&sg.diffuse_texture, ColorSpace::Srgb, warnings);
                out.metallic = 0.0;
                out.metallic_roughness_texture = None;
                out.specular = 1.0;
                out.specular_texture = None;
                out.ior = 1.5;
                out.specular_color = Vec3::from(sg.specular_factor.0) / 0.04;
                let gloss = sg.glossiness_factor.0;
                out.roughness = 1.0 - gloss;
                out.specular_color_texture = None;
                if let Some(info) = &sg.specular_glossiness_texture {
                    let tt = info
                        .extensions
                        .as_ref()
                        .and_then(|e| e.texture_transform.as_ref());
                    let index = info.index.value();
                    out.specular_color_texture = self.slot(
                        index,
                        info.tex_coord,
                        tt,
                        ColorSpace::Srgb,
                        Derivation::None,
                        warnings,
                    );
                    let derivation = Derivation::GlossToRoughness {
                        factor_bits: gloss.to_bits(),
                    };
                    out.metallic_roughness_texture = self.slot(
                        index,
                        info.tex_coord,
                        tt,
                        ColorSpace::Linear,
                        derivation,
                        warnings,
                    );
                    out.roughness = 1.0;
                }
            }
        }
        sanitize(&mut out, self.file, warnings);
        out
    }

    /// Decodes every requested texture (in parallel), then points the materials' texture slots
    /// at the decoded textures. A texture that cannot be read is dropped with a warning, and the
    /// material falls back to its factors.
    pub fn finish(
        self,
        materials: &mut [Material],
        buffers: &Buffers,
        source: &SceneSource,
        limits: &Limits,
        warnings: &mut Warnings,
    ) -> Vec<Texture> {
        let fetched: Vec<Result<Fetched, SceneError>> = self
            .requests
            .par_iter()
            .map(|r| self.fetch(r, buffers, source, limits))
            .collect();
        // Admit the images against the limit on all texture pixels by their headers, in request
        // order, before decoding any: a small file of many highly compressed large images must
        // not be decoded (up to gigabytes each) only to be dropped afterwards.
        let mut total_pixels = 0u64;
        let admitted: Vec<Result<Fetched, SceneError>> = self
            .requests
            .iter()
            .zip(fetched)
            .map(|(r, f)| {
                let f = f?;
                total_pixels = total_pixels.saturating_add(f.width as u64 * f.height as u64);
                if total_pixels > limits.max_total_texture_pixels {
                    return Err(SceneError::new(
                        self.file,
                        format!(
                            "image {}: the textures exceed the limit of {} pixels in all",
                            r.image, limits.max_total_texture_pixels
                        ),
                    ));
                }
                Ok(f)
            })
            .collect();
        let decoded: Vec<Result<Texture, SceneError>> = admitted
            .into_par_iter()
            .zip(self.requests.par_iter())
            .map(|(f, r)| f.and_then(|f| self.decode(r, f, limits)))
            .collect();
        let mut textures = Vec::new();
        let mut final_id = Vec::with_capacity(decoded.len());
        for d in decoded {
            match d {
                Ok(t) => {
                    final_id.push(Some(textures.len() as u32));
                    textures.push(t);
                }
                Err(e) => {
                    warnings.push(
                        &e.file,
                        format!("{}; the material uses its factors instead", e.problem),
                    );
                    final_id.push(None);
                }
            }
        }
        for m in materials {
            m.for_each_texture_slot(|slot| {
                if let Some(r) = slot {
                    match final_id[r.texture as usize] {
                        Some(id) => r.texture = id,
                        None => *slot = None,
                    }
                }
            });
        }
        textures
    }

    /// Reads the bytes of a requested image and the size its header declares.
    fn fetch<'b>(
        &self,
        r: &Request,
        buffers: &'b Buffers,
        source: &SceneSource,
        limits: &Limits,
    ) -> Result<Fetched<'b>, SceneError> {
        let image = &self.root.images[r.image];
        let what = |p: &str| format!("image {}: {p}", r.image);
        let (bytes, from): (Cow<[u8]>, PathBuf) = match (&image.uri, image.buffer_view) {
            (Some(uri), _) => match decode_data_uri(uri, self.file) {
                Some(b) => (b?.into(), self.file.to_path_buf()),
                None => {
                    let path = resolve_uri(source, self.file, uri)
                        .map_err(|e| SceneError::new(&e.file, what(&e.problem)))?;
                    (source.read(&path, limits.max_file_bytes)?.into(), path)
                }
            },
            (None, Some(view)) => (
                buffers.view(self.root, view.value(), self.file)?.into(),
                self.file.to_path_buf(),
            ),
            (None, None) => {
                return Err(SceneError::new(
                    self.file,
                    what("has neither a URI nor a bufferView"),
                ))
            }
        };
        let (_, width, height) = image_header(&bytes, &from)
            .and_then(|(f, w, h)| {
                check_pixels(&from, w, h, limits.max_texture_pixels).map(|_| (f, w, h))
            })
            .map_err(|e| self.name(r, &from, e))?;
        Ok(Fetched {
            bytes,
            from,
            width,
            height,
        })
    }

    /// An image error, saying which image when the file named is the scene file itself.
    fn name(&self, r: &Request, from: &Path, e: SceneError) -> SceneError {
        if from == self.file {
            SceneError::new(&e.file, format!("image {}: {}", r.image, e.problem))
        } else {
            e
        }
    }

    /// Decodes a fetched image into a texture.
    fn decode(&self, r: &Request, f: Fetched, limits: &Limits) -> Result<Texture, SceneError> {
        let image = &self.root.images[r.image];
        let (w, h, mut texels) = decode_image(&f.bytes, &f.from, limits.max_texture_pixels)
            .map_err(|e| self.name(r, &f.from, e))?;
        if let Derivation::GlossToRoughness { factor_bits } = r.derivation {
            let g = f32::from_bits(factor_bits);
            for t in &mut texels {
                let rough = 1.0 - g * (t[3] as f32 / 255.0);
                *t = [0, (rough.clamp(0.0, 1.0) * 255.0 + 0.5) as u8, 0, 255];
            }
        }
        let name = image
            .name
            .clone()
            .or_else(|| image.uri.clone().filter(|u| !u.starts_with("data:")))
            .unwrap_or_else(|| format!("image {}", r.image));
        Ok(Texture::new(name, w, h, texels, r.color_space))
    }
}

fn sampler(s: &json::texture::Sampler) -> Sampler {
    use json::texture::{MagFilter, MinFilter, WrappingMode};
    let wrap = |w: &Checked<WrappingMode>| match w {
        Checked::Valid(WrappingMode::ClampToEdge) => Wrap::ClampToEdge,
        Checked::Valid(WrappingMode::MirroredRepeat) => Wrap::MirroredRepeat,
        _ => Wrap::Repeat,
    };
    Sampler {
        wrap_s: wrap(&s.wrap_s),
        wrap_t: wrap(&s.wrap_t),
        nearest: s.mag_filter == Some(Checked::Valid(MagFilter::Nearest)),
        mipmaps: !matches!(
            s.min_filter,
            Some(Checked::Valid(MinFilter::Nearest | MinFilter::Linear))
        ),
    }
}

/// `KHR_texture_transform` on a normal or occlusion texture, which gltf-json keeps unparsed.
fn transform_from_others(
    others: Option<&serde_json::Map<String, serde_json::Value>>,
) -> Option<json::extensions::texture::TextureTransform> {
    let v = others?.get("KHR_texture_transform")?;
    serde_json::from_value(v.clone()).ok()
}

/// Replaces non-finite or out-of-range factors with the glTF defaults, with a warning.
fn sanitize(m: &mut Material, file: &Path, warnings: &mut Warnings) {
    let mut fixed = Vec::new();
    let mut unit = |v: &mut f32, default: f32, name: &str| {
        if !(0.0..=1.0).contains(v) {
            fixed.push(format!("{name} {v}"));
            *v = if v.is_finite() {
                v.clamp(0.0, 1.0)
            } else {
                default
            };
        }
    };
    unit(&mut m.metallic, 1.0, "metallic");
    unit(&mut m.roughness, 1.0, "roughness");
    unit(&mut m.specular, 1.0, "specular");
    unit(&mut m.transmission, 0.0, "transmission");
    unit(&mut m.occlusion_strength, 1.0, "occlusion strength");
    for k in 0..4 {
        unit(&mut m.base_color[k], 1.0, "base colour");
    }
    if !m.emissive.is_finite() || m.emissive.min_element() < 0.0 {
        fixed.push(format!("emissive {}", m.emissive));
        m.emissive = Vec3::ZERO;
    }
    if !m.specular_color.is_finite() || m.specular_color.min_element() < 0.0 {
        fixed.push(format!("specular colour {}", m.specular_color));
        m.specular_color = Vec3::ONE;
    }
    if !(m.ior.is_finite() && m.ior >= 1.0) {
        fixed.push(format!("ior {}", m.ior));
        m.ior = 1.5;
    }
    if !m.normal_scale.is_finite() {
        fixed.push(format!("normal scale {}", m.normal_scale));
        m.normal_scale = 1.0;
    }
    if let AlphaMode::Mask { cutoff } = &mut m.alpha_mode {
        if !cutoff.is_finite() || *cutoff < 0.0 {
            fixed.push(format!("alpha cutoff {cutoff}"));
            *cutoff = 0.5;
        }
    }
    if let Some(v) = &mut m.volume {
        if !(v.thickness.is_finite() && v.thickness >= 0.0) {
            fixed.push(format!("thickness {}", v.thickness));
            v.thickness = 0.0;
        }
        if v.attenuation_distance.is_nan() || v.attenuation_distance <= 0.0 {
            fixed.push(format!("attenuation distance {}", v.attenuation_distance));
            v.attenuation_distance = f32::INFINITY;
        }
        if !v.attenuation_color.is_finite() {
            v.attenuation_color = Vec3::ONE;
        }
    }
    if !fixed.is_empty() {
        warnings.push(
            file,
            format!(
                "material \"{}\": invalid values replaced: {}",
                m.name,
                fixed.join(", ")
            ),
        );
    }
}
