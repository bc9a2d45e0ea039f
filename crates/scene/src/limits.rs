//! Limits that keep a hostile or absurd scene from taking unbounded time or memory.

/// Upper bounds checked while loading, before anything of that size is allocated.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Limits {
    /// Triangles in the whole scene, counted over instances (what the renderer would trace).
    pub max_triangles: u64,
    /// Vertices in one mesh.
    pub max_vertices: u64,
    /// Pixels in one texture or environment map (width x height).
    pub max_texture_pixels: u64,
    /// Pixels in all textures together.
    pub max_total_texture_pixels: u64,
    /// Bytes of one file read from disk (scene, buffer, image, material library).
    pub max_file_bytes: u64,
    /// Instances (mesh uses by nodes).
    pub max_instances: u64,
}

impl Default for Limits {
    fn default() -> Self {
        Self {
            max_triangles: 100_000_000,
            max_vertices: 100_000_000,
            max_texture_pixels: 16384 * 16384,
            max_total_texture_pixels: 1 << 31,
            max_file_bytes: 4 << 30,
            max_instances: 10_000_000,
        }
    }
}
