//! Hand-built scenes for the render crate's integration tests.
#![allow(dead_code)]

use glam::{Mat4, Vec3, Vec4};
use pathlight_render::config::CameraConfig;
use pathlight_render::{Config, World};
use pathlight_scene::{Camera, Environment, Instance, Material, Mesh, Scene};

/// A unit sphere (subdivided octahedron with smooth normals) around `centre`.
pub fn sphere(material: u32, subdivisions: u32) -> Mesh {
    let mut positions = vec![Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z];
    let mut indices: Vec<[u32; 3]> = vec![
        [0, 2, 4],
        [2, 1, 4],
        [1, 3, 4],
        [3, 0, 4],
        [2, 0, 5],
        [1, 2, 5],
        [3, 1, 5],
        [0, 3, 5],
    ];
    for _ in 0..subdivisions {
        let mut next = Vec::new();
        let mut midpoint = std::collections::HashMap::new();
        let mut mid = |a: u32, b: u32, positions: &mut Vec<Vec3>| -> u32 {
            *midpoint.entry((a.min(b), a.max(b))).or_insert_with(|| {
                positions.push(((positions[a as usize] + positions[b as usize]) * 0.5).normalize());
                positions.len() as u32 - 1
            })
        };
        for [a, b, c] in indices {
            let ab = mid(a, b, &mut positions);
            let bc = mid(b, c, &mut positions);
            let ca = mid(c, a, &mut positions);
            next.extend([[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]);
        }
        indices = next;
    }
    Mesh {
        name: "sphere".into(),
        normals: Some(positions.clone()),
        positions,
        indices,
        material,
        ..Default::default()
    }
}

/// A faceted unit sphere above a 4x4 floor at y = -1 facing up, both of material 0: the white
/// furnace's objects. Flat shading: interpolated normals on a faceted sphere are not
/// energy-conserving (paths whose sampled direction falls below the true surface are dropped),
/// which would bias a furnace by ~0.2%.
pub fn ball_and_floor() -> Vec<Mesh> {
    let mut floor = quad(0, 2.0, 0.0);
    for p in &mut floor.positions {
        *p = Vec3::new(p.x, -1.0, p.y);
    }
    floor.normals = Some(vec![Vec3::Y; 4]);
    let mut ball = sphere(0, 3);
    ball.normals = None;
    vec![ball, floor]
}

/// A quad in the plane z = `z`, x and y in [-half, half], facing +Z, with UVs and tangents.
pub fn quad(material: u32, half: f32, z: f32) -> Mesh {
    Mesh {
        name: "quad".into(),
        positions: vec![
            Vec3::new(-half, -half, z),
            Vec3::new(half, -half, z),
            Vec3::new(half, half, z),
            Vec3::new(-half, half, z),
        ],
        normals: Some(vec![Vec3::Z; 4]),
        tangents: Some(vec![Vec4::new(1.0, 0.0, 0.0, 1.0); 4]),
        uv0: Some(vec![
            glam::Vec2::new(0.0, 1.0),
            glam::Vec2::new(1.0, 1.0),
            glam::Vec2::new(1.0, 0.0),
            glam::Vec2::new(0.0, 0.0),
        ]),
        indices: vec![[0, 1, 2], [0, 2, 3]],
        material,
        ..Default::default()
    }
}

/// A scene of `meshes` (one identity instance each) with `materials`, an optional constant
/// environment and a camera at `from` looking at the origin.
pub fn scene(meshes: Vec<Mesh>, materials: Vec<Material>, env: Option<Vec3>, from: Vec3) -> Scene {
    let instances = (0..meshes.len() as u32)
        .map(|mesh| Instance {
            mesh,
            transform: Mat4::IDENTITY,
            name: String::new(),
        })
        .collect();
    let mut scene = Scene {
        name: "test".into(),
        meshes,
        instances,
        materials,
        environment: env.map(Environment::constant),
        cameras: vec![Camera::look_at("test", from, Vec3::ZERO, Vec3::Y, 40.0)],
        ..Default::default()
    };
    scene.collect_emissive_triangles();
    scene
}

pub fn world(scene: Scene) -> World {
    World::new(scene, Default::default())
}

pub fn config(width: u32, height: u32, spp: u32) -> Config {
    Config {
        width,
        height,
        spp,
        ..Config::default()
    }
}

/// The built-in Cornell box, ready to render.
pub fn cornell() -> World {
    World::new(
        pathlight_scene::load(None, &Default::default()).unwrap(),
        Default::default(),
    )
}

/// Runs `f` on a pool of exactly `threads` workers.
pub fn in_pool<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
        .install(f)
}

/// BoxTextured (its base colour a texture) on a floor, under a dim constant sky and a dozen
/// random point lights.
pub fn textured() -> World {
    let dir = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/box-textured");
    let mut scene =
        pathlight_scene::load_file(&dir.join("BoxTextured.gltf"), &Default::default()).unwrap();
    let floor_material = scene.materials.len() as u32;
    scene
        .materials
        .push(Material::lambertian("floor", Vec3::new(0.6, 0.55, 0.5)));
    scene.meshes.push(quad(floor_material, 3.0, 0.0));
    scene.instances.push(Instance {
        mesh: scene.meshes.len() as u32 - 1,
        transform: Mat4::from_translation(Vec3::new(0.0, -0.5, 0.0))
            * Mat4::from_rotation_x(-std::f32::consts::FRAC_PI_2),
        name: "floor".into(),
    });
    scene.environment = Some(Environment::constant(Vec3::new(0.2, 0.25, 0.3)));
    scene.add_random_point_lights(12, 5, 1.0);
    scene.collect_emissive_triangles();
    World::new(scene, Default::default())
}

/// The textured scene's first view.
pub fn textured_view() -> CameraConfig {
    CameraConfig {
        look_from: Some([1.6, 1.1, 2.4]),
        look_at: Some([0.0, -0.1, 0.0]),
        fov_y: Some(45.0),
        ..CameraConfig::default()
    }
}
