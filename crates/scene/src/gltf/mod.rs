//! glTF 2.0 loader (`.gltf` with external or embedded buffers, `.glb`).
//!
//! The JSON is parsed and its references validated by `gltf-json`; everything that touches
//! binary data is done here with explicit bounds checks (see `accessor`, `buffer`, `glb`).
//!
//! What is read: the default scene (or `scenes[0]`, or every root node when there is no scene),
//! every node transform (matrix or TRS), triangle primitives (lists, strips and fans; points and
//! lines are skipped with a warning) with POSITION, NORMAL, TANGENT, TEXCOORD_0/1 and COLOR_0,
//! materials (see `material`), `KHR_lights_punctual` lights and perspective/orthographic cameras.
//! Morph targets and skins are ignored (the bind pose is used).
//!
//! Geometry is cleaned: triangles with a non-finite corner or zero area are dropped (counted in
//! one warning), unused vertices are removed, normals are renormalised, and meshes whose
//! material has a normal map but no tangents get MikkTSpace tangents.

mod accessor;
mod buffer;
pub mod glb;
mod material;

use std::collections::HashMap;
use std::path::Path;

use ::gltf::json;
use glam::{Mat4, Quat, Vec2, Vec3, Vec4};
use json::accessor::Type;
use json::validation::{Checked, Validate};
use rayon::prelude::*;

use self::accessor::AccessorReader;
use self::buffer::Buffers;
use self::material::MaterialConverter;
use crate::camera::{Camera, Projection};
use crate::error::{Result, SceneError, Warnings};
use crate::light::{PunctualKind, PunctualLight};
use crate::limits::Limits;
use crate::material::Material;
use crate::mesh::{Dropped, Instance, Mesh};
use crate::scene::Scene;
use crate::source::{read_file_limited, SceneSource};
use crate::tangent::{generate_tangents, make_flat_normals};

/// Extensions pathlight reads; a file that requires any other is refused.
pub const SUPPORTED_EXTENSIONS: &[&str] = &[
    "KHR_lights_punctual",
    "KHR_materials_pbrSpecularGlossiness",
    "KHR_texture_transform",
    "KHR_materials_transmission",
    "KHR_materials_ior",
    "KHR_materials_volume",
    "KHR_materials_emissive_strength",
    "KHR_materials_specular",
    "KHR_mesh_quantization",
];

/// Loads a `.gltf` or `.glb` file.
pub fn load(path: &Path, limits: &Limits) -> Result<Scene> {
    let bytes = read_file_limited(path, limits.max_file_bytes)?;
    let is_glb_name = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("glb"));
    // A `.glb` that does not start with the magic is reported as a broken GLB (truncated, or not
    // a GLB at all) rather than as unparsable JSON; a JSON document named `.glb` still loads.
    if is_glb_name && !glb::is_glb(&bytes) && bytes.trim_ascii_start().first() != Some(&b'{') {
        return Err(SceneError::new(
            path,
            if bytes.is_empty() {
                "invalid GLB: the file is empty".to_string()
            } else {
                format!(
                    "invalid GLB: it does not start with the magic \"glTF\" ({} bytes; truncated, or not a GLB file)",
                    bytes.len()
                )
            },
        ));
    }
    let source = SceneSource::for_file(path)?;
    parse(&bytes, path, &source, limits)
}

/// Parses glTF (JSON or GLB) bytes; `file` names it in messages, `source` gives its folder.
pub fn parse(bytes: &[u8], file: &Path, source: &SceneSource, limits: &Limits) -> Result<Scene> {
    let (json_bytes, bin) = if glb::is_glb(bytes) {
        let g = glb::parse(bytes, file)?;
        (g.json, g.bin)
    } else {
        (bytes, None)
    };
    if json_bytes.trim_ascii().is_empty() {
        return Err(SceneError::new(
            file,
            if glb::is_glb(bytes) {
                "invalid GLB: the JSON chunk is empty"
            } else {
                "the file is empty"
            },
        ));
    }
    let root: json::Root = serde_json::from_slice(json_bytes)
        .map_err(|e| SceneError::new(file, format!("invalid glTF JSON: {e}")))?;
    check_extensions(&root, file)?;
    validate(&root, file)?;
    let mut warnings = Warnings::default();
    for ext in &root.extensions_used {
        if !SUPPORTED_EXTENSIONS.contains(&ext.as_str()) {
            warnings.push(
                file,
                format!("extension {ext} is not supported and is ignored"),
            );
        }
    }
    let buffers = Buffers::load(&root, bin, source, file, limits)?;
    let reader = AccessorReader {
        root: &root,
        buffers: &buffers,
        file,
        max_count: limits
            .max_vertices
            .max(limits.max_triangles.saturating_mul(3)),
    };

    // Walk the node tree: instances of meshes, cameras, lights.
    let placements = walk_nodes(&root, file, limits, &mut warnings)?;

    // Convert every primitive of every mesh in use, in parallel.
    let mut used_meshes: Vec<usize> = placements.iter().filter_map(|p| p.mesh).collect();
    used_meshes.sort_unstable();
    used_meshes.dedup();
    let mut unique_triangles = 0u64;
    // Every primitive reads its whole POSITION accessor, even when many primitives share one
    // large accessor: bound the total, or a small file could make the loader read the same
    // megabytes thousands of times.
    let mut vertices_read = 0u64;
    for &m in &used_meshes {
        for p in &root.meshes[m].primitives {
            if let Some(pos) = p
                .attributes
                .get(&Checked::Valid(json::mesh::Semantic::Positions))
            {
                vertices_read = vertices_read.saturating_add(reader.count(pos.value())?);
            }
            // Saturating: hostile counts near u64::MAX must not overflow the sum.
            if let Some(i) = p.indices {
                unique_triangles = unique_triangles.saturating_add(reader.count(i.value())? / 3);
            } else if let Some(pos) = p
                .attributes
                .get(&Checked::Valid(json::mesh::Semantic::Positions))
            {
                unique_triangles = unique_triangles.saturating_add(reader.count(pos.value())? / 3);
            }
        }
    }
    if vertices_read > reader.max_count {
        return Err(SceneError::new(
            file,
            format!(
                "the mesh primitives read {vertices_read} vertices in all (an accessor shared by \
                 several primitives counts once for each), over the limit of {}",
                reader.max_count
            ),
        ));
    }
    if unique_triangles > limits.max_triangles {
        return Err(SceneError::new(
            file,
            format!(
                "the meshes hold about {unique_triangles} triangles, over the limit of {}",
                limits.max_triangles
            ),
        ));
    }
    type Converted = Result<(Vec<Option<Mesh>>, Warnings, Dropped)>;
    let converted: Vec<Converted> = used_meshes
        .par_iter()
        .map(|&m| {
            let mut w = Warnings::default();
            let mut d = Dropped::default();
            let prims = root.meshes[m]
                .primitives
                .iter()
                .enumerate()
                .map(|(p, prim)| convert_primitive(&reader, limits, m, p, prim, &mut w, &mut d))
                .collect::<Result<Vec<_>>>()?;
            Ok((prims, w, d))
        })
        .collect();

    let mut scene = Scene {
        name: file
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default(),
        ..Scene::default()
    };
    let mut materials = MaterialConverter::new(&root, file);
    let mut material_ids: HashMap<Option<usize>, u32> = HashMap::new();
    // glTF mesh index -> our mesh ids of its primitives.
    let mut mesh_ids: HashMap<usize, Vec<u32>> = HashMap::new();
    let mut dropped = Dropped::default();
    for (&m, result) in used_meshes.iter().zip(converted) {
        let (prims, w, d) = result?;
        warnings.messages.extend(w.messages);
        dropped.non_finite += d.non_finite;
        dropped.degenerate += d.degenerate;
        let mut ids = Vec::new();
        for (p, mesh) in prims.into_iter().enumerate() {
            let Some(mut mesh) = mesh else { continue };
            let material = root.meshes[m].primitives[p].material.map(|i| i.value());
            let next = scene.materials.len() as u32;
            let mid = *material_ids.entry(material).or_insert_with(|| {
                scene.materials.push(match material {
                    Some(i) => materials.convert(i, &mut warnings),
                    None => Material {
                        name: "glTF default material".into(),
                        ..Material::default()
                    },
                });
                next
            });
            mesh.material = mid;
            ids.push(scene.meshes.len() as u32);
            scene.meshes.push(mesh);
        }
        mesh_ids.insert(m, ids);
    }
    dropped.warn(file, &mut warnings);
    scene.dropped_triangles = (dropped.non_finite + dropped.degenerate) as u64;

    scene.textures = materials.finish(
        &mut scene.materials,
        &buffers,
        source,
        limits,
        &mut warnings,
    );
    finish_meshes(&mut scene, file, &mut warnings);

    let mut instanced = 0u64;
    for p in &placements {
        if let Some(m) = p.mesh {
            if !is_invertible(&p.transform) {
                warnings.push(
                    file,
                    format!(
                        "node {} has a singular transform (zero scale); its mesh is skipped",
                        p.node
                    ),
                );
                continue;
            }
            for &id in mesh_ids.get(&m).map(Vec::as_slice).unwrap_or(&[]) {
                instanced += scene.meshes[id as usize].indices.len() as u64;
                if instanced > limits.max_triangles {
                    return Err(SceneError::new(
                        file,
                        format!(
                            "the instanced scene has over {} triangles (the limit)",
                            limits.max_triangles
                        ),
                    ));
                }
                if scene.instances.len() as u64 >= limits.max_instances {
                    return Err(SceneError::new(
                        file,
                        format!("over {} instances (the limit)", limits.max_instances),
                    ));
                }
                scene.instances.push(Instance {
                    mesh: id,
                    transform: p.transform,
                    name: p.name.clone(),
                });
            }
        }
        if let Some(c) = p.camera {
            if let Some(cam) = camera(&root, c, p, file, &mut warnings) {
                scene.cameras.push(cam);
            }
        }
        if let Some(l) = p.light {
            if let Some(light) = light(&root, l, p, file, &mut warnings) {
                scene.lights.push(light);
            }
        }
    }
    scene.warnings = warnings.messages;
    Ok(scene)
}

/// Refuses a file that requires an extension pathlight does not read, naming them all.
fn check_extensions(root: &json::Root, file: &Path) -> Result<()> {
    let missing: Vec<&str> = root
        .extensions_required
        .iter()
        .map(String::as_str)
        .filter(|e| !SUPPORTED_EXTENSIONS.contains(e))
        .collect();
    if missing.is_empty() {
        Ok(())
    } else {
        Err(SceneError::new(
            file,
            format!(
                "requires extensions pathlight does not support: {}",
                missing.join(", ")
            ),
        ))
    }
}

/// Checks every reference between objects (dangling indices) and every enumerated value.
fn validate(root: &json::Root, file: &Path) -> Result<()> {
    // gltf-json's primitive validation indexes `accessors` with the POSITION accessor without
    // a bounds check (gltf-json 1.4.1, mesh.rs), so a dangling POSITION would panic there:
    // report those first and do not call it.
    let mut dangling = Vec::new();
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, prim) in mesh.primitives.iter().enumerate() {
            let pos = prim
                .attributes
                .get(&Checked::Valid(json::mesh::Semantic::Positions))
                .map(|a| a.value());
            if let Some(pos) = pos.filter(|&a| a >= root.accessors.len()) {
                dangling.push(format!(
                    "meshes[{m}].primitives[{p}].attributes[\"POSITION\"]: Index out of bounds \
                     (accessor {pos} of {})",
                    root.accessors.len()
                ));
            }
        }
    }
    if !dangling.is_empty() {
        return Err(SceneError::new(
            file,
            format!("invalid glTF: {}", dangling.join("; ")),
        ));
    }
    let mut errors = Vec::new();
    root.validate(root, json::Path::new, &mut |path, error| {
        let path = path().to_string();
        // Required extensions are checked by `check_extensions`, against pathlight's own list.
        if !(path.starts_with("extensionsRequired")
            && error == json::validation::Error::Unsupported)
        {
            errors.push(format!("{path}: {error}"));
        }
    });
    if root.asset.version != "2.0" && !root.asset.version.starts_with("2.") {
        errors.push(format!(
            "asset.version is \"{}\", not 2.x",
            root.asset.version.escape_debug()
        ));
    }
    if errors.is_empty() {
        return Ok(());
    }
    let shown = errors.len().min(5);
    let more = if errors.len() > shown {
        format!(" (and {} more)", errors.len() - shown)
    } else {
        String::new()
    };
    Err(SceneError::new(
        file,
        format!("invalid glTF: {}{more}", errors[..shown].join("; ")),
    ))
}

/// A node with its world transform, as found by [`walk_nodes`].
struct Placement {
    node: usize,
    name: String,
    transform: Mat4,
    mesh: Option<usize>,
    camera: Option<usize>,
    light: Option<usize>,
}

fn local_transform(node: &json::scene::Node, index: usize, file: &Path) -> Result<Mat4> {
    let m = if let Some(m) = node.matrix {
        Mat4::from_cols_array(&m)
    } else {
        let t = Vec3::from(node.translation.unwrap_or([0.0; 3]));
        let r = node.rotation.as_ref().map_or([0.0, 0.0, 0.0, 1.0], |r| r.0);
        let s = Vec3::from(node.scale.unwrap_or([1.0; 3]));
        let q = Quat::from_array(r);
        if !q.is_finite() || q.length_squared() == 0.0 {
            return Err(SceneError::new(
                file,
                format!("node {index}: rotation {r:?} is not a valid quaternion"),
            ));
        }
        Mat4::from_scale_rotation_translation(s, q.normalize(), t)
    };
    if !m.is_finite() {
        return Err(SceneError::new(
            file,
            format!("node {index}: its transform has NaN or infinite values"),
        ));
    }
    Ok(m)
}

/// Walks the default scene's node tree without recursion. A node reached twice (a cycle, or a
/// node with two parents, which glTF forbids) is an error.
fn walk_nodes(
    root: &json::Root,
    file: &Path,
    limits: &Limits,
    warnings: &mut Warnings,
) -> Result<Vec<Placement>> {
    let roots: Vec<usize> = match root.scene.map(|s| s.value()).or(if root.scenes.is_empty() {
        None
    } else {
        Some(0)
    }) {
        Some(s) => root
            .scenes
            .get(s)
            .map(|s| s.nodes.iter().map(|n| n.value()).collect())
            .unwrap_or_default(),
        None => {
            // No scene: every node that is nobody's child is a root.
            let mut is_child = vec![false; root.nodes.len()];
            for n in &root.nodes {
                for c in n.children.iter().flatten() {
                    if let Some(slot) = is_child.get_mut(c.value()) {
                        *slot = true;
                    }
                }
            }
            if !root.nodes.is_empty() {
                warnings.push(file, "the file defines no scene; showing every root node");
            }
            (0..root.nodes.len()).filter(|&i| !is_child[i]).collect()
        }
    };
    let mut seen = vec![false; root.nodes.len()];
    let mut out = Vec::new();
    let mut stack: Vec<(usize, Mat4)> = roots.iter().rev().map(|&n| (n, Mat4::IDENTITY)).collect();
    let mut skinned = false;
    while let Some((index, parent)) = stack.pop() {
        let node = root
            .nodes
            .get(index)
            .ok_or_else(|| SceneError::new(file, format!("node {index} does not exist")))?;
        if std::mem::replace(&mut seen[index], true) {
            return Err(SceneError::new(
                file,
                format!("node {index} is reached twice: the node graph has a cycle or a node with two parents"),
            ));
        }
        let world = parent * local_transform(node, index, file)?;
        if !world.is_finite() {
            return Err(SceneError::new(
                file,
                format!("node {index}: its world transform overflows"),
            ));
        }
        skinned |= node.skin.is_some();
        let light = node
            .extensions
            .as_ref()
            .and_then(|e| e.khr_lights_punctual.as_ref())
            .map(|l| l.light.value());
        if node.mesh.is_some() || node.camera.is_some() || light.is_some() {
            if out.len() as u64 >= limits.max_instances {
                return Err(SceneError::new(
                    file,
                    format!(
                        "over {} placed nodes (the instance limit)",
                        limits.max_instances
                    ),
                ));
            }
            out.push(Placement {
                node: index,
                name: node.name.clone().unwrap_or_default(),
                transform: world,
                mesh: node.mesh.map(|m| m.value()),
                camera: node.camera.map(|c| c.value()),
                light,
            });
        }
        for c in node.children.iter().flatten().rev() {
            stack.push((c.value(), world));
        }
    }
    if skinned {
        warnings.push(
            file,
            "skins are not supported: skinned meshes are shown in their bind pose",
        );
    }
    Ok(out)
}

fn is_invertible(m: &Mat4) -> bool {
    let d = m.determinant();
    d.is_finite() && d.abs() > 1e-30
}

/// Reads one primitive into a mesh (material set later). `None` for skipped primitives.
fn convert_primitive(
    reader: &AccessorReader,
    limits: &Limits,
    mesh: usize,
    prim_index: usize,
    prim: &json::mesh::Primitive,
    warnings: &mut Warnings,
    dropped: &mut Dropped,
) -> Result<Option<Mesh>> {
    use json::mesh::{Mode, Semantic};
    let file = reader.file;
    let here = format!("mesh {mesh} primitive {prim_index}");
    let mode = match prim.mode {
        Checked::Valid(m) => m,
        Checked::Invalid => return Err(SceneError::new(file, format!("{here}: invalid mode"))),
    };
    if !matches!(
        mode,
        Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
    ) {
        warnings.push(
            file,
            format!("{here}: {mode:?} primitives are not triangles and are skipped"),
        );
        return Ok(None);
    }
    let attr = |s: Semantic| prim.attributes.get(&Checked::Valid(s)).map(|a| a.value());
    let Some(pos) = attr(Semantic::Positions) else {
        warnings.push(file, format!("{here}: no POSITION attribute; skipped"));
        return Ok(None);
    };
    let vertex_count = reader.count(pos)?;
    if vertex_count > limits.max_vertices {
        return Err(SceneError::new(
            file,
            format!(
                "{here}: {vertex_count} vertices, over the limit of {} vertices per mesh",
                limits.max_vertices
            ),
        ));
    }
    let positions: Vec<Vec3> = reader
        .read_floats::<3>(pos, &[Type::Vec3], false)?
        .into_iter()
        .map(Vec3::from)
        .collect();
    let n = positions.len();
    // A secondary attribute, its count checked against POSITION's before it is read, so that a
    // hostile count is refused before anything of its size is allocated.
    fn secondary<const N: usize, T: From<[f32; N]>>(
        reader: &AccessorReader,
        here: &str,
        name: &str,
        accessor: Option<usize>,
        n: usize,
        types: &[Type],
        normalized: bool,
    ) -> Result<Option<Vec<T>>> {
        let Some(a) = accessor else { return Ok(None) };
        let len = reader.count(a)?;
        if len != n as u64 {
            return Err(SceneError::new(
                reader.file,
                format!("{here}: {name} has {len} elements but POSITION has {n}"),
            ));
        }
        let values = reader.read_floats::<N>(a, types, normalized)?;
        Ok(Some(values.into_iter().map(T::from).collect()))
    }
    let normals: Option<Vec<Vec3>> = secondary(
        reader,
        &here,
        "NORMAL",
        attr(Semantic::Normals),
        n,
        &[Type::Vec3],
        false,
    )?;
    // glTF: without normals, tangents are ignored.
    let tangent_accessor = attr(Semantic::Tangents).filter(|_| normals.is_some());
    let tangents: Option<Vec<Vec4>> = secondary(
        reader,
        &here,
        "TANGENT",
        tangent_accessor,
        n,
        &[Type::Vec4],
        false,
    )?;
    let uv0: Option<Vec<Vec2>> = secondary(
        reader,
        &here,
        "TEXCOORD_0",
        attr(Semantic::TexCoords(0)),
        n,
        &[Type::Vec2],
        true,
    )?;
    let uv1: Option<Vec<Vec2>> = secondary(
        reader,
        &here,
        "TEXCOORD_1",
        attr(Semantic::TexCoords(1)),
        n,
        &[Type::Vec2],
        true,
    )?;
    let colors: Option<Vec<Vec4>> = secondary(
        reader,
        &here,
        "COLOR_0",
        attr(Semantic::Colors(0)),
        n,
        &[Type::Vec3, Type::Vec4],
        true,
    )?;
    let indices: Vec<u32> = match prim.indices {
        Some(i) => {
            let idx = reader.read_indices(i.value())?;
            if let Some((k, &bad)) = idx.iter().enumerate().find(|(_, &v)| v as usize >= n) {
                return Err(SceneError::new(
                    file,
                    format!("{here}: index {k} is {bad}, out of range for {n} vertices"),
                ));
            }
            idx
        }
        None => (0..n as u32).collect(),
    };
    let what = if prim.indices.is_some() {
        "indices"
    } else {
        "vertices"
    };
    if indices.len() < 3 {
        warnings.push(
            file,
            format!(
                "{here}: {mode:?} primitive of {} {what}, fewer than 3: no triangle; skipped",
                indices.len()
            ),
        );
        return Ok(None);
    }
    let trailing = indices.len() % 3;
    if mode == Mode::Triangles && trailing != 0 {
        warnings.push(
            file,
            format!(
                "{here}: {} {what} is not a multiple of 3; the last {} are ignored",
                indices.len(),
                trailing
            ),
        );
    }
    let triangles: Vec<[u32; 3]> = match mode {
        Mode::Triangles => indices
            .chunks_exact(3)
            .map(|c| [c[0], c[1], c[2]])
            .collect(),
        Mode::TriangleStrip => (0..indices.len().saturating_sub(2))
            .map(|i| {
                if i % 2 == 0 {
                    [indices[i], indices[i + 1], indices[i + 2]]
                } else {
                    [indices[i + 1], indices[i], indices[i + 2]]
                }
            })
            .collect(),
        _ => (1..indices.len().saturating_sub(1))
            .map(|i| [indices[0], indices[i], indices[i + 1]])
            .collect(),
    };
    let mut out = Mesh {
        name: reader.root.meshes[mesh]
            .name
            .clone()
            .map_or_else(|| here.clone(), |name| format!("{name} #{prim_index}")),
        positions,
        normals,
        tangents,
        uv0,
        uv1,
        colors,
        indices: triangles,
        material: 0,
    };
    dropped.add(out.clean());
    if out.indices.is_empty() {
        return Ok(None);
    }
    Ok(Some(out))
}

/// Normal-mapped meshes get flat normals if they have none, and MikkTSpace tangents if they
/// have none.
fn finish_meshes(scene: &mut Scene, file: &Path, warnings: &mut Warnings) {
    let materials = &scene.materials;
    let failed: Vec<String> = scene
        .meshes
        .par_iter_mut()
        .filter_map(|mesh| {
            let normal_map = materials[mesh.material as usize].normal_texture?;
            if mesh.normals.is_none() {
                make_flat_normals(mesh);
            }
            if mesh.tangents.is_none() && !generate_tangents(mesh, normal_map.texcoord) {
                return Some(mesh.name.clone());
            }
            None
        })
        .collect();
    if !failed.is_empty() {
        warnings.push(
            file,
            format!(
                "no tangents could be made (no texture coordinates?) for normal-mapped meshes: {}",
                failed.join(", ")
            ),
        );
    }
}

/// Removes the scale from a node transform, keeping rotation and translation.
fn rigid(m: &Mat4) -> Mat4 {
    let x = m.x_axis.truncate().normalize_or(Vec3::X);
    let y0 = m.y_axis.truncate();
    let z = x.cross(y0).normalize_or(Vec3::Z);
    let y = z.cross(x);
    Mat4::from_cols(x.extend(0.0), y.extend(0.0), z.extend(0.0), m.w_axis)
}

fn camera(
    root: &json::Root,
    index: usize,
    p: &Placement,
    file: &Path,
    warnings: &mut Warnings,
) -> Option<Camera> {
    let c = root.cameras.get(index)?;
    let projection = match (&c.perspective, &c.orthographic) {
        (Some(pc), _) if pc.yfov.is_finite() && pc.yfov > 0.0 && pc.yfov < std::f32::consts::PI => {
            Projection::Perspective {
                yfov: pc.yfov,
                aspect: pc.aspect_ratio.filter(|a| a.is_finite() && *a > 0.0),
                znear: pc.znear.max(0.0),
            }
        }
        (None, Some(o))
            if o.xmag.is_finite() && o.ymag.is_finite() && o.xmag != 0.0 && o.ymag != 0.0 =>
        {
            Projection::Orthographic {
                xmag: o.xmag.abs(),
                ymag: o.ymag.abs(),
                znear: o.znear.max(0.0),
            }
        }
        _ => {
            warnings.push(
                file,
                format!("camera {index} has invalid projection values; ignored"),
            );
            return None;
        }
    };
    Some(Camera {
        name: c.name.clone().unwrap_or_else(|| format!("camera {index}")),
        transform: rigid(&p.transform),
        projection,
    })
}

fn light(
    root: &json::Root,
    index: usize,
    p: &Placement,
    file: &Path,
    warnings: &mut Warnings,
) -> Option<PunctualLight> {
    use json::extensions::scene::khr_lights_punctual::Type as LightType;
    let l = root
        .extensions
        .as_ref()?
        .khr_lights_punctual
        .as_ref()?
        .lights
        .get(index)?;
    let color = Vec3::from(l.color);
    let intensity = color * l.intensity;
    if !intensity.is_finite() || intensity.min_element() < 0.0 {
        warnings.push(
            file,
            format!("light {index} has an invalid colour or intensity; ignored"),
        );
        return None;
    }
    let kind = match l.type_ {
        Checked::Valid(LightType::Point) => PunctualKind::Point,
        Checked::Valid(LightType::Directional) => PunctualKind::Directional,
        Checked::Valid(LightType::Spot) => {
            let s = l.spot.clone().unwrap_or_default();
            let outer = if s.outer_cone_angle.is_finite() {
                s.outer_cone_angle.clamp(0.0, std::f32::consts::FRAC_PI_2)
            } else {
                std::f32::consts::FRAC_PI_4
            };
            let inner = if s.inner_cone_angle.is_finite() {
                s.inner_cone_angle.clamp(0.0, outer)
            } else {
                0.0
            };
            PunctualKind::Spot {
                inner_cone: inner,
                outer_cone: outer,
            }
        }
        Checked::Invalid => return None,
    };
    Some(PunctualLight {
        name: l.name.clone().unwrap_or_else(|| format!("light {index}")),
        kind,
        position: p.transform.transform_point3(Vec3::ZERO),
        direction: p
            .transform
            .transform_vector3(Vec3::NEG_Z)
            .normalize_or(Vec3::NEG_Z),
        intensity,
        range: l.range.filter(|r| r.is_finite() && *r > 0.0),
    })
}
