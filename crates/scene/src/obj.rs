//! OBJ/MTL loader, written by hand for line-numbered errors, bounded memory and file access
//! confined to the scene's folder.
//!
//! # OBJ
//! Read: `v x y z [w]` (`w` and any vertex colour after it are ignored), `vt u [v [w]]`,
//! `vn x y z`, `f`/`fo` with `v`, `v/vt`, `v//vn`, `v/vt/vn` corners and positive or negative
//! (relative) indices, `o`, `g`, `usemtl`, `mtllib`. `s` and `vp` are ignored silently; other
//! statements (`l`, `p`, curves, surfaces, ...) are ignored with one warning that lists them.
//! `#` starts a comment; a line ending in `\` continues on the next; CRLF is accepted; bytes that
//! are not UTF-8 are replaced (U+FFFD), so they can only end up in names or give a "bad number".
//!
//! Polygons are fan-triangulated from their first corner. Each run of faces with the same
//! object/group name and the same material becomes one [`Mesh`] (named after the group, or the
//! object) holding only the vertices it uses, one per distinct `(v, vt, vn)` triple, and one
//! [`Instance`] with the identity transform. Texture coordinates are flipped to the glTF
//! convention, `(u, v)` -> `(u, 1 - v)`, so that uv (0, 0) is the image's top-left corner.
//! A corner without `vn` in a mesh that has normals gets the area-weighted mean of its faces'
//! normals ([`Mesh::clean`]); one without `vt` gets uv (0, 0).
//!
//! Triangles with a NaN or infinite corner, or of zero area, are dropped and counted in one
//! warning. Errors, each naming the file and line: bad numbers, index 0, indices (absolute or
//! relative) outside the vertices defined so far, faces with fewer than 3 corners, more
//! triangles than [`Limits::max_triangles`] (in the whole file) or more vertices than
//! [`Limits::max_vertices`] (in one attribute list or in one mesh), more meshes than
//! [`Limits::max_instances`]. Limits are checked before the memory is allocated.
//!
//! Materials: faces before any `usemtl` get a default two-sided Lambertian grey (0.8). A
//! `usemtl` naming a material that no material library defines gives one warning per name and
//! the same default material. A `mtllib` that cannot be read, or that is refused because it is
//! absolute or leads outside the scene's folder, gives a warning (its materials are then
//! unknown), not an error. Only materials that some face uses are kept, in order of first use.
//!
//! # MTL
//! Statement names are case-insensitive; numbers must be finite.
//!
//! | MTL | material |
//! |---|---|
//! | `Kd` | `base_color` (linear, used as-is; negative values become 0). Default 0.8, or 1 with `map_Kd` |
//! | — | `metallic = 0`, `double_sided = true` (OBJ has no notion of a face's side) |
//! | `Ks` absent or 0, or `illum` 0 or 1 | `specular = 0`: exactly Lambertian |
//! | `Ks` > 0 | `specular = 1`, `specular_color = Ks / F0(ior)` so that [`Material::dielectric_f0`] = `Ks` (clamped to 1) |
//! | `Ns` | `roughness = sqrt(alpha)` with the Phong-to-Beckmann/GGX `alpha = sqrt(2 / (Ns + 2))`, in [0, 1]; `Ns` absent counts as 0 (roughness 1) |
//! | `Ke` | `emissive`, from the front face only (`emits_from_back = false`): the side the face's winding (counter-clockwise) faces, as area emitters in Mitsuba and pbrt |
//! | `Ni` | `ior` when `Ni > 1`; otherwise (absent, or `Ni <= 1`, which exporters write as a placeholder and which would leave a dielectric no reflection at all) 1.5 |
//! | `d` (or `1 - Tr`; `d` wins when both are given) | `d < 1`: `AlphaMode::Blend` and `base_color.w = d` |
//! | `map_Kd` | `base_color_texture` (sRGB; multiplied by `Kd`, as in glTF) |
//! | `map_d` | alpha channel of `base_color_texture` (the map's alpha if it has one, else its mean of R, G, B, resampled to `map_Kd`'s size), `AlphaMode::Mask` at 0.5 (or `Blend` when `d < 1`) |
//! | `map_Ks` | `specular_color_texture` (sRGB; `Ks` defaults to 1 with it) |
//! | `map_Ke` | `emissive_texture` (sRGB; `Ke` defaults to 1 with it) |
//! | `norm` (or `map_norm`) | `normal_texture`: a tangent-space normal map (linear), `normal_scale = -bm` |
//! | `bump`, `map_bump` | a tangent-space normal map if the image looks like one (coloured, mean blue high, mean red and green near 0.5): as `norm`. Otherwise a height map, converted at load time to a normal map by central differences: slope = `-bm` x (height difference of the two neighbours, heights in [0, 1]) / 2 per texel, `normal_scale = 1` |
//!
//! `Ka`, `map_Ka`, `Tf`, `sharpness` and `illum` 2..10 are ignored silently; other statements
//! with one warning per library. Texture options: `-o` and `-s` become the [`TextureRef`]'s
//! transform, `-clamp on` clamps, `-bm` scales bumps; `-blendu`, `-blendv`, `-boost`, `-cc`,
//! `-imfchan`, `-mm`, `-t`, `-texres`, `-type` are skipped with their arguments. The file name is
//! the rest of the line (it may hold spaces). Texture paths are relative to the material
//! library's folder. A texture that is missing, refused, over a size limit or not a valid
//! PNG/JPEG gives a warning and the material goes without it (as in the glTF loader). Textures
//! are shared between materials by (file, use) and decoded in parallel.
//!
//! Meshes whose material has a normal map get flat normals if they have none, then MikkTSpace
//! tangents.

use std::borrow::Cow;
use std::collections::{BTreeMap, HashMap, HashSet};
use std::path::{Path, PathBuf};

use glam::{Affine2, Mat2, Vec2, Vec3};
use rayon::prelude::*;

use crate::error::{Result, SceneError, Warnings};
use crate::limits::Limits;
use crate::material::{AlphaMode, Material, Sampler, TextureRef, Wrap};
use crate::mesh::{doubled_area, Dropped, Instance, Mesh};
use crate::scene::Scene;
use crate::source::{read_file_limited, SceneSource};
use crate::tangent::{generate_tangents, make_flat_normals};
use crate::texture::{check_pixels, decode_image, image_header, ColorSpace, Texture};

/// Loads an OBJ file and the material libraries and textures it names (inside its folder only).
pub fn load(path: &Path, limits: &Limits) -> Result<Scene> {
    let bytes = read_file_limited(path, limits.max_file_bytes)?;
    let source = SceneSource::for_file(path)?;
    parse(&bytes, path, &source, limits)
}

/// Parses OBJ text. `file` names it in messages; `mtllib` and texture references are resolved
/// and read through `source`. Emissive triangles are not collected (the caller does that).
pub fn parse(text: &[u8], file: &Path, source: &SceneSource, limits: &Limits) -> Result<Scene> {
    let mut parser = ObjParser::new(file, source, limits);
    let mut lines = Lines::new(text);
    while let Some((line, content)) = lines.next_line() {
        parser.statement(line, &content)?;
    }
    parser.finish()
}

/// Default material of faces without (or with an unknown) `usemtl`.
pub fn default_material() -> Material {
    Material::lambertian("default", Vec3::splat(0.8))
}

// ---------------------------------------------------------------------------------------------
// Lines

/// Logical lines: comments removed, `\r` stripped, backslash continuations joined.
struct Lines<'a> {
    rest: &'a [u8],
    line: usize,
    joined: Vec<u8>,
}

impl<'a> Lines<'a> {
    fn new(text: &'a [u8]) -> Self {
        Self {
            rest: text,
            line: 0,
            joined: Vec::new(),
        }
    }

    /// The next logical line and the number of its first physical line (1-based).
    fn next_line(&mut self) -> Option<(usize, Cow<'_, str>)> {
        if self.rest.is_empty() {
            return None;
        }
        let first = self.line + 1;
        let mut single: &'a [u8] = &[];
        let mut continued = false;
        self.joined.clear();
        loop {
            let (raw, rest) = match self.rest.iter().position(|&b| b == b'\n') {
                Some(i) => (&self.rest[..i], &self.rest[i + 1..]),
                None => (self.rest, &self.rest[self.rest.len()..]),
            };
            self.rest = rest;
            self.line += 1;
            let raw = raw.strip_suffix(b"\r").unwrap_or(raw);
            // A comment ends the line, and a backslash inside a comment continues nothing.
            let (raw, commented) = match raw.iter().position(|&b| b == b'#') {
                Some(i) => (&raw[..i], true),
                None => (raw, false),
            };
            let trimmed = raw.trim_ascii_end();
            if !commented && trimmed.ends_with(b"\\") && !self.rest.is_empty() {
                self.joined.extend_from_slice(&trimmed[..trimmed.len() - 1]);
                self.joined.push(b' ');
                continued = true;
                continue;
            }
            if continued {
                self.joined.extend_from_slice(raw);
            } else {
                single = raw;
            }
            break;
        }
        let bytes: &[u8] = if continued { &self.joined } else { single };
        Some((first, String::from_utf8_lossy(bytes)))
    }
}

/// Splits a line into its statement name and the rest (trimmed).
fn split_keyword(line: &str) -> (&str, &str) {
    let line = line.trim_ascii();
    match line.find(|c: char| c.is_ascii_whitespace()) {
        Some(i) => (&line[..i], line[i..].trim_ascii()),
        None => (line, ""),
    }
}

/// The whitespace-separated tokens of `s` with their byte offsets.
fn tokens(s: &str) -> impl Iterator<Item = (usize, &str)> {
    s.split_ascii_whitespace()
        .map(move |t| (t.as_ptr() as usize - s.as_ptr() as usize, t))
}

fn line_error(file: &Path, line: usize, what: impl std::fmt::Display) -> SceneError {
    SceneError::new(file, format!("line {line}: {what}"))
}

/// Parses one number of a `what` statement.
fn number(file: &Path, line: usize, what: &str, token: &str) -> Result<f32> {
    token.parse::<f32>().map_err(|_| {
        line_error(
            file,
            line,
            format!(
                "bad number \"{}\" in a {what} statement",
                token.escape_debug()
            ),
        )
    })
}

/// Counts ignored statement names for one warning (at most 32 distinct names are kept).
#[derive(Default)]
struct Ignored {
    names: BTreeMap<String, usize>,
    others: usize,
}

impl Ignored {
    fn add(&mut self, name: &str) {
        if let Some(n) = self.names.get_mut(name) {
            *n += 1;
        } else if self.names.len() < 32 {
            self.names.insert(name.to_owned(), 1);
        } else {
            self.others += 1;
        }
    }

    fn warn(&self, file: &Path, warnings: &mut Warnings) {
        if self.names.is_empty() {
            return;
        }
        let mut list: Vec<String> = self
            .names
            .iter()
            .map(|(k, n)| format!("{} ({n}x)", k.escape_debug()))
            .collect();
        if self.others > 0 {
            list.push(format!("{} more", self.others));
        }
        warnings.push(
            file,
            format!("ignored unsupported statements: {}", list.join(", ")),
        );
    }
}

// ---------------------------------------------------------------------------------------------
// OBJ

const NONE: u32 = u32::MAX;

/// A mesh being built from one run of faces.
struct MeshBuilder {
    run: u64,
    name: String,
    /// `usemtl` name and the line of that `usemtl`.
    material: Option<String>,
    usemtl_line: usize,
    /// (v, vt, vn) -> vertex.
    vertices: HashMap<[u32; 3], u32>,
    positions: Vec<Vec3>,
    /// Empty until a corner has a `vt`; then padded with zeros.
    uvs: Vec<Vec2>,
    /// Empty until a corner has a `vn`; then padded with zeros (fixed by `Mesh::clean`).
    normals: Vec<Vec3>,
    indices: Vec<[u32; 3]>,
}

/// A finished mesh and the `usemtl` it asked for.
struct RawMesh {
    mesh: Mesh,
    material: Option<String>,
    usemtl_line: usize,
}

struct ObjParser<'a> {
    file: &'a Path,
    source: &'a SceneSource,
    limits: &'a Limits,
    warnings: Warnings,
    positions: Vec<Vec3>,
    texcoords: Vec<Vec2>,
    normals: Vec<Vec3>,
    /// Object/group name and `usemtl` of the faces to come, and a counter that changes with them.
    name: String,
    usemtl: Option<String>,
    /// The line of the last `usemtl`.
    usemtl_line: usize,
    run: u64,
    builder: Option<MeshBuilder>,
    meshes: Vec<RawMesh>,
    triangles: u64,
    dropped: Dropped,
    corners: Vec<[u32; 3]>,
    library: MaterialLibrary,
    libraries_read: HashSet<PathBuf>,
    ignored: Ignored,
}

impl<'a> ObjParser<'a> {
    fn new(file: &'a Path, source: &'a SceneSource, limits: &'a Limits) -> Self {
        Self {
            file,
            source,
            limits,
            warnings: Warnings::default(),
            positions: Vec::new(),
            texcoords: Vec::new(),
            normals: Vec::new(),
            name: "default".to_owned(),
            usemtl: None,
            usemtl_line: 0,
            run: 0,
            builder: None,
            meshes: Vec::new(),
            triangles: 0,
            dropped: Dropped::default(),
            corners: Vec::new(),
            library: MaterialLibrary::default(),
            libraries_read: HashSet::new(),
            ignored: Ignored::default(),
        }
    }

    fn error(&self, line: usize, what: impl std::fmt::Display) -> SceneError {
        line_error(self.file, line, what)
    }

    fn statement(&mut self, line: usize, content: &str) -> Result<()> {
        let (keyword, rest) = split_keyword(content);
        match keyword {
            "" => {}
            "v" => {
                let v = self.vector(line, "v", rest, 3, 7)?;
                self.check_pool(line, self.positions.len(), "vertex positions (v)")?;
                self.positions.push(Vec3::new(v[0], v[1], v[2]));
            }
            "vt" => {
                let v = self.vector(line, "vt", rest, 1, 3)?;
                self.check_pool(line, self.texcoords.len(), "texture coordinates (vt)")?;
                // OBJ's v runs up the image; ours runs down from the top-left corner.
                self.texcoords.push(Vec2::new(v[0], 1.0 - v[1]));
            }
            "vn" => {
                let v = self.vector(line, "vn", rest, 3, 3)?;
                self.check_pool(line, self.normals.len(), "normals (vn)")?;
                self.normals.push(Vec3::new(v[0], v[1], v[2]));
            }
            "f" | "fo" => self.face(line, rest)?,
            "o" | "g" => {
                let name = if rest.is_empty() { "default" } else { rest };
                if name != self.name {
                    self.name = name.to_owned();
                    self.run += 1;
                }
            }
            "usemtl" => {
                let material = (!rest.is_empty()).then(|| rest.to_owned());
                if rest.is_empty() {
                    self.warnings.push(
                        self.file,
                        format!("line {line}: usemtl without a name; using the default material"),
                    );
                }
                if material != self.usemtl {
                    self.usemtl = material;
                    self.usemtl_line = line;
                    self.run += 1;
                }
            }
            "mtllib" => self.mtllib(line, rest)?,
            "s" | "vp" => {}
            other => self.ignored.add(other),
        }
        Ok(())
    }

    /// Parses between `min` and `max` numbers (missing ones are 0).
    fn vector(
        &self,
        line: usize,
        what: &str,
        rest: &str,
        min: usize,
        max: usize,
    ) -> Result<[f32; 3]> {
        let mut out = [0.0; 3];
        let mut n = 0;
        for (_, token) in tokens(rest) {
            if n == max {
                return Err(self.error(
                    line,
                    format!("a {what} statement has more than {max} numbers"),
                ));
            }
            let x = number(self.file, line, what, token)?;
            if n < 3 {
                out[n] = x;
            }
            n += 1;
        }
        if n < min {
            return Err(self.error(
                line,
                format!("a {what} statement needs at least {min} numbers, found {n}"),
            ));
        }
        Ok(out)
    }

    fn check_pool(&self, line: usize, len: usize, what: &str) -> Result<()> {
        if len as u64 >= self.limits.max_vertices {
            return Err(self.error(
                line,
                format!(
                    "more than {} {what}, over the vertex limit",
                    self.limits.max_vertices
                ),
            ));
        }
        Ok(())
    }

    /// Resolves an OBJ index (1-based, or negative: relative to the end) into `len` elements.
    fn index(&self, line: usize, token: &str, len: usize, what: &str) -> Result<u32> {
        let i: i64 = token.parse().map_err(|_| {
            self.error(
                line,
                format!("bad {what} index \"{}\" in a face", token.escape_debug()),
            )
        })?;
        if i == 0 {
            return Err(self.error(
                line,
                format!("{what} index 0 in a face (OBJ indices start at 1)"),
            ));
        }
        let resolved = if i > 0 { i - 1 } else { len as i64 + i };
        if resolved < 0 || resolved >= len as i64 {
            return Err(self.error(
                line,
                format!("{what} index {i} is out of range: {len} defined so far"),
            ));
        }
        Ok(resolved as u32)
    }

    fn face(&mut self, line: usize, rest: &str) -> Result<()> {
        let mut corners = std::mem::take(&mut self.corners);
        corners.clear();
        let result = self.face_corners(line, rest, &mut corners);
        let result = result.and_then(|()| self.face_triangles(line, &corners));
        self.corners = corners;
        result
    }

    fn face_corners(&self, line: usize, rest: &str, corners: &mut Vec<[u32; 3]>) -> Result<()> {
        for (_, token) in tokens(rest) {
            let mut parts = token.split('/');
            let v = parts.next().unwrap_or("");
            let vt = parts.next().unwrap_or("");
            let vn = parts.next().unwrap_or("");
            if parts.next().is_some() {
                return Err(self.error(
                    line,
                    format!("bad face corner \"{}\"", token.escape_debug()),
                ));
            }
            let v = self.index(line, v, self.positions.len(), "vertex")?;
            let vt = match vt {
                "" => NONE,
                t => self.index(line, t, self.texcoords.len(), "texture coordinate")?,
            };
            let vn = match vn {
                "" => NONE,
                n => self.index(line, n, self.normals.len(), "normal")?,
            };
            corners.push([v, vt, vn]);
        }
        if corners.len() < 3 {
            return Err(self.error(
                line,
                format!("a face needs at least 3 corners, found {}", corners.len()),
            ));
        }
        Ok(())
    }

    fn face_triangles(&mut self, line: usize, corners: &[[u32; 3]]) -> Result<()> {
        let count = corners.len() as u64 - 2;
        if self.triangles + count > self.limits.max_triangles {
            return Err(self.error(
                line,
                format!(
                    "more than {} triangles, over the triangle limit",
                    self.limits.max_triangles
                ),
            ));
        }
        for i in 1..corners.len() - 1 {
            let tri = [corners[0], corners[i], corners[i + 1]];
            let [a, b, c] = tri.map(|k| self.positions[k[0] as usize]);
            if !(a.is_finite() && b.is_finite() && c.is_finite()) {
                self.dropped.non_finite += 1;
                continue;
            }
            if doubled_area(a, b, c) == 0.0 {
                self.dropped.degenerate += 1;
                continue;
            }
            self.start_run(line)?;
            let mut t = [0u32; 3];
            for (slot, corner) in t.iter_mut().zip(tri) {
                *slot = self.vertex(line, corner)?;
            }
            if let Some(b) = &mut self.builder {
                b.indices.push(t);
            }
            self.triangles += 1;
        }
        Ok(())
    }

    /// Makes sure the current builder belongs to the current name and material.
    fn start_run(&mut self, line: usize) -> Result<()> {
        if self.builder.as_ref().is_some_and(|b| b.run == self.run) {
            return Ok(());
        }
        self.flush()?;
        if self.meshes.len() as u64 >= self.limits.max_instances {
            return Err(self.error(
                line,
                format!(
                    "more than {} meshes, over the instance limit",
                    self.limits.max_instances
                ),
            ));
        }
        self.builder = Some(MeshBuilder {
            run: self.run,
            name: self.name.clone(),
            material: self.usemtl.clone(),
            usemtl_line: self.usemtl_line,
            vertices: HashMap::new(),
            positions: Vec::new(),
            uvs: Vec::new(),
            normals: Vec::new(),
            indices: Vec::new(),
        });
        Ok(())
    }

    /// The builder's vertex for a corner, added if new.
    fn vertex(&mut self, line: usize, corner: [u32; 3]) -> Result<u32> {
        let max = self.limits.max_vertices;
        let b = self.builder.as_mut().expect("start_run made a builder");
        if let Some(&i) = b.vertices.get(&corner) {
            return Ok(i);
        }
        let i = b.positions.len();
        if i as u64 >= max {
            return Err(line_error(
                self.file,
                line,
                format!(
                    "the mesh \"{}\" has more than {max} vertices, over the vertex limit",
                    b.name
                ),
            ));
        }
        b.positions.push(self.positions[corner[0] as usize]);
        if corner[1] != NONE {
            b.uvs.resize(i, Vec2::ZERO);
            b.uvs.push(self.texcoords[corner[1] as usize]);
        }
        if corner[2] != NONE {
            b.normals.resize(i, Vec3::ZERO);
            b.normals.push(self.normals[corner[2] as usize]);
        }
        b.vertices.insert(corner, i as u32);
        Ok(i as u32)
    }

    /// Turns the current builder, if it has triangles, into a mesh.
    fn flush(&mut self) -> Result<()> {
        let Some(b) = self.builder.take() else {
            return Ok(());
        };
        if b.indices.is_empty() {
            return Ok(());
        }
        let n = b.positions.len();
        fn pad<T: Copy>(mut v: Vec<T>, n: usize, zero: T) -> Option<Vec<T>> {
            if v.is_empty() {
                None
            } else {
                v.resize(n, zero);
                Some(v)
            }
        }
        let mut mesh = Mesh {
            name: b.name,
            positions: b.positions,
            normals: pad(b.normals, n, Vec3::ZERO),
            uv0: pad(b.uvs, n, Vec2::ZERO),
            indices: b.indices,
            ..Mesh::default()
        };
        // Fixes missing or broken normals and non-finite uvs; triangles were checked already.
        let dropped = mesh.clean();
        self.dropped.add(dropped);
        self.meshes.push(RawMesh {
            mesh,
            material: b.material,
            usemtl_line: b.usemtl_line,
        });
        Ok(())
    }

    fn mtllib(&mut self, line: usize, rest: &str) -> Result<()> {
        if rest.is_empty() {
            self.warnings.push(
                self.file,
                format!("line {line}: mtllib without a file name"),
            );
            return Ok(());
        }
        // Several libraries may follow `mtllib`; a name with spaces is one library.
        let names: Vec<&str> =
            if tokens(rest).all(|(_, t)| t.to_ascii_lowercase().ends_with(".mtl")) {
                tokens(rest).map(|(_, t)| t).collect()
            } else {
                vec![rest]
            };
        for name in names {
            let path = match self.source.resolve(self.file, name) {
                Ok(p) => p,
                Err(e) => {
                    self.warnings.push(
                        self.file,
                        format!("line {line}: {}; its materials are unknown", e.problem),
                    );
                    continue;
                }
            };
            if !self.libraries_read.insert(path.clone()) {
                continue;
            }
            let bytes = match self.source.read(&path, self.limits.max_file_bytes) {
                Ok(b) => b,
                Err(e) => {
                    self.warnings.push(
                        self.file,
                        format!(
                            "line {line}: cannot read the material library \"{}\" ({}); its materials are unknown",
                            name.escape_debug(),
                            e.problem
                        ),
                    );
                    continue;
                }
            };
            let normalised = name.replace('\\', "/");
            let dir = Path::new(&normalised)
                .parent()
                .map(|p| p.to_string_lossy().into_owned())
                .unwrap_or_default();
            self.library
                .parse(&bytes, &path, &dir, &mut self.warnings)?;
        }
        Ok(())
    }

    fn finish(mut self) -> Result<Scene> {
        self.flush()?;
        let file = self.file;
        let mut warnings = std::mem::take(&mut self.warnings);
        self.dropped.warn(file, &mut warnings);
        self.ignored.warn(file, &mut warnings);

        // Materials in order of first use: `None` is the default material.
        let mut slots: Vec<Option<usize>> = Vec::new();
        let mut slot_of: HashMap<Option<usize>, u32> = HashMap::new();
        let mut unknown: HashSet<String> = HashSet::new();
        let mut meshes = Vec::with_capacity(self.meshes.len());
        for raw in std::mem::take(&mut self.meshes) {
            let id = match &raw.material {
                None => None,
                Some(name) => match self.library.by_name.get(name) {
                    Some(&i) => Some(i),
                    None => {
                        if unknown.insert(name.clone()) {
                            warnings.push(
                                file,
                                format!(
                                    "line {}: unknown material \"{}\" (no material library defines it); using the default material",
                                    raw.usemtl_line,
                                    name.escape_debug()
                                ),
                            );
                        }
                        None
                    }
                },
            };
            let slot = *slot_of.entry(id).or_insert_with(|| {
                slots.push(id);
                slots.len() as u32 - 1
            });
            let mut mesh = raw.mesh;
            mesh.material = slot;
            meshes.push(mesh);
        }

        let (materials, textures) = build_materials(
            &self.library,
            &slots,
            self.source,
            self.limits,
            &mut warnings,
        )?;

        for mesh in &mut meshes {
            if materials[mesh.material as usize].normal_texture.is_none() {
                continue;
            }
            if mesh.uv0.is_none() {
                warnings.push(
                    file,
                    format!(
                        "the mesh \"{}\" has a normal-mapped material but no texture coordinates; the normal map cannot apply to it",
                        mesh.name
                    ),
                );
                continue;
            }
            if mesh.normals.is_none() {
                make_flat_normals(mesh);
            }
            generate_tangents(mesh, 0);
            if mesh.positions.len() as u64 > self.limits.max_vertices {
                return Err(SceneError::new(
                    file,
                    format!(
                        "the mesh \"{}\" has more than {} vertices once its tangents are added, over the vertex limit",
                        mesh.name, self.limits.max_vertices
                    ),
                ));
            }
        }

        let instances = meshes
            .iter()
            .enumerate()
            .map(|(i, m)| Instance {
                mesh: i as u32,
                transform: glam::Mat4::IDENTITY,
                name: m.name.clone(),
            })
            .collect();
        Ok(Scene {
            name: file
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_else(|| file.display().to_string()),
            meshes,
            instances,
            materials,
            textures,
            warnings: warnings.messages,
            dropped_triangles: (self.dropped.non_finite + self.dropped.degenerate) as u64,
            ..Scene::default()
        })
    }
}

// ---------------------------------------------------------------------------------------------
// MTL

/// A texture statement of a material library.
#[derive(Debug, Clone, PartialEq)]
struct MapRef {
    /// The file name as written.
    reference: String,
    line: usize,
    scale: Vec2,
    offset: Vec2,
    clamp: bool,
    /// `-bm`.
    bump: f32,
}

/// A material as its library defines it.
#[derive(Debug, Clone, Default, PartialEq)]
struct MtlMaterial {
    name: String,
    /// The library that defines it and that library's folder relative to the scene's folder.
    file: PathBuf,
    dir: String,
    kd: Option<Vec3>,
    ks: Option<Vec3>,
    ke: Option<Vec3>,
    ns: Option<f32>,
    ni: Option<f32>,
    d: Option<f32>,
    tr: Option<f32>,
    illum: Option<f32>,
    map_kd: Option<MapRef>,
    map_ks: Option<MapRef>,
    map_ke: Option<MapRef>,
    map_d: Option<MapRef>,
    /// `norm`: always a tangent-space normal map.
    norm: Option<MapRef>,
    /// `bump`/`map_bump`: a height map or a normal map.
    bump: Option<MapRef>,
}

#[derive(Default)]
struct MaterialLibrary {
    materials: Vec<MtlMaterial>,
    by_name: HashMap<String, usize>,
}

impl MaterialLibrary {
    /// Parses one library into `self`. A later definition of a name replaces the earlier one.
    fn parse(
        &mut self,
        text: &[u8],
        file: &Path,
        dir: &str,
        warnings: &mut Warnings,
    ) -> Result<()> {
        let mut lines = Lines::new(text);
        let mut current: Option<usize> = None;
        let mut ignored = Ignored::default();
        while let Some((line, content)) = lines.next_line() {
            let (keyword, rest) = split_keyword(&content);
            if keyword.is_empty() {
                continue;
            }
            let keyword = keyword.to_ascii_lowercase();
            if keyword == "newmtl" {
                if rest.is_empty() {
                    return Err(line_error(file, line, "newmtl without a name"));
                }
                if self.by_name.contains_key(rest) {
                    warnings.push(
                        file,
                        format!(
                            "line {line}: the material \"{}\" is defined again; the new definition replaces the earlier one",
                            rest.escape_debug()
                        ),
                    );
                }
                self.materials.push(MtlMaterial {
                    name: rest.to_owned(),
                    file: file.to_path_buf(),
                    dir: dir.to_owned(),
                    ..MtlMaterial::default()
                });
                current = Some(self.materials.len() - 1);
                self.by_name
                    .insert(rest.to_owned(), self.materials.len() - 1);
                continue;
            }
            let Some(m) = current.map(|i| &mut self.materials[i]) else {
                ignored.add(&format!("{keyword} (before newmtl)"));
                continue;
            };
            let scalar = |what: &str| -> Result<f32> {
                let mut it = tokens(rest).map(|(_, t)| t);
                // `d -halo factor`: the halo form is read as a plain dissolve.
                let mut t = it.next();
                if t.is_some_and(|t| t.eq_ignore_ascii_case("-halo")) {
                    t = it.next();
                }
                let Some(t) = t else {
                    return Err(line_error(file, line, format!("{what} needs a number")));
                };
                let x = number(file, line, what, t)?;
                if !x.is_finite() {
                    return Err(line_error(file, line, format!("{what} must be finite")));
                }
                Ok(x)
            };
            match keyword.as_str() {
                "kd" | "ks" | "ke" => {
                    let Some(c) = color(file, line, &keyword, rest, warnings)? else {
                        continue;
                    };
                    match keyword.as_str() {
                        "kd" => m.kd = Some(c),
                        "ks" => m.ks = Some(c),
                        _ => m.ke = Some(c),
                    }
                }
                "ns" => m.ns = Some(scalar("Ns")?),
                "ni" => m.ni = Some(scalar("Ni")?),
                "d" => m.d = Some(scalar("d")?),
                "tr" => m.tr = Some(scalar("Tr")?),
                "illum" => m.illum = Some(scalar("illum")?),
                "map_kd" | "map_ks" | "map_ke" | "map_d" | "norm" | "map_norm" | "bump"
                | "map_bump" => {
                    let Some(map) = map_ref(file, line, rest, warnings)? else {
                        continue;
                    };
                    match keyword.as_str() {
                        "map_kd" => m.map_kd = Some(map),
                        "map_ks" => m.map_ks = Some(map),
                        "map_ke" => m.map_ke = Some(map),
                        "map_d" => m.map_d = Some(map),
                        "norm" | "map_norm" => m.norm = Some(map),
                        _ => m.bump = Some(map),
                    }
                }
                "ka" | "map_ka" | "tf" | "sharpness" => {}
                _ => ignored.add(&keyword),
            }
        }
        ignored.warn(file, warnings);
        Ok(())
    }
}

/// Parses `r [g b]` (g and b default to r). `spectral` and `xyz` forms give a warning and `None`.
fn color(
    file: &Path,
    line: usize,
    what: &str,
    rest: &str,
    warnings: &mut Warnings,
) -> Result<Option<Vec3>> {
    let first = rest.split_ascii_whitespace().next().unwrap_or("");
    if first.eq_ignore_ascii_case("spectral") || first.eq_ignore_ascii_case("xyz") {
        warnings.push(
            file,
            format!("line {line}: {what} {first} is not supported; ignored"),
        );
        return Ok(None);
    }
    let mut c = Vec::with_capacity(3);
    for (_, t) in tokens(rest) {
        if c.len() == 3 {
            return Err(line_error(
                file,
                line,
                format!("{what} has more than 3 numbers"),
            ));
        }
        c.push(number(file, line, what, t)?);
    }
    let c = match c[..] {
        [r] => Vec3::splat(r),
        [r, g, b] => Vec3::new(r, g, b),
        _ => {
            return Err(line_error(
                file,
                line,
                format!("{what} needs 1 or 3 numbers, found {}", c.len()),
            ))
        }
    };
    if !c.is_finite() {
        return Err(line_error(file, line, format!("{what} must be finite")));
    }
    Ok(Some(c.max(Vec3::ZERO)))
}

/// Parses a texture statement: options, then the file name (the rest of the line).
fn map_ref(
    file: &Path,
    line: usize,
    rest: &str,
    warnings: &mut Warnings,
) -> Result<Option<MapRef>> {
    let mut map = MapRef {
        reference: String::new(),
        line,
        scale: Vec2::ONE,
        offset: Vec2::ZERO,
        clamp: false,
        bump: 1.0,
    };
    let mut it = tokens(rest).peekable();
    let is_number = |t: &str| t.parse::<f32>().is_ok();
    while let Some(&(at, token)) = it.peek() {
        if !token.starts_with('-') || token.len() == 1 || is_number(token) {
            let name = rest[at..].trim_ascii();
            let name = name
                .strip_prefix('"')
                .and_then(|n| n.strip_suffix('"'))
                .unwrap_or(name);
            map.reference = name.to_owned();
            return Ok(Some(map));
        }
        it.next();
        let option = token.to_ascii_lowercase();
        match option.as_str() {
            "-o" | "-s" | "-t" => {
                let mut v = [f32::NAN; 3];
                for x in &mut v {
                    match it.peek().and_then(|(_, t)| t.parse::<f32>().ok()) {
                        Some(n) => {
                            *x = n;
                            it.next();
                        }
                        None => break,
                    }
                }
                let default = if option == "-s" { 1.0 } else { 0.0 };
                let u = if v[0].is_finite() { v[0] } else { default };
                let w = if v[1].is_finite() { v[1] } else { default };
                match option.as_str() {
                    "-o" => map.offset = Vec2::new(u, w),
                    "-s" => map.scale = Vec2::new(u, w),
                    _ => {}
                }
            }
            "-bm" => {
                let Some((_, t)) = it.next() else {
                    return Err(line_error(file, line, "-bm needs a number"));
                };
                let x = number(file, line, "-bm", t)?;
                if !x.is_finite() {
                    return Err(line_error(file, line, "-bm must be finite"));
                }
                map.bump = x;
            }
            "-clamp" => {
                map.clamp = it.next().is_some_and(|(_, t)| t.eq_ignore_ascii_case("on"));
            }
            "-mm" => {
                it.next();
                it.next();
            }
            "-blendu" | "-blendv" | "-boost" | "-cc" | "-imfchan" | "-texres" | "-type" => {
                it.next();
            }
            _ => warnings.push(
                file,
                format!(
                    "line {line}: unknown texture option \"{}\"; skipped",
                    token.escape_debug()
                ),
            ),
        }
    }
    warnings.push(
        file,
        format!("line {line}: a texture statement without a file name; ignored"),
    );
    Ok(None)
}

// ---------------------------------------------------------------------------------------------
// Materials and textures

/// How a texture is made from its file(s).
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
enum TexKey {
    /// sRGB colour.
    Color(PathBuf),
    /// sRGB colour (white without a file) with the alpha channel taken from the second file.
    ColorAlpha(Option<PathBuf>, PathBuf),
    /// A tangent-space normal map.
    Normal(PathBuf),
    /// A height or normal map, with the bits of its `-bm`.
    Bump(PathBuf, u32),
}

impl TexKey {
    fn files(&self) -> impl Iterator<Item = &PathBuf> {
        let (a, b) = match self {
            Self::Color(p) | Self::Normal(p) | Self::Bump(p, _) => (Some(p), None),
            Self::ColorAlpha(c, d) => (c.as_ref(), Some(d)),
        };
        a.into_iter().chain(b)
    }
}

/// A material's request for a texture in one slot.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Slot {
    BaseColor,
    SpecularColor,
    Emissive,
    Normal,
}

struct Request {
    material: usize,
    slot: Slot,
    key: TexKey,
    map: MapRef,
}

/// A decoded image.
type Image = (u32, u32, Vec<[u8; 4]>);

/// Builds the scene's materials for `slots` (`None` = the default material) and decodes their
/// textures in parallel.
fn build_materials(
    library: &MaterialLibrary,
    slots: &[Option<usize>],
    source: &SceneSource,
    limits: &Limits,
    warnings: &mut Warnings,
) -> Result<(Vec<Material>, Vec<Texture>)> {
    let mut materials = Vec::with_capacity(slots.len());
    let mut requests = Vec::new();
    // Where each file was first referenced, for warnings.
    let mut referrer: HashMap<PathBuf, (PathBuf, usize, String)> = HashMap::new();
    for (index, slot) in slots.iter().enumerate() {
        let Some(m) = slot.map(|i| &library.materials[i]) else {
            materials.push(default_material());
            continue;
        };
        materials.push(convert_material(m, warnings));
        let mut resolve = |map: &MapRef| -> Option<PathBuf> {
            match resolve_texture(source, m, &map.reference) {
                Ok(p) => {
                    referrer
                        .entry(p.clone())
                        .or_insert_with(|| (m.file.clone(), map.line, map.reference.clone()));
                    Some(p)
                }
                Err(e) => {
                    warnings.push(
                        &m.file,
                        format!(
                            "line {}: {}; the material goes without it",
                            map.line, e.problem
                        ),
                    );
                    None
                }
            }
        };
        let kd = m
            .map_kd
            .as_ref()
            .and_then(|map| resolve(map).map(|p| (p, map)));
        let d = m
            .map_d
            .as_ref()
            .and_then(|map| resolve(map).map(|p| (p, map)));
        let mut push = |slot, key, map: &MapRef| {
            requests.push(Request {
                material: index,
                slot,
                key,
                map: map.clone(),
            })
        };
        match (kd, d) {
            (Some((kd, map)), Some((d, _))) => {
                push(Slot::BaseColor, TexKey::ColorAlpha(Some(kd), d), map)
            }
            (Some((kd, map)), None) => push(Slot::BaseColor, TexKey::Color(kd), map),
            (None, Some((d, map))) => push(Slot::BaseColor, TexKey::ColorAlpha(None, d), map),
            (None, None) => {}
        }
        if let Some(map) = &m.map_ks {
            if let Some(p) = resolve(map) {
                push(Slot::SpecularColor, TexKey::Color(p), map);
            }
        }
        if let Some(map) = &m.map_ke {
            if let Some(p) = resolve(map) {
                push(Slot::Emissive, TexKey::Color(p), map);
            }
        }
        if let Some(map) = &m.norm {
            if let Some(p) = resolve(map) {
                push(Slot::Normal, TexKey::Normal(p), map);
            }
        } else if let Some(map) = &m.bump {
            if let Some(p) = resolve(map) {
                push(Slot::Normal, TexKey::Bump(p, map.bump.to_bits()), map);
            }
        }
    }

    // Read every file once, check the pixel limits from the headers, then decode in parallel.
    let mut files: Vec<&PathBuf> = Vec::new();
    let mut seen = HashSet::new();
    for r in &requests {
        for f in r.key.files() {
            if seen.insert(f) {
                files.push(f);
            }
        }
    }
    let read: Vec<(&PathBuf, Result<Vec<u8>>)> = files
        .par_iter()
        .map(|&f| (f, source.read(f, limits.max_file_bytes)))
        .collect();
    let mut total_pixels = 0u64;
    let mut bytes_of: Vec<(&PathBuf, Vec<u8>)> = Vec::new();
    let warn = |warnings: &mut Warnings, f: &PathBuf, problem: &str| {
        let (lib, line, reference) = &referrer[f];
        warnings.push(
            lib,
            format!(
                "line {line}: the texture \"{}\" is not used: {problem}",
                reference.escape_debug()
            ),
        );
    };
    for (f, result) in read {
        match result {
            Ok(bytes) => {
                // Limits are checked on the header, before decoding; like a missing texture,
                // one over a limit is dropped with a warning (as the glTF loader does).
                if let Ok((_, w, h)) = image_header(&bytes, f) {
                    if let Err(e) = check_pixels(f, w, h, limits.max_texture_pixels) {
                        warn(warnings, f, &e.to_string());
                        continue;
                    }
                    total_pixels += w as u64 * h as u64;
                    if total_pixels > limits.max_total_texture_pixels {
                        let problem = format!(
                            "the textures hold over {} pixels in all (the limit)",
                            limits.max_total_texture_pixels
                        );
                        warn(warnings, f, &problem);
                        continue;
                    }
                }
                bytes_of.push((f, bytes));
            }
            Err(e) => warn(warnings, f, &e.to_string()),
        }
    }
    let decoded: Vec<(&PathBuf, Result<Image>)> = bytes_of
        .par_iter()
        .map(|(f, bytes)| (*f, decode_image(bytes, f, limits.max_texture_pixels)))
        .collect();
    let mut images: HashMap<&PathBuf, Image> = HashMap::new();
    for (f, result) in decoded {
        match result {
            Ok(img) => {
                images.insert(f, img);
            }
            Err(e) => warn(warnings, f, &e.to_string()),
        }
    }

    // One texture per distinct key, built in parallel, in order of first request.
    let mut keys: Vec<(&TexKey, &MapRef)> = Vec::new();
    let mut key_index: HashMap<&TexKey, usize> = HashMap::new();
    for r in &requests {
        key_index.entry(&r.key).or_insert_with(|| {
            keys.push((&r.key, &r.map));
            keys.len() - 1
        });
    }
    let built: Vec<Option<(Texture, bool)>> = keys
        .par_iter()
        .map(|(key, map)| build_texture(key, map, &images))
        .collect();
    let mut textures = Vec::new();
    let mut texture_of: Vec<Option<(u32, bool)>> = Vec::with_capacity(built.len());
    for b in built {
        texture_of.push(b.map(|(t, baked)| {
            textures.push(t);
            (textures.len() as u32 - 1, baked)
        }));
    }
    for r in &requests {
        let Some((texture, baked)) = texture_of[key_index[&r.key]] else {
            continue;
        };
        let mut tref = TextureRef::new(texture);
        tref.transform = map_transform(&r.map);
        if r.map.clamp {
            tref.sampler = Sampler {
                wrap_s: Wrap::ClampToEdge,
                wrap_t: Wrap::ClampToEdge,
                ..Sampler::default()
            };
        }
        let m = &mut materials[r.material];
        match r.slot {
            Slot::BaseColor => {
                m.base_color_texture = Some(tref);
                if matches!(r.key, TexKey::ColorAlpha(..)) && m.alpha_mode == AlphaMode::Opaque {
                    m.alpha_mode = AlphaMode::Mask { cutoff: 0.5 };
                }
            }
            Slot::SpecularColor => m.specular_color_texture = Some(tref),
            Slot::Emissive => m.emissive_texture = Some(tref),
            Slot::Normal => {
                m.normal_texture = Some(tref);
                m.normal_scale = if baked { 1.0 } else { r.map.bump };
            }
        }
    }
    Ok((materials, textures))
}

/// Resolves a texture reference relative to its material library's folder.
fn resolve_texture(source: &SceneSource, m: &MtlMaterial, reference: &str) -> Result<PathBuf> {
    let r = reference.replace('\\', "/");
    if m.dir.is_empty() || r.starts_with('/') || r.contains(':') {
        source.resolve(&m.file, reference)
    } else {
        source.resolve(&m.file, &format!("{}/{r}", m.dir))
    }
}

/// `-s` and `-o` in our uv convention: OBJ maps (u, v_up) to (u s_u + o_u, v_up s_v + o_v);
/// with v = 1 - v_up that is v' = v s_v + (1 - s_v - o_v).
fn map_transform(map: &MapRef) -> Affine2 {
    if map.scale == Vec2::ONE && map.offset == Vec2::ZERO {
        return Affine2::IDENTITY;
    }
    Affine2::from_mat2_translation(
        Mat2::from_diagonal(map.scale),
        Vec2::new(map.offset.x, 1.0 - map.scale.y - map.offset.y),
    )
}

/// Converts an MTL material, textures aside.
fn convert_material(m: &MtlMaterial, warnings: &mut Warnings) -> Material {
    let kd = m.kd.unwrap_or(if m.map_kd.is_some() {
        Vec3::ONE
    } else {
        Vec3::splat(0.8)
    });
    let ior = match m.ni {
        Some(ni) if ni > 1.0 => ni,
        _ => 1.5,
    };
    let ks = m.ks.unwrap_or(if m.map_ks.is_some() {
        Vec3::ONE
    } else {
        Vec3::ZERO
    });
    let diffuse_only = m.illum.is_some_and(|i| i == 0.0 || i == 1.0);
    let (specular, specular_color) = if ks.max_element() > 0.0 && !diffuse_only {
        let r = (ior - 1.0) / (ior + 1.0);
        (1.0, ks / (r * r))
    } else {
        (0.0, Vec3::ONE)
    };
    let ns = m.ns.unwrap_or(0.0).max(0.0);
    let alpha = (2.0 / (ns + 2.0)).sqrt();
    let roughness = alpha.sqrt().clamp(0.0, 1.0);
    let emissive = m.ke.unwrap_or(if m.map_ke.is_some() {
        Vec3::ONE
    } else {
        Vec3::ZERO
    });
    let d =
        m.d.or(m.tr.map(|tr| 1.0 - tr))
            .unwrap_or(1.0)
            .clamp(0.0, 1.0);
    if d == 0.0 {
        warnings.push(
            &m.file,
            format!(
                "the material \"{}\" is fully transparent (d 0 or Tr 1)",
                m.name.escape_debug()
            ),
        );
    }
    Material {
        name: m.name.clone(),
        base_color: kd.extend(d),
        metallic: 0.0,
        roughness,
        specular,
        specular_color,
        ior,
        emissive,
        alpha_mode: if d < 1.0 {
            AlphaMode::Blend
        } else {
            AlphaMode::Opaque
        },
        double_sided: true,
        ..Material::default()
    }
}

/// Builds the texture of a key from decoded images; the flag says a height map was converted
/// (its bump scale is baked in). `None` when a needed image is missing.
fn build_texture(
    key: &TexKey,
    map: &MapRef,
    images: &HashMap<&PathBuf, Image>,
) -> Option<(Texture, bool)> {
    let name = map.reference.clone();
    match key {
        TexKey::Color(p) => {
            let (w, h, t) = images.get(p)?;
            Some((
                Texture::new(name, *w, *h, t.clone(), ColorSpace::Srgb),
                false,
            ))
        }
        TexKey::Normal(p) => {
            let (w, h, t) = images.get(p)?;
            Some((
                Texture::new(name, *w, *h, t.clone(), ColorSpace::Linear),
                false,
            ))
        }
        TexKey::Bump(p, bits) => {
            let (w, h, t) = images.get(p)?;
            if looks_like_normal_map(t) {
                Some((
                    Texture::new(name, *w, *h, t.clone(), ColorSpace::Linear),
                    false,
                ))
            } else {
                let n = height_to_normal(*w, *h, t, f32::from_bits(*bits), map.clamp);
                Some((Texture::new(name, *w, *h, n, ColorSpace::Linear), true))
            }
        }
        TexKey::ColorAlpha(color, d) => {
            let alpha = images.get(d);
            let color = color.as_ref().and_then(|c| images.get(c));
            match (color, alpha) {
                (None, None) => None,
                (Some((w, h, t)), None) => Some((
                    Texture::new(name, *w, *h, t.clone(), ColorSpace::Srgb),
                    false,
                )),
                (color, Some((aw, ah, at))) => {
                    let (w, h, mut texels) = match color {
                        Some((w, h, t)) => (*w, *h, t.clone()),
                        None => (*aw, *ah, vec![[255; 4]; *aw as usize * *ah as usize]),
                    };
                    let has_alpha = at.iter().any(|t| t[3] != 255);
                    for y in 0..h {
                        let sy = (y as u64 * *ah as u64 / h as u64) as usize;
                        for x in 0..w {
                            let sx = (x as u64 * *aw as u64 / w as u64) as usize;
                            let s = at[sy * *aw as usize + sx];
                            let a = if has_alpha {
                                s[3]
                            } else {
                                ((s[0] as u32 + s[1] as u32 + s[2] as u32 + 1) / 3) as u8
                            };
                            texels[y as usize * w as usize + x as usize][3] = a;
                        }
                    }
                    Some((Texture::new(name, w, h, texels, ColorSpace::Srgb), false))
                }
            }
        }
    }
}

/// True when an image looks like a tangent-space normal map rather than a height map: coloured,
/// with a high mean blue and mean red and green near the middle.
fn looks_like_normal_map(texels: &[[u8; 4]]) -> bool {
    let step = (texels.len() / 65536).max(1);
    let (mut sum, mut chroma, mut n) = ([0f64; 3], 0f64, 0f64);
    for t in texels.iter().step_by(step) {
        for (s, c) in sum.iter_mut().zip(t) {
            *s += *c as f64;
        }
        chroma += (t[0] as f64 - t[1] as f64).abs() + (t[1] as f64 - t[2] as f64).abs();
        n += 1.0;
    }
    if n == 0.0 {
        return false;
    }
    let [r, g, b] = sum.map(|s| s / n / 255.0);
    chroma / n >= 6.0 && b > 0.6 && (0.3..=0.7).contains(&r) && (0.3..=0.7).contains(&g)
}

/// Converts a height map (mean of R, G, B in [0, 1]) into a tangent-space normal map (+X along
/// u, +Y up the image) by central differences, the slope scaled by `scale`. Edges wrap, or clamp.
fn height_to_normal(
    width: u32,
    height: u32,
    texels: &[[u8; 4]],
    scale: f32,
    clamp: bool,
) -> Vec<[u8; 4]> {
    let (w, h) = (width as i64, height as i64);
    let at = |x: i64, y: i64| {
        let (x, y) = if clamp {
            (x.clamp(0, w - 1), y.clamp(0, h - 1))
        } else {
            (x.rem_euclid(w), y.rem_euclid(h))
        };
        let t = texels[(y * w + x) as usize];
        (t[0] as f32 + t[1] as f32 + t[2] as f32) / (3.0 * 255.0)
    };
    let mut out = vec![[0u8; 4]; texels.len()];
    out.par_chunks_mut(width as usize)
        .enumerate()
        .for_each(|(y, row)| {
            let y = y as i64;
            for (x, o) in row.iter_mut().enumerate() {
                let x = x as i64;
                let dx = (at(x + 1, y) - at(x - 1, y)) * 0.5 * scale;
                // Image rows run down; tangent-space +Y runs up.
                let dy = (at(x, y - 1) - at(x, y + 1)) * 0.5 * scale;
                let n = Vec3::new(-dx, -dy, 1.0).normalize();
                let e = |c: f32| ((c * 0.5 + 0.5) * 255.0).round().clamp(0.0, 255.0) as u8;
                *o = [e(n.x), e(n.y), e(n.z), 255];
            }
        });
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn memory(files: &[(&str, &[u8])]) -> SceneSource {
        SceneSource::Memory(
            files
                .iter()
                .map(|(k, v)| (k.to_string(), v.to_vec()))
                .collect(),
        )
    }

    fn parse_with(obj: &str, files: &[(&str, &[u8])]) -> Result<Scene> {
        parse(
            obj.as_bytes(),
            Path::new("test.obj"),
            &memory(files),
            &Limits::default(),
        )
    }

    fn parse_str(obj: &str) -> Result<Scene> {
        parse_with(obj, &[])
    }

    fn err(obj: &str) -> String {
        parse_str(obj).unwrap_err().to_string()
    }

    const QUAD: &str = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n";

    #[test]
    fn polygon_is_fan_triangulated() {
        let s = parse_str(&format!("{QUAD}v 0.5 1.5 0\nf 1 2 3 5 4\n")).unwrap();
        assert_eq!(s.meshes.len(), 1);
        assert_eq!(s.meshes[0].indices, vec![[0, 1, 2], [0, 2, 3], [0, 3, 4]]);
        assert_eq!(s.meshes[0].positions[3], Vec3::new(0.5, 1.5, 0.0));
        assert_eq!(s.instances.len(), 1);
        assert_eq!(s.instances[0].transform, glam::Mat4::IDENTITY);
        assert_eq!(s.name, "test.obj");
        assert!(s.warnings.is_empty(), "{:?}", s.warnings);
    }

    #[test]
    fn relative_indices_and_corner_forms() {
        let obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nvn 0 0 1\n\
                   f -3/-3/-1 -2/-2/-1 -1/-1/-1\n\
                   v 5 0 0\nv 6 0 0\nv 5 1 0\n\
                   f -3//1 -2//1 -1//1\n\
                   f 1/1 2/2 3/3\n\
                   f 4 5 6\n";
        let s = parse_str(obj).unwrap();
        assert_eq!(s.meshes.len(), 1);
        let m = &s.meshes[0];
        assert_eq!(m.triangle_count(), 4);
        // Distinct (v, vt, vn) triples: 3 + 3 + 3 + 3 (the last two faces lack vn or vt).
        assert_eq!(m.positions.len(), 12);
        assert_eq!(
            m.triangle(1),
            [
                Vec3::new(5.0, 0.0, 0.0),
                Vec3::new(6.0, 0.0, 0.0),
                Vec3::new(5.0, 1.0, 0.0)
            ]
        );
        assert_eq!(m.triangle(0), [Vec3::ZERO, Vec3::X, Vec3::Y]);
        assert_eq!(m.triangle(3), m.triangle(1));
        // Vertices without vn got their face's normal.
        assert!(m
            .normals
            .as_ref()
            .unwrap()
            .iter()
            .all(|n| (*n - Vec3::Z).length() < 1e-6));
    }

    #[test]
    fn vertices_are_shared_by_index_triple() {
        let s = parse_str(&format!("{QUAD}f 1 2 3\nf 1 3 4\n")).unwrap();
        assert_eq!(s.meshes[0].positions.len(), 4);
        assert_eq!(s.meshes[0].indices, vec![[0, 1, 2], [0, 2, 3]]);
        assert!(s.meshes[0].normals.is_none() && s.meshes[0].uv0.is_none());
    }

    #[test]
    fn texture_coordinates_get_a_top_left_origin() {
        let obj = format!("{QUAD}vt 0 0\nvt 1 0\nvt 1 1\nvt 0.25 0.75\nf 1/1 2/2 3/3 4/4\n");
        let s = parse_str(&obj).unwrap();
        let uv = s.meshes[0].uv0.as_ref().unwrap();
        // OBJ (0, 0) is the image's bottom-left: our (0, 1).
        assert_eq!(uv[0], Vec2::new(0.0, 1.0));
        assert_eq!(uv[1], Vec2::new(1.0, 1.0));
        assert_eq!(uv[2], Vec2::new(1.0, 0.0));
        assert_eq!(uv[3], Vec2::new(0.25, 0.25));
    }

    #[test]
    fn one_mesh_per_group_and_material_run() {
        let mtl = b"newmtl a\nKd 1 0 0\nnewmtl b\nKd 0 1 0\n";
        let obj = format!(
            "mtllib m.mtl\n{QUAD}g one\nusemtl a\nf 1 2 3\nf 1 3 4\nusemtl b\nf 1 2 3\n\
             g two\nf 1 3 4\ng two\nusemtl b\nf 1 2 4\no three\nusemtl a\nf 2 3 4\n"
        );
        let s = parse_with(&obj, &[("m.mtl", mtl)]).unwrap();
        let runs: Vec<_> = s
            .meshes
            .iter()
            .map(|m| {
                (
                    m.name.as_str(),
                    s.materials[m.material as usize].name.as_str(),
                    m.triangle_count(),
                )
            })
            .collect();
        assert_eq!(
            runs,
            vec![
                ("one", "a", 2),
                ("one", "b", 1),
                ("two", "b", 2),
                ("three", "a", 1)
            ]
        );
        assert_eq!(s.materials.len(), 2);
        // Each mesh holds only its own vertices.
        assert_eq!(s.meshes[1].positions.len(), 3);
        assert_eq!(s.instances.len(), 4);
        assert_eq!(s.instances[2].mesh, 2);
    }

    #[test]
    fn comments_continuations_crlf_and_bad_utf8() {
        let mut obj =
            b"# header \\\r\nv 0 0 0 # a comment\r\nv 1 \\\r\n 0 0\r\nv 0 1 0\r\n".to_vec();
        obj.extend_from_slice(b"g caf\xe9\r\nf 1 2 \\\n 3\r\nunknownthing 1 2\nl 1 2\nl 2 3\n");
        let s = parse(&obj, Path::new("t.obj"), &memory(&[]), &Limits::default()).unwrap();
        assert_eq!(s.meshes[0].positions, vec![Vec3::ZERO, Vec3::X, Vec3::Y]);
        assert_eq!(s.meshes[0].name, "caf\u{fffd}");
        assert_eq!(s.warnings.len(), 1, "{:?}", s.warnings);
        assert!(
            s.warnings[0].contains("l (2x), unknownthing (1x)"),
            "{:?}",
            s.warnings
        );
        // Bad bytes in a number are an error, never a panic.
        let e = parse(
            b"v 0 0 \xff\n",
            Path::new("t.obj"),
            &memory(&[]),
            &Limits::default(),
        );
        assert!(e
            .unwrap_err()
            .to_string()
            .contains("t.obj: line 1: bad number"));
    }

    #[test]
    fn continuation_keeps_the_first_line_number_for_errors() {
        let e = err("v 0 0 0\nf 1 \\\n 2\n");
        assert!(e.contains("line 2:"), "{e}");
        let e = err("v 0 0 0\nv 1 \\\n 2 \\\n 3\nv 1 x 0\n");
        assert!(e.contains("line 5:"), "{e}");
    }

    #[test]
    fn errors_name_the_file_and_line() {
        let cases: &[(&str, usize, &str)] = &[
            ("v 0 0 0\nv 1 0 zero\n", 2, "bad number \"zero\""),
            ("v 0 0\n", 1, "at least 3 numbers"),
            ("v 0 0 0 1 1 1 1 1\n", 1, "more than 7 numbers"),
            ("vt\n", 1, "at least 1 numbers"),
            ("vn 0 0 x\n", 1, "bad number"),
            (&format!("{QUAD}f 0 1 2\n"), 5, "index 0"),
            (
                &format!("{QUAD}f 1 2 5\n"),
                5,
                "vertex index 5 is out of range: 4 defined",
            ),
            (
                &format!("{QUAD}f -1 -2 -5\n"),
                5,
                "vertex index -5 is out of range",
            ),
            (&format!("f 1 2 3\n{QUAD}"), 1, "out of range: 0 defined"),
            (
                &format!("{QUAD}vt 0 0\nf 1/2 2/1 3/1\n"),
                6,
                "texture coordinate index 2 is out of range",
            ),
            (
                &format!("{QUAD}f 1//1 2//1 3//1\n"),
                5,
                "normal index 1 is out of range",
            ),
            (
                &format!("{QUAD}\n\nf 1 2\n"),
                7,
                "at least 3 corners, found 2",
            ),
            (&format!("{QUAD}f\n"), 5, "found 0"),
            (&format!("{QUAD}f 1 2 3x\n"), 5, "bad vertex index \"3x\""),
            (&format!("{QUAD}f 1/1/1/1 2 3\n"), 5, "bad face corner"),
            (
                &format!("{QUAD}f 1 2 99999999999999999999999\n"),
                5,
                "bad vertex index",
            ),
        ];
        for (obj, line, what) in cases {
            let e = err(obj);
            assert!(
                e.starts_with(&format!("test.obj: line {line}: ")),
                "{obj:?}: {e}"
            );
            assert!(e.contains(what), "{obj:?}: {e}");
        }
    }

    #[test]
    fn non_finite_and_degenerate_triangles_are_dropped_with_one_warning() {
        let obj = format!(
            "{QUAD}v nan 0 0\nv inf 1 1\nv 2 0 0\n\
             f 1 2 3\nf 1 5 2\nf 6 1 2\nf 1 2 7\nf 1 1 3\nf 1 2 3 4\n"
        );
        let s = parse_str(&obj).unwrap();
        assert_eq!(s.meshes[0].triangle_count(), 3);
        assert!(s.meshes[0].positions.iter().all(|p| p.is_finite()));
        assert_eq!(s.dropped_triangles, 4);
        assert_eq!(s.warnings.len(), 1, "{:?}", s.warnings);
        let w = &s.warnings[0];
        assert!(w.starts_with("test.obj: dropped 4 triangles"), "{w}");
        assert!(
            w.contains("2 with a NaN or infinite corner, 2 of zero area"),
            "{w}"
        );
        // A file of only bad triangles is an empty scene, not an error.
        let s = parse_str("v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
        assert!(s.meshes.is_empty() && s.instances.is_empty());
        assert!(s.warnings[0].contains("dropped 1 triangles"));
    }

    #[test]
    fn limits_are_errors_before_allocation() {
        let limits = Limits {
            max_triangles: 3,
            max_vertices: 4,
            ..Limits::default()
        };
        let run = |obj: &str| {
            parse(obj.as_bytes(), Path::new("big.obj"), &memory(&[]), &limits)
                .unwrap_err()
                .to_string()
        };
        let e = run(&format!("{QUAD}v 2 2 2\n"));
        assert!(
            e.contains("big.obj: line 5: more than 4 vertex positions"),
            "{e}"
        );
        let e = run("vt 0\nvt 0\nvt 0\nvt 0\nvt 0\n");
        assert!(
            e.contains("line 5") && e.contains("texture coordinates"),
            "{e}"
        );
        // A polygon of 6 corners needs 4 triangles: refused before any is stored.
        let e = run("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4 1 2\n");
        assert!(e.contains("line 5: more than 3 triangles"), "{e}");
        let e = run(&format!("{QUAD}f 1 2 3\nf 1 3 4\nf 2 3 4\nf 1 2 4\n"));
        assert!(e.contains("line 8: more than 3 triangles"), "{e}");
        // The mesh vertex limit counts distinct (v, vt, vn) triples.
        let e = run(&format!(
            "{QUAD}vt 0 0\nvt 1 0\nf 1/1 2/1 3/1\nf 1/2 2/2 3/2\n"
        ));
        assert!(
            e.contains("line 8: the mesh \"default\" has more than 4 vertices"),
            "{e}"
        );
        let limits = Limits {
            max_instances: 1,
            ..Limits::default()
        };
        let e = parse(
            format!("{QUAD}g a\nf 1 2 3\ng b\nf 1 3 4\n").as_bytes(),
            Path::new("big.obj"),
            &memory(&[]),
            &limits,
        )
        .unwrap_err();
        assert!(e.to_string().contains("line 8: more than 1 meshes"), "{e}");
    }

    #[test]
    fn a_huge_polygon_is_refused_quickly() {
        let mut obj = String::from("v 0 0 0\nv 1 0 0\nv 0 1 0\nf");
        for _ in 0..200_000 {
            obj.push_str(" 1 2 3");
        }
        let limits = Limits {
            max_triangles: 1000,
            ..Limits::default()
        };
        let t = std::time::Instant::now();
        let e = parse(obj.as_bytes(), Path::new("h.obj"), &memory(&[]), &limits).unwrap_err();
        assert!(
            e.to_string().contains("line 4: more than 1000 triangles"),
            "{e}"
        );
        assert!(t.elapsed().as_secs_f32() < 2.0);
    }

    fn material(mtl: &str) -> (Scene, Material) {
        let obj = format!("mtllib m.mtl\n{QUAD}usemtl m\nf 1 2 3\n");
        let s = parse_with(&obj, &[("m.mtl", mtl.as_bytes())]).unwrap();
        let m = s.materials[0].clone();
        (s, m)
    }

    #[test]
    fn kd_only_material_is_exactly_lambertian() {
        let (s, m) = material("newmtl m\nKd 0.63 0.065 0.05\nKs 0 0 0\nNs 10\nillum 2\nKa 1 1 1\n");
        assert!(s.warnings.is_empty(), "{:?}", s.warnings);
        assert_eq!(m.name, "m");
        assert_eq!(m.base_color, glam::Vec4::new(0.63, 0.065, 0.05, 1.0));
        assert_eq!((m.metallic, m.specular), (0.0, 0.0));
        assert_eq!(m.dielectric_f0(), Vec3::ZERO);
        assert!(m.double_sided);
        assert_eq!(m.alpha_mode, AlphaMode::Opaque);
        assert_eq!(m.emissive, Vec3::ZERO);
        let (_, m) = material("newmtl m\nKd 0.5\n");
        assert_eq!(m.base_color, glam::Vec4::new(0.5, 0.5, 0.5, 1.0));
        assert_eq!(m.specular, 0.0);
        // illum 1 is diffuse only even with Ks.
        let (_, m) = material("newmtl m\nKd 0.5\nKs 0.5 0.5 0.5\nillum 1\n");
        assert_eq!(m.specular, 0.0);
    }

    #[test]
    fn specular_mapping() {
        let (_, m) = material("newmtl m\nkd 0.2 0.3 0.4\nKS 0.04 0.5 2\nNs 98\n");
        assert_eq!(m.specular, 1.0);
        assert_eq!(m.metallic, 0.0);
        assert_eq!(m.ior, 1.5);
        let f0 = m.dielectric_f0();
        assert!(
            (f0 - Vec3::new(0.04, 0.5, 1.0)).abs().max_element() < 1e-6,
            "{f0}"
        );
        assert!(
            (m.specular_color - Vec3::new(1.0, 12.5, 50.0))
                .abs()
                .max_element()
                < 1e-4
        );
        // alpha = sqrt(2 / 100), roughness = sqrt(alpha).
        assert!((m.roughness - 0.02f32.sqrt().sqrt()).abs() < 1e-6);
        let (_, m) = material("newmtl m\nKs 1 1 1\nNs 0\n");
        assert_eq!(m.roughness, 1.0);
        let (_, m) = material("newmtl m\nKs 1 1 1\nNs 1e9\n");
        assert!(m.roughness > 0.0 && m.roughness < 0.01);
        // Ni sets the ior, and F0 stays Ks.
        let (_, m) = material("newmtl m\nKs 0.1 0.1 0.1\nNi 1.33\n");
        assert_eq!(m.ior, 1.33);
        assert!((m.dielectric_f0() - Vec3::splat(0.1)).abs().max_element() < 1e-6);
        for ni in ["1.0", "0", "-2"] {
            let (_, m) = material(&format!("newmtl m\nNi {ni}\n"));
            assert_eq!(m.ior, 1.5, "Ni {ni}");
        }
    }

    #[test]
    fn emission_and_transparency() {
        let (_, m) = material("newmtl m\nKe 17 12 4\n");
        assert_eq!(m.emissive, Vec3::new(17.0, 12.0, 4.0));
        assert!(m.is_emissive());
        let (_, m) = material("newmtl m\nKd 1 1 1\nd 0.25\n");
        assert_eq!(m.alpha_mode, AlphaMode::Blend);
        assert_eq!(m.base_color.w, 0.25);
        let (_, m) = material("newmtl m\nTr 0.75\n");
        assert_eq!((m.alpha_mode, m.base_color.w), (AlphaMode::Blend, 0.25));
        let (_, m) = material("newmtl m\nd -halo 0.5\nTr 0.9\n");
        assert_eq!(m.base_color.w, 0.5, "d wins over Tr");
        let (_, m) = material("newmtl m\nd 1\n");
        assert_eq!(m.alpha_mode, AlphaMode::Opaque);
        let (s, _) = material("newmtl m\nd 0\n");
        assert!(s.warnings[0].contains("fully transparent"));
    }

    #[test]
    fn mtl_errors_name_the_library_and_line() {
        let obj = format!("mtllib lib.mtl\n{QUAD}usemtl m\nf 1 2 3\n");
        for (mtl, line, what) in [
            (
                "newmtl m\nKd 1 x 1\n",
                2,
                "bad number \"x\" in a kd statement",
            ),
            ("newmtl m\n\nKd 1 1\n", 3, "1 or 3 numbers"),
            ("newmtl m\nNs nan\n", 2, "Ns must be finite"),
            ("newmtl m\nKe inf 0 0\n", 2, "must be finite"),
            ("newmtl\n", 1, "newmtl without a name"),
            ("newmtl m\nmap_Kd -bm x.png\n", 2, "bad number \"x.png\""),
        ] {
            let e = parse_with(&obj, &[("lib.mtl", mtl.as_bytes())])
                .unwrap_err()
                .to_string();
            assert!(
                e.starts_with(&format!("lib.mtl: line {line}: ")),
                "{mtl:?}: {e}"
            );
            assert!(e.contains(what), "{mtl:?}: {e}");
        }
    }

    #[test]
    fn unknown_material_and_missing_library_warn_and_use_the_default() {
        let obj = format!(
            "mtllib nothere.mtl\n{QUAD}usemtl red\nf 1 2 3\nusemtl red\nf 1 3 4\nf 2 3 4\n"
        );
        let s = parse_str(&obj).unwrap();
        assert_eq!(s.materials, vec![default_material()]);
        assert_eq!(s.meshes.len(), 1, "one run: same group, same usemtl");
        assert_eq!(s.warnings.len(), 2, "{:?}", s.warnings);
        assert!(s.warnings[0].contains("line 1: cannot read the material library \"nothere.mtl\""));
        assert!(
            s.warnings[1].contains("line 6: unknown material \"red\""),
            "{:?}",
            s.warnings
        );
        // Faces without usemtl get the default material, silently.
        let s = parse_str(&format!("{QUAD}f 1 2 3\n")).unwrap();
        assert_eq!(s.materials, vec![default_material()]);
        assert_eq!(
            s.materials[0].base_color,
            glam::Vec4::new(0.8, 0.8, 0.8, 1.0)
        );
    }

    #[test]
    fn escaping_library_references_are_refused() {
        for bad in [
            "../../etc/passwd",
            "/etc/passwd",
            "C:\\x.mtl",
            "file:///etc/passwd",
        ] {
            let obj = format!("mtllib {bad}\n{QUAD}usemtl m\nf 1 2 3\n");
            let s = parse_str(&obj).unwrap();
            assert!(s.warnings[0].contains("refused"), "{bad}: {:?}", s.warnings);
            assert!(
                s.warnings[0].starts_with("test.obj: line 1: "),
                "{:?}",
                s.warnings
            );
            assert_eq!(s.materials, vec![default_material()]);
        }
    }

    #[test]
    fn several_libraries_on_one_line_and_names_with_spaces() {
        let a = b"newmtl a\nKd 1 0 0\n";
        let b = b"newmtl b\nKd 0 1 0\n";
        let obj = format!("mtllib a.mtl sub/b.mtl\n{QUAD}usemtl b\nf 1 2 3\nusemtl a\nf 1 3 4\n");
        let s = parse_with(&obj, &[("a.mtl", a), ("sub/b.mtl", b)]).unwrap();
        assert!(s.warnings.is_empty(), "{:?}", s.warnings);
        assert_eq!(s.materials[0].name, "b");
        assert_eq!(s.materials[1].name, "a");
        let obj = format!("mtllib my materials.mtl\n{QUAD}usemtl my red\nf 1 2 3\n");
        let s = parse_with(&obj, &[("my materials.mtl", b"newmtl my red\nKd 1 0 0\n")]).unwrap();
        assert!(s.warnings.is_empty(), "{:?}", s.warnings);
        assert_eq!(s.materials[0].name, "my red");
    }

    #[test]
    fn texture_options_do_not_eat_the_file_name() {
        let mut w = Warnings::default();
        let f = Path::new("m.mtl");
        let m = map_ref(
            f,
            3,
            "-s 2 3 -o 0.5 -blendu off -clamp on -mm 0 1 -imfchan r my tex.png",
            &mut w,
        )
        .unwrap()
        .unwrap();
        assert_eq!(m.reference, "my tex.png");
        assert_eq!(
            (m.scale, m.offset, m.clamp),
            (Vec2::new(2.0, 3.0), Vec2::new(0.5, 0.0), true)
        );
        let m = map_ref(f, 3, "-bm 0.3 -s 1 1 1 bump.jpg", &mut w)
            .unwrap()
            .unwrap();
        assert_eq!((m.reference.as_str(), m.bump), ("bump.jpg", 0.3));
        let m = map_ref(f, 3, "-o 1 2.png", &mut w).unwrap().unwrap();
        assert_eq!(m.reference, "2.png");
        let m = map_ref(f, 3, "\"quoted name.png\"", &mut w)
            .unwrap()
            .unwrap();
        assert_eq!(m.reference, "quoted name.png");
        assert!(w.messages.is_empty());
        assert!(map_ref(f, 3, "-s 1 1", &mut w).unwrap().is_none());
        assert!(w.messages[0].contains("line 3: a texture statement without a file name"));
    }

    #[test]
    fn scale_and_offset_follow_the_flipped_v() {
        let map = MapRef {
            reference: String::new(),
            line: 1,
            scale: Vec2::new(2.0, 4.0),
            offset: Vec2::new(0.25, 0.5),
            clamp: false,
            bump: 1.0,
        };
        let t = map_transform(&map);
        // OBJ uv (u, v_up) -> (u s + o); ours is (u, 1 - v_up) -> (u', 1 - v_up').
        for (u, v_up) in [(0.0, 0.0), (0.3, 0.7), (1.0, 1.0)] {
            let ours = t.transform_point2(Vec2::new(u, 1.0 - v_up));
            let expected = Vec2::new(u * 2.0 + 0.25, 1.0 - (v_up * 4.0 + 0.5));
            assert!((ours - expected).length() < 1e-6, "{ours} {expected}");
        }
    }

    fn png(w: u32, h: u32, f: impl Fn(u32, u32) -> [u8; 4]) -> Vec<u8> {
        let img = image::RgbaImage::from_fn(w, h, |x, y| image::Rgba(f(x, y)));
        let mut out = Vec::new();
        img.write_to(&mut std::io::Cursor::new(&mut out), image::ImageFormat::Png)
            .unwrap();
        out
    }

    const TEXTURED: &str = "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n\
                            vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nusemtl m\nf 1/1 2/2 3/3 4/4\n";

    #[test]
    fn textures_are_decoded_shared_and_assigned() {
        let red = png(2, 2, |_, _| [255, 0, 0, 255]);
        let mtl = b"newmtl m\nmap_Kd tex/red.png\nmap_Ks tex/red.png\nmap_Ke -s 2 2 tex/red.png\n";
        let s = parse_with(TEXTURED, &[("m.mtl", mtl), ("tex/red.png", &red)]).unwrap();
        assert!(s.warnings.is_empty(), "{:?}", s.warnings);
        assert_eq!(s.textures.len(), 1, "one file, one colour space");
        let m = &s.materials[0];
        assert_eq!(
            m.base_color,
            glam::Vec4::ONE,
            "Kd defaults to 1 with map_Kd"
        );
        assert_eq!(m.base_color_texture.unwrap().texture, 0);
        assert_eq!(m.specular_color_texture.unwrap().texture, 0);
        assert_eq!(m.emissive, Vec3::ONE);
        assert_eq!(
            m.emissive_texture.unwrap().transform.matrix2,
            Mat2::from_diagonal(Vec2::splat(2.0))
        );
        assert_eq!(s.textures[0].color_space, ColorSpace::Srgb);
        assert_eq!(s.textures[0].name, "tex/red.png");
        assert_eq!(
            s.textures[0].texel(0, 0, 0),
            glam::Vec4::new(1.0, 0.0, 0.0, 1.0)
        );
    }

    #[test]
    fn texture_paths_are_relative_to_the_library() {
        let red = png(1, 1, |_, _| [255, 0, 0, 255]);
        let obj = TEXTURED.replace("mtllib m.mtl", "mtllib mat/m.mtl");
        let mtl = b"newmtl m\nmap_Kd ../tex/red.png\nmap_Ks ../../escape.png\n";
        let s = parse_with(&obj, &[("mat/m.mtl", mtl), ("tex/red.png", &red)]).unwrap();
        assert!(s.materials[0].base_color_texture.is_some());
        assert!(s.materials[0].specular_color_texture.is_none());
        assert_eq!(s.warnings.len(), 1, "{:?}", s.warnings);
        assert!(
            s.warnings[0].starts_with("mat/m.mtl: line 3: refused"),
            "{:?}",
            s.warnings
        );
    }

    #[test]
    fn missing_or_broken_textures_warn_and_fall_back() {
        let mtl =
            b"newmtl m\nKd 0.5 0.5 0.5\nmap_Kd missing.png\nbump broken.png\nmap_Ks /abs.png\n";
        let s = parse_with(TEXTURED, &[("m.mtl", mtl), ("broken.png", b"not a png")]).unwrap();
        let m = &s.materials[0];
        assert!(m.base_color_texture.is_none() && m.normal_texture.is_none());
        assert!(m.specular_color_texture.is_none());
        assert_eq!(m.base_color.truncate(), Vec3::splat(0.5));
        assert!(s.textures.is_empty());
        let w = s.warnings.join("\n");
        assert_eq!(s.warnings.len(), 3, "{w}");
        assert!(w.contains("m.mtl: line 5: refused"), "{w}");
        assert!(
            w.contains("m.mtl: line 3: the texture \"missing.png\" is not used"),
            "{w}"
        );
        assert!(
            w.contains("m.mtl: line 4: the texture \"broken.png\" is not used"),
            "{w}"
        );
    }

    #[test]
    fn textures_over_the_limits_are_dropped_with_a_warning() {
        let big = png(8, 8, |_, _| [0; 4]);
        let mtl = b"newmtl m\nmap_Kd big.png\n";
        let files: &[(&str, &[u8])] = &[("m.mtl", mtl), ("big.png", &big)];
        let limits = Limits {
            max_texture_pixels: 63,
            ..Limits::default()
        };
        let run = |limits: &Limits| {
            parse(
                TEXTURED.as_bytes(),
                Path::new("t.obj"),
                &memory(files),
                limits,
            )
        };
        let dropped = |s: Scene| {
            assert!(s.textures.is_empty() && s.materials[0].base_color_texture.is_none());
            assert!(
                s.warnings
                    .iter()
                    .any(|w| w.contains("over the limit") || w.contains("(the limit)")),
                "{:?}",
                s.warnings
            );
        };
        dropped(run(&limits).unwrap());
        let limits = Limits {
            max_total_texture_pixels: 63,
            ..Limits::default()
        };
        dropped(run(&limits).unwrap());
        assert_eq!(run(&Limits::default()).unwrap().textures.len(), 1);
    }

    #[test]
    fn map_d_becomes_the_alpha_channel() {
        let color = png(2, 2, |_, _| [0, 0, 255, 255]);
        let mask = png(1, 2, |_, y| {
            if y == 0 {
                [255, 255, 255, 255]
            } else {
                [0, 0, 0, 255]
            }
        });
        let mtl = b"newmtl m\nmap_Kd c.png\nmap_d mask.png\n";
        let s = parse_with(
            TEXTURED,
            &[("m.mtl", mtl), ("c.png", &color), ("mask.png", &mask)],
        )
        .unwrap();
        let m = &s.materials[0];
        assert_eq!(m.alpha_mode, AlphaMode::Mask { cutoff: 0.5 });
        let t = &s.textures[m.base_color_texture.unwrap().texture as usize];
        assert_eq!(
            t.levels[0].texels,
            vec![
                [0, 0, 255, 255],
                [0, 0, 255, 255],
                [0, 0, 255, 0],
                [0, 0, 255, 0]
            ]
        );
    }

    #[test]
    fn height_map_becomes_a_normal_map_and_meshes_get_tangents() {
        // Height rises to the right (+u): the normal leans to -X.
        let ramp = png(4, 4, |x, _| {
            [x as u8 * 60; 3]
                .into_iter()
                .chain([255])
                .collect::<Vec<_>>()
                .try_into()
                .unwrap()
        });
        let mtl = b"newmtl m\nbump -bm 2 h.png\n";
        let s = parse_with(TEXTURED, &[("m.mtl", mtl), ("h.png", &ramp)]).unwrap();
        assert!(s.warnings.is_empty(), "{:?}", s.warnings);
        let m = &s.materials[0];
        let n = m.normal_texture.unwrap();
        assert_eq!(m.normal_scale, 1.0, "the scale is baked into the map");
        let t = &s.textures[n.texture as usize];
        assert_eq!(t.color_space, ColorSpace::Linear);
        // Texel (1, 1): neighbours 60 and 180 -> slope 2 * (120 / 255) / 2.
        let v = t.texel(0, 1, 1).truncate() * 2.0 - Vec3::ONE;
        let slope = 120.0 / 255.0 * 2.0 / 2.0;
        let expected = Vec3::new(-slope, 0.0, 1.0).normalize();
        assert!((v - expected).length() < 0.02, "{v} {expected}");
        let mesh = &s.meshes[0];
        assert!(mesh.normals.is_some(), "flat normals were made");
        assert_eq!(mesh.tangents.as_ref().unwrap().len(), mesh.positions.len());
        let tan = mesh.tangents.as_ref().unwrap()[0];
        assert!((tan.truncate() - Vec3::X).length() < 1e-5, "{tan}");
    }

    #[test]
    fn bump_that_is_a_normal_map_is_kept() {
        let flat = png(2, 2, |_, _| [128, 128, 255, 255]);
        let mtl = b"newmtl m\nmap_bump -bm 0.5 n.png\nnewmtl k\nnorm -bm 0.7 n.png\n";
        let obj = format!("{TEXTURED}usemtl k\nf 1/1 3/3 4/4\n");
        let s = parse_with(&obj, &[("m.mtl", mtl), ("n.png", &flat)]).unwrap();
        assert_eq!(s.materials[0].normal_scale, 0.5);
        assert_eq!(s.materials[1].normal_scale, 0.7);
        assert_eq!(
            s.textures.len(),
            2,
            "norm and bump keys differ, {:?}",
            s.textures.iter().map(|t| &t.name).collect::<Vec<_>>()
        );
        assert_eq!(s.textures[0].levels[0].texels[0], [128, 128, 255, 255]);
        let flat_height = png(2, 2, |_, _| [90, 90, 90, 255]);
        assert!(!looks_like_normal_map(
            &decode_image(&flat_height, Path::new("x"), 100).unwrap().2
        ));
        assert!(looks_like_normal_map(
            &decode_image(&flat, Path::new("x"), 100).unwrap().2
        ));
    }

    #[test]
    fn unknown_mtl_statements_warn_once() {
        let (s, _) = material("newmtl m\nPr 0.5\nPm 1\nPr 0.2\nKa 1 1 1\nTf 1 1 1\n");
        assert_eq!(s.warnings.len(), 1, "{:?}", s.warnings);
        assert!(
            s.warnings[0].contains("m.mtl: ignored unsupported statements: pm (1x), pr (2x)"),
            "{:?}",
            s.warnings
        );
    }
}
