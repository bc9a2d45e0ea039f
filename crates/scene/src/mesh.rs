//! Triangle meshes and their instances.

use glam::{Mat4, Vec2, Vec3, Vec4};

/// An indexed triangle mesh with one material, in object space.
///
/// Optional attributes are `None` when the file has none; when present they have one entry per
/// position. Loaders guarantee: every index is below `positions.len()`, every position is finite,
/// and no triangle has zero area (such triangles are dropped with a warning).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Mesh {
    pub name: String,
    pub positions: Vec<Vec3>,
    /// Unit shading normals.
    pub normals: Option<Vec<Vec3>>,
    /// Unit tangents with the bitangent sign in `w` (glTF convention: B = w * cross(N, T)).
    pub tangents: Option<Vec<Vec4>>,
    pub uv0: Option<Vec<Vec2>>,
    pub uv1: Option<Vec<Vec2>>,
    /// Linear RGBA vertex colours.
    pub colors: Option<Vec<Vec4>>,
    pub indices: Vec<[u32; 3]>,
    /// Index into [`Scene::materials`](crate::Scene::materials).
    pub material: u32,
}

impl Mesh {
    pub fn triangle_count(&self) -> usize {
        self.indices.len()
    }

    /// The three object-space corners of triangle `t`.
    #[inline]
    pub fn triangle(&self, t: usize) -> [Vec3; 3] {
        let [a, b, c] = self.indices[t];
        [
            self.positions[a as usize],
            self.positions[b as usize],
            self.positions[c as usize],
        ]
    }

    /// Approximate heap bytes held by the mesh.
    pub fn heap_bytes(&self) -> usize {
        fn len<T>(v: &Option<Vec<T>>) -> usize {
            v.as_ref().map_or(0, |v| v.len() * std::mem::size_of::<T>())
        }
        self.positions.len() * 12
            + len(&self.normals)
            + len(&self.tangents)
            + len(&self.uv0)
            + len(&self.uv1)
            + len(&self.colors)
            + self.indices.len() * 12
    }
}

/// A placement of a mesh in the world.
#[derive(Debug, Clone, PartialEq)]
pub struct Instance {
    /// Index into [`Scene::meshes`](crate::Scene::meshes).
    pub mesh: u32,
    /// Object to world.
    pub transform: Mat4,
    /// Name of the node that placed the mesh, if any.
    pub name: String,
}

impl Instance {
    /// The matrix that takes object-space normals to world space (inverse transpose).
    pub fn normal_matrix(&self) -> glam::Mat3 {
        glam::Mat3::from_mat4(self.transform).inverse().transpose()
    }
}

/// The attribute values at `indices`, or `None` when the attribute is absent.
pub fn gather<T: Copy>(values: &Option<Vec<T>>, indices: &[u32]) -> Option<Vec<T>> {
    values
        .as_ref()
        .map(|v| indices.iter().map(|&i| v[i as usize]).collect())
}

/// Twice the area of a triangle, or 0 when it is degenerate or not finite.
#[inline]
pub fn doubled_area(a: Vec3, b: Vec3, c: Vec3) -> f32 {
    let n = (b - a).cross(c - a).length();
    if n.is_finite() {
        n
    } else {
        0.0
    }
}

/// Triangles a loader dropped, reported in one warning per file.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub struct Dropped {
    /// Triangles with a NaN or infinite corner.
    pub non_finite: usize,
    /// Triangles of zero area (collinear or repeated corners).
    pub degenerate: usize,
}

impl Dropped {
    pub fn add(&mut self, other: Dropped) {
        self.non_finite += other.non_finite;
        self.degenerate += other.degenerate;
    }

    /// Adds one warning to `warnings` if anything was dropped.
    pub fn warn(&self, file: &std::path::Path, warnings: &mut crate::error::Warnings) {
        if self.non_finite + self.degenerate > 0 {
            warnings.push(
                file,
                format!(
                    "dropped {} triangles: {} with a NaN or infinite corner, {} of zero area",
                    self.non_finite + self.degenerate,
                    self.non_finite,
                    self.degenerate
                ),
            );
        }
    }
}

impl Mesh {
    /// Makes a freshly loaded mesh safe to render: drops triangles with a non-finite corner or
    /// zero area, removes vertices no triangle uses, renormalises normals (a missing or broken
    /// normal becomes the area-weighted mean of its faces' normals), replaces non-finite texture
    /// coordinates by 0 and colours by 1, and discards tangents if any is broken.
    ///
    /// Every index must already be below `positions.len()` (loaders check it).
    pub fn clean(&mut self) -> Dropped {
        let mut dropped = Dropped::default();
        let positions = &self.positions;
        self.indices.retain(|t| {
            let [a, b, c] = t.map(|i| positions[i as usize]);
            if !(a.is_finite() && b.is_finite() && c.is_finite()) {
                dropped.non_finite += 1;
                false
            } else if doubled_area(a, b, c) == 0.0 {
                dropped.degenerate += 1;
                false
            } else {
                true
            }
        });
        // Compact, keeping the order of the vertices that stay.
        let mut remap = vec![u32::MAX; self.positions.len()];
        for t in &self.indices {
            for &i in t {
                remap[i as usize] = 0;
            }
        }
        let mut kept = Vec::new();
        for (i, r) in remap.iter_mut().enumerate() {
            if *r == 0 {
                *r = kept.len() as u32;
                kept.push(i as u32);
            }
        }
        if kept.len() != self.positions.len() {
            for t in &mut self.indices {
                *t = t.map(|i| remap[i as usize]);
            }
            self.positions =
                gather(&Some(std::mem::take(&mut self.positions)), &kept).unwrap_or_default();
            self.normals = gather(&self.normals, &kept);
            self.tangents = gather(&self.tangents, &kept);
            self.uv0 = gather(&self.uv0, &kept);
            self.uv1 = gather(&self.uv1, &kept);
            self.colors = gather(&self.colors, &kept);
        }
        if let Some(normals) = &mut self.normals {
            let mut face_sum: Option<Vec<Vec3>> = None;
            for i in 0..normals.len() {
                let n = normals[i];
                let len = n.length();
                if len.is_finite() && len > 1e-20 {
                    normals[i] = n / len;
                    continue;
                }
                let sums = face_sum.get_or_insert_with(|| {
                    let mut s = vec![Vec3::ZERO; self.positions.len()];
                    for t in &self.indices {
                        let [a, b, c] = t.map(|i| self.positions[i as usize]);
                        let n = (b - a).cross(c - a);
                        for &v in t {
                            s[v as usize] += n;
                        }
                    }
                    s
                });
                normals[i] = sums[i].normalize_or(Vec3::Z);
            }
        }
        for uvs in [&mut self.uv0, &mut self.uv1].into_iter().flatten() {
            for uv in uvs.iter_mut().filter(|uv| !uv.is_finite()) {
                *uv = Vec2::ZERO;
            }
        }
        if let Some(colors) = &mut self.colors {
            for c in colors.iter_mut().filter(|c| !c.is_finite()) {
                *c = Vec4::ONE;
            }
        }
        if self.tangents.as_ref().is_some_and(|t| {
            t.iter()
                .any(|t| !t.is_finite() || t.truncate().length_squared() == 0.0)
        }) {
            self.tangents = None;
        }
        dropped
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clean_drops_bad_triangles_and_compacts() {
        let mut m = Mesh {
            positions: vec![
                Vec3::ZERO,
                Vec3::X,
                Vec3::Y,
                Vec3::new(f32::NAN, 0.0, 0.0),
                Vec3::new(2.0, 0.0, 0.0), // collinear with 0 and 1
                Vec3::new(9.0, 9.0, 9.0), // unused
                Vec3::Z,
            ],
            normals: Some(vec![
                Vec3::new(0.0, 0.0, 2.0),
                Vec3::Z,
                Vec3::splat(f32::NAN),
                Vec3::Z,
                Vec3::Z,
                Vec3::Z,
                Vec3::ZERO,
            ]),
            uv0: Some(vec![Vec2::new(f32::INFINITY, 0.5); 7]),
            indices: vec![[0, 1, 2], [0, 1, 3], [0, 1, 4], [0, 0, 2], [0, 2, 6]],
            ..Mesh::default()
        };
        let d = m.clean();
        assert_eq!(
            d,
            Dropped {
                non_finite: 1,
                degenerate: 2
            }
        );
        assert_eq!(m.indices, vec![[0, 1, 2], [0, 2, 3]]);
        assert_eq!(m.positions, vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z]);
        let n = m.normals.unwrap();
        assert_eq!(n[0], Vec3::Z);
        // Vertex 2's normal was NaN: the mean of its faces' normals (+Z and +X).
        assert!((n[2] - Vec3::new(1.0, 0.0, 1.0).normalize()).length() < 1e-6);
        // Vertex 3 (old 6) had a zero normal: its one face's normal, +X.
        assert!((n[3] - Vec3::X).length() < 1e-6);
        assert!(m.uv0.unwrap().iter().all(|uv| *uv == Vec2::ZERO));
    }
}
