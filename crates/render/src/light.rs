//! The scene's lights as the path tracer samples them: emissive triangles, punctual lights
//! (glTF `KHR_lights_punctual`) and the environment, chosen in proportion to power (or
//! uniformly) with an alias table.
//!
//! Light indices: the scene's emissive triangles first (in `Scene::emissive_triangles` order),
//! then its punctual lights (in `Scene::lights` order), then the environment.
//!
//! Conventions:
//! - Emissive triangles: world corners are the instance's transform of the mesh's corners. The
//!   front face is the side of `normal_matrix * cross(b - a, c - a)` (object space), which is
//!   `sign(det M) * cross` of the world corners: a mirroring transform keeps the front where the
//!   object space put it, as glTF requires. One-sided emitters (`two_sided == false`) shine
//!   from the front only. Points are sampled uniformly by area (`sqrt(u)` barycentric map);
//!   densities are converted to solid angle (`pdf_area * d^2 / |cos_light|`). Radiance is the
//!   material's `emissive` times its emissive texture at the point's interpolated UV.
//! - Punctual lights: point and spot intensities are candela (W/sr): radiance term
//!   `I / d^2`; spots use glTF's smooth falloff, directional lights give their illuminance.
//!   glTF's range window `clamp(1 - (d/range)^4, 0, 1)^2` applies when `range` is set.
//! - Environment: importance sampled in proportion to luminance over the sphere, texel by
//!   texel ([`environment::EnvironmentMap`]: a block of texels by a 2D CDF, a texel in it by
//!   16-bit cuts, a direction uniform in solid angle within the texel; texels that are exactly
//!   black get probability 0; there is no floor). A direction's radiance and density are
//!   those of the texel it falls in, one record read; `sample` evaluates its density and
//!   radiance from the sampled direction through the same lookup as `pdf_environment` and
//!   `environment_radiance`, so they agree bit for bit.
//!
//! Power (for [`LightSelection::Power`], as luminance), pbrt-v4's conventions: triangle
//! `EmissiveTriangle::power` (pi * area * mean radiance, doubled when two-sided); point 4 pi I;
//! spot 2 pi I (1 - (cos_inner + cos_outer) / 2); directional pi r^2 E; environment
//! pi r^2 * (integral of radiance over the sphere), with r the radius of the scene's bounding
//! sphere (1 when the scene has no geometry).
//!
//! `Lights` owns what sampling needs, as `sample` gets no scene: each emissive triangle's world
//! corners and front normal (64 bytes), the UVs of textured emitters, clones of the textures
//! used as emissive textures, and the environment's texels with their densities (16 bytes per
//! texel) and sampling tables (about 2 bytes per texel).

use std::collections::HashMap;
use std::f32::consts::PI;

use glam::{Mat3, Vec2, Vec3, Vec4Swizzles};
use pathlight_scene::{Material, PunctualKind, Scene, Texture, TextureRef};
use serde::{Deserialize, Serialize};

use crate::alias::AliasTable;

pub mod environment;
pub mod sun;

use environment::{weight, EnvironmentMap};
#[cfg(test)]
pub(crate) mod tests;

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

/// A light point as seed 004's SIMD lanes evaluate it ([`Lights::lane_light`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum LaneLight {
    Point {
        position: Vec3,
        intensity: Vec3,
        inv_range: f32,
    },
    /// A point of an emissive triangle, with the emission there (its texture evaluated).
    Triangle {
        point: Vec3,
        normal: Vec3,
        two_sided: bool,
        emission: Vec3,
    },
    /// Light from a direction, the same at every point (the environment's direction, a
    /// directional light): unit `wi` toward it, the radiance (illuminance) arriving along it.
    Distant { wi: Vec3, radiance: Vec3 },
}

/// A point chosen on a light, independent of any shading point (seed 004's reservoirs keep
/// it and re-evaluate it at other pixels and frames with [`Lights::evaluate`]).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct LightPoint {
    /// The light's index (see the module doc).
    pub light: u32,
    /// Area lights: the world point; the environment: the unit direction toward it; punctual
    /// lights: unused (zero).
    pub point: Vec3,
    /// Area lights: the point's barycentrics (for the emissive texture).
    pub bary: Vec2,
}

/// "No entry" in the index tables.
const NONE: u32 = u32::MAX;

/// An emissive triangle in world space.
#[derive(Debug, Clone, Copy)]
struct TriangleLight {
    a: Vec3,
    /// b - a and c - a: the point of barycentrics (u, v) is a + u e1 + v e2.
    e1: Vec3,
    e2: Vec3,
    /// Unit normal on the emitting (front) side.
    normal: Vec3,
    area: f32,
    two_sided: bool,
    /// Index into `Lights::emitters`.
    emitter: u32,
    /// Index into `Lights::uvs` (the corners' UVs for the emissive texture), or `NONE`.
    uvs: u32,
}

/// The emission of one material: its factor and its texture (index into `Lights::textures`).
#[derive(Debug, Clone, Copy)]
struct Emitter {
    emissive: Vec3,
    texture: Option<(u32, TextureRef)>,
}

#[derive(Debug, Clone, Copy)]
enum Punctual {
    Point {
        position: Vec3,
        intensity: Vec3,
        /// 1 / range, 0 without range.
        inv_range: f32,
    },
    Spot {
        position: Vec3,
        /// Unit direction the light travels along the axis.
        axis: Vec3,
        intensity: Vec3,
        inv_range: f32,
        /// glTF's falloff: clamp(cos * scale + offset, 0, 1)^2.
        scale: f32,
        offset: f32,
    },
    Directional {
        /// Unit direction toward the light.
        wi: Vec3,
        illuminance: Vec3,
    },
}

/// The environment: its map (never selected when every texel is black).
#[derive(Debug, Clone)]
struct EnvironmentLight {
    map: EnvironmentMap,
}

/// Every light of a scene, ready to sample.
#[derive(Debug, Clone)]
pub struct Lights {
    count: usize,
    /// Over all lights; `None` when no light has positive power.
    selection: Option<AliasTable>,
    triangles: Vec<TriangleLight>,
    emitters: Vec<Emitter>,
    uvs: Vec<[Vec2; 3]>,
    textures: Vec<Texture>,
    punctual: Vec<Punctual>,
    environment: Option<EnvironmentLight>,
    /// (instance, triangle) -> light: `triangle_lights[instance_base[instance] + triangle]`
    /// (`instance_base` is `NONE` for instances without emissive triangles; entries are `NONE`
    /// for triangles that are not lights). One u32 per triangle of the instances that emit:
    /// O(1) lookup, no hashing.
    instance_base: Vec<u32>,
    triangle_lights: Vec<u32>,
    /// Per light, what [`lane_light`](Self::lane_light) reads (one lookup per candidate
    /// instead of the selection table's, the triangle's, the emitter's and the punctual
    /// light's).
    lanes: Vec<LaneEntry>,
}

/// A light as the SIMD lanes read it ([`Lights::lane_light`]).
#[derive(Debug, Clone, Copy)]
enum LaneEntry {
    /// Not in the lanes: spot lights, lights that cannot be selected.
    None,
    /// A point or directional light: the same wherever it is seen from.
    Fixed(LaneLight),
    /// The environment: its radiance along the point's direction.
    Environment,
    /// An emissive triangle, with its emission when that has no texture.
    Triangle {
        normal: Vec3,
        two_sided: bool,
        emission: Option<Vec3>,
    },
}

/// glTF's range window (1 without range).
#[inline]
pub(crate) fn range_window(distance: f32, inv_range: f32) -> f32 {
    let x = distance * inv_range;
    let w = (1.0 - (x * x) * (x * x)).clamp(0.0, 1.0);
    w * w
}

/// The emissive texture of a material and the UVs of a triangle's corners for it.
fn emissive_texture_uvs(
    scene: &Scene,
    mat: &Material,
    mesh: u32,
    triangle: usize,
) -> Option<(TextureRef, [Vec2; 3])> {
    let tex = mat.emissive_texture?;
    scene.textures.get(tex.texture as usize)?;
    let mesh = &scene.meshes[mesh as usize];
    let uvs = match tex.texcoord {
        0 => mesh.uv0.as_ref(),
        _ => mesh.uv1.as_ref(),
    }?;
    let corners = mesh.indices[triangle].map(|i| uvs[i as usize]);
    Some((tex, corners))
}

/// `emissive` times the texture at barycentrics `bary` of the corners' UVs.
#[inline]
fn textured(
    emissive: Vec3,
    texture: &Texture,
    tex: &TextureRef,
    uvs: [Vec2; 3],
    bary: Vec2,
) -> Vec3 {
    let uv = uvs[0] * (1.0 - bary.x - bary.y) + uvs[1] * bary.x + uvs[2] * bary.y;
    emissive * texture.sample(tex.apply(uv), &tex.sampler).xyz()
}

impl Lights {
    pub fn new(scene: &Scene, selection: LightSelection) -> Self {
        let mut weights = Vec::new();

        // Emissive triangles.
        let mut triangles = Vec::with_capacity(scene.emissive_triangles.len());
        let mut emitters = Vec::new();
        let mut emitter_of_material: HashMap<u32, u32> = HashMap::new();
        let mut textures = Vec::new();
        let mut texture_index: HashMap<u32, u32> = HashMap::new();
        let mut uvs = Vec::new();
        let mut instance_base = vec![NONE; scene.instances.len()];
        let mut triangle_lights = Vec::new();
        for (light, et) in scene.emissive_triangles.iter().enumerate() {
            let inst = &scene.instances[et.instance as usize];
            let mesh = &scene.meshes[inst.mesh as usize];
            let material = mesh.material;
            let mat = &scene.materials[material as usize];
            let [a, b, c] = mesh
                .triangle(et.triangle as usize)
                .map(|p| inst.transform.transform_point3(p));
            let (e1, e2) = (b - a, c - a);
            let cross = e1.cross(e2);
            let det = Mat3::from_mat4(inst.transform).determinant();
            let normal = (cross * det.signum()).normalize_or_zero();
            let area = 0.5 * cross.length();
            let emitter = *emitter_of_material.entry(material).or_insert_with(|| {
                let texture = mat.emissive_texture.and_then(|t| {
                    scene.textures.get(t.texture as usize)?;
                    let local = *texture_index.entry(t.texture).or_insert_with(|| {
                        textures.push(scene.textures[t.texture as usize].clone());
                        textures.len() as u32 - 1
                    });
                    Some((local, t))
                });
                emitters.push(Emitter {
                    emissive: mat.emissive,
                    texture,
                });
                emitters.len() as u32 - 1
            });
            let corner_uvs = if emitters[emitter as usize].texture.is_some() {
                emissive_texture_uvs(scene, mat, inst.mesh, et.triangle as usize).map_or(
                    NONE,
                    |(_, c)| {
                        uvs.push(c);
                        uvs.len() as u32 - 1
                    },
                )
            } else {
                NONE
            };
            let usable = area > 0.0 && area.is_finite() && normal != Vec3::ZERO;
            triangles.push(TriangleLight {
                a,
                e1,
                e2,
                normal,
                area,
                two_sided: et.two_sided,
                emitter,
                uvs: corner_uvs,
            });
            weights.push(if usable { weight(et.power) } else { 0.0 });

            let base = &mut instance_base[et.instance as usize];
            if *base == NONE {
                *base = triangle_lights.len() as u32;
                triangle_lights.resize(triangle_lights.len() + mesh.indices.len(), NONE);
            }
            triangle_lights[*base as usize + et.triangle as usize] = light as u32;
        }

        // The scene's bounding-sphere radius, for the power of lights at infinity.
        let needs_radius = scene.environment.is_some()
            || scene
                .lights
                .iter()
                .any(|l| l.kind == PunctualKind::Directional);
        let radius = if needs_radius {
            let b = scene.bounds();
            let r = 0.5 * b.diagonal().length();
            if !b.is_empty() && r > 0.0 && r.is_finite() {
                r
            } else {
                1.0
            }
        } else {
            1.0
        };
        let disk = PI * radius * radius;

        // Punctual lights.
        let mut punctual = Vec::with_capacity(scene.lights.len());
        for l in &scene.lights {
            let inv_range = match l.range {
                Some(r) if r > 0.0 && r.is_finite() => 1.0 / r,
                _ => 0.0,
            };
            let intensity = l.intensity;
            let (light, power) = match l.kind {
                PunctualKind::Point => (
                    Punctual::Point {
                        position: l.position,
                        intensity,
                        inv_range,
                    },
                    4.0 * PI * intensity,
                ),
                PunctualKind::Spot {
                    inner_cone,
                    outer_cone,
                } => {
                    let (cos_inner, cos_outer) = (inner_cone.cos(), outer_cone.cos());
                    let scale = 1.0 / (cos_inner - cos_outer).max(0.001);
                    let axis = l.direction.normalize_or_zero();
                    (
                        Punctual::Spot {
                            position: l.position,
                            axis,
                            intensity,
                            inv_range,
                            scale,
                            offset: -cos_outer * scale,
                        },
                        if axis == Vec3::ZERO {
                            Vec3::ZERO
                        } else {
                            2.0 * PI * intensity * (1.0 - 0.5 * (cos_inner + cos_outer))
                        },
                    )
                }
                PunctualKind::Directional => {
                    let wi = -l.direction.normalize_or_zero();
                    (
                        Punctual::Directional {
                            wi,
                            illuminance: intensity,
                        },
                        if wi == Vec3::ZERO {
                            Vec3::ZERO
                        } else {
                            disk * intensity
                        },
                    )
                }
            };
            punctual.push(light);
            weights.push(weight(power));
        }

        // The environment.
        let environment = scene.environment.as_ref().map(|env| {
            let map = EnvironmentMap::new(env);
            let power = if map.is_lit() {
                disk * map.integral as f32
            } else {
                0.0
            };
            weights.push(if power.is_finite() { power } else { 0.0 });
            EnvironmentLight { map }
        });

        if selection == LightSelection::Uniform {
            for w in &mut weights {
                *w = if *w > 0.0 { 1.0 } else { 0.0 };
            }
        }
        let mut lights = Self {
            count: weights.len(),
            selection: AliasTable::new(&weights),
            triangles,
            emitters,
            uvs,
            textures,
            punctual,
            environment,
            instance_base,
            triangle_lights,
            lanes: Vec::new(),
        };
        lights.lanes = (0..lights.count).map(|i| lights.lane_entry(i)).collect();
        lights
    }

    /// Light `index` as [`lane_light`](Self::lane_light) reads it.
    fn lane_entry(&self, index: usize) -> LaneEntry {
        let select = self.selection_pmf(index);
        if !(select > 0.0 && select.is_finite()) {
            return LaneEntry::None;
        }
        if let Some(t) = self.triangles.get(index) {
            let e = &self.emitters[t.emitter as usize];
            let textured = e.texture.is_some() && t.uvs != NONE;
            return LaneEntry::Triangle {
                normal: t.normal,
                two_sided: t.two_sided,
                emission: (!textured).then_some(e.emissive),
            };
        }
        match self.punctual.get(index - self.triangles.len()) {
            Some(&Punctual::Point {
                position,
                intensity,
                inv_range,
            }) => LaneEntry::Fixed(LaneLight::Point {
                position,
                intensity,
                inv_range,
            }),
            Some(&Punctual::Directional { wi, illuminance }) => {
                LaneEntry::Fixed(LaneLight::Distant {
                    wi,
                    radiance: illuminance,
                })
            }
            Some(Punctual::Spot { .. }) => LaneEntry::None,
            None if self.environment.is_some() => LaneEntry::Environment,
            None => LaneEntry::None,
        }
    }

    /// Number of lights (emissive triangles + punctual lights + the environment).
    pub fn len(&self) -> usize {
        self.count
    }

    pub fn is_empty(&self) -> bool {
        self.count == 0
    }

    /// The light sources apart from the environment: emissive materials (each however many
    /// triangles it covers) and punctual lights.
    pub fn sources(&self) -> usize {
        self.emitters.len() + self.punctual.len()
    }

    /// The punctual lights (point, spot, directional).
    pub fn punctual_lights(&self) -> usize {
        self.punctual.len()
    }

    /// Whether an environment map lights the scene.
    pub fn has_environment(&self) -> bool {
        self.environment.is_some()
    }

    /// The probability of selecting light `index` (see the module doc for the indices).
    pub fn selection_pmf(&self, index: usize) -> f32 {
        self.selection.as_ref().map_or(0.0, |t| t.pmf(index))
    }

    /// The light index of emissive `triangle` of `instance`, if it is a light: O(1).
    #[inline]
    pub fn triangle_light(&self, instance: u32, triangle: u32) -> Option<usize> {
        let base = *self.instance_base.get(instance as usize)?;
        if base == NONE {
            return None;
        }
        let light = *self
            .triangle_lights
            .get(base as usize + triangle as usize)?;
        (light != NONE).then_some(light as usize)
    }

    /// Samples a light and a point on it as seen from `p`: `u_select` picks the light, `u` the
    /// point. `None` when nothing can be sampled (no light, or the point is behind a one-sided
    /// emitter), and whenever the sample would carry no radiance (outside a spot's cone or a
    /// light's range, on a black texel). The same as [`choose`](Self::choose), then
    /// [`sample_point`](Self::sample_point), then [`evaluate`](Self::evaluate).
    #[inline]
    pub fn sample(&self, p: Vec3, u_select: f32, u: Vec2) -> Option<LightSample> {
        let (index, select) = self.choose(u_select)?;
        let (ls, _) = self.evaluate_selected(p, &self.sample_point(index, u)?, select)?;
        Some(ls)
    }

    /// Picks a light: its index and the probability of picking it.
    #[inline]
    pub fn choose(&self, u: f32) -> Option<(usize, f32)> {
        Some(self.selection.as_ref()?.sample(u))
    }

    /// A point on light `index` (see the module doc for the indices), independent of the
    /// shading point: what a reservoir keeps and re-evaluates elsewhere (seed 004). Area
    /// lights: uniform by area; punctual lights: the light itself; the environment: a
    /// direction from its distribution. `None` for an index out of range or a black
    /// environment.
    #[inline]
    pub fn sample_point(&self, index: usize, u: Vec2) -> Option<LightPoint> {
        let n_tri = self.triangles.len();
        if let Some(t) = self.triangles.get(index) {
            let s = u.x.max(0.0).sqrt();
            let bu = u.y * s;
            let bv = s - bu;
            let bary = Vec2::new(bu, bv);
            Some(LightPoint {
                light: index as u32,
                point: t.a + t.e1 * bu + t.e2 * bv,
                bary,
            })
        } else if index - n_tri < self.punctual.len() {
            Some(LightPoint {
                light: index as u32,
                point: Vec3::ZERO,
                bary: Vec2::ZERO,
            })
        } else if index + 1 == self.count {
            let light = self.environment.as_ref()?;
            Some(LightPoint {
                light: index as u32,
                point: light.map.sample(u)?,
                bary: Vec2::ZERO,
            })
        } else {
            None
        }
    }

    /// [`choose`](Self::choose) then [`sample_point`](Self::sample_point), with the point's
    /// density [`point_pdf`](Self::point_pdf) (seed 004's candidates).
    #[inline]
    pub fn draw(&self, u_select: f32, u: Vec2) -> Option<(LightPoint, f32)> {
        let (index, select) = self.choose(u_select)?;
        let point = self.sample_point(index, u)?;
        Some((point, self.point_pdf_selected(&point, select)))
    }

    /// What seed 004's lanes need to evaluate `point` as
    /// [`evaluate_geometry`](Self::evaluate_geometry) does, for point and directional lights,
    /// emissive triangles and the environment whose selection probability is positive and
    /// finite (the environment's radiance looked up once here, zero where its density is not
    /// positive and finite, as `evaluate_geometry` finds nothing there); `None` for every
    /// other light (the lanes leave those to `evaluate_geometry`).
    #[inline]
    pub fn lane_light(&self, point: &LightPoint) -> Option<LaneLight> {
        let index = point.light as usize;
        match *self.lanes.get(index)? {
            LaneEntry::None => None,
            LaneEntry::Fixed(light) => Some(light),
            LaneEntry::Environment => {
                let texel = self.environment.as_ref()?.map.lookup(point.point);
                let pdf = self.selection_pmf(index) * texel.pdf;
                Some(LaneLight::Distant {
                    wi: point.point,
                    radiance: match pdf > 0.0 && pdf.is_finite() {
                        true => texel.radiance,
                        false => Vec3::ZERO,
                    },
                })
            }
            LaneEntry::Triangle {
                normal,
                two_sided,
                emission,
            } => Some(LaneLight::Triangle {
                point: point.point,
                normal,
                two_sided,
                emission: emission
                    .unwrap_or_else(|| self.triangle_radiance(&self.triangles[index], point.bary)),
            }),
        }
    }

    /// [`evaluate`](Self::evaluate) and the geometry term that converts the point's measure to
    /// solid angle at `p` (`point_pdf / pdf`): `cos_light / d^2` on triangles, 1 elsewhere.
    #[inline]
    pub fn evaluate_geometry(&self, p: Vec3, point: &LightPoint) -> Option<(LightSample, f32)> {
        if point.light as usize >= self.count {
            return None;
        }
        let select = self.selection_pmf(point.light as usize);
        self.evaluate_selected(p, point, select)
    }

    /// `point` (from [`sample_point`](Self::sample_point)) as seen from `p`: direction,
    /// distance, radiance, and the solid-angle density (selection included) with which
    /// [`sample`](Self::sample) at `p` returns it. `None` where `p` is behind a one-sided
    /// emitter or the point carries no radiance toward `p`.
    #[inline]
    pub fn evaluate(&self, p: Vec3, point: &LightPoint) -> Option<LightSample> {
        if point.light as usize >= self.count {
            return None;
        }
        let select = self.selection_pmf(point.light as usize);
        self.evaluate_selected(p, point, select).map(|(ls, _)| ls)
    }

    /// The density with which [`choose`](Self::choose) then
    /// [`sample_point`](Self::sample_point) produce `point`, in the point's own measure:
    /// per unit area on triangles, per light for punctual lights, per unit solid angle for the
    /// environment (seed 004's reservoirs resample in this domain).
    #[inline]
    pub fn point_pdf(&self, point: &LightPoint) -> f32 {
        let index = point.light as usize;
        if index >= self.count {
            return 0.0;
        }
        self.point_pdf_selected(point, self.selection_pmf(index))
    }

    /// [`point_pdf`](Self::point_pdf) given the light's selection probability `select`.
    #[inline]
    fn point_pdf_selected(&self, point: &LightPoint, select: f32) -> f32 {
        let index = point.light as usize;
        if select == 0.0 {
            return 0.0;
        }
        if let Some(t) = self.triangles.get(index) {
            select / t.area
        } else if index - self.triangles.len() < self.punctual.len() {
            select
        } else {
            (self.environment.as_ref())
                .map_or(0.0, |light| select * light.map.lookup(point.point).pdf)
        }
    }

    /// The point seen from `p` with selection probability `select`, and its geometry term
    /// ([`evaluate_geometry`](Self::evaluate_geometry)).
    #[inline]
    fn evaluate_selected(
        &self,
        p: Vec3,
        point: &LightPoint,
        select: f32,
    ) -> Option<(LightSample, f32)> {
        let index = point.light as usize;
        let n_tri = self.triangles.len();
        let (sample, g) = if let Some(t) = self.triangles.get(index) {
            let (wi, distance, pdf) = solid_angle(t, p, point.point)?;
            (
                LightSample {
                    wi,
                    distance,
                    radiance: self.triangle_radiance(t, point.bary),
                    pdf: select * pdf,
                    delta: false,
                },
                1.0 / (t.area * pdf),
            )
        } else if let Some(light) = self.punctual.get(index - n_tri) {
            (sample_punctual(light, p, select)?, 1.0)
        } else {
            (self.environment_sample(point.point, select)?, 1.0)
        };
        (sample.radiance.max_element() > 0.0 && sample.pdf > 0.0 && sample.pdf.is_finite())
            .then_some((sample, g))
    }

    #[inline(always)]
    fn triangle_radiance(&self, t: &TriangleLight, bary: Vec2) -> Vec3 {
        let e = &self.emitters[t.emitter as usize];
        match e.texture {
            Some((texture, tex)) if t.uvs != NONE => textured(
                e.emissive,
                &self.textures[texture as usize],
                &tex,
                self.uvs[t.uvs as usize],
                bary,
            ),
            _ => e.emissive,
        }
    }

    /// The environment light toward direction `wi` (unit), as sampled.
    fn environment_sample(&self, wi: Vec3, select: f32) -> Option<LightSample> {
        let light = self.environment.as_ref()?;
        // The density and radiance of the direction itself, as `environment` finds them for a
        // ray that escapes that way: the same texel, bit for bit (so that the MIS weights of
        // the two strategies agree exactly).
        let texel = light.map.lookup(wi);
        Some(LightSample {
            wi,
            distance: f32::INFINITY,
            radiance: texel.radiance,
            pdf: select * texel.pdf,
            delta: false,
        })
    }

    /// Radiance emitted toward `wo` (unit, pointing away from the surface toward the viewer)
    /// from the point with barycentrics `bary` (the hit's u, v) of `triangle` of `instance`;
    /// zero on the back of a one-sided emitter and on non-emitters.
    ///
    /// Triangles of an emissive material that are not in the light list (those
    /// `Scene::collect_emissive_triangles` found black at its sample points) are evaluated from
    /// `scene`: they are then seen only by BSDF sampling, and `pdf_triangle` is 0 for them.
    pub fn emitted(
        &self,
        scene: &Scene,
        instance: u32,
        triangle: u32,
        bary: Vec2,
        wo: Vec3,
    ) -> Vec3 {
        if let Some(light) = self.triangle_light(instance, triangle) {
            let t = &self.triangles[light];
            if !t.two_sided && t.normal.dot(wo) <= 0.0 {
                return Vec3::ZERO;
            }
            return self.triangle_radiance(t, bary);
        }
        emitted_from_scene(scene, instance, triangle, bary, wo)
    }

    /// The solid-angle density (selection included) with which [`sample`](Self::sample), called
    /// at `p`, returns the point `q` of emissive `triangle` of `instance`; 0 when it is not a
    /// light or `p` is behind a one-sided emitter.
    pub fn pdf_triangle(&self, p: Vec3, instance: u32, triangle: u32, q: Vec3) -> f32 {
        let Some(light) = self.triangle_light(instance, triangle) else {
            return 0.0;
        };
        let select = self.selection_pmf(light);
        if select == 0.0 {
            return 0.0;
        }
        solid_angle(&self.triangles[light], p, q).map_or(0.0, |(_, _, pdf)| select * pdf)
    }

    /// The most a white Lambertian surface lit by these lights directly can reflect, in
    /// luminance: the environment's irradiance at most (its luminance over the whole sphere)
    /// over pi, plus the brightest emissive triangle's luminance (a surface against it receives
    /// at most pi times that); infinite with a punctual light (a point's irradiance grows
    /// without bound as a surface nears it). Light beyond it reaching a surface through one
    /// bounce came off a glossy or specular surface (a caustic).
    pub fn reflected_bound(&self) -> f32 {
        if !self.punctual.is_empty() {
            return f32::INFINITY;
        }
        let environment = (self.environment.as_ref()).map_or(0.0, |e| e.map.integral as f32 / PI);
        // (An emissive texture scales the factor by at most 1.)
        let emitters = (self.emitters.iter())
            .map(|e| weight(e.emissive))
            .fold(0.0f32, f32::max);
        environment + emitters
    }

    /// Radiance of the environment along `dir` (toward the sky); zero without one.
    pub fn environment_radiance(&self, dir: Vec3) -> Vec3 {
        self.environment(dir).0
    }

    /// The solid-angle density (selection included) of sampling environment direction `dir`
    /// (unit length).
    pub fn pdf_environment(&self, dir: Vec3) -> f32 {
        self.environment(dir).1
    }

    /// The environment's radiance from direction `dir` (unit length) and the solid-angle
    /// density (selection included) of sampling it, from one lookup.
    pub fn environment(&self, dir: Vec3) -> (Vec3, f32) {
        let Some(light) = &self.environment else {
            return (Vec3::ZERO, 0.0);
        };
        let texel = light.map.lookup(dir);
        let select = self.selection_pmf(self.count - 1);
        let pdf = if select == 0.0 {
            0.0
        } else {
            select * texel.pdf
        };
        (texel.radiance, pdf)
    }
}

/// Direction, distance and solid-angle density (without selection) of point `q` of `t` seen
/// from `p`; `None` when `p` is behind a one-sided emitter or the density is not finite.
#[inline]
fn solid_angle(t: &TriangleLight, p: Vec3, q: Vec3) -> Option<(Vec3, f32, f32)> {
    let to = q - p;
    let d2 = to.length_squared();
    let distance = d2.sqrt();
    let wi = to / distance;
    let cos = -t.normal.dot(wi);
    let cos = if t.two_sided { cos.abs() } else { cos };
    if cos.is_nan() || cos <= 0.0 {
        return None;
    }
    let pdf = d2 / (t.area * cos);
    (pdf > 0.0 && pdf.is_finite()).then_some((wi, distance, pdf))
}

#[inline]
fn sample_punctual(light: &Punctual, p: Vec3, select: f32) -> Option<LightSample> {
    let toward = |position: Vec3| {
        let to = position - p;
        let d2 = to.length_squared();
        let d = d2.sqrt();
        (d2 > 0.0 && d2.is_finite()).then(|| (to / d, d, d2))
    };
    let (wi, distance, radiance) = match *light {
        Punctual::Point {
            position,
            intensity,
            inv_range,
        } => {
            let (wi, d, d2) = toward(position)?;
            (wi, d, intensity * (range_window(d, inv_range) / d2))
        }
        Punctual::Spot {
            position,
            axis,
            intensity,
            inv_range,
            scale,
            offset,
        } => {
            let (wi, d, d2) = toward(position)?;
            let falloff = (axis.dot(-wi) * scale + offset).clamp(0.0, 1.0);
            let falloff = falloff * falloff;
            (
                wi,
                d,
                intensity * (falloff * range_window(d, inv_range) / d2),
            )
        }
        Punctual::Directional { wi, illuminance } => (wi, f32::INFINITY, illuminance),
    };
    Some(LightSample {
        wi,
        distance,
        radiance,
        pdf: select,
        delta: true,
    })
}

/// [`Lights::emitted`] for a triangle that is not in the light list, from the scene itself.
fn emitted_from_scene(scene: &Scene, instance: u32, triangle: u32, bary: Vec2, wo: Vec3) -> Vec3 {
    let Some(inst) = scene.instances.get(instance as usize) else {
        return Vec3::ZERO;
    };
    let Some(mesh) = scene.meshes.get(inst.mesh as usize) else {
        return Vec3::ZERO;
    };
    let Some(mat) = scene.materials.get(mesh.material as usize) else {
        return Vec3::ZERO;
    };
    if !mat.is_emissive() || triangle as usize >= mesh.indices.len() {
        return Vec3::ZERO;
    }
    if !mat.emits_from_back {
        let [a, b, c] = mesh
            .triangle(triangle as usize)
            .map(|p| inst.transform.transform_point3(p));
        let det = Mat3::from_mat4(inst.transform).determinant();
        if (b - a).cross(c - a).dot(wo) * det.signum() <= 0.0 {
            return Vec3::ZERO;
        }
    }
    match emissive_texture_uvs(scene, mat, inst.mesh, triangle as usize) {
        Some((tex, uvs)) => textured(
            mat.emissive,
            &scene.textures[tex.texture as usize],
            &tex,
            uvs,
            bary,
        ),
        None => mat.emissive,
    }
}
