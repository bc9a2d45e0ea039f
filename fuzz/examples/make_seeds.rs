//! Writes the seed corpora of the fuzz targets: `cargo run --example make_seeds -- SCENES OUT`
//! where SCENES is the shared scenes folder (holding CornellBox/, KHR_lights_punctual_playcanvas/,
//! BoxTextured_pbrSpecularGlossiness/) and OUT the corpus folder (fuzz/corpus). Run by seed.sh.
//! Everything else (HDR, EXR, PNG, JPEG) is generated here.

use std::io::Cursor;
use std::path::{Path, PathBuf};

use base64::Engine;
use serde_json::Value;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.len() != 3 {
        eprintln!("usage: make_seeds SCENES_DIR CORPUS_DIR");
        std::process::exit(2);
    }
    let scenes = PathBuf::from(&args[1]);
    let out = PathBuf::from(&args[2]);
    gltf_and_glb(&scenes, &out);
    obj(&scenes, &out);
    env_hdr(&out);
    env_exr(&out);
    texture(&scenes, &out);
}

fn write(out: &Path, target: &str, name: &str, bytes: &[u8]) {
    let dir = out.join(target);
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join(name), bytes).unwrap();
    println!("{target}/{name}: {} bytes", bytes.len());
}

fn read(path: &Path) -> Vec<u8> {
    std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn data_uri(mime: &str, bytes: &[u8]) -> String {
    format!(
        "data:{mime};base64,{}",
        base64::engine::general_purpose::STANDARD.encode(bytes)
    )
}

fn json(v: &Value) -> Vec<u8> {
    serde_json::to_vec(v).unwrap()
}

fn gltf_and_glb(scenes: &Path, out: &Path) {
    // Cornell box: buffer renamed to the in-memory "a.bin" (the same bytes), inlined, and GLB.
    let cornell_dir = scenes.join("CornellBox");
    let bin = read(&cornell_dir.join("CornellBox-Original.bin"));
    let mut doc: Value =
        serde_json::from_slice(&read(&cornell_dir.join("CornellBox-Original.gltf"))).unwrap();
    doc["buffers"][0]["uri"] = "a.bin".into();
    write(out, "gltf", "cornell-a-bin.gltf", &json(&doc));
    doc["buffers"][0]["uri"] = data_uri("application/octet-stream", &bin).into();
    write(out, "gltf", "cornell-data-uri.gltf", &json(&doc));
    doc["buffers"][0].as_object_mut().unwrap().remove("uri");
    let glb = pathlight_scene::gltf::glb::write(&json(&doc), Some(&bin));
    write(out, "gltf", "cornell.glb", &glb);
    write(out, "glb", "cornell.glb", &glb);

    // KHR_lights_punctual GLBs as they are.
    for name in ["Lights.glb", "geometry-camera-light.glb"] {
        let bytes = read(&scenes.join("KHR_lights_punctual_playcanvas").join(name));
        write(out, "gltf", name, &bytes);
        write(out, "glb", name, &bytes);
    }

    // BoxTextured: buffer inlined, image renamed to the in-memory "t.png" / inlined.
    let box_dir = scenes.join("BoxTextured_pbrSpecularGlossiness");
    let box_bin = read(&box_dir.join("BoxTextured0.bin"));
    let png = read(&box_dir.join("CesiumLogoFlat.png"));
    let mut doc: Value = serde_json::from_slice(&read(&box_dir.join("BoxTextured.gltf"))).unwrap();
    doc["buffers"][0]["uri"] = data_uri("application/octet-stream", &box_bin).into();
    doc["images"][0]["uri"] = "t.png".into();
    write(out, "gltf", "box-textured-t-png.gltf", &json(&doc));
    doc["images"][0]["uri"] = data_uri("image/png", &png).into();
    write(out, "gltf", "box-textured-data-uri.gltf", &json(&doc));

    // A minimal document, a few bytes for the mutator to grow from.
    write(out, "gltf", "minimal.gltf", br#"{"asset":{"version":"2.0"}}"#);
    write(out, "glb", "minimal.glb", &pathlight_scene::gltf::glb::write(br#"{"asset":{"version":"2.0"}}"#, Some(&[0; 8])));
}

fn obj(scenes: &Path, out: &Path) {
    let dir = scenes.join("CornellBox");
    let obj = String::from_utf8(read(&dir.join("CornellBox-Original.obj"))).unwrap();
    let obj = obj.replace("mtllib CornellBox-Original.mtl", "mtllib a.mtl");
    let mtl = read(&dir.join("CornellBox-Original.mtl"));
    // Without a NUL the target uses the Cornell library as "a.mtl".
    write(out, "obj", "cornell.obj", obj.as_bytes());
    let mut with_mtl = obj.clone().into_bytes();
    with_mtl.push(0);
    with_mtl.extend_from_slice(&mtl);
    write(out, "obj", "cornell-with-mtl.obj", &with_mtl);

    // A textured, smoothed quad using every index form, and a library with a texture.
    let quad = "mtllib a.mtl\no quad\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n\
                vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\ns 1\nusemtl tex\n\
                f 1/1/1 2/2/1 3/3/1 4/4/1\nf -4//1 -3//1 -2//1\nf 1/1 3/3 4/4\ng g2\nusemtl light\nf 1 2 3\n";
    let lib = "newmtl tex\nKd 1 1 1\nKs 0.1 0.1 0.1\nNs 100\nd 1\nillum 2\nmap_Kd t.png\nbump -bm 0.5 t.png\n\
               newmtl light\nKd 0 0 0\nKe 10 10 10\nNi 1.5\nTf 1 1 1\n";
    let mut textured = quad.as_bytes().to_vec();
    textured.push(0);
    textured.extend_from_slice(lib.as_bytes());
    write(out, "obj", "textured-quad.obj", &textured);
}

fn encode(img: image::DynamicImage, format: image::ImageFormat) -> Vec<u8> {
    let mut buf = Cursor::new(Vec::new());
    img.write_to(&mut buf, format).unwrap();
    buf.into_inner()
}

fn rgb32f(w: u32, h: u32) -> image::DynamicImage {
    let img = image::Rgb32FImage::from_fn(w, h, |x, y| {
        image::Rgb([x as f32 / w as f32 * 4.0, y as f32 / h as f32, 0.25])
    });
    image::DynamicImage::ImageRgb32F(img)
}

fn env_hdr(out: &Path) {
    // 8 wide: run-length encoded scanlines; 4 wide: flat; 40 wide: RLE with real runs.
    for (w, h) in [(8, 4), (4, 2), (40, 2)] {
        write(out, "env_hdr", &format!("{w}x{h}.hdr"), &encode(rgb32f(w, h), image::ImageFormat::Hdr));
    }
}

fn env_exr(out: &Path) {
    use exr::prelude::*;
    write(out, "env_exr", "image-crate-8x4.exr", &encode(rgb32f(8, 4), image::ImageFormat::OpenExr));
    let compressions = [
        ("none", Compression::Uncompressed),
        ("rle", Compression::RLE),
        ("zips", Compression::ZIP1),
        ("zip", Compression::ZIP16),
        ("piz", Compression::PIZ),
        ("pxr24", Compression::PXR24),
        ("b44", Compression::B44),
    ];
    for (name, compression) in compressions {
        for tiled in [false, true] {
            let blocks = if tiled {
                Blocks::Tiles(Vec2(4, 4))
            } else {
                Blocks::ScanLines
            };
            let encoding = Encoding { compression, blocks, line_order: LineOrder::Increasing };
            let layout = if tiled { "tiled" } else { "lines" };
            // Half floats.
            let layer = Layer::new(
                (8, 4),
                LayerAttributes::named("env"),
                encoding,
                SpecificChannels::rgb(|p: Vec2<usize>| {
                    (f16::from_f32(p.x() as f32), f16::from_f32(p.y() as f32 * 0.5), f16::from_f32(0.25))
                }),
            );
            let mut buf = Cursor::new(Vec::new());
            match Image::from_layer(layer).write().to_buffered(&mut buf) {
                Ok(()) => write(out, "env_exr", &format!("half-{name}-{layout}.exr"), buf.get_ref()),
                Err(e) => eprintln!("skipped half {name} {layout}: {e}"),
            }
            // 32-bit floats with alpha.
            let layer = Layer::new(
                (8, 4),
                LayerAttributes::named("env"),
                encoding,
                SpecificChannels::rgba(|p: Vec2<usize>| (p.x() as f32, p.y() as f32, 1.5f32, 1.0f32)),
            );
            let mut buf = Cursor::new(Vec::new());
            match Image::from_layer(layer).write().to_buffered(&mut buf) {
                Ok(()) => write(out, "env_exr", &format!("float-{name}-{layout}.exr"), buf.get_ref()),
                Err(e) => eprintln!("skipped float {name} {layout}: {e}"),
            }
        }
    }
}

fn texture(scenes: &Path, out: &Path) {
    use image::{DynamicImage, ImageFormat};
    let rgba = image::RgbaImage::from_fn(8, 8, |x, y| image::Rgba([x as u8 * 32, y as u8 * 32, 128, 200]));
    let img = DynamicImage::ImageRgba8(rgba);
    write(out, "texture", "rgba8.png", &encode(img.clone(), ImageFormat::Png));
    write(out, "texture", "rgb8.png", &encode(DynamicImage::ImageRgb8(img.to_rgb8()), ImageFormat::Png));
    write(out, "texture", "l8.png", &encode(DynamicImage::ImageLuma8(img.to_luma8()), ImageFormat::Png));
    write(out, "texture", "la8.png", &encode(DynamicImage::ImageLumaA8(img.to_luma_alpha8()), ImageFormat::Png));
    write(out, "texture", "rgb16.png", &encode(DynamicImage::ImageRgb16(img.to_rgb16()), ImageFormat::Png));
    write(out, "texture", "rgb8.jpg", &encode(DynamicImage::ImageRgb8(img.to_rgb8()), ImageFormat::Jpeg));
    write(out, "texture", "l8.jpg", &encode(DynamicImage::ImageLuma8(img.to_luma8()), ImageFormat::Jpeg));
    let logo = read(&scenes.join("BoxTextured_pbrSpecularGlossiness").join("CesiumLogoFlat.png"));
    write(out, "texture", "cesium-logo.png", &logo);
}
