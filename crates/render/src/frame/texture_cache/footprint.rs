//! A camera ray's footprint at its first hit, from ray differentials (Igehy 1999), and the
//! texture-space level of detail it asks for (seed 002, the texture-space shading cache):
//!
//! - the rays through the neighbouring pixels (one pixel right, one down; the same lens point)
//!   are carried to the plane of the hit, which gives the hit's world-space derivatives
//!   `dp/dx`, `dp/dy` along the film;
//! - their projections on the hit triangle give the derivatives of its barycentric
//!   coordinates (`b1`, `b2`: the weights of corners 1 and 2, the triangle's own unique
//!   parameterisation, on which the cache lays its per-triangle grids) and of its first texture
//!   coordinates, where the mesh has them;
//! - Eq. 1, `l = log2 min(w |du/dx|, h |du/dy|)` for a grid of base resolution `w x h` over
//!   `u` (here the barycentrics), is the level at which a grid cell is about a pixel, biased to
//!   the finer of the two directions; the cache adds its `lod_bias` and takes
//!   `floor(l + bias)`, clamped to the grid's levels ([`Level`]);
//! - Eq. 2 quantises `u` to the centre of its cell at that level ([`Level::cell`]).
//!
//! The differential rays meet the hit's tangent plane (the geometric normal's), so the
//! derivatives are exact on flat triangles and first-order elsewhere; a ray that grazes the
//! plane (or an orthographic camera's parallel rays at a plane that contains them) gives no
//! footprint.

use glam::{UVec2, Vec2, Vec3};

use crate::camera::CameraRay;
use crate::surface::Surface;
use crate::world::World;

/// Where the neighbouring pixels' rays meet the plane of a hit, as derivatives along the film.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Footprint {
    /// World-space derivatives of the hit point along the film's x and y (per pixel).
    pub dpdx: Vec3,
    pub dpdy: Vec3,
    /// Derivatives of the barycentric coordinates `(b1, b2)`.
    pub dbdx: Vec2,
    pub dbdy: Vec2,
    /// Derivatives of the first texture coordinates (zero where the mesh has none).
    pub duvdx: Vec2,
    pub duvdy: Vec2,
}

/// Where a ray `origin + t direction` meets the plane through `p` with normal `n` (`None` when
/// parallel to it or behind the origin).
#[inline]
fn on_plane(origin: Vec3, direction: Vec3, p: Vec3, n: Vec3) -> Option<Vec3> {
    let denom = n.dot(direction);
    if denom.abs() < 1e-12 {
        return None;
    }
    let t = n.dot(p - origin) / denom;
    (t.is_finite() && t > 0.0).then(|| origin + direction * t)
}

impl Footprint {
    /// The footprint of camera ray `ray` at its first hit `surface` in `world`.
    pub fn at(world: &World, ray: &CameraRay, surface: &Surface) -> Option<Self> {
        let (p, n) = (surface.p, surface.ng);
        let px = on_plane(ray.dx_origin, ray.dx_direction, p, n)?;
        let py = on_plane(ray.dy_origin, ray.dy_direction, p, n)?;
        let (dpdx, dpdy) = (px - p, py - p);
        let scene = &world.scene;
        let [a, b, c] = scene.world_triangle(surface.instance, surface.triangle);
        let mesh = &scene.meshes[scene.instances[surface.instance as usize].mesh as usize];
        let idx = mesh.indices[surface.triangle as usize];
        // dp = db1 e1 + db2 e2, solved in the triangle's plane (least squares on the Gram
        // matrix, exact for dp in the plane).
        let (e1, e2) = (b - a, c - a);
        let (g11, g12, g22) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
        let det = g11 * g22 - g12 * g12;
        if !(det.abs() > f32::MIN_POSITIVE && det.is_finite()) {
            return None;
        }
        let bary = |dp: Vec3| {
            let (r1, r2) = (e1.dot(dp), e2.dot(dp));
            Vec2::new(g22 * r1 - g12 * r2, g11 * r2 - g12 * r1) / det
        };
        let (dbdx, dbdy) = (bary(dpdx), bary(dpdy));
        let uv = |db: Vec2| {
            mesh.uv0.as_ref().map_or(Vec2::ZERO, |uv| {
                let [t0, t1, t2] = idx.map(|i| uv[i as usize]);
                (t1 - t0) * db.x + (t2 - t0) * db.y
            })
        };
        let f = Self {
            dpdx,
            dpdy,
            dbdx,
            dbdy,
            duvdx: uv(dbdx),
            duvdy: uv(dbdy),
        };
        [f.dpdx, f.dpdy].iter().all(|v| v.is_finite()).then_some(f)
    }

    /// Eq. 1: the continuous level of detail of a grid of base resolution `w x h` over the
    /// barycentric coordinates: `log2 min(w |db/dx|, h |db/dy|)` (0: a cell of the base grid
    /// per pixel; each level up halves the resolution).
    pub fn level(&self, w: f32, h: f32) -> f32 {
        (w * self.dbdx.length()).min(h * self.dbdy.length()).log2()
    }

    /// The level at which a cell of a grid of base resolution `w x h` over the barycentrics
    /// covers about a pixel's area: `log2 sqrt(w h |db/dx x db/dy|)`. Eq. 1 takes the finer
    /// direction, which on a long thin triangle (whose barycentric cells are slivers) gives
    /// cells far smaller than a pixel across; this measure keeps the cells shaded per pixel
    /// near one whatever the triangle's shape. Equal to Eq. 1's where the footprint is square
    /// in the grid.
    pub fn area_level(&self, w: f32, h: f32) -> f32 {
        0.5 * (w * h * self.dbdx.perp_dot(self.dbdy).abs()).log2()
    }
}

/// A grid's level of detail: which of its levels a footprint shades, and the cells there.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Level {
    /// The level (0: the base resolution).
    pub level: u32,
    /// The grid's resolution at that level, at least one cell each way.
    pub width: u32,
    pub height: u32,
}

impl Level {
    /// The level of continuous level `l` (Eq. 1) biased by `bias` levels (towards coarser
    /// grids when positive): `floor(l + bias)`, clamped to `0 ..= levels - 1` (a footprint
    /// smaller than a base cell shades the base grid; NaN, from a degenerate footprint, too),
    /// for a grid of base resolution `width x height`.
    pub fn of(l: f32, bias: f32, width: u32, height: u32, levels: u32) -> Self {
        let top = levels.max(1) - 1;
        let level = match (l + bias).floor() {
            x if x >= top as f32 => top,
            x if x > 0.0 => x as u32,
            _ => 0,
        };
        Self {
            level,
            width: (width >> level).max(1),
            height: (height >> level).max(1),
        }
    }

    /// Eq. 2: the cell of `u` (in `[0, 1]^2`, clamped) at this level, and `u` quantised to its
    /// centre, `(floor(u w_i) + 0.5) / w_i` (the same in v).
    pub fn cell(&self, u: Vec2) -> (UVec2, Vec2) {
        let size = Vec2::new(self.width as f32, self.height as f32);
        let cell = (u.clamp(Vec2::ZERO, Vec2::ONE) * size)
            .floor()
            .min(size - Vec2::ONE)
            .max(Vec2::ZERO);
        (cell.as_uvec2(), (cell + Vec2::splat(0.5)) / size)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{Mat4, Vec4};
    use pathlight_scene::{Camera as SceneCamera, Instance, Material, Mesh, Scene};

    /// A square of side `2 half` in the plane z = 0 facing +Z (two triangles, with UVs),
    /// seen by a camera on the z axis at distance `distance`, 64x64 pixels, 40 degrees.
    fn square(distance: f32, half: f32) -> (World, crate::camera::Camera) {
        let mesh = Mesh {
            name: "square".into(),
            positions: vec![
                Vec3::new(-half, -half, 0.0),
                Vec3::new(half, -half, 0.0),
                Vec3::new(half, half, 0.0),
                Vec3::new(-half, half, 0.0),
            ],
            normals: Some(vec![Vec3::Z; 4]),
            uv0: Some(vec![
                Vec2::new(0.0, 1.0),
                Vec2::new(1.0, 1.0),
                Vec2::new(1.0, 0.0),
                Vec2::new(0.0, 0.0),
            ]),
            tangents: Some(vec![Vec4::new(1.0, 0.0, 0.0, 1.0); 4]),
            indices: vec![[0, 1, 2], [0, 2, 3]],
            material: 0,
            ..Default::default()
        };
        let mut scene = Scene {
            name: "square".into(),
            meshes: vec![mesh],
            instances: vec![Instance {
                mesh: 0,
                transform: Mat4::IDENTITY,
                name: String::new(),
            }],
            materials: vec![Material::lambertian("grey", Vec3::splat(0.5))],
            ..Default::default()
        };
        scene.collect_emissive_triangles();
        let world = World::new(scene, Default::default());
        let cam = SceneCamera::look_at(
            "c",
            Vec3::new(0.0, 0.0, distance),
            Vec3::ZERO,
            Vec3::Y,
            40.0,
        );
        (world, crate::camera::Camera::new(&cam, 64, 64))
    }

    /// The footprint of the ray through film position `film`, and its hit's surface.
    fn footprint_at(
        world: &World,
        camera: &crate::camera::Camera,
        film: Vec2,
    ) -> (Footprint, Surface) {
        let ray = camera.ray(film, Vec2::splat(0.5));
        let hit = world
            .accel
            .intersect(&ray.ray)
            .expect("the ray hits the square");
        let surface = world.surface(&ray.ray, &hit);
        (Footprint::at(world, &ray, &surface).unwrap(), surface)
    }

    #[test]
    fn the_level_rises_by_one_at_twice_the_distance() {
        for film in [Vec2::new(32.0, 32.0), Vec2::new(40.5, 21.25)] {
            let (w1, c1) = square(2.0, 10.0);
            let (w2, c2) = square(4.0, 10.0);
            let (f1, _) = footprint_at(&w1, &c1, film);
            let (f2, _) = footprint_at(&w2, &c2, film);
            for res in [64.0, 1024.0] {
                let (l1, l2) = (f1.level(res, res), f2.level(res, res));
                assert!((l2 - l1 - 1.0).abs() < 1e-3, "{film}: {l1} -> {l2}");
            }
        }
    }

    /// The derivatives are those of the neighbouring pixels' own hits (brute force: their
    /// rays traced against the scene), exact on a flat square.
    #[test]
    fn derivatives_match_the_neighbouring_pixels_hits() {
        let (world, camera) = square(3.0, 2.0);
        let film = Vec2::new(29.3, 35.7);
        let (f, s) = footprint_at(&world, &camera, film);
        for (step, dp, db, duv) in [
            (Vec2::X, f.dpdx, f.dbdx, f.duvdx),
            (Vec2::Y, f.dpdy, f.dbdy, f.duvdy),
        ] {
            let (_, n) = footprint_at(&world, &camera, film + step);
            assert!((n.p - s.p - dp).length() < 1e-5, "{dp} vs {}", n.p - s.p);
            // Both points lie on the same triangle here (checked), so their barycentrics'
            // difference is the derivative.
            assert_eq!(n.triangle, s.triangle);
            assert!(
                (n.bary - s.bary - db).length() < 1e-5,
                "{db} vs {}",
                n.bary - s.bary
            );
            // The UVs span the square once: u along x, v down along -y.
            let side = 4.0;
            let want = Vec2::new(dp.x / side, -dp.y / side);
            assert!((duv - want).length() < 1e-5, "{duv} vs {want}");
        }
        // A pixel of a 40-degree, 64-pixel film at distance 3: 2 * 3 * tan(20 deg) / 64 wide.
        let pixel = 2.0 * 3.0 * 20f32.to_radians().tan() / 64.0;
        assert!(
            (f.dpdx.length() / pixel - 1.0).abs() < 0.05,
            "{}",
            f.dpdx.length()
        );
    }

    /// Eq. 1 takes the finer direction: a surface seen at a grazing angle (stretched along
    /// y on the film) is shaded at the resolution its x extent asks for.
    #[test]
    fn the_level_follows_the_finer_direction() {
        let f = Footprint {
            dpdx: Vec3::X,
            dpdy: Vec3::Y,
            dbdx: Vec2::new(1.0 / 256.0, 0.0),
            dbdy: Vec2::new(0.0, 1.0 / 16.0),
            duvdx: Vec2::ZERO,
            duvdy: Vec2::ZERO,
        };
        assert_eq!(f.level(1024.0, 1024.0), 2.0);
        assert_eq!(f.level(1024.0, 64.0), 2.0);
        assert_eq!(f.level(64.0, 64.0), -2.0);
        // The area measure: the geometric mean of the two directions where they are
        // orthogonal.
        assert!(
            (f.area_level(1024.0, 1024.0) - 0.5 * (2.0 + 6.0)).abs() < 1e-5,
            "{f:?}"
        );
    }

    #[test]
    fn levels_are_floored_biased_and_clamped() {
        let at = |l: f32, bias: f32| Level::of(l, bias, 64, 16, 7);
        assert_eq!(
            at(2.7, 0.0),
            Level {
                level: 2,
                width: 16,
                height: 4
            }
        );
        assert_eq!(at(2.7, 1.0).level, 3);
        assert_eq!(at(-3.0, 1.0).level, 0);
        assert_eq!(at(f32::NAN, 1.0).level, 0);
        // The top level keeps at least one cell each way.
        assert_eq!(
            at(50.0, 0.0),
            Level {
                level: 6,
                width: 1,
                height: 1
            }
        );
    }

    /// Eq. 2: a point quantised to the centre of its cell stays in that cell, and the centres
    /// of a level's cells are `(i + 0.5) / w`.
    #[test]
    fn points_quantise_to_their_cells_centre() {
        let level = Level::of(1.0, 0.0, 8, 8, 4);
        assert_eq!((level.width, level.height), (4, 4));
        let (cell, centre) = level.cell(Vec2::new(0.3, 0.99));
        assert_eq!(cell, UVec2::new(1, 3));
        assert_eq!(centre, Vec2::new(1.5 / 4.0, 3.5 / 4.0));
        assert_eq!(level.cell(centre), (cell, centre));
        // The edges and beyond clamp into the grid.
        assert_eq!(level.cell(Vec2::ONE).0, UVec2::new(3, 3));
        assert_eq!(level.cell(Vec2::new(-0.5, 2.0)).0, UVec2::new(0, 3));
    }

    #[test]
    fn a_grazing_ray_has_no_footprint() {
        assert!(on_plane(Vec3::ZERO, Vec3::X, Vec3::new(0.0, 0.0, 1.0), Vec3::Z).is_none());
        assert!(on_plane(Vec3::ZERO, -Vec3::Z, Vec3::new(0.0, 0.0, 1.0), Vec3::Z).is_none());
    }
}
