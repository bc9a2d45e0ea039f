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
