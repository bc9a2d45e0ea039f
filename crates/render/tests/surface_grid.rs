//! Seed 002's shading grids on the shared scenes (and the built-in Cornell box): every
//! triangle of every instance has its grid; the cells named by different triangles, sides,
//! levels or places have different keys; and the surface the cache shades a cell at is the one
//! a ray to that point reports (brute force: the ray traced against the scene). The grids'
//! build time and memory are printed (`--nocapture`) for BENCHMARKS.md.

use std::collections::HashMap;
use std::time::Instant;

use pathlight_accel::{Hit, Ray};
use pathlight_core::rng::Rng;
use pathlight_render::frame::texture_cache::surface_grid::{Cell, SurfaceGrids};
use pathlight_render::World;

/// The shared scenes (relative to `scenes/`), each loaded as `pathlight info` loads it.
const SCENES: [&str; 12] = [
    "CornellBox/CornellBox-Original.obj",
    "BoxTextured_pbrSpecularGlossiness/BoxTextured.gltf",
    "DamagedHelmet/glTF/DamagedHelmet.gltf",
    "KHR_lights_punctual_playcanvas/Lights.glb",
    "KHR_lights_punctual_playcanvas/geometry-camera-light.glb",
    "NormalTangentTest/NormalTangentTest.glb",
    "AlphaBlendModeTest_trimesh-reexport/AlphaBlendModeTest.glb",
    "extras_meshopt/dream-apartment.glb",
    "extras_meshopt/stanford-bunny.glb",
    "hotel-room-lotus-carpet/scene.glb",
    "japanese-bridge-garden/scene.glb",
    "sd-macross-city-standoff-diorama/scene.glb",
];

/// Cells checked per scene (triangles drawn at random when there are more).
const SAMPLES: usize = 4000;

/// Checks one world's grids; returns (triangles, cells checked, rays that report the cell's
/// surface: its own triangle, or a coplanar one through the same point).
fn check(name: &str, world: &World) -> (usize, usize, usize) {
    let t = Instant::now();
    let grids = SurfaceGrids::new(world);
    let ms = t.elapsed().as_secs_f64() * 1e3;
    let scene = &world.scene;
    // Every triangle of every instance has its grid.
    let triangles: usize = scene
        .instances
        .iter()
        .map(|i| scene.meshes[i.mesh as usize].indices.len())
        .sum();
    assert_eq!(grids.triangles(), triangles, "{name}");
    let cells: f64 = scene
        .instances
        .iter()
        .enumerate()
        .flat_map(|(i, inst)| {
            let grids = &grids;
            (0..scene.meshes[inst.mesh as usize].indices.len())
                .map(move |t| 4f64.powi(grids.exponent(i as u32, t as u32) as i32))
        })
        .sum();
    println!(
        "{name}: {triangles} triangles over instances, grids built in {ms:.1} ms, {} bytes; \
         base cell {:.3e} scene units; {cells:.3e} base cells",
        grids.bytes(),
        grids.base_cell
    );
    let mut rng = Rng::new(7, 0);
    let mut keys: HashMap<u64, Cell> = HashMap::new();
    let (mut checked, mut agree) = (0, 0);
    let all: Vec<(u32, u32)> = scene
        .instances
        .iter()
        .enumerate()
        .flat_map(|(i, inst)| {
            (0..scene.meshes[inst.mesh as usize].indices.len() as u32).map(move |t| (i as u32, t))
        })
        .collect();
    for k in 0..SAMPLES.min(all.len()) {
        let (instance, triangle) = if all.len() <= SAMPLES {
            all[k]
        } else {
            all[(rng.next_f32() * all.len() as f32) as usize % all.len()]
        };
        // A random point of the triangle, seen from a random side, at a random level.
        let (mut u, mut v) = (rng.next_f32(), rng.next_f32());
        if u + v > 1.0 {
            (u, v) = (1.0 - u, 1.0 - v);
        }
        let e = grids.exponent(instance, triangle);
        let level = (rng.next_f32() * (e as f32 + 1.0)) as u8;
        let hit = Hit {
            t: 1.0,
            u,
            v,
            instance,
            triangle,
        };
        let probe = grids.surface(
            world,
            &Cell {
                instance,
                triangle,
                back: rng.next_f32() < 0.5,
                level: 0,
                square: Default::default(),
                upper: false,
            },
        );
        let toward = -probe.ng;
        let surface = world.surface(&Ray::new(probe.p - toward, toward), &hit);
        let cell = grids.cell_at(&surface, level);
        // No two cells share a key.
        if let Some(other) = keys.insert(cell.key(), cell) {
            assert_eq!(other, cell, "{name}: two cells with one key");
        }
        // The surface at the cell's centroid is in the cell and on its side.
        let s = grids.surface(world, &cell);
        assert_eq!(grids.cell_at(&s, level), cell, "{name}: {cell:?}");
        let centroid = grids.centroid(&cell);
        assert!((s.bary - centroid).length() < 1e-5, "{name}");
        // A ray from the cell's side to the centroid reports that surface, where nothing
        // nearer covers it.
        let lift = 4.0 * grids.base_cell.max(1e-5 * s.p.abs().max_element());
        let ray = Ray::new(s.p + s.ng * lift, -s.ng);
        checked += 1;
        let Some(h) = world.accel.intersect(&ray) else {
            panic!("{name}: the ray to {cell:?} hit nothing");
        };
        let r = world.surface(&ray, &h);
        let scale = 1.0 + s.p.abs().max_element();
        let same_point = (r.p - s.p).length() < 1e-4 * scale && (r.ng - s.ng).length() < 1e-3;
        if (h.instance, h.triangle) == (instance, triangle) {
            agree += 1;
            assert!(same_point, "{name}: {cell:?}: {} vs {}", r.p, s.p);
            // The intersector's barycentrics are as precise as the scene's coordinates: on a
            // tiny triangle they differ by more, and the shading normal with them (at most by
            // the difference of the corners' normals, 2).
            let db = (r.bary - s.bary).length();
            assert!(
                (r.ns - s.ns).length() < 1e-3 + 4.0 * db,
                "{name}: {} vs {} ({db})",
                r.ns,
                s.ns
            );
            assert_eq!(r.front, s.front, "{name}");
        } else if same_point {
            // Another triangle through the same point with the same normal (a coplanar
            // overlap in the mesh): the same surface.
            agree += 1;
        }
    }
    (triangles, checked, agree)
}

#[test]
fn every_triangle_has_its_cells_and_each_cell_its_surface() {
    let cornell = World::new(
        pathlight_scene::load(None, &Default::default()).unwrap(),
        Default::default(),
    );
    let (_, checked, agree) = check("built-in Cornell box", &cornell);
    println!("  {agree} of {checked} rays to a cell's centroid report its surface");
    assert!(
        agree * 10 >= checked * 9,
        "the Cornell box: {agree} of {checked}"
    );
    let dir = pathlight_core::shared_data::dir(env!("CARGO_MANIFEST_DIR")).join("scenes");
    for rel in SCENES {
        let path = dir.join(rel);
        if !pathlight_core::shared_data::present(&path) {
            continue;
        }
        let scene = pathlight_scene::load(Some(&path), &Default::default()).unwrap();
        let world = World::new(scene, Default::default());
        let (_, checked, agree) = check(rel, &world);
        println!("  {agree} of {checked} rays to a cell's centroid report its surface");
        // Most rays reach their own triangle: the others start inside another surface or
        // behind a nearer one (coplanar or nested geometry).
        assert!(agree * 10 >= checked * 9, "{rel}: {agree} of {checked}");
    }
}

/// A hit's cell follows its footprint: a wall twice as far is shaded one level coarser, and
/// `lod_bias` moves every level by its amount.
#[test]
fn the_cells_level_follows_the_footprint() {
    use glam::Vec3;
    use pathlight_render::config::CameraConfig;
    use pathlight_render::frame::texture_cache::footprint::Footprint;
    use pathlight_render::Config;
    let world = World::new(
        pathlight_scene::load(None, &Default::default()).unwrap(),
        Default::default(),
    );
    let grids = SurfaceGrids::new(&world);
    // The Cornell box's back wall (z = -1.04) seen head on from two distances.
    let level_at = |z: f32, bias: f32, area: bool| {
        let config = Config {
            width: 64,
            height: 64,
            camera: CameraConfig {
                look_from: Some([0.0, 1.7, z]),
                look_at: Some([0.0, 1.7, -1.04]),
                fov_y: Some(10.0),
                ..CameraConfig::default()
            },
            ..Config::default()
        };
        let camera = config.render_camera(&world);
        let ray = camera.ray(glam::Vec2::new(32.0, 32.0), glam::Vec2::splat(0.5));
        let hit = world.accel.intersect(&ray.ray).unwrap();
        let s = world.surface(&ray.ray, &hit);
        assert!((s.ng - Vec3::Z).length() < 1e-3, "the back wall: {}", s.ng);
        let f = Footprint::at(&world, &ray, &s).unwrap();
        grids.cell(&s, Some(&f), bias, area).level
    };
    // Eq. 1's measure and the area measure alike.
    for area in [false, true] {
        let (near, far) = (level_at(0.96, 0.0, area), level_at(2.96, 0.0, area));
        assert_eq!(far, near + 1, "{near} -> {far}");
        assert_eq!(level_at(0.96, 2.0, area), near + 2);
        assert_eq!(level_at(0.96, -50.0, area), 0);
    }
}
