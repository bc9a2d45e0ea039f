//! How large the visible triangles are against a pixel's footprint (seed 002: per-triangle
//! shading grids only reuse shading within a triangle, so the share of pixels whose triangle
//! is smaller than their footprint decides how the cache's filter must reach across them).
//!
//! ```sh
//! cargo run --release -p pathlight-render --example footprints -- SCENE WIDTH HEIGHT \
//!     [FROM_X,FROM_Y,FROM_Z AT_X,AT_Y,AT_Z FOV_DEGREES]
//! ```
//! (no scene: `-` for the built-in Cornell box). Prints, over the pixels whose centre ray hits
//! something: the share whose triangle's area is below 1, 4 and 16 pixel footprints, the
//! median of the triangle's area over the footprint's, and the distinct triangles seen with the
//! share of them below one footprint.

use std::collections::HashMap;

use glam::Vec2;
use pathlight_render::config::CameraConfig;
use pathlight_render::frame::texture_cache::footprint::Footprint;
use pathlight_render::{Config, World};

fn triple(s: &str) -> [f32; 3] {
    let v: Vec<f32> = s.split(',').map(|x| x.parse().expect("a number")).collect();
    [v[0], v[1], v[2]]
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let path = (args[0] != "-").then(|| std::path::PathBuf::from(&args[0]));
    let (width, height): (u32, u32) = (args[1].parse().unwrap(), args[2].parse().unwrap());
    let mut camera = CameraConfig::default();
    if args.len() >= 6 {
        camera.look_from = Some(triple(&args[3]));
        camera.look_at = Some(triple(&args[4]));
        camera.up = Some([0.0, 1.0, 0.0]);
        camera.fov_y = Some(args[5].parse().unwrap());
    }
    let scene = pathlight_scene::load(path.as_deref(), &Default::default()).expect("a scene");
    let world = World::new(scene, Default::default());
    let config = Config {
        width,
        height,
        camera,
        ..Config::default()
    };
    let cam = config.render_camera(&world);
    let mut ratios = Vec::new();
    let mut seen: HashMap<(u32, u32), f32> = HashMap::new();
    for y in 0..height {
        for x in 0..width {
            let ray = cam.ray(Vec2::new(x as f32 + 0.5, y as f32 + 0.5), Vec2::splat(0.5));
            let Some(hit) = world.accel.intersect(&ray.ray) else {
                continue;
            };
            let s = world.surface(&ray.ray, &hit);
            let Some(f) = Footprint::at(&world, &ray, &s) else {
                continue;
            };
            let pixel = f.dpdx.cross(f.dpdy).length();
            let [a, b, c] = world.scene.world_triangle(s.instance, s.triangle);
            let area = 0.5 * (b - a).cross(c - a).length();
            if pixel > 0.0 && area.is_finite() {
                let r = area / pixel;
                ratios.push(r);
                seen.insert((s.instance, s.triangle), r);
            }
        }
    }
    ratios.sort_by(f32::total_cmp);
    let n = ratios.len().max(1) as f32;
    let below = |k: f32| ratios.iter().filter(|&&r| r < k).count() as f32 / n;
    let small = seen.values().filter(|&&r| r < 1.0).count() as f32 / seen.len().max(1) as f32;
    println!(
        "{} {}x{}: {} pixels hit; triangle below 1 / 4 / 16 footprints: {:.1}% / {:.1}% / {:.1}%; \
         median triangle / footprint {:.1}; {} triangles seen, {:.1}% below one footprint",
        args[0],
        width,
        height,
        ratios.len(),
        100.0 * below(1.0),
        100.0 * below(4.0),
        100.0 * below(16.0),
        ratios.get(ratios.len() / 2).copied().unwrap_or(0.0),
        seen.len(),
        100.0 * small
    );
}
