//! Tangent frames for normal mapping: MikkTSpace tangents (the `mikktspace` crate) where a mesh
//! has none, and flat normals where it has no normals.

use std::collections::HashMap;

use glam::{Vec2, Vec3, Vec4};

use crate::mesh::{gather, Mesh};

/// Gives the mesh one vertex per triangle corner with the triangle's normal (glTF: "when normals
/// are not specified, client implementations MUST calculate flat normals").
pub fn make_flat_normals(mesh: &mut Mesh) {
    let corners: Vec<u32> = mesh.indices.iter().flatten().copied().collect();
    let positions: Vec<Vec3> = corners
        .iter()
        .map(|&i| mesh.positions[i as usize])
        .collect();
    let normals = positions
        .chunks_exact(3)
        .flat_map(|p| {
            let n = (p[1] - p[0]).cross(p[2] - p[0]).normalize_or(Vec3::Z);
            [n; 3]
        })
        .collect();
    mesh.uv0 = gather(&mesh.uv0, &corners);
    mesh.uv1 = gather(&mesh.uv1, &corners);
    mesh.colors = gather(&mesh.colors, &corners);
    mesh.tangents = None;
    mesh.normals = Some(normals);
    mesh.positions = positions;
    mesh.indices = (0..mesh.indices.len() as u32)
        .map(|t| [3 * t, 3 * t + 1, 3 * t + 2])
        .collect();
}

struct Corners<'a> {
    mesh: &'a Mesh,
    normals: &'a [Vec3],
    uvs: &'a [Vec2],
    tangents: Vec<Vec4>,
}

impl bevy_mikktspace::Geometry for Corners<'_> {
    fn num_faces(&self) -> usize {
        self.mesh.indices.len()
    }
    fn num_vertices_of_face(&self, _face: usize) -> usize {
        3
    }
    fn position(&self, face: usize, vert: usize) -> [f32; 3] {
        self.mesh.positions[self.mesh.indices[face][vert] as usize].into()
    }
    fn normal(&self, face: usize, vert: usize) -> [f32; 3] {
        self.normals[self.mesh.indices[face][vert] as usize].into()
    }
    fn tex_coord(&self, face: usize, vert: usize) -> [f32; 2] {
        // glTF's v runs down the image; MikkTSpace (like Blender) expects v up.
        let uv = self.uvs[self.mesh.indices[face][vert] as usize];
        [uv.x, 1.0 - uv.y]
    }
    fn set_tangent(
        &mut self,
        tangent: Option<bevy_mikktspace::TangentSpace>,
        face: usize,
        vert: usize,
    ) {
        if let Some(t) = tangent {
            self.tangents[face * 3 + vert] = Vec4::from(t.tangent_encoded());
        }
    }
}

/// Computes MikkTSpace tangents from the normals and the UV set `texcoord` (0 or 1). Vertices
/// whose corners get different tangents are split. Returns `false` (mesh unchanged) when the
/// mesh has no normals or no such UVs, or MikkTSpace fails.
pub fn generate_tangents(mesh: &mut Mesh, texcoord: u32) -> bool {
    let uvs = match texcoord {
        0 => mesh.uv0.as_ref(),
        _ => mesh.uv1.as_ref(),
    };
    let (Some(normals), Some(uvs)) = (mesh.normals.as_ref(), uvs) else {
        return false;
    };
    let mut corners = Corners {
        mesh,
        normals,
        uvs,
        tangents: vec![Vec4::ZERO; mesh.indices.len() * 3],
    };
    if bevy_mikktspace::generate_tangents(&mut corners).is_err() {
        return false;
    }
    let corner_tangents = corners.tangents;
    // Weld: one vertex per (original vertex, tangent) pair.
    let mut new_index: HashMap<(u32, [u32; 4]), u32> = HashMap::new();
    let mut origin: Vec<u32> = Vec::with_capacity(mesh.positions.len());
    let mut tangents: Vec<Vec4> = Vec::with_capacity(mesh.positions.len());
    for (c, t) in corner_tangents.iter().enumerate() {
        let tri = &mut mesh.indices[c / 3];
        let v = tri[c % 3];
        // Corners MikkTSpace left alone (degenerate UVs) get any frame orthogonal to the normal.
        let t = if t.is_finite() && t.truncate().length_squared() > 0.0 {
            *t
        } else {
            mesh.normals
                .as_ref()
                .map_or(Vec3::X, |n| n[v as usize].any_orthonormal_vector())
                .extend(1.0)
        };
        let key = (v, t.to_array().map(f32::to_bits));
        let next = origin.len() as u32;
        let id = *new_index.entry(key).or_insert_with(|| {
            origin.push(v);
            tangents.push(t);
            next
        });
        tri[c % 3] = id;
    }
    mesh.normals = gather(&mesh.normals, &origin);
    mesh.uv0 = gather(&mesh.uv0, &origin);
    mesh.uv1 = gather(&mesh.uv1, &origin);
    mesh.colors = gather(&mesh.colors, &origin);
    mesh.positions = origin.iter().map(|&i| mesh.positions[i as usize]).collect();
    mesh.tangents = Some(tangents);
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A unit quad in the XY plane facing +Z, textured the glTF way: the image's top (v = 0) at
    /// +Y, so "up" in the normal map (+Y, OpenGL convention) must be world +Y.
    fn quad() -> Mesh {
        Mesh {
            positions: vec![
                Vec3::new(0.0, 0.0, 0.0),
                Vec3::new(1.0, 0.0, 0.0),
                Vec3::new(1.0, 1.0, 0.0),
                Vec3::new(0.0, 1.0, 0.0),
            ],
            normals: Some(vec![Vec3::Z; 4]),
            uv0: Some(vec![
                Vec2::new(0.0, 1.0),
                Vec2::new(1.0, 1.0),
                Vec2::new(1.0, 0.0),
                Vec2::new(0.0, 0.0),
            ]),
            indices: vec![[0, 1, 2], [0, 2, 3]],
            ..Mesh::default()
        }
    }

    #[test]
    fn tangent_follows_u_and_bitangent_points_up_the_image() {
        let mut m = quad();
        assert!(generate_tangents(&mut m, 0));
        let t = m.tangents.as_ref().unwrap();
        assert_eq!(t.len(), 4, "a flat quad needs no split vertices");
        for (i, t) in t.iter().enumerate() {
            assert!((t.truncate() - Vec3::X).length() < 1e-5, "{i}: {t}");
            let n = m.normals.as_ref().unwrap()[i];
            let b = t.w * n.cross(t.truncate());
            assert!((b - Vec3::Y).length() < 1e-5, "bitangent {b}");
        }
    }

    #[test]
    fn mirrored_uvs_flip_the_sign() {
        let mut m = quad();
        for uv in m.uv0.as_mut().unwrap() {
            uv.x = 1.0 - uv.x;
        }
        assert!(generate_tangents(&mut m, 0));
        for t in m.tangents.as_ref().unwrap() {
            assert!((t.truncate() + Vec3::X).length() < 1e-5);
            let b = t.w * Vec3::Z.cross(t.truncate());
            assert!((b - Vec3::Y).length() < 1e-5);
        }
    }

    #[test]
    fn flat_normals_unweld() {
        let mut m = quad();
        m.normals = None;
        make_flat_normals(&mut m);
        assert_eq!(m.positions.len(), 6);
        assert!(m
            .normals
            .unwrap()
            .iter()
            .all(|n| (*n - Vec3::Z).length() < 1e-6));
    }

    #[test]
    fn no_uvs_no_tangents() {
        let mut m = quad();
        m.uv0 = None;
        assert!(!generate_tangents(&mut m, 0));
        assert!(m.tangents.is_none());
    }
}
