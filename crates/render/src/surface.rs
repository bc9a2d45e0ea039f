//! What a ray hit: position, normals, shading frame, texture coordinates and the material's
//! values there (textures applied), ready for the BSDF.

use glam::{Mat3, Vec2, Vec3, Vec4, Vec4Swizzles};
use pathlight_accel::{Hit, Ray};
use pathlight_scene::{AlphaMode, Material, Scene, TextureRef};

use crate::bsdf::{BsdfParams, Microfacet};

/// A shading point.
#[derive(Debug, Clone, Copy)]
pub struct Surface {
    pub p: Vec3,
    /// Unit geometric normal on the side the ray came from.
    pub ng: Vec3,
    /// Unit shading normal (interpolated, normal-mapped), on the same side as `ng`.
    pub ns: Vec3,
    /// Unit tangent and bitangent completing the shading frame (`t x b = ns`).
    pub t: Vec3,
    pub b: Vec3,
    /// True when the ray hit the front face (the winding's side).
    pub front: bool,
    pub instance: u32,
    pub triangle: u32,
    /// The hit's barycentrics (weights of corners 1 and 2).
    pub bary: Vec2,
    pub material: u32,
}

/// The material evaluated at a shading point.
#[derive(Debug, Clone, Copy)]
pub struct Shading {
    pub params: BsdfParams,
    /// Coverage in [0, 1] (1 for opaque materials; 0 where a mask cuts the surface out).
    pub alpha: f32,
    /// True when the surface bounds a refracting volume (transmission without thin walls).
    pub volume: bool,
    /// Absorption coefficient of that volume per scene unit (Beer-Lambert), zero without one.
    pub sigma_a: Vec3,
}

impl Surface {
    /// The shading point of `hit` on `ray` in `scene` (`World::surface`), with the texture
    /// coordinates and the vertex colour (linear RGBA, white without one) there. Opaque and
    /// thin materials are shaded on the side the ray came from (both faces look the same, as
    /// in Cycles); refracting volumes keep their outward normal, so that `wo.z < 0` in the
    /// shading frame means "from inside". `normal_matrices` and `linear` are the instances'
    /// normal matrices (inverse transpose) and linear parts.
    #[inline(always)]
    pub fn at(
        scene: &Scene,
        normal_matrices: &[Mat3],
        linear: &[Mat3],
        ray: &Ray,
        hit: &Hit,
    ) -> (Self, [Vec2; 2], Vec4) {
        let inst = &scene.instances[hit.instance as usize];
        let mesh = &scene.meshes[inst.mesh as usize];
        let idx = mesh.indices[hit.triangle as usize];
        let [a, b, c] = idx.map(|i| mesh.positions[i as usize]);
        let nm = normal_matrices[hit.instance as usize];
        let (u, v) = (hit.u, hit.v);
        let w = 1.0 - u - v;
        let p_obj = a * w + b * u + c * v;
        let p = inst.transform.transform_point3(p_obj);
        let mut ng = (nm * (b - a).cross(c - a)).normalize_or(Vec3::Y);
        let interp3 = |vals: &[Vec3]| {
            vals[idx[0] as usize] * w + vals[idx[1] as usize] * u + vals[idx[2] as usize] * v
        };
        let mut ns = match &mesh.normals {
            Some(n) => (nm * interp3(n)).normalize_or(ng),
            None => ng,
        };
        let interp2 = |vals: &Option<Vec<Vec2>>| {
            vals.as_ref().map_or(Vec2::ZERO, |t| {
                t[idx[0] as usize] * w + t[idx[1] as usize] * u + t[idx[2] as usize] * v
            })
        };
        let uv = [interp2(&mesh.uv0), interp2(&mesh.uv1)];
        let color = mesh.colors.as_ref().map_or(Vec4::ONE, |cs| {
            cs[idx[0] as usize] * w + cs[idx[1] as usize] * u + cs[idx[2] as usize] * v
        });
        // The tangent from the mesh's tangents when present; without them any frame around
        // the final normal does.
        let mut tangent = mesh.tangents.as_ref().and_then(|ts| {
            let t4 = ts[idx[0] as usize] * w + ts[idx[1] as usize] * u + ts[idx[2] as usize] * v;
            let t = linear[hit.instance as usize] * t4.xyz();
            let t = (t - ns * ns.dot(t)).normalize_or_zero();
            (t != Vec3::ZERO).then_some(t)
        });
        let material = mesh.material;
        let mat = &scene.materials[material as usize];
        // Normal map (tangent space, glTF convention: +Y up in the texture = bitangent).
        if let Some(tex) = &mat.normal_texture {
            let (t, bt) = match (tangent, &mesh.tangents) {
                (Some(t), Some(ts)) => {
                    let sign = if ts[idx[0] as usize].w < 0.0 {
                        -1.0
                    } else {
                        1.0
                    };
                    (t, ns.cross(t) * sign)
                }
                _ => frame(ns),
            };
            let n = sample(scene, tex, uv).xyz() * 2.0 - Vec3::ONE;
            let n = Vec3::new(n.x * mat.normal_scale, n.y * mat.normal_scale, n.z);
            let mapped = (t * n.x + bt * n.y + ns * n.z).normalize_or(ns);
            // Keep the mapped normal on the geometric side (no light leaks through the
            // surface from extreme maps).
            if mapped.dot(ng) * ns.dot(ng) > 0.0 {
                ns = mapped;
            }
            tangent = Some(t);
        }
        let front = ray.direction.dot(ng) < 0.0;
        let refracting = mat.transmission > 0.0 && mat.volume.is_some();
        if !front && !refracting {
            ng = -ng;
            ns = -ns;
        }
        // Interpolated normals can face away from the geometric side; keep them consistent.
        if ns.dot(ng) < 0.0 {
            ns = (ns - ng * (2.0 * ns.dot(ng))).normalize_or(ng);
        }
        let (t, b) = match tangent {
            Some(t) => reframe(ns, t),
            None => frame(ns),
        };
        let surface = Self {
            p,
            ng,
            ns,
            t,
            b,
            front,
            instance: hit.instance,
            triangle: hit.triangle,
            bary: Vec2::new(u, v),
            material,
        };
        (surface, uv, color)
    }

    /// World direction to shading frame.
    #[inline]
    pub fn to_local(&self, d: Vec3) -> Vec3 {
        Vec3::new(d.dot(self.t), d.dot(self.b), d.dot(self.ns))
    }

    /// Shading frame to world direction.
    #[inline]
    pub fn to_world(&self, d: Vec3) -> Vec3 {
        self.t * d.x + self.b * d.y + self.ns * d.z
    }

    /// A ray origin off the surface on the side of direction `d` (avoids self-intersection).
    #[inline]
    pub fn spawn_origin(&self, d: Vec3) -> Vec3 {
        offset_origin(self.p, self.ng, d)
    }
}

/// Offsets `p` along `n` toward the side of `d`, by an amount that grows with |p| (float
/// precision of the hit point).
#[inline]
pub fn offset_origin(p: Vec3, n: Vec3, d: Vec3) -> Vec3 {
    let eps = 1e-4 + p.abs().max_element() * 2e-6;
    if d.dot(n) >= 0.0 {
        p + n * eps
    } else {
        p - n * eps
    }
}

/// An orthonormal tangent and bitangent around unit `n` (Duff et al. 2017).
#[inline]
pub fn frame(n: Vec3) -> (Vec3, Vec3) {
    let sign = 1.0f32.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    (
        Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x),
        Vec3::new(b, sign + n.y * n.y * a, -n.y),
    )
}

/// A frame around `n` whose tangent is `t` made orthogonal to `n` (or any frame when `t` is
/// parallel to `n`).
fn reframe(n: Vec3, t: Vec3) -> (Vec3, Vec3) {
    let t = (t - n * n.dot(t)).normalize_or_zero();
    if t == Vec3::ZERO {
        frame(n)
    } else {
        (t, n.cross(t))
    }
}

#[inline]
fn sample(scene: &Scene, tex: &TextureRef, uv: [Vec2; 2]) -> Vec4 {
    let uv = uv[(tex.texcoord as usize).min(1)];
    scene.textures[tex.texture as usize].sample(tex.apply(uv), &tex.sampler)
}

/// Evaluates `mat`'s parameters at texture coordinates `uv` with vertex colour `color`.
pub fn shade_material(
    scene: &Scene,
    mat: &Material,
    uv: [Vec2; 2],
    color: Vec4,
    distribution: Microfacet,
) -> Shading {
    let tex = |t: &Option<TextureRef>| t.as_ref().map(|t| sample(scene, t, uv));
    let mut base = mat.base_color * color;
    if let Some(c) = tex(&mat.base_color_texture) {
        base *= c;
    }
    let (mut metallic, mut roughness) = (mat.metallic, mat.roughness);
    if let Some(mr) = tex(&mat.metallic_roughness_texture) {
        roughness *= mr.y;
        metallic *= mr.z;
    }
    let mut specular = mat.specular;
    if let Some(s) = tex(&mat.specular_texture) {
        specular *= s.w;
    }
    let mut specular_color = mat.specular_color;
    if let Some(s) = tex(&mat.specular_color_texture) {
        specular_color *= s.xyz();
    }
    let mut transmission = mat.transmission;
    if let Some(t) = tex(&mat.transmission_texture) {
        transmission *= t.x;
    }
    let alpha = match mat.alpha_mode {
        AlphaMode::Opaque => 1.0,
        AlphaMode::Mask { cutoff } => {
            if base.w >= cutoff {
                1.0
            } else {
                0.0
            }
        }
        AlphaMode::Blend => base.w.clamp(0.0, 1.0),
    };
    let volume = transmission > 0.0 && mat.volume.is_some();
    let sigma_a = match &mat.volume {
        Some(v) if volume && v.attenuation_distance.is_finite() && v.attenuation_distance > 0.0 => {
            -v.attenuation_color
                .clamp(Vec3::splat(1e-6), Vec3::ONE)
                .map(f32::ln)
                / v.attenuation_distance
        }
        _ => Vec3::ZERO,
    };
    Shading {
        params: BsdfParams {
            base_color: base.xyz().clamp(Vec3::ZERO, Vec3::ONE),
            metallic: metallic.clamp(0.0, 1.0),
            roughness: roughness.clamp(0.0, 1.0),
            specular: specular.clamp(0.0, 1.0),
            specular_color: specular_color.max(Vec3::ZERO),
            ior: if mat.ior.is_finite() && mat.ior >= 1.0 {
                mat.ior
            } else {
                1.5
            },
            transmission: transmission.clamp(0.0, 1.0),
            thin_walled: !volume,
            distribution,
        },
        alpha,
        volume,
        sigma_a,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_are_orthonormal() {
        for n in [
            Vec3::Z,
            -Vec3::Z,
            Vec3::new(0.3, -0.5, 0.81).normalize(),
            Vec3::X,
        ] {
            let (t, b) = frame(n);
            assert!((t.length() - 1.0).abs() < 1e-5 && (b.length() - 1.0).abs() < 1e-5);
            assert!(t.dot(n).abs() < 1e-5 && b.dot(n).abs() < 1e-5 && t.dot(b).abs() < 1e-5);
            assert!((t.cross(b) - n).length() < 1e-5);
        }
    }
}
