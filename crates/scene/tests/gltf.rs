//! glTF loading done right: material conversions and colour spaces on the shared test scenes
//! (skipped with a note when the scene pack is absent), and generated files for
//! `KHR_texture_transform`, spec-gloss textures, strips and fans.
//!
//! The scene pack is found at `$PATHLIGHT_SHARED/scenes`, else `../../../shared/scenes` from
//! this crate's folder.

mod common;

use std::f32::consts::FRAC_PI_2;
use std::path::PathBuf;

use common::*;
use glam::{Vec2, Vec3, Vec4};
use pathlight_scene::{
    AlphaMode, ColorSpace, Material, PunctualKind, Scene, SceneError, TextureRef,
};
use serde_json::json;

/// The path of a file of the shared scene pack, or `None` when it is missing (skipped off CI,
/// see [`pathlight_core::shared_data`]).
fn shared(relative: &str) -> Option<PathBuf> {
    let path = pathlight_core::shared_data::dir(env!("CARGO_MANIFEST_DIR"))
        .join("scenes")
        .join(relative);
    pathlight_core::shared_data::present(&path).then_some(path)
}

fn load_shared(relative: &str) -> Option<Scene> {
    let path = shared(relative)?;
    Some(
        load(&path, limits())
            .unwrap_or_else(|e: SceneError| panic!("{relative} does not load: {e}")),
    )
}

fn material<'a>(scene: &'a Scene, name: &str) -> &'a Material {
    scene
        .materials
        .iter()
        .find(|m| m.name == name)
        .unwrap_or_else(|| panic!("no material {name} in {:?}", names(scene)))
}

fn names(scene: &Scene) -> Vec<&str> {
    scene.materials.iter().map(|m| m.name.as_str()).collect()
}

fn color_space(scene: &Scene, t: Option<TextureRef>) -> ColorSpace {
    let t = t.expect("a texture");
    scene.textures[t.texture as usize].color_space
}

fn close(a: f32, b: f32) -> bool {
    (a - b).abs() <= 1e-5 * (1.0 + b.abs())
}

#[track_caller]
fn assert_close3(a: Vec3, b: Vec3) {
    assert!(
        (a - b).abs().max_element() <= 1e-4 * (1.0 + b.abs().max_element()),
        "{a} != {b}"
    );
}

// ---------------------------------------------------------------------------------------------
// Shared scenes

#[test]
fn box_textured_spec_gloss_is_converted() {
    let Some(s) = load_shared("BoxTextured_pbrSpecularGlossiness/BoxTextured.gltf") else {
        return;
    };
    // From the .gltf: diffuseTexture 0 (no diffuseFactor: white), specularFactor 0.2 (grey),
    // glossinessFactor 1.0; the core fallback has metallicFactor 0.
    let m = material(&s, "Texture");
    assert_eq!(m.metallic, 0.0);
    assert_eq!(m.base_color, Vec4::ONE);
    assert!(close(m.roughness, 1.0 - 1.0), "roughness {}", m.roughness);
    let spec = 0.2f32 / 0.04;
    assert_close3(m.specular_color, Vec3::splat(spec));
    assert_eq!(m.specular, 1.0);
    assert_eq!(m.ior, 1.5);
    // F0 = min(0.04 * specular_color, 1) = specularFactor.
    assert_close3(m.dielectric_f0(), Vec3::splat(0.2));
    assert_eq!(color_space(&s, m.base_color_texture), ColorSpace::Srgb);
    assert_eq!(m.metallic_roughness_texture, None);
    assert_eq!(m.specular_color_texture, None);
    let t = &s.textures[m.base_color_texture.unwrap().texture as usize];
    assert!(t.name.contains("CesiumLogoFlat"), "{}", t.name);
    assert_eq!(s.triangle_count(), 12);
    assert!(s.warnings.is_empty(), "{:?}", s.warnings);
}

#[test]
fn damaged_helmet_colour_spaces() {
    let Some(s) = load_shared("DamagedHelmet/glTF/DamagedHelmet.gltf") else {
        return;
    };
    assert_eq!(s.materials.len(), 1);
    let m = &s.materials[0];
    assert_eq!(color_space(&s, m.base_color_texture), ColorSpace::Srgb);
    assert_eq!(color_space(&s, m.emissive_texture), ColorSpace::Srgb);
    assert_eq!(
        color_space(&s, m.metallic_roughness_texture),
        ColorSpace::Linear
    );
    assert_eq!(color_space(&s, m.normal_texture), ColorSpace::Linear);
    assert_eq!(color_space(&s, m.occlusion_texture), ColorSpace::Linear);
    assert_eq!(m.emissive, Vec3::ONE);
    assert_eq!(s.textures.len(), 5);
    assert_eq!(s.triangle_count(), 15_452);
    // The emissive texture makes part of the helmet a light.
    assert!(!s.emissive_triangles.is_empty());
}

#[test]
fn alpha_modes_and_cutoffs() {
    let Some(s) = load_shared("AlphaBlendModeTest_trimesh-reexport/AlphaBlendModeTest.glb") else {
        return;
    };
    assert_eq!(
        material(&s, "MatCutoff25").alpha_mode,
        AlphaMode::Mask { cutoff: 0.25 }
    );
    assert_eq!(
        material(&s, "MatCutoff75").alpha_mode,
        AlphaMode::Mask { cutoff: 0.75 }
    );
    assert_eq!(
        material(&s, "MatCutoffDefault").alpha_mode,
        AlphaMode::Mask { cutoff: 0.5 }
    );
    assert_eq!(material(&s, "MatBlend").alpha_mode, AlphaMode::Blend);
    assert_eq!(material(&s, "MatOpaque").alpha_mode, AlphaMode::Opaque);
}

#[test]
fn punctual_lights() {
    let Some(s) = load_shared("KHR_lights_punctual_playcanvas/Lights.glb") else {
        return;
    };
    assert_eq!(s.lights.len(), 4);
    let light = |name: &str| {
        s.lights
            .iter()
            .find(|l| l.name == name)
            .unwrap_or_else(|| panic!("no light {name}"))
    };
    let point = light("Light");
    assert_eq!(point.kind, PunctualKind::Point);
    assert_close3(point.intensity, Vec3::new(5.0, 0.0, 0.0));
    let spot = light("Spot");
    match spot.kind {
        PunctualKind::Spot {
            inner_cone,
            outer_cone,
        } => {
            assert!(close(inner_cone, 0.333_794_23), "{inner_cone}");
            assert!(
                close(outer_cone, std::f32::consts::FRAC_PI_8),
                "{outer_cone}"
            );
        }
        k => panic!("Spot is {k:?}"),
    }
    assert_close3(spot.intensity, Vec3::new(0.0, 10.0, 0.0));
    let spot2 = light("Spot.001");
    assert!(matches!(spot2.kind, PunctualKind::Spot { .. }));
    assert_close3(spot2.intensity, Vec3::new(0.0, 0.0, 10.0));
    let sun = light("Sun");
    assert_eq!(sun.kind, PunctualKind::Directional);
    assert_close3(sun.intensity, Vec3::new(0.0, 1.0, 1.0));
    for l in &s.lights {
        assert!(
            (l.direction.length() - 1.0).abs() < 1e-5,
            "{}: {}",
            l.name,
            l.direction
        );
        assert!(l.position.is_finite());
    }
    let kinds = |k: fn(&PunctualKind) -> bool| s.lights.iter().filter(|l| k(&l.kind)).count();
    assert_eq!(kinds(|k| *k == PunctualKind::Directional), 1);
    assert_eq!(kinds(|k| *k == PunctualKind::Point), 1);
    assert_eq!(kinds(|k| matches!(k, PunctualKind::Spot { .. })), 2);
}

#[test]
fn normal_tangent_test_gets_tangents() {
    let Some(s) = load_shared("NormalTangentTest/NormalTangentTest.glb") else {
        return;
    };
    assert!(!s.meshes.is_empty());
    for mesh in &s.meshes {
        let normals = mesh.normals.as_ref().expect("normals");
        let tangents = mesh.tangents.as_ref().expect("generated tangents");
        assert_eq!(tangents.len(), mesh.positions.len());
        for (t, n) in tangents.iter().zip(normals) {
            let t3 = t.truncate();
            assert!((t3.length() - 1.0).abs() < 1e-3, "tangent {t}");
            assert!(t3.dot(*n).abs() < 1e-3, "tangent {t} . normal {n}");
            assert!(t.w == 1.0 || t.w == -1.0, "sign {}", t.w);
        }
    }
    assert!(s.warnings.is_empty(), "{:?}", s.warnings);
}

#[test]
fn cornell_box_emission() {
    let Some(s) = load_shared("CornellBox/CornellBox-Original.gltf") else {
        return;
    };
    // emissiveFactor (1, 12/17, 4/17) x KHR_materials_emissive_strength 17.
    let light = material(&s, "light");
    assert_close3(light.emissive, Vec3::new(17.0, 12.0, 4.0));
    assert_eq!(s.emissive_triangles.len(), 2);
    for t in &s.emissive_triangles {
        assert_close3(t.radiance, Vec3::new(17.0, 12.0, 4.0));
    }
    assert_eq!(s.triangle_count(), 36);
    assert_eq!(s.cameras.len(), 1);
}

// ---------------------------------------------------------------------------------------------
// Generated files

#[test]
fn texture_transform_matches_the_extension_matrix() {
    let dir = TempDir::new("texture-transform");
    dir.write("t.png", png(2, 2, |_, _| [200, 100, 50, 255]));
    let mut d = Doc::quad();
    d.textured(json!({"uri": "t.png"}));
    let (ox, oy, r, sx, sy) = (0.5f32, 0.25f32, FRAC_PI_2, 2.0f32, 3.0f32);
    d.json["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"]["extensions"] = json!({
        "KHR_texture_transform": {"offset": [ox, oy], "rotation": r, "scale": [sx, sy]}
    });
    // On a normal texture (which gltf-json keeps as an unparsed extension), with texCoord 1.
    d.json["materials"][0]["normalTexture"] = json!({
        "index": 0,
        "extensions": {"KHR_texture_transform": {"offset": [0.1, 0.2], "texCoord": 1}}
    });
    d.set("/extensionsUsed", json!(["KHR_texture_transform"]));
    let uv = d.add_floats([0.0, 0.0, 1.0, 0.0, 1.0, 1.0, 0.0, 1.0], 4, "VEC2");
    d.prim()["attributes"]["TEXCOORD_0"] = json!(uv);
    d.prim()["attributes"]["TEXCOORD_1"] = json!(uv);
    let p = d.write_gltf(dir.path(), "tt");
    let s = expect_ok(&p, limits());
    let t = s.materials[0]
        .base_color_texture
        .expect("base colour texture");
    // The extension's matrix, written out: T * R * S with R = [cos sin; -sin cos]:
    //   u' =  cos(r) sx u + sin(r) sy v + ox
    //   v' = -sin(r) sx u + cos(r) sy v + oy
    let expected = |u: f32, v: f32| {
        let (sn, cs) = r.sin_cos();
        Vec2::new(
            cs * sx * u + sn * sy * v + ox,
            -sn * sx * u + cs * sy * v + oy,
        )
    };
    for (u, v) in [(0.0, 0.0), (0.1, 0.2), (1.0, 0.0), (0.0, 1.0), (-0.7, 2.5)] {
        let got = t.apply(Vec2::new(u, v));
        assert!((got - expected(u, v)).length() < 1e-5, "({u}, {v}): {got}");
    }
    // By hand for rotation 90 degrees: (0.1, 0.2) -> (3 * 0.2 + 0.5, -2 * 0.1 + 0.25).
    assert!((t.apply(Vec2::new(0.1, 0.2)) - Vec2::new(1.1, 0.05)).length() < 1e-5);
    assert_eq!(t.texcoord, 0);
    let n = s.materials[0].normal_texture.expect("normal texture");
    assert_eq!(n.texcoord, 1);
    assert!((n.apply(Vec2::new(0.5, 0.5)) - Vec2::new(0.6, 0.7)).length() < 1e-6);
}

#[test]
fn spec_gloss_texture_is_converted() {
    let dir = TempDir::new("spec-gloss-texture");
    // RGB: specular colour (sRGB); A: glossiness.
    let texel = |x: u32, _y: u32| match x {
        0 => [255, 128, 0, 255],
        1 => [64, 64, 64, 128],
        _ => [10, 20, 30, 0],
    };
    dir.write("sg.png", png(3, 1, texel));
    dir.write("diffuse.png", png(1, 1, |_, _| [128, 128, 128, 255]));
    let mut d = Doc::quad();
    let uv = d.add_floats([0.0; 8], 4, "VEC2");
    d.prim()["attributes"]["TEXCOORD_0"] = json!(uv);
    d.json["images"] = json!([{"uri": "sg.png"}, {"uri": "diffuse.png"}]);
    d.json["textures"] = json!([{"source": 0}, {"source": 1}]);
    let gloss = 0.8f32;
    d.json["materials"] = json!([{
        "name": "sg",
        "extensions": {"KHR_materials_pbrSpecularGlossiness": {
            "diffuseFactor": [0.5, 0.6, 0.7, 1.0],
            "diffuseTexture": {"index": 1},
            "specularFactor": [0.02, 0.04, 0.08],
            "glossinessFactor": gloss,
            "specularGlossinessTexture": {"index": 0}
        }}
    }]);
    d.set(
        "/extensionsUsed",
        json!(["KHR_materials_pbrSpecularGlossiness"]),
    );
    d.prim()["material"] = json!(0);
    let p = d.write_gltf(dir.path(), "sg");
    let s = expect_ok(&p, limits());
    let m = &s.materials[0];
    assert_eq!(m.metallic, 0.0);
    assert_eq!(
        m.roughness, 1.0,
        "the derived texture carries the roughness"
    );
    assert_eq!(m.base_color, Vec4::new(0.5, 0.6, 0.7, 1.0));
    assert_close3(m.specular_color, Vec3::new(0.5, 1.0, 2.0));
    assert_eq!(color_space(&s, m.base_color_texture), ColorSpace::Srgb);
    // The specular colour texture is the spec-gloss image's RGB, in sRGB.
    let sc = m.specular_color_texture.expect("specular colour texture");
    let sct = &s.textures[sc.texture as usize];
    assert_eq!(sct.color_space, ColorSpace::Srgb);
    assert_eq!(sct.levels[0].texels[0], [255, 128, 0, 255]);
    let lin = sct.texel(0, 0, 0);
    assert!(
        (lin.y - 0.2158605).abs() < 1e-3,
        "sRGB 128 decodes to 0.2159: {lin}"
    );
    // The roughness texture: linear, green = 1 - gloss * alpha, metallic (blue) = 0.
    let mr = m
        .metallic_roughness_texture
        .expect("derived roughness texture");
    let mrt = &s.textures[mr.texture as usize];
    assert_eq!(mrt.color_space, ColorSpace::Linear);
    assert_ne!(mr.texture, sc.texture);
    for x in 0..3 {
        let a = texel(x, 0)[3] as f32 / 255.0;
        let want = 1.0 - gloss * a;
        let got = mrt.texel(0, x, 0);
        assert!(
            (got.y - want).abs() <= 0.5 / 255.0 + 1e-6,
            "x {x}: {} vs {want}",
            got.y
        );
        assert_eq!(got.z, 0.0);
    }
}

#[test]
fn strips_and_fans() {
    let dir = TempDir::new("strips-fans");
    // A strip zigzagging up the XY plane, counter-clockwise seen from +Z.
    let strip: Vec<[f32; 3]> = (0..6)
        .map(|k| [(k % 2) as f32, (k / 2) as f32, 0.0])
        .collect();
    // A fan around the origin, counter-clockwise.
    let fan = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
        [-1.0, 1.0, 0.0],
        [-1.0, 0.0, 0.0],
    ];
    for (mode, positions, indexed) in [
        (5, strip.clone(), false),
        (5, strip, true),
        (6, fan.to_vec(), false),
        (6, fan.to_vec(), true),
    ] {
        let idx: Vec<u32> = (0..positions.len() as u32).collect();
        let mut d = Doc::mesh(&positions, indexed.then_some(&idx[..]));
        d.prim()["mode"] = json!(mode);
        let p = d.write_glb(dir.path(), "sf");
        let s = expect_ok(&p, limits());
        assert!(s.warnings.is_empty(), "{:?}", s.warnings);
        assert_eq!(s.triangle_count(), 4, "mode {mode}");
        let mesh = &s.meshes[0];
        for t in 0..mesh.triangle_count() {
            let [a, b, c] = mesh.triangle(t);
            let n = (b - a).cross(c - a);
            assert!(
                n.z > 0.0 && n.x == 0.0 && n.y == 0.0,
                "mode {mode} triangle {t}: {n}"
            );
        }
        if mode == 6 {
            assert!(
                mesh.indices.iter().all(|t| t.contains(&0)),
                "every fan triangle uses v0"
            );
        } else {
            // glTF: triangle i is (v_i, v_{i+1+i%2}, v_{i+2-i%2}), up to rotation.
            let rotations = |t: [u32; 3]| [t, [t[1], t[2], t[0]], [t[2], t[0], t[1]]];
            for (i, t) in mesh.indices.iter().enumerate() {
                let i = i as u32;
                let want = [i, i + 1 + i % 2, i + 2 - i % 2];
                assert!(
                    rotations(*t).contains(&want),
                    "triangle {i}: {t:?} vs {want:?}"
                );
            }
        }
    }
}
