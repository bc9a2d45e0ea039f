//! OBJ/MTL loading from disk: the real Cornell box, confinement to the scene's folder, textures.

use std::path::{Path, PathBuf};

use glam::{Vec3, Vec4};
use pathlight_scene::{cornell, load_file, obj, AlphaMode, Limits};

fn asset(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("assets/cornell-box")
        .join(name)
}

/// A fresh folder under the system's temporary folder, removed on drop.
struct TempDir(PathBuf);

impl TempDir {
    fn new(name: &str) -> Self {
        let dir =
            std::env::temp_dir().join(format!("pathlight-obj-test-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        Self(dir)
    }

    fn write(&self, name: &str, bytes: &[u8]) -> PathBuf {
        let path = self.0.join(name);
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(&path, bytes).unwrap();
        path
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// The light quad's corners as the file gives them (`## Object light`).
fn light_quad_from_file() -> Vec<Vec3> {
    let text = std::fs::read_to_string(asset("CornellBox-Original.obj")).unwrap();
    let after = text.split("## Object light").nth(1).unwrap();
    after
        .lines()
        .filter_map(|l| l.trim().strip_prefix("v"))
        .map(|v| {
            let n: Vec<f32> = v.split_whitespace().map(|x| x.parse().unwrap()).collect();
            Vec3::new(n[0], n[1], n[2])
        })
        .collect()
}

#[test]
fn the_real_cornell_box() {
    let path = asset("CornellBox-Original.obj");
    let s = load_file(&path, &Limits::default()).unwrap();
    assert!(s.warnings.is_empty(), "{:?}", s.warnings);
    assert_eq!(s.name, "CornellBox-Original.obj");
    assert_eq!(s.triangle_count(), 36);
    assert_eq!(s.materials.len(), 8);
    let mut names: Vec<&str> = s.materials.iter().map(|m| m.name.as_str()).collect();
    names.sort();
    assert_eq!(
        names,
        [
            "backWall",
            "ceiling",
            "floor",
            "leftWall",
            "light",
            "rightWall",
            "shortBox",
            "tallBox"
        ]
    );
    for m in &s.materials {
        assert_eq!(
            (m.metallic, m.specular),
            (0.0, 0.0),
            "{}: Lambertian",
            m.name
        );
        assert!(m.double_sided);
        assert_eq!(m.alpha_mode, AlphaMode::Opaque);
    }
    let red = s.materials.iter().find(|m| m.name == "leftWall").unwrap();
    assert_eq!(red.base_color, Vec4::new(0.63, 0.065, 0.05, 1.0));

    // The light: 2 triangles of the quad x in [-0.24, 0.23], z in [-0.22, 0.16] at y = 1.98.
    assert_eq!(s.emissive_triangles.len(), 2);
    let quad = light_quad_from_file();
    assert_eq!(quad.len(), 4);
    let quad_area = (quad[1] - quad[0]).cross(quad[3] - quad[0]).length();
    assert!((quad_area - 0.47 * 0.38).abs() < 1e-5, "{quad_area}");
    let area: f32 = s.emissive_triangles.iter().map(|t| t.area).sum();
    assert!((area - quad_area).abs() < 1e-5, "{area} vs {quad_area}");
    for t in &s.emissive_triangles {
        assert_eq!(t.radiance, Vec3::new(17.0, 12.0, 4.0));
        // OBJ emitters shine from their front face only; the quad's winding faces down.
        assert!(!t.two_sided);
        let power = std::f32::consts::PI * t.area * t.radiance;
        assert!((t.power - power).length() < 1e-4 * power.length());
    }
    let light = s.materials.iter().find(|m| m.name == "light").unwrap();
    assert_eq!(light.emissive, Vec3::new(17.0, 12.0, 4.0));
    assert_eq!(light.base_color, Vec4::new(0.78, 0.78, 0.78, 1.0));
    let b = s.bounds();
    assert!((b.min - Vec3::new(-1.02, 0.0, -1.04)).abs().max_element() < 1e-6);
    assert!((b.max - Vec3::new(1.0, 1.99, 0.99)).abs().max_element() < 1e-6);
}

#[test]
fn the_built_in_box_is_the_asset_plus_a_camera() {
    let disk = load_file(&asset("CornellBox-Original.obj"), &Limits::default()).unwrap();
    let builtin = cornell::cornell_box();
    assert_eq!(builtin.meshes, disk.meshes);
    assert_eq!(builtin.materials, disk.materials);
    assert_eq!(builtin.emissive_triangles, disk.emissive_triangles);
    assert_eq!(builtin.name, "built-in Cornell box");
    let cam = &builtin.cameras[0];
    assert!((cam.position() - Vec3::new(0.0, 1.0, 3.5)).length() < 1e-6);
    assert!((cam.forward() - Vec3::NEG_Z).length() < 1e-6);
    match cam.projection {
        pathlight_scene::Projection::Perspective { yfov, .. } => {
            assert!((yfov - 40.107f32.to_radians()).abs() < 1e-6)
        }
        p => panic!("{p:?}"),
    }
    // The copied asset is the shared scene, byte for byte.
    let shared =
        pathlight_core::shared_data::dir(env!("CARGO_MANIFEST_DIR")).join("scenes/CornellBox");
    for name in ["CornellBox-Original.obj", "CornellBox-Original.mtl"] {
        let original = shared.join(name);
        if pathlight_core::shared_data::present(&original) {
            let original = std::fs::read(original).unwrap();
            assert_eq!(std::fs::read(asset(name)).unwrap(), original, "{name}");
        }
    }
}

#[test]
fn libraries_outside_the_folder_are_refused() {
    let dir = TempDir::new("refuse");
    let secret = dir.write("secret.mtl", b"newmtl m\nKe 1 1 1\n");
    let quad = "v 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl m\nf 1 2 3\n";
    let cases = [
        "../secret.mtl".to_owned(),
        "../../etc/passwd".to_owned(),
        secret.display().to_string(),
    ];
    for lib in cases {
        let obj = dir.write("scene/a.obj", format!("mtllib {lib}\n{quad}").as_bytes());
        let s = obj::load(&obj, &Limits::default()).unwrap();
        assert!(
            s.warnings[0].contains("line 1: refused"),
            "{lib}: {:?}",
            s.warnings
        );
        assert!(!s.materials[0].is_emissive(), "{lib}: the secret was read");
        assert_eq!(s.materials[0].name, "default");
    }
    // A symbolic link inside the folder that leads out of it.
    #[cfg(unix)]
    {
        let link = dir.0.join("scene/link.mtl");
        std::os::unix::fs::symlink(&secret, &link).unwrap();
        let obj = dir.write("scene/b.obj", format!("mtllib link.mtl\n{quad}").as_bytes());
        let s = obj::load(&obj, &Limits::default()).unwrap();
        assert!(s.warnings[0].contains("refused"), "{:?}", s.warnings);
        assert!(!s.materials[0].is_emissive());
    }
}

#[test]
fn textures_on_disk_and_missing_ones() {
    let dir = TempDir::new("textures");
    let mut png = Vec::new();
    image::RgbaImage::from_pixel(4, 2, image::Rgba([10, 20, 30, 255]))
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .unwrap();
    dir.write("maps/wood.png", &png);
    dir.write(
        "mat/scene.mtl",
        b"newmtl wood\nKd 1 1 1\nmap_Kd ../maps/wood.png\nnewmtl gone\nmap_Kd ../maps/gone.png\n",
    );
    let obj = dir.write(
        "scene.obj",
        b"mtllib mat/scene.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\n\
          usemtl wood\nf 1/1 2/2 3/3\nusemtl gone\nf 1/1 3/3 2/2\n",
    );
    let s = load_file(&obj, &Limits::default()).unwrap();
    assert_eq!(s.path.as_deref(), Some(obj.as_path()));
    assert_eq!(s.textures.len(), 1);
    assert_eq!((s.textures[0].width(), s.textures[0].height()), (4, 2));
    assert!(s.materials[0].base_color_texture.is_some());
    assert!(s.materials[1].base_color_texture.is_none());
    assert_eq!(s.warnings.len(), 1, "{:?}", s.warnings);
    assert!(
        s.warnings[0].contains("line 5: the texture \"../maps/gone.png\" is not used"),
        "{:?}",
        s.warnings
    );
}

#[test]
fn files_over_the_size_limit_are_refused() {
    let dir = TempDir::new("size");
    let obj = dir.write("big.obj", &b"v 0 0 0\n".repeat(1000));
    let limits = Limits {
        max_file_bytes: 1000,
        ..Limits::default()
    };
    let e = obj::load(&obj, &limits).unwrap_err();
    assert!(e.to_string().contains("over the limit"), "{e}");
    // A material library over it is not read, like a missing one: a warning, default materials.
    dir.write("big.mtl", &b"# padding\n".repeat(200));
    let obj = dir.write("small.obj", b"mtllib big.mtl\n");
    let s = obj::load(&obj, &limits).unwrap();
    assert!(
        s.warnings
            .iter()
            .any(|w| w.contains("big.mtl") && w.contains("over the limit")),
        "{:?}",
        s.warnings
    );
}

#[test]
fn a_generated_grid_loads_with_shared_vertices() {
    let n = 100;
    let mut text = String::new();
    for y in 0..=n {
        for x in 0..=n {
            text.push_str(&format!("v {x} {y} 0\nvn 0 0 1\n"));
        }
    }
    for y in 0..n {
        for x in 0..n {
            let i = y * (n + 1) + x + 1;
            let j = i + n + 1;
            text.push_str(&format!(
                "f {i}//{i} {}//{} {}//{} {j}//{j}\n",
                i + 1,
                i + 1,
                j + 1,
                j + 1
            ));
        }
    }
    let dir = TempDir::new("grid");
    let obj = dir.write("grid.obj", text.as_bytes());
    let s = obj::load(&obj, &Limits::default()).unwrap();
    assert_eq!(s.triangle_count(), 2 * n as u64 * n as u64);
    assert_eq!(s.meshes[0].positions.len(), (n + 1) * (n + 1));
    assert!(s.warnings.is_empty());
}
