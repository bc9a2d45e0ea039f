//! The bad-input corpus: malformed, truncated and hostile scene files, generated here.
//!
//! Every case loads on its own thread with a time bound (see `common::timed`), so a panic or a
//! hang fails the test. A case either expects an error whose message names the file at fault
//! and what is wrong with it, or a scene with a specific warning where loading is the right
//! answer (a missing texture, dropped triangles, an unknown optional extension, ...).

mod common;

use std::path::Path;
use std::time::{Duration, Instant};

use common::*;
use pathlight_scene::{Limits, LoadOptions};
use serde_json::json;

// ---------------------------------------------------------------------------------------------
// JSON

#[test]
fn invalid_json() {
    let dir = TempDir::new("invalid-json");
    let p = dir.write(
        "broken.gltf",
        br#"{"asset": {"version": "2.0"},, "nodes": []}"#,
    );
    expect_err(&p, limits(), &["invalid glTF JSON", "line 1"]);
}

#[test]
fn truncated_json() {
    let dir = TempDir::new("truncated-json");
    let text = Doc::triangle().json_bytes();
    for cut in [1, text.len() / 3, text.len() / 2, text.len() - 1] {
        let p = dir.write("cut.gltf", &text[..cut]);
        expect_err(&p, limits(), &["invalid glTF JSON", "EOF"]);
    }
}

#[test]
fn wrong_json_types() {
    let dir = TempDir::new("wrong-types");
    let cases = [
        ("/accessors", json!(5), "invalid type"),
        ("/accessors/0/count", json!("x"), "invalid type"),
        ("/nodes/0/mesh", json!(-1), "invalid type"),
        ("/nodes/0/matrix", json!([1, 2, 3]), "invalid length"),
        ("/asset", json!(null), "invalid type"),
        ("/buffers/0/byteLength", json!(1e15), "invalid type"),
    ];
    for (pointer, value, keyword) in cases {
        let mut d = Doc::triangle();
        d.set(pointer, value);
        let p = d.write_gltf(dir.path(), "types");
        let m = expect_err(&p, limits(), &["invalid glTF JSON", keyword]);
        println!("{pointer}: {m}");
    }
}

#[test]
fn deeply_nested_json() {
    let dir = TempDir::new("nested");
    let depth = 10_000;
    let nested = format!("{}{}", "[".repeat(depth), "]".repeat(depth));
    // As the whole document: not a glTF object.
    let p = dir.write("nested.gltf", &nested);
    expect_err(&p, limits(), &["invalid glTF JSON"]);
    // Where the value is parsed into a JSON tree (accessor min/max, unparsed extensions),
    // serde_json's recursion limit refuses it.
    let mut d = Doc::quad();
    d.json["accessors"][0]["min"] = json!("NESTED");
    d.json["nodes"][0]["extensions"] = json!({"EXT_unknown": "NESTED"});
    let text = d.write_gltf(dir.path(), "n");
    let text = std::fs::read_to_string(&text)
        .unwrap()
        .replacen("\"NESTED\"", &nested, 1);
    let p = dir.write("nested-min.gltf", &text);
    expect_err(&p, limits(), &["invalid glTF JSON", "recursion limit"]);
    // Where it is skipped (extras are kept raw, unknown properties ignored), serde_json skips
    // it without recursion: no stack overflow even 100 times deeper, on a 2 MiB thread stack.
    let deeper = format!("{}{}", "[".repeat(100 * depth), "]".repeat(100 * depth));
    let objects = format!("{}1{}", r#"{"a":"#.repeat(depth), "}".repeat(depth));
    for (key, value) in [
        ("extras", &nested),
        ("somethingUnknown", &deeper),
        ("extras", &objects),
    ] {
        let text = format!(r#"{{"asset": {{"version": "2.0"}}, "{key}": {value}}}"#);
        let p = dir.write("nested-skipped.gltf", &text);
        match load(&p, limits()) {
            Ok(s) => assert_eq!(s.triangle_count(), 0),
            Err(e) => assert!(e.to_string().contains("recursion limit"), "{e}"),
        }
    }
}

#[test]
fn empty_file() {
    let dir = TempDir::new("empty");
    let p = dir.write("e.gltf", b"");
    expect_err(&p, limits(), &["the file is empty"]);
    let p = dir.write("e.glb", b"");
    expect_err(&p, limits(), &["invalid GLB", "the file is empty"]);
    // A GLB whose JSON chunk is empty.
    let p = dir.write("j.glb", pathlight_scene::gltf::glb::write(b"", None));
    expect_err(&p, limits(), &["invalid GLB", "JSON chunk is empty"]);
    let p = dir.write("blank.gltf", b" \n\t ");
    expect_err(&p, limits(), &["the file is empty"]);
}

#[test]
fn random_bytes() {
    let dir = TempDir::new("random");
    // A fixed xorshift sequence: reproducible garbage.
    let mut x = 0x9E37_79B9_7F4A_7C15u64;
    let bytes: Vec<u8> = (0..4096)
        .map(|_| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (x >> 24) as u8
        })
        .collect();
    let p = dir.write("noise.gltf", &bytes);
    expect_err(&p, limits(), &["invalid glTF JSON"]);
    let p = dir.write("noise.glb", &bytes);
    expect_err(&p, limits(), &["invalid GLB", "magic"]);
    // Random bytes after a valid GLB magic and version.
    let mut g = b"glTF\x02\x00\x00\x00".to_vec();
    g.extend_from_slice(&bytes);
    let p = dir.write("noise2.glb", &g);
    expect_err(&p, limits(), &["invalid GLB"]);
    // Not a scene format at all.
    let p = dir.write("noise.fbx", &bytes);
    expect_err(&p, limits(), &["unknown scene format"]);
}

#[test]
fn json_object_of_nothing() {
    let dir = TempDir::new("nothing");
    // No asset: glTF requires one.
    let p = dir.write("noasset.gltf", b"{}");
    expect_err(&p, limits(), &["asset"]);
    let p = dir.write("v1.gltf", br#"{"asset": {"version": "1.0"}}"#);
    expect_err(&p, limits(), &["version", "1.0"]);
    // A valid, empty document loads as an empty scene.
    let p = dir.write("minimal.gltf", br#"{"asset": {"version": "2.0"}}"#);
    let s = expect_ok(&p, limits());
    assert_eq!(s.triangle_count(), 0);
}

// ---------------------------------------------------------------------------------------------
// GLB container

#[test]
fn glb_truncated_anywhere() {
    let dir = TempDir::new("glb-cut");
    let glb = Doc::quad().glb();
    assert!(expect_ok(&Doc::quad().write_glb(dir.path(), "whole"), limits()).triangle_count() == 2);
    for cut in (1..glb.len())
        .step_by(3)
        .chain([4, 11, 12, 19, 20, glb.len() - 1])
    {
        let p = dir.write("cut.glb", &glb[..cut]);
        let m = expect_err(&p, limits(), &["invalid GLB"]);
        if cut >= 12 {
            assert!(m.contains("truncated"), "cut at {cut}: {m}");
        }
    }
}

#[test]
fn glb_header_length_lies() {
    let dir = TempDir::new("glb-len");
    let glb = Doc::quad().glb();
    let with_len = |n: u32| {
        let mut g = glb.clone();
        g[8..12].copy_from_slice(&n.to_le_bytes());
        g
    };
    let p = dir.write("big.glb", with_len(glb.len() as u32 + 100));
    expect_err(&p, limits(), &["invalid GLB", "declares", "truncated"]);
    let p = dir.write("huge.glb", with_len(u32::MAX));
    expect_err(&p, limits(), &["invalid GLB", "declares"]);
    let p = dir.write("small.glb", with_len(30));
    expect_err(&p, limits(), &["invalid GLB", "chunk 0", "past the end"]);
    let p = dir.write("tiny.glb", with_len(5));
    expect_err(&p, limits(), &["invalid GLB", "length of 5"]);
}

#[test]
fn glb_chunk_length_past_the_end() {
    let dir = TempDir::new("glb-chunk");
    let glb = Doc::quad().glb();
    let json_len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
    let bin_at = 20 + json_len;
    for (at, len) in [
        (12, glb.len() as u32),
        (12, u32::MAX),
        (bin_at, 1 << 30),
        (bin_at, u32::MAX - 3),
    ] {
        let mut g = glb.clone();
        g[at..at + 4].copy_from_slice(&len.to_le_bytes());
        let p = dir.write("chunk.glb", &g);
        expect_err(&p, limits(), &["invalid GLB", "past the end"]);
    }
}

#[test]
fn glb_json_chunk_missing() {
    let dir = TempDir::new("glb-nojson");
    // The header alone.
    let mut g = b"glTF".to_vec();
    g.extend_from_slice(&2u32.to_le_bytes());
    g.extend_from_slice(&12u32.to_le_bytes());
    let p = dir.write("header.glb", &g);
    expect_err(&p, limits(), &["invalid GLB", "no JSON chunk"]);
    // A BIN chunk first.
    let mut g = b"glTF".to_vec();
    g.extend_from_slice(&2u32.to_le_bytes());
    g.extend_from_slice(&24u32.to_le_bytes());
    g.extend_from_slice(&4u32.to_le_bytes());
    g.extend_from_slice(b"BIN\0");
    g.extend_from_slice(&[0; 4]);
    let p = dir.write("binfirst.glb", &g);
    expect_err(&p, limits(), &["invalid GLB", "not JSON"]);
}

#[test]
fn glb_bin_chunk_missing() {
    let dir = TempDir::new("glb-nobin");
    let d = Doc::quad();
    let mut json = d.json.clone();
    json["buffers"][0].as_object_mut().unwrap().remove("uri");
    let g = pathlight_scene::gltf::glb::write(&serde_json::to_vec(&json).unwrap(), None);
    let p = dir.write("nobin.glb", &g);
    expect_err(&p, limits(), &["buffer 0", "no URI", "binary chunk"]);
    // The same document as .gltf: a buffer without URI and no GLB at all.
    let p = dir.write("nobin.gltf", serde_json::to_vec(&json).unwrap());
    expect_err(&p, limits(), &["buffer 0", "no URI"]);
}

#[test]
fn glb_version_1() {
    let dir = TempDir::new("glb-v1");
    let mut g = Doc::quad().glb();
    g[4..8].copy_from_slice(&1u32.to_le_bytes());
    let p = dir.write("old.glb", &g);
    expect_err(&p, limits(), &["invalid GLB", "version 1"]);
}

// ---------------------------------------------------------------------------------------------
// Buffers

#[test]
fn missing_bin_file() {
    let dir = TempDir::new("nobin");
    let mut d = Doc::quad();
    d.set("/buffers/0/uri", json!("gone.bin"));
    let p = d.write_gltf(dir.path(), "scene");
    let m = assert_err(load(&p, limits()), "gone.bin", &["cannot open"]);
    assert!(m.contains("scene.gltf") || m.contains("gone.bin"), "{m}");
}

#[test]
fn bin_shorter_than_byte_length() {
    let dir = TempDir::new("shortbin");
    let d = Doc::quad();
    let p = d.write_gltf(dir.path(), "short");
    let bin = dir.path().join("short.bin");
    std::fs::write(&bin, &d.bin[..d.bin.len() - 5]).unwrap();
    assert_err(
        load(&p, limits()),
        "short.bin",
        &["buffer 0", "declares", "truncated"],
    );
}

#[test]
fn absurd_byte_length() {
    let dir = TempDir::new("absurdlen");
    let mut d = Doc::quad();
    d.set("/buffers/0/byteLength", json!(1_000_000_000_000_000u64));
    let p = d.write_gltf(dir.path(), "absurd");
    assert_err(
        load(&p, limits()),
        "absurd.bin",
        &["1000000000000000", "has only"],
    );
    // The same in a GLB (the BIN chunk is short) and as a data URI.
    let p = d.write_glb(dir.path(), "absurd");
    expect_err(&p, limits(), &["1000000000000000", "has only"]);
}

#[test]
fn data_uris() {
    let dir = TempDir::new("datauri");
    let cases = [
        (
            "data:application/octet-stream;base64,@@@@not*base64",
            "invalid base64",
        ),
        (
            "data:application/octet-stream;base64,AAAAA",
            "invalid base64",
        ),
        ("data:application/octet-stream,plain%20text", "not base64"),
        ("data:application/octet-stream;base64", "no ','"),
    ];
    for (uri, keyword) in cases {
        let mut d = Doc::quad();
        d.set("/buffers/0/uri", json!(uri));
        let p = d.write_gltf(dir.path(), "data");
        expect_err(&p, limits(), &[keyword]);
    }
    // A valid data URI loads.
    use base64::Engine;
    let mut d = Doc::quad();
    let uri = format!(
        "data:application/octet-stream;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(&d.bin)
    );
    d.set("/buffers/0/uri", json!(uri));
    let p = d.write_gltf(dir.path(), "good");
    assert_eq!(expect_ok(&p, limits()).triangle_count(), 2);
}

// ---------------------------------------------------------------------------------------------
// Buffer views and accessors

#[test]
fn buffer_view_outside_the_buffer() {
    let dir = TempDir::new("view-out");
    for (pointer, value) in [
        ("/bufferViews/0/byteOffset", json!(1000)),
        ("/bufferViews/0/byteLength", json!(1000)),
        ("/bufferViews/0/byteOffset", json!(u64::MAX - 4)),
    ] {
        let mut d = Doc::quad();
        d.set(pointer, value);
        let p = d.write_gltf(dir.path(), "view");
        expect_err(&p, limits(), &["bufferView 0", "outside buffer 0"]);
    }
}

#[test]
fn accessor_past_its_view() {
    let dir = TempDir::new("acc-past");
    for (pointer, value) in [
        ("/accessors/0/count", json!(5)),
        ("/accessors/0/byteOffset", json!(4)),
        ("/accessors/1/byteOffset", json!(u64::MAX - 2)),
    ] {
        let mut d = Doc::quad();
        d.set(pointer, value);
        let p = d.write_gltf(dir.path(), "acc");
        expect_err(&p, limits(), &["accessor", "do not fit in bufferView"]);
    }
}

#[test]
fn absurd_counts_are_refused_quickly() {
    let dir = TempDir::new("absurd-count");
    // Each would ask for gigabytes if allocated before the bounds check.
    let cases = [
        (
            "/accessors/0/count",
            4_000_000_000u64,
            "4000000000 vertices in all",
        ),
        (
            "/accessors/1/count",
            4_000_000_000,
            "1333333333 triangles, over the limit",
        ),
        (
            "/accessors/0/count",
            99_000_000,
            "accessor 0: 99000000 elements",
        ),
        (
            "/accessors/1/count",
            290_000_000,
            "accessor 1: 290000000 elements",
        ),
        (
            "/accessors/0/count",
            u64::MAX,
            "18446744073709551615 vertices",
        ),
        (
            "/accessors/2/count",
            99_000_000,
            "NORMAL has 99000000 elements but POSITION has 4",
        ),
        (
            "/accessors/3/count",
            250_000_000,
            "TEXCOORD_0 has 250000000 elements",
        ),
    ];
    for (pointer, count, keyword) in cases {
        let mut d = Doc::quad();
        let n = d.add_floats([0.0, 0.0, 1.0].repeat(4), 4, "VEC3");
        d.prim()["attributes"]["NORMAL"] = json!(n);
        let uv = d.add_floats([0.5; 8], 4, "VEC2");
        d.prim()["attributes"]["TEXCOORD_0"] = json!(uv);
        d.set(pointer, json!(count));
        let p = d.write_gltf(dir.path(), "count");
        let t = Instant::now();
        expect_err(&p, limits(), &[keyword]);
        assert!(
            t.elapsed() < Duration::from_secs(2),
            "{pointer} {count}: {:?}",
            t.elapsed()
        );
    }
    // Many primitives with absurd counts: the triangle total must not overflow.
    let mut d = Doc::quad();
    d.set("/accessors/1/count", json!(u64::MAX));
    let prim = d.json["meshes"][0]["primitives"][0].clone();
    d.json["meshes"][0]["primitives"] = json!([prim.clone(), prim.clone(), prim.clone(), prim]);
    let p = d.write_gltf(dir.path(), "overflow");
    expect_err(&p, limits(), &["triangles", "limit"]);
}

#[test]
fn many_primitives_sharing_a_large_accessor() {
    // Each primitive reads the whole POSITION accessor: 3000 primitives sharing a 100000-vertex
    // accessor read 3e8 vertices from a 1.2 MB file. The total is bounded by the same limit as
    // one accessor's count (max(max_vertices, 3 x max_triangles)).
    let dir = TempDir::new("shared-accessor");
    let positions: Vec<[f32; 3]> = (0..100_000)
        .map(|i| [i as f32, (i % 2) as f32, 0.0])
        .collect();
    let mut d = Doc::mesh(&positions, Some(&[0, 1, 2]));
    let prim = d.json["meshes"][0]["primitives"][0].clone();
    d.json["meshes"][0]["primitives"] = json!(vec![prim; 3001]);
    let p = d.write_glb(dir.path(), "shared");
    let t = Instant::now();
    expect_err(
        &p,
        limits(),
        &["300100000 vertices in all", "over the limit of 300000000"],
    );
    assert!(t.elapsed() < Duration::from_secs(2), "{:?}", t.elapsed());
    // Under a smaller limit, a few primitives are enough.
    let small = Limits {
        max_vertices: 150_000,
        max_triangles: 10,
        ..Limits::default()
    };
    d.json["meshes"][0]["primitives"] =
        json!(vec![d.json["meshes"][0]["primitives"][0].clone(); 2]);
    let p = d.write_glb(dir.path(), "two");
    expect_err(&p, small, &["200000 vertices in all", "limit of 150000"]);
}

#[test]
fn byte_stride_smaller_than_the_element() {
    let dir = TempDir::new("stride");
    let mut d = Doc::quad();
    d.set("/bufferViews/0/byteStride", json!(8));
    let p = d.write_gltf(dir.path(), "stride");
    expect_err(
        &p,
        limits(),
        &["accessor 0", "byteStride 8", "smaller than one element"],
    );
    // Out of glTF's range (4..=252, multiple of 4).
    d.set("/bufferViews/0/byteStride", json!(2));
    let p = d.write_gltf(dir.path(), "stride2");
    expect_err(&p, limits(), &["bufferViews[0].byteStride"]);
}

#[test]
fn dangling_indices() {
    let dir = TempDir::new("dangling");
    let with_texture = || {
        let mut d = Doc::quad();
        d.textured(json!({"uri": "t.png"}));
        d.json["samplers"] = json!([{}]);
        d.json["textures"][0]["sampler"] = json!(0);
        d
    };
    let cases: Vec<(&str, Doc, &str)> = vec![
        (
            "/meshes/0/primitives/0/attributes/POSITION",
            Doc::quad(),
            "POSITION",
        ),
        (
            "/meshes/0/primitives/0/attributes/NORMAL",
            Doc::quad(),
            "NORMAL",
        ),
        ("/meshes/0/primitives/0/indices", Doc::quad(), "indices"),
        ("/accessors/0/bufferView", Doc::quad(), "bufferView"),
        ("/bufferViews/0/buffer", Doc::quad(), "buffer"),
        ("/meshes/0/primitives/0/material", Doc::quad(), "material"),
        ("/nodes/0/mesh", Doc::quad(), "mesh"),
        ("/nodes/0/children", Doc::quad(), "children"),
        ("/nodes/0/camera", Doc::quad(), "camera"),
        ("/scenes/0/nodes/0", Doc::quad(), "scenes[0].nodes[0]"),
        ("/scene", Doc::quad(), "scene"),
        (
            "/materials/0/pbrMetallicRoughness/baseColorTexture/index",
            with_texture(),
            "baseColorTexture",
        ),
        ("/textures/0/source", with_texture(), "source"),
        ("/textures/0/sampler", with_texture(), "sampler"),
        ("/images/0/bufferView", with_texture(), "bufferView"),
    ];
    for (pointer, mut d, keyword) in cases {
        let value = if pointer.ends_with("children") {
            json!([99])
        } else {
            json!(99)
        };
        d.set(pointer, value);
        if pointer.starts_with("/images") {
            d.remove("/images/0/uri");
            d.json["images"][0]["mimeType"] = json!("image/png");
        }
        let p = d.write_gltf(dir.path(), "dangling");
        let m = expect_err(&p, limits(), &["invalid glTF", keyword, "out of bounds"]);
        println!("{pointer}: {m}");
    }
    // A dangling POSITION in a GLB and in a morph target.
    let mut d = Doc::quad();
    d.set("/meshes/0/primitives/0/attributes/POSITION", json!(99));
    let p = d.write_glb(dir.path(), "dangling");
    expect_err(&p, limits(), &["POSITION", "out of bounds"]);
    let mut d = Doc::quad();
    d.set("/meshes/0/primitives/0/targets", json!([{"POSITION": 99}]));
    let p = d.write_gltf(dir.path(), "target");
    expect_err(&p, limits(), &["targets", "out of bounds"]);
}

#[test]
fn wrong_accessor_type_for_position() {
    let dir = TempDir::new("vec2");
    let mut d = Doc::quad();
    d.set("/accessors/0/type", json!("VEC2"));
    d.set("/accessors/0/min", json!([0, 0, 0]));
    let p = d.write_gltf(dir.path(), "vec2");
    expect_err(&p, limits(), &["accessor 0", "Vec2", "expected"]);
    // Indices that are not SCALAR, or floats.
    let mut d = Doc::quad();
    d.set("/accessors/1/type", json!("VEC3"));
    d.set("/accessors/1/count", json!(2));
    let p = d.write_gltf(dir.path(), "idxvec3");
    expect_err(&p, limits(), &["accessor 1", "SCALAR"]);
    let mut d = Doc::quad();
    d.set("/accessors/1/componentType", json!(FLOAT));
    let p = d.write_gltf(dir.path(), "idxfloat");
    expect_err(&p, limits(), &["accessor 1", "unsigned"]);
    // An unknown type name.
    let mut d = Doc::quad();
    d.set("/accessors/0/type", json!("VEC7"));
    let p = d.write_gltf(dir.path(), "vec7");
    expect_err(&p, limits(), &["accessors[0].type"]);
}

#[test]
fn invalid_component_type() {
    let dir = TempDir::new("comptype");
    let mut d = Doc::quad();
    d.set("/accessors/0/componentType", json!(5000));
    let p = d.write_gltf(dir.path(), "comp");
    expect_err(&p, limits(), &["accessors[0].componentType", "invalid"]);
}

#[test]
fn indices_out_of_range() {
    let dir = TempDir::new("idx-range");
    let mut d = Doc::quad();
    let i = d.add_indices(&[0, 1, 2, 0, 2, 7]);
    d.prim()["indices"] = json!(i);
    let p = d.write_gltf(dir.path(), "idx");
    expect_err(
        &p,
        limits(),
        &["index 5 is 7", "out of range for 4 vertices"],
    );
    let mut d = Doc::quad();
    let i = d.add_indices(&[0, 1, u32::MAX]);
    d.prim()["indices"] = json!(i);
    let p = d.write_glb(dir.path(), "idxmax");
    expect_err(&p, limits(), &["4294967295", "out of range"]);
}

#[test]
fn sparse_accessor_out_of_range() {
    let dir = TempDir::new("sparse");
    let mut d = Doc::quad();
    let idx = d.add_view(&5u32.to_le_bytes());
    let val = d.add_view(&[0u8; 12]);
    d.set(
        "/accessors/0/sparse",
        json!({
            "count": 1,
            "indices": {"bufferView": idx, "componentType": UNSIGNED_INT},
            "values": {"bufferView": val}
        }),
    );
    let p = d.write_gltf(dir.path(), "sparse");
    expect_err(
        &p,
        limits(),
        &["accessor 0", "sparse index 5", "out of range"],
    );
    // A sparse count over the accessor's count, and a sparse view too short.
    d.set("/accessors/0/sparse/count", json!(9));
    let p = d.write_gltf(dir.path(), "sparse2");
    expect_err(&p, limits(), &["accessor 0", "sparse count 9"]);
    d.set("/accessors/0/sparse/count", json!(3));
    let p = d.write_gltf(dir.path(), "sparse3");
    expect_err(&p, limits(), &["accessor 0", "do not fit"]);
    // A valid sparse accessor moves vertex 2.
    let mut d = Doc::quad();
    let idx = d.add_view(&2u32.to_le_bytes());
    let val: Vec<u8> = [2.0f32, 2.0, 0.0]
        .iter()
        .flat_map(|f| f.to_le_bytes())
        .collect();
    let val = d.add_view(&val);
    d.set(
        "/accessors/0/sparse",
        json!({
            "count": 1,
            "indices": {"bufferView": idx, "componentType": UNSIGNED_INT},
            "values": {"bufferView": val}
        }),
    );
    let p = d.write_gltf(dir.path(), "sparse-ok");
    let s = expect_ok(&p, limits());
    assert_eq!(s.meshes[0].positions[2], glam::Vec3::new(2.0, 2.0, 0.0));
}

// ---------------------------------------------------------------------------------------------
// Node graph

#[test]
fn node_cycles_and_shared_children() {
    let dir = TempDir::new("cycle");
    let cases = [
        // 0 -> 1 -> 0
        (
            json!([{"mesh": 0, "children": [1]}, {"children": [0]}]),
            json!([0]),
        ),
        // 0 -> 0
        (json!([{"mesh": 0, "children": [0]}]), json!([0])),
        // 0 and 1 both parents of 2
        (
            json!([{"children": [2]}, {"children": [2]}, {"mesh": 0}]),
            json!([0, 1]),
        ),
        // a root listed twice
        (json!([{"mesh": 0}]), json!([0, 0])),
        // a cycle below the root: 0 -> 1 -> 2 -> 1
        (
            json!([{"children": [1]}, {"children": [2]}, {"mesh": 0, "children": [1]}]),
            json!([0]),
        ),
    ];
    for (nodes, roots) in cases {
        let mut d = Doc::quad();
        d.json["nodes"] = nodes.clone();
        d.json["scenes"][0]["nodes"] = roots;
        let p = d.write_gltf(dir.path(), "cycle");
        expect_err(&p, limits(), &["reached twice", "cycle"]);
        // Without a scene, every root node is shown: a pure cycle has no root at all.
        d.remove("/scene");
        d.remove("/scenes");
        let p = d.write_gltf(dir.path(), "cycle-noscene");
        match load(&p, limits()) {
            Ok(s) => {
                warning(&s, &["no scene"]);
            }
            Err(e) => assert!(e.to_string().contains("reached twice"), "{nodes}: {e}"),
        }
    }
}

#[test]
fn very_deep_node_chain_loads() {
    let dir = TempDir::new("deep");
    let n = 100_000;
    let mut d = Doc::quad();
    let mut nodes: Vec<serde_json::Value> = (0..n - 1)
        .map(|i| json!({"children": [i + 1], "translation": [0.0, 0.0, 1.0]}))
        .collect();
    nodes.push(json!({"mesh": 0}));
    d.json["nodes"] = json!(nodes);
    let t = Instant::now();
    let p = d.write_glb(dir.path(), "deep");
    let s = expect_ok(&p, limits());
    assert_eq!(s.instances.len(), 1);
    let z = s.instances[0].transform.w_axis.z;
    assert_eq!(z, (n - 1) as f32);
    assert!(t.elapsed() < Duration::from_secs(5), "{:?}", t.elapsed());
}

#[test]
fn scene_lists_missing_node() {
    let dir = TempDir::new("scene-node");
    let mut d = Doc::quad();
    d.set("/scenes/0/nodes", json!([0, 99]));
    let p = d.write_gltf(dir.path(), "scene");
    expect_err(&p, limits(), &["scenes[0].nodes[1]", "out of bounds"]);
}

#[test]
fn non_finite_node_transforms() {
    let dir = TempDir::new("node-nan");
    let mut m: Vec<f64> = vec![
        1., 0., 0., 0., 0., 1., 0., 0., 0., 0., 1., 0., 0., 0., 0., 1.,
    ];
    m[12] = 1e39; // infinite as f32 (JSON has no NaN)
    let cases = [
        ("/nodes/0/matrix", json!(m), "NaN or infinite"),
        (
            "/nodes/0/translation",
            json!([1e39, 0, 0]),
            "NaN or infinite",
        ),
        ("/nodes/0/scale", json!([1, -1e39, 1]), "NaN or infinite"),
        (
            "/nodes/0/rotation",
            json!([0, 0, 0, 0]),
            "not a valid quaternion",
        ),
        (
            "/nodes/0/rotation",
            json!([1e39, 0, 0, 1]),
            "not a valid quaternion",
        ),
    ];
    for (pointer, value, keyword) in cases {
        let mut d = Doc::quad();
        d.set(pointer, value);
        let p = d.write_gltf(dir.path(), "nan");
        expect_err(&p, limits(), &["node 0", keyword]);
    }
    // Finite transforms whose product overflows.
    let mut d = Doc::quad();
    d.json["nodes"] = json!([
        {"scale": [1e30, 1e30, 1e30], "children": [1]},
        {"scale": [1e30, 1e30, 1e30], "mesh": 0}
    ]);
    let p = d.write_gltf(dir.path(), "overflow");
    expect_err(&p, limits(), &["node 1", "overflows"]);
    // A zero scale: the mesh is skipped with a warning.
    let mut d = Doc::quad();
    d.set("/nodes/0/scale", json!([0, 0, 0]));
    let p = d.write_gltf(dir.path(), "zero");
    let s = expect_ok(&p, limits());
    warning(&s, &["node 0", "singular"]);
    assert_eq!(s.triangle_count(), 0);
}

// ---------------------------------------------------------------------------------------------
// Extensions

#[test]
fn required_extensions_not_supported() {
    let dir = TempDir::new("ext-req");
    let mut d = Doc::quad();
    let exts = json!(["EXT_meshopt_compression", "KHR_draco_mesh_compression"]);
    d.set("/extensionsUsed", exts.clone());
    d.set("/extensionsRequired", exts);
    let p = d.write_gltf(dir.path(), "req");
    expect_err(
        &p,
        limits(),
        &[
            "requires extensions",
            "EXT_meshopt_compression",
            "KHR_draco_mesh_compression",
        ],
    );
    // A supported required extension loads.
    let mut d = Doc::quad();
    d.set("/extensionsUsed", json!(["KHR_texture_transform"]));
    d.set("/extensionsRequired", json!(["KHR_texture_transform"]));
    let p = d.write_gltf(dir.path(), "ok");
    expect_ok(&p, limits());
}

#[test]
fn unknown_used_extension_warns() {
    let dir = TempDir::new("ext-used");
    let mut d = Doc::quad();
    d.set("/extensionsUsed", json!(["EXT_totally_made_up"]));
    d.set(
        "/meshes/0/extensions",
        json!({"EXT_totally_made_up": {"x": 1}}),
    );
    let p = d.write_gltf(dir.path(), "used");
    let s = expect_ok(&p, limits());
    warning(&s, &["EXT_totally_made_up", "not supported"]);
    assert_eq!(s.triangle_count(), 2);
}

// ---------------------------------------------------------------------------------------------
// URIs that leave the scene's folder

/// A folder `scene/` inside a temporary folder that also holds `outside.bin` and `outside.png`
/// (valid files: only the refusal keeps them from being read).
fn escape_setup(tag: &str) -> (TempDir, std::path::PathBuf) {
    let dir = TempDir::new(tag);
    dir.write("outside.bin", Doc::quad().bin);
    dir.write("outside.png", png(4, 4, |_, _| [255, 0, 0, 255]));
    let scene = dir.sub("scene");
    (dir, scene)
}

const HOSTILE_URIS: &[&str] = &[
    "/etc/passwd",
    "../outside.bin",
    "..%2Foutside.bin",
    "%2e%2e/outside.bin",
    "%2E%2E%2Foutside.bin",
    "sub/../../outside.bin",
    "..\\outside.bin",
    "file:///etc/passwd",
    "http://example.com/x.bin",
    "%2Fetc%2Fpasswd",
    "",
];

#[test]
fn buffer_uris_outside_the_folder_are_refused() {
    let (_dir, scene) = escape_setup("uri-buffer");
    for uri in HOSTILE_URIS {
        let uri = uri.replace("outside.png", "outside.bin");
        let mut d = Doc::quad();
        d.set("/buffers/0/uri", json!(uri));
        let p = d.write_gltf(&scene, "escape");
        let m = expect_err(&p, limits(), &["refused"]);
        println!("{uri}: {m}");
    }
}

#[test]
fn symlink_leading_outside_is_refused() {
    let (dir, scene) = escape_setup("uri-symlink");
    std::os::unix::fs::symlink(dir.path().join("outside.bin"), scene.join("link.bin")).unwrap();
    std::os::unix::fs::symlink(dir.path().join("outside.png"), scene.join("link.png")).unwrap();
    // A symlinked folder too.
    std::os::unix::fs::symlink(dir.path(), scene.join("up")).unwrap();
    for uri in ["link.bin", "up/outside.bin"] {
        let mut d = Doc::quad();
        d.set("/buffers/0/uri", json!(uri));
        let p = d.write_gltf(&scene, "link");
        assert_err(
            load(&p, limits()),
            uri.rsplit('/').next().unwrap(),
            &["refused", "symbolic link"],
        );
    }
    for uri in ["link.png", "up/outside.png"] {
        let mut d = Doc::quad();
        d.textured(json!({"uri": uri}));
        let p = d.write_gltf(&scene, "link-image");
        let s = expect_ok(&p, limits());
        warning(&s, &["refused", "symbolic link"]);
        assert_eq!(s.materials[0].base_color_texture, None);
    }
}

#[test]
fn image_uris_outside_the_folder_are_refused_with_a_warning() {
    let (_dir, scene) = escape_setup("uri-image");
    for uri in HOSTILE_URIS {
        let uri = uri.replace("outside.bin", "outside.png");
        let mut d = Doc::quad();
        d.textured(json!({"uri": uri}));
        let p = d.write_gltf(&scene, "escape");
        let s = expect_ok(&p, limits());
        let w = warning(&s, &["refused"]);
        assert!(w.contains("escape.gltf"), "{w}");
        assert!(w.contains("image 0"), "{w}");
        assert_eq!(s.materials[0].base_color_texture, None, "{uri}");
        assert!(s.textures.is_empty());
    }
}

// ---------------------------------------------------------------------------------------------
// Non-finite and degenerate geometry

fn tri_positions() -> Vec<[f32; 3]> {
    vec![
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [1.0, 1.0, 0.0],
        [f32::NAN, 0.0, 0.0],
        [0.0, f32::INFINITY, 0.0],
        [2.0, 0.0, 0.0], // collinear with 0 and 1
    ]
}

#[test]
fn non_finite_and_degenerate_triangles_are_dropped() {
    let dir = TempDir::new("degenerate");
    let idx = [
        0, 1, 2, // good
        1, 3, 2, // good
        0, 1, 4, // NaN corner
        5, 1, 2, // infinite corner
        0, 1, 6, // zero area (collinear)
        0, 0, 2, // repeated index
        3, 3, 3, // all the same
    ];
    let d = Doc::mesh(&tri_positions(), Some(&idx));
    let p = d.write_gltf(dir.path(), "bad-tris");
    let s = expect_ok(&p, limits());
    let w = warning(
        &s,
        &[
            "dropped 5 triangles",
            "2 with a NaN or infinite corner",
            "3 of zero area",
        ],
    );
    assert!(w.contains("bad-tris.gltf"), "{w}");
    assert_eq!(s.triangle_count(), 2);
    assert_eq!(s.dropped_triangles, 5);
    assert_eq!(
        s.meshes[0].positions.len(),
        4,
        "unused vertices are removed"
    );
    assert!(s.meshes[0].positions.iter().all(|p| p.is_finite()));
}

#[test]
fn mesh_of_only_degenerate_triangles() {
    let dir = TempDir::new("all-degenerate");
    let d = Doc::mesh(&tri_positions(), Some(&[0, 1, 6, 0, 0, 2, 4, 5, 4]));
    let p = d.write_glb(dir.path(), "nothing");
    let s = expect_ok(&p, limits());
    warning(&s, &["dropped 3 triangles"]);
    assert_eq!(s.triangle_count(), 0);
    assert!(s.meshes.is_empty());
}

#[test]
fn non_finite_normals_load() {
    let dir = TempDir::new("nan-normals");
    let mut d = Doc::quad();
    let n = [
        [0.0, 0.0, 1.0],
        [f32::NAN, 0.0, 1.0],
        [0.0, 0.0, f32::INFINITY],
        [0.0, 0.0, 0.0],
    ];
    let a = d.add_floats(n.iter().flatten().copied(), 4, "VEC3");
    d.prim()["attributes"]["NORMAL"] = json!(a);
    let uv = d.add_floats([f32::NAN; 8], 4, "VEC2");
    d.prim()["attributes"]["TEXCOORD_0"] = json!(uv);
    let p = d.write_gltf(dir.path(), "normals");
    let s = expect_ok(&p, limits());
    assert_eq!(s.triangle_count(), 2);
    let normals = s.meshes[0].normals.as_ref().unwrap();
    for n in normals {
        assert!(n.is_finite() && (n.length() - 1.0).abs() < 1e-5, "{n}");
    }
    assert!(s.meshes[0]
        .uv0
        .as_ref()
        .unwrap()
        .iter()
        .all(|uv| uv.is_finite()));
}

#[test]
fn non_finite_material_factors_fall_back() {
    let dir = TempDir::new("nan-material");
    let mut d = Doc::quad();
    d.json["materials"] = json!([{
        "name": "broken",
        "pbrMetallicRoughness": {
            "roughnessFactor": 1e39,
            "metallicFactor": -1e39,
            "baseColorFactor": [1e39, 0.5, 0.5, 1]
        },
        "emissiveFactor": [1e39, 0, 0]
    }]);
    d.prim()["material"] = json!(0);
    let p = d.write_gltf(dir.path(), "material");
    let s = expect_ok(&p, limits());
    warning(
        &s,
        &[
            "material \"broken\"",
            "invalid values replaced",
            "roughness",
        ],
    );
    let m = &s.materials[0];
    assert_eq!(m.roughness, 1.0);
    assert_eq!(m.metallic, 1.0, "metallic falls back to the glTF default");
    assert_eq!(m.base_color.x, 1.0);
    assert_eq!(m.emissive, glam::Vec3::ZERO);
}

// ---------------------------------------------------------------------------------------------
// Textures

#[test]
fn missing_image_falls_back() {
    let dir = TempDir::new("img-missing");
    let mut d = Doc::quad();
    d.textured(json!({"uri": "nowhere.png"}));
    let p = d.write_gltf(dir.path(), "tex");
    let s = expect_ok(&p, limits());
    let w = warning(&s, &["nowhere.png", "cannot open", "uses its factors"]);
    println!("{w}");
    assert_eq!(s.materials[0].base_color_texture, None);
    assert_eq!(s.triangle_count(), 2);
}

#[test]
fn corrupt_images_fall_back() {
    let dir = TempDir::new("img-corrupt");
    let good = png(8, 8, |x, y| [x as u8, y as u8, 0, 255]);
    let mut flipped = good.clone();
    let mid = flipped.len() / 2;
    for b in &mut flipped[mid..] {
        *b ^= 0x5a;
    }
    let cases: Vec<(&str, Vec<u8>, &str)> = vec![
        ("cut.png", good[..good.len() / 2].to_vec(), "cannot decode"),
        ("flipped.png", flipped, "cannot decode"),
        (
            "magic.png",
            b"\x89PNG\r\n\x1a\ngarbage garbage garbage".to_vec(),
            "image",
        ),
        (
            "text.png",
            b"hello, not an image".to_vec(),
            "not a PNG or JPEG",
        ),
        ("empty.png", Vec::new(), "not a PNG or JPEG"),
        (
            "jpeg.png",
            b"\xff\xd8\xff\xe0\x00\x10JFIF\x00garbage".to_vec(),
            "image",
        ),
        (
            "gif.png",
            b"GIF89a\x01\x00\x01\x00\x00\x00\x00;".to_vec(),
            "PNG or JPEG",
        ),
    ];
    for (name, bytes, keyword) in cases {
        dir.write(name, &bytes);
        let mut d = Doc::quad();
        d.textured(json!({"uri": name}));
        let p = d.write_gltf(dir.path(), "tex");
        let s = expect_ok(&p, limits());
        let w = warning(&s, &[name, keyword]);
        println!("{w}");
        assert_eq!(s.materials[0].base_color_texture, None, "{name}");
    }
    // The same bytes held in a bufferView of a GLB.
    let mut d = Doc::quad();
    let v = d.add_view(&good[..good.len() / 2]);
    d.textured(json!({"bufferView": v, "mimeType": "image/png"}));
    let p = d.write_glb(dir.path(), "embedded");
    let s = expect_ok(&p, limits());
    warning(&s, &["embedded.glb", "image 0", "cannot decode"]);
    assert_eq!(s.materials[0].base_color_texture, None);
}

#[test]
fn huge_png_header_is_refused_quickly() {
    let dir = TempDir::new("img-huge");
    dir.write("huge.png", png_header_only(100_000, 100_000));
    let mut d = Doc::quad();
    d.textured(json!({"uri": "huge.png"}));
    let p = d.write_gltf(dir.path(), "tex");
    let t = Instant::now();
    let s = expect_ok(&p, limits());
    assert!(t.elapsed() < Duration::from_secs(2), "{:?}", t.elapsed());
    warning(&s, &["huge.png", "100000x100000", "over the limit"]);
    assert_eq!(s.materials[0].base_color_texture, None);
    // Under the pixel limit but lying about its size: refused by the decoder, not allocated.
    dir.write("liar.png", png_header_only(8000, 8000));
    let mut d = Doc::quad();
    d.textured(json!({"uri": "liar.png"}));
    let p = d.write_gltf(dir.path(), "liar");
    let s = expect_ok(&p, limits());
    warning(&s, &["liar.png", "decode"]);
}

#[test]
fn texture_over_a_small_pixel_limit() {
    let dir = TempDir::new("img-limit");
    dir.write("t.png", png(64, 64, |_, _| [9, 9, 9, 255]));
    let mut d = Doc::quad();
    d.textured(json!({"uri": "t.png"}));
    let p = d.write_gltf(dir.path(), "tex");
    let small = Limits {
        max_texture_pixels: 1000,
        ..Limits::default()
    };
    let s = expect_ok(&p, small);
    warning(&s, &["t.png", "64x64", "over the limit of 1000"]);
    assert_eq!(s.materials[0].base_color_texture, None);
    // Within the per-texture limit but over the total.
    let total = Limits {
        max_total_texture_pixels: 1000,
        ..Limits::default()
    };
    let s = expect_ok(&p, total);
    warning(&s, &["image 0", "limit of 1000 pixels in all"]);
    assert_eq!(s.materials[0].base_color_texture, None);
    // The total is checked on the images' headers before any is decoded: of three images that
    // claim 10000x10000 pixels each, only the first is decoded (and found to be a lie).
    let mut d = Doc::quad();
    d.textured(json!({"uri": "big0.png"}));
    for i in 0..3 {
        dir.write(&format!("big{i}.png"), png_header_only(10_000, 10_000));
    }
    d.json["images"] = json!([{"uri": "big0.png"}, {"uri": "big1.png"}, {"uri": "big2.png"}]);
    d.json["textures"] = json!([{"source": 0}, {"source": 1}, {"source": 2}]);
    d.json["materials"][0]["emissiveTexture"] = json!({"index": 1});
    d.json["materials"][0]["emissiveFactor"] = json!([1, 1, 1]);
    d.json["materials"][0]["normalTexture"] = json!({"index": 2});
    let p2 = d.write_gltf(dir.path(), "many");
    let total = Limits {
        max_total_texture_pixels: 150_000_000,
        ..Limits::default()
    };
    let t = Instant::now();
    let s = expect_ok(&p2, total);
    assert!(t.elapsed() < Duration::from_secs(2), "{:?}", t.elapsed());
    warning(&s, &["big0.png", "decode"]);
    warning(&s, &["image 1", "limit of 150000000 pixels in all"]);
    warning(&s, &["image 2", "limit of 150000000 pixels in all"]);
    assert!(s.textures.is_empty());
    // And within both, it is used.
    let s = expect_ok(&p, limits());
    assert!(s.materials[0].base_color_texture.is_some());
    assert_eq!(s.textures.len(), 1);
}

// ---------------------------------------------------------------------------------------------
// Limits

#[test]
fn over_max_triangles() {
    let dir = TempDir::new("lim-tris");
    let n = 12u32;
    let positions: Vec<[f32; 3]> = (0..n + 2)
        .map(|i| [i as f32, (i % 2) as f32, 0.0])
        .collect();
    let idx: Vec<u32> = (0..n).flat_map(|i| [i, i + 1, i + 2]).collect();
    let d = Doc::mesh(&positions, Some(&idx));
    let p = d.write_gltf(dir.path(), "tris");
    let small = Limits {
        max_triangles: 10,
        ..Limits::default()
    };
    expect_err(&p, small, &["12 triangles", "limit of 10"]);
    // 6 triangles under the limit, but instanced twice they are over it.
    let d = Doc::mesh(&positions, Some(&idx[..18]));
    let mut d2 = d.clone();
    d2.json["nodes"] = json!([{"mesh": 0}, {"mesh": 0, "translation": [0, 0, 1]}]);
    d2.json["scenes"][0]["nodes"] = json!([0, 1]);
    let p = d2.write_gltf(dir.path(), "instanced");
    expect_err(&p, small, &["instanced", "10 triangles", "limit"]);
    let p = d.write_gltf(dir.path(), "once");
    assert_eq!(expect_ok(&p, small).triangle_count(), 6);
}

#[test]
fn over_max_vertices() {
    let dir = TempDir::new("lim-verts");
    let d = Doc::quad();
    let p = d.write_gltf(dir.path(), "verts");
    let small = Limits {
        max_vertices: 3,
        ..Limits::default()
    };
    expect_err(
        &p,
        small,
        &["mesh 0 primitive 0", "4 vertices", "limit of 3"],
    );
}

#[test]
fn over_max_instances() {
    let dir = TempDir::new("lim-inst");
    let mut d = Doc::triangle();
    d.json["nodes"] = json!((0..5).map(|_| json!({"mesh": 0})).collect::<Vec<_>>());
    d.json["scenes"][0]["nodes"] = json!([0, 1, 2, 3, 4]);
    let p = d.write_gltf(dir.path(), "inst");
    let small = Limits {
        max_instances: 3,
        ..Limits::default()
    };
    expect_err(&p, small, &["instance", "limit"]);
}

#[test]
fn over_max_file_bytes() {
    let dir = TempDir::new("lim-bytes");
    let d = Doc::quad();
    let p = d.write_gltf(dir.path(), "bytes");
    let len = std::fs::metadata(&p).unwrap().len();
    let small = Limits {
        max_file_bytes: len - 1,
        ..Limits::default()
    };
    expect_err(
        &p,
        small,
        &["over the limit", &format!("{} bytes", len - 1)],
    );
    // The scene fits but its buffer does not.
    let small = Limits {
        max_file_bytes: len,
        ..Limits::default()
    };
    let mut big = Doc::quad();
    big.bin.resize(len as usize + 100, 0);
    big.json["buffers"][0]["byteLength"] = json!(big.bin.len());
    let p = big.write_gltf(dir.path(), "bigbin");
    let len2 = std::fs::metadata(&p).unwrap().len();
    let small = Limits {
        max_file_bytes: small.max_file_bytes.max(len2),
        ..small
    };
    assert_err(load(&p, small), "bigbin.bin", &["over the limit"]);
    // A GLB over the limit.
    let p = d.write_glb(dir.path(), "bytes");
    let tiny = Limits {
        max_file_bytes: 100,
        ..Limits::default()
    };
    expect_err(&p, tiny, &["over the limit of 100 bytes"]);
}

// ---------------------------------------------------------------------------------------------
// Primitive modes

#[test]
fn short_strips_fans_and_non_triangle_modes() {
    let dir = TempDir::new("modes");
    // mode, index count, expected triangles
    for (mode, indices, keyword) in [
        (5, vec![0, 1], "fewer than 3"),
        (6, vec![0, 1], "fewer than 3"),
        (6, vec![], "fewer than 3"),
        (4, vec![0, 1], "fewer than 3"),
        (0, vec![0, 1, 2], "Points"),
        (1, vec![0, 1, 2, 3], "Lines"),
        (2, vec![0, 1, 2], "LineLoop"),
        (3, vec![0, 1, 2], "LineStrip"),
    ] {
        let mut d = Doc::quad();
        let i = d.add_indices(&indices);
        d.prim()["indices"] = json!(i);
        d.prim()["mode"] = json!(mode);
        // A second, good primitive: the mesh still loads.
        let good = json!({"attributes": {"POSITION": 0}, "indices": 1});
        d.json["meshes"][0]["primitives"]
            .as_array_mut()
            .unwrap()
            .push(good);
        let p = d.write_gltf(dir.path(), "modes");
        let s = expect_ok(&p, limits());
        warning(&s, &["mesh 0 primitive 0", keyword]);
        assert_eq!(s.triangle_count(), 2, "mode {mode}");
    }
    // A TRIANGLES index count that is not a multiple of 3.
    let mut d = Doc::quad();
    let i = d.add_indices(&[0, 1, 2, 0, 2, 3, 1, 2]);
    d.prim()["indices"] = json!(i);
    let p = d.write_gltf(dir.path(), "trailing");
    let s = expect_ok(&p, limits());
    warning(&s, &["8 indices", "not a multiple of 3"]);
    assert_eq!(s.triangle_count(), 2);
    // An invalid mode number.
    let mut d = Doc::quad();
    d.prim()["mode"] = json!(7);
    let p = d.write_gltf(dir.path(), "mode7");
    expect_err(&p, limits(), &["mode"]);
}

// ---------------------------------------------------------------------------------------------
// Environment maps

fn hdr_bytes(w: u32, h: u32) -> Vec<u8> {
    let img = image::Rgb32FImage::from_fn(w, h, |x, y| image::Rgb([x as f32, y as f32, 0.5]));
    let mut out = Vec::new();
    image::DynamicImage::ImageRgb32F(img)
        .write_to(&mut std::io::Cursor::new(&mut out), image::ImageFormat::Hdr)
        .unwrap();
    out
}

fn exr_bytes(img: image::Rgb32FImage) -> Vec<u8> {
    let mut out = Vec::new();
    image::DynamicImage::ImageRgb32F(img)
        .write_to(
            &mut std::io::Cursor::new(&mut out),
            image::ImageFormat::OpenExr,
        )
        .unwrap();
    out
}

#[test]
fn environment_truncated_hdr() {
    let dir = TempDir::new("env-cut");
    let hdr = hdr_bytes(64, 32);
    let p = dir.write("whole.hdr", &hdr);
    let env = load_env(&p, 1.0, limits()).expect("a valid .hdr loads");
    assert_eq!((env.width, env.height), (64, 32));
    for cut in [0, 5, 20, hdr.len() / 2, hdr.len() - 1] {
        let p = dir.write("cut.hdr", &hdr[..cut]);
        let m = assert_err(load_env(&p, 1.0, limits()), "cut.hdr", &["hdr"]);
        println!("cut {cut}: {m}");
    }
}

#[test]
fn environment_garbage() {
    let dir = TempDir::new("env-garbage");
    let garbage: Vec<u8> = (0..2000u32)
        .map(|i| (i.wrapping_mul(2_654_435_761) >> 13) as u8)
        .collect();
    for name in ["g.hdr", "g.exr"] {
        let p = dir.write(name, &garbage);
        assert_err(load_env(&p, 1.0, limits()), name, &["not a valid"]);
        let p = dir.write(name, b"");
        assert_err(load_env(&p, 1.0, limits()), name, &["not a valid"]);
    }
    // EXR magic followed by garbage, and a truncated EXR.
    let mut exr = vec![0x76, 0x2f, 0x31, 0x01, 2, 0, 0, 0];
    exr.extend_from_slice(&garbage);
    let p = dir.write("magic.exr", &exr);
    assert_err(load_env(&p, 1.0, limits()), "magic.exr", &["exr"]);
    let good = exr_bytes(image::Rgb32FImage::from_pixel(
        16,
        8,
        image::Rgb([1.0, 2.0, 3.0]),
    ));
    for cut in [good.len() / 3, good.len() / 2, good.len() - 4] {
        let p = dir.write("cut.exr", &good[..cut]);
        assert_err(load_env(&p, 1.0, limits()), "cut.exr", &["exr"]);
    }
    // A missing file.
    assert_err(
        load_env(&dir.path().join("none.hdr"), 1.0, limits()),
        "none.hdr",
        &["cannot open"],
    );
}

#[test]
fn environment_huge_header() {
    let dir = TempDir::new("env-huge");
    let mut hdr = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 100000 +X 100000\n".to_vec();
    hdr.extend_from_slice(&[2, 2, 0x80, 0, 1, 2, 3, 4]);
    let p = dir.write("huge.hdr", &hdr);
    let t = Instant::now();
    assert_err(
        load_env(&p, 1.0, limits()),
        "huge.hdr",
        &["100000x100000", "over the limit"],
    );
    assert!(t.elapsed() < Duration::from_secs(2));
    // A small map over a configured limit.
    let p = dir.write("small.hdr", hdr_bytes(64, 32));
    let small = Limits {
        max_texture_pixels: 1000,
        ..Limits::default()
    };
    assert_err(
        load_env(&p, 1.0, small),
        "small.hdr",
        &["64x32", "over the limit of 1000"],
    );
    // Under the pixel limit but claiming far more data than it has.
    let mut liar = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 8000 +X 8000\n".to_vec();
    liar.extend_from_slice(&[2, 2, 0x1f, 0x40, 1, 2, 3, 4]);
    let p = dir.write("liar.hdr", &liar);
    assert_err(load_env(&p, 1.0, limits()), "liar.hdr", &["hdr"]);
}

#[test]
fn environment_unknown_extension_and_bad_intensity() {
    let dir = TempDir::new("env-ext");
    let p = dir.write("sky.png", png(4, 2, |_, _| [1, 2, 3, 255]));
    assert_err(
        load_env(&p, 1.0, limits()),
        "sky.png",
        &["unknown environment map format"],
    );
    let p = dir.write("sky", hdr_bytes(4, 2));
    assert_err(
        load_env(&p, 1.0, limits()),
        "sky",
        &["unknown environment map format"],
    );
    let p = dir.write("sky.hdr", hdr_bytes(4, 2));
    for bad in [f32::NAN, f32::INFINITY, -1.0] {
        assert_err(
            load_env(&p, bad, limits()),
            "sky.hdr",
            &["intensity", "finite"],
        );
    }
    // The same through `load` with options, on top of a scene.
    let scene = Doc::quad().write_gltf(dir.path(), "scene");
    let options = LoadOptions {
        environment: Some(dir.path().join("missing.exr")),
        ..LoadOptions::default()
    };
    let o = options.clone();
    let r = timed("load with env", move || {
        pathlight_scene::load(Some(&scene), &o)
    });
    assert_err(r, "missing.exr", &["cannot open"]);
}

#[test]
fn environment_non_finite_texels_become_zero() {
    let dir = TempDir::new("env-nan");
    let img = image::Rgb32FImage::from_fn(8, 4, |x, y| match (x, y) {
        (1, 1) => image::Rgb([f32::NAN, 1.0, 1.0]),
        (2, 1) => image::Rgb([f32::INFINITY, 1.0, 1.0]),
        (3, 1) => image::Rgb([-5.0, 1.0, 1.0]),
        _ => image::Rgb([0.5, 0.5, 0.5]),
    });
    let p = dir.write("nan.exr", exr_bytes(img));
    let env = load_env(&p, 1.0, limits()).expect("loads");
    assert!(env
        .texels
        .iter()
        .all(|t| t.is_finite() && t.min_element() >= 0.0));
    assert_eq!(env.texels[8 + 1], glam::Vec3::new(0.0, 1.0, 1.0));
    assert_eq!(env.texels[8 + 3], glam::Vec3::new(0.0, 1.0, 1.0));
}

// ---------------------------------------------------------------------------------------------
// Whole-file sanity: the generated documents load as the tests above assume.

#[test]
fn generated_documents_are_valid() {
    let dir = TempDir::new("valid");
    for d in [Doc::triangle(), Doc::quad()] {
        for p in [d.write_gltf(dir.path(), "v"), d.write_glb(dir.path(), "v")] {
            let s = expect_ok(&p, limits());
            assert!(s.warnings.is_empty(), "{:?}", s.warnings);
            assert_eq!(s.instances.len(), 1);
            assert!(s.triangle_count() >= 1);
        }
    }
    let _ = Path::new("");
}

/// Regression: a B44-compressed EXR found by `cargo fuzz run env_exr` made exr 1.74's decoder
/// overflow a subtraction on its own thread (a panic that aborts the process). The workspace
/// builds exr with wrapping arithmetic, as the reference decoder has it; the file must load or
/// be refused, never abort.
/// The second, `env_exr-zip-huge-allocation.exr`, makes zune-inflate ask for an 8.8 GB zeroed
/// buffer (libFuzzer's malloc limit flags it; the pages are never touched) and is refused.
#[test]
fn fuzz_found_exr_files_do_not_abort() {
    for (name, must_fail) in [
        ("env_exr-b44-subtract-overflow.exr", false),
        ("env_exr-zip-huge-allocation.exr", true),
    ] {
        let artifact = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../fuzz/artifacts-found")
            .join(name);
        let bytes = std::fs::read(&artifact).expect("the fuzz artifact is in the repository");
        let dir = TempDir::new("fuzz-exr");
        let p = dir.write(name, &bytes);
        match load_env(&p, 1.0, limits()) {
            Err(e) => assert!(e.to_string().contains(name), "{e}"),
            Ok(_) => assert!(!must_fail, "{name} loaded"),
        }
    }
}
