//! Shading grids on every triangle of every instance (seed 002, the texture-space shading
//! cache): the unique parameterisation the cache shades, filters and looks up in.
//!
//! The paper shades on Ptex quads; pathlight's scenes are triangle meshes, most without
//! unique UVs (the interior and the garden have none), so each triangle carries a grid of its
//! own over its barycentric coordinates (`b1`, `b2`: the weights of corners 1 and 2), as "mesh
//! colors" do: at resolution `R` the triangle is cut into `R x R` equal sub-triangles, the
//! cells, `R` along each edge, each cell `(i, j)` of the square `[i, i+1) x [j, j+1) / R` split
//! by its diagonal into a lower (`i + j` fractional parts below 1) and an upper one; a point
//! falls in exactly one cell, and every cell's centroid, where it is shaded, lies inside the
//! triangle. Levels: `R_0` at level 0, halved at each level up, down to one cell.
//!
//! **Sizes from world area**: a triangle's base resolution `R_0` is the power of two that
//! makes its cells' edges at most `base_cell` long (`sqrt(2 area) / R_0 <= base_cell`; one cell
//! for a triangle smaller than that), so cells of equal level are about equally large in the
//! world whatever the triangulation. `base_cell` is the scene's diagonal over
//! [`BASE_CELLS`]: finer than any pixel's footprint at the resolutions the pipeline runs.
//!
//! **Level of detail** (Eq. 1 with `w = h = R_0`, [`super::footprint`]): `l = log2 min(R_0
//! |db/dx|, R_0 |db/dy|)`, then `floor(l + lod_bias)` clamped to the triangle's levels.
//!
//! **Keys** (Eq. 3): a cell is `(instance, triangle, side, level, cell index)`; its key for the
//! caches is a 64-bit hash of these ([`Cell::key`]), and the caches keep the whole cell as the
//! tag that catches colliding keys. `side` tells the triangle's two faces apart: a two-sided
//! surface's back is shaded apart from its front.
//!
//! **Across triangles** (measured: BENCHMARKS.md, "Seed 002"): seen from the bench camera,
//! the interior's pixels lie on triangles thousands of footprints large, where a 13x13 filter
//! fits inside one triangle's grid; the garden's and the helmet's pixels lie half on triangles
//! below four footprints, where a filter confined to its triangle barely filters. The meshes'
//! vertices are not welded across seams (glTF and OBJ split them at UV and normal seams), so
//! adjacency would miss many edges: the filter (issue 50, part 5) is to reach across triangles
//! through a neighbourhood of cached cells found in the surface's plane, by a world-space hash
//! of their centroids at the cell's level, with the paper's normal test.
//!
//! Memory: one byte per triangle of every instance (the base resolution's exponent) and one
//! offset per instance.

use glam::{UVec2, Vec2, Vec3};
use pathlight_accel::{Hit, Ray};
use pathlight_core::rng::hash;

use super::footprint::{Footprint, Level};
use crate::surface::Surface;
use crate::world::World;

/// The scene's diagonal over this is the base cells' largest edge.
pub const BASE_CELLS: f32 = 65536.0;
/// The finest base resolution: `2^MAX_EXPONENT` cells along a triangle's edge.
pub const MAX_EXPONENT: u8 = 15;

/// Every triangle's grid.
#[derive(Debug, Clone, Default)]
pub struct SurfaceGrids {
    /// The largest edge of a base cell, in scene units.
    pub base_cell: f32,
    /// Per instance, the index of its first triangle in `exponents`.
    offsets: Vec<u32>,
    /// Per triangle of every instance, the base resolution's exponent: `R_0 = 2^e`.
    exponents: Vec<u8>,
    /// Per instance, its transform mirrors (negative determinant): the intersector's geometric
    /// normal (the object-space normal through the normal matrix) points against the
    /// world-space corners' winding.
    mirrored: Vec<bool>,
}

/// One grid cell of one side of one triangle at one level.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Cell {
    pub instance: u32,
    pub triangle: u32,
    /// The back face (the side the geometric normal points away from).
    pub back: bool,
    pub level: u8,
    /// The cell's square `(i, j)` and half (upper: the half beyond the square's diagonal).
    pub square: UVec2,
    pub upper: bool,
}

impl Cell {
    /// Eq. 3: the cell's key in the caches (a hash of everything that names it).
    pub fn key(&self) -> u64 {
        hash(&[
            self.instance as u64,
            self.triangle as u64,
            (self.level as u64) << 2 | (self.back as u64) << 1 | self.upper as u64,
            (self.square.x as u64) << 32 | self.square.y as u64,
        ])
    }
}

impl SurfaceGrids {
    /// The grids of every triangle of `world`'s instances.
    pub fn new(world: &World) -> Self {
        let scene = &world.scene;
        let diagonal = scene.bounds().diagonal().length();
        let base_cell = if diagonal.is_finite() && diagonal > 0.0 {
            diagonal / BASE_CELLS
        } else {
            1.0
        };
        let mut offsets = Vec::with_capacity(scene.instances.len());
        let mut exponents = Vec::new();
        for (i, inst) in scene.instances.iter().enumerate() {
            offsets.push(exponents.len() as u32);
            let triangles = scene.meshes[inst.mesh as usize].indices.len() as u32;
            exponents.extend((0..triangles).map(|t| {
                let [a, b, c] = scene.world_triangle(i as u32, t);
                exponent((b - a).cross(c - a).length() * 0.5, base_cell)
            }));
        }
        Self {
            base_cell,
            offsets,
            exponents,
            mirrored: (scene.instances.iter())
                .map(|inst| inst.transform.determinant() < 0.0)
                .collect(),
        }
    }

    /// The base resolution's exponent of triangle `triangle` of instance `instance`.
    pub fn exponent(&self, instance: u32, triangle: u32) -> u8 {
        self.exponents[self.offsets[instance as usize] as usize + triangle as usize]
    }

    /// Triangles over all instances.
    pub fn triangles(&self) -> usize {
        self.exponents.len()
    }

    /// Bytes held.
    pub fn bytes(&self) -> usize {
        self.exponents.capacity()
            + self.offsets.capacity() * std::mem::size_of::<u32>()
            + self.mirrored.capacity()
    }

    /// The cell a hit falls in: the level its footprint asks for (Eq. 1, or with `area` the
    /// footprint's area measure [`Footprint::area_level`]; biased by `lod_bias` levels; the
    /// base level without a footprint), the cell of its barycentrics at that level (the side
    /// the ray came from).
    pub fn cell(
        &self,
        surface: &Surface,
        footprint: Option<&Footprint>,
        lod_bias: f32,
        area: bool,
    ) -> Cell {
        let e = self.exponent(surface.instance, surface.triangle);
        let r0 = 1u32 << e;
        let r = r0 as f32;
        let l = footprint.map_or(f32::NAN, |f| match area {
            true => f.area_level(r, r),
            false => f.level(r, r),
        });
        let level = Level::of(l, lod_bias, r0, r0, e as u32 + 1).level;
        cell_in(surface, e, level as u8)
    }

    /// The cell a hit falls in at level `level` (clamped to its triangle's levels).
    pub fn cell_at(&self, surface: &Surface, level: u8) -> Cell {
        cell_in(
            surface,
            self.exponent(surface.instance, surface.triangle),
            level,
        )
    }

    /// The barycentrics `(b1, b2)` of `cell`'s centroid.
    pub fn centroid(&self, cell: &Cell) -> Vec2 {
        let e = self.exponent(cell.instance, cell.triangle);
        let r = (1u32 << (e - cell.level.min(e))) as f32;
        let third = if cell.upper { 2.0 / 3.0 } else { 1.0 / 3.0 };
        (cell.square.as_vec2() + Vec2::splat(third)) / r
    }

    /// Cells along each edge of `cell`'s triangle at `cell`'s level.
    pub fn resolution(&self, cell: &Cell) -> u32 {
        let e = self.exponent(cell.instance, cell.triangle);
        1u32 << (e - cell.level.min(e))
    }

    /// The surface at `cell`'s centroid, as a ray from its side would see it: the point the
    /// cache shades the cell at.
    pub fn surface(&self, world: &World, cell: &Cell) -> Surface {
        let (ray, hit) = self.probe(world, cell);
        world.surface(&ray, &hit)
    }

    /// A ray that arrives at `cell`'s centroid from its side (one unit away, along the
    /// geometric normal) and its hit there: what [`World::surface`] and [`World::shaded`]
    /// evaluate the cell's surface from.
    pub fn probe(&self, world: &World, cell: &Cell) -> (Ray, Hit) {
        let b = self.centroid(cell);
        let [p0, p1, p2] = world.scene.world_triangle(cell.instance, cell.triangle);
        let p = p0 * (1.0 - b.x - b.y) + p1 * b.x + p2 * b.y;
        // The geometric normal as the intersector's surfaces have it: the object-space normal
        // through the instance's normal matrix, which a mirroring transform (negative
        // determinant) turns against the world-space corners' winding.
        let mirrored = self.mirrored[cell.instance as usize];
        let n = (p1 - p0).cross(p2 - p0).normalize_or(Vec3::Z) * if mirrored { -1.0 } else { 1.0 };
        // A ray arriving from the cell's side, one unit away.
        let toward = if cell.back { n } else { -n };
        let ray = Ray::new(p - toward, toward);
        let hit = Hit {
            t: 1.0,
            u: b.x,
            v: b.y,
            instance: cell.instance,
            triangle: cell.triangle,
        };
        (ray, hit)
    }
}

/// The exponent `e` of the smallest power of two `R_0 = 2^e` whose cells on a triangle of area
/// `area` have edges at most `base_cell` long (`sqrt(2 area) / R_0`), at most
/// [`MAX_EXPONENT`].
fn exponent(area: f32, base_cell: f32) -> u8 {
    let cells = (2.0 * area).sqrt() / base_cell;
    if cells.is_nan() || cells <= 1.0 {
        return 0;
    }
    (cells.log2().ceil() as u8).min(MAX_EXPONENT)
}

/// The cell of `surface` at level `level` (clamped to its triangle's) of a triangle of base
/// resolution `2^e`.
fn cell_in(surface: &Surface, e: u8, level: u8) -> Cell {
    let level = level.min(e);
    let (square, upper) = locate(surface.bary, 1u32 << (e - level));
    Cell {
        instance: surface.instance,
        triangle: surface.triangle,
        back: !surface.front,
        level,
        square,
        upper,
    }
}

/// The cell of barycentrics `b` at resolution `r`: its square and half.
#[inline]
fn locate(b: Vec2, r: u32) -> (UVec2, bool) {
    let rf = r as f32;
    let s = b.clamp(Vec2::ZERO, Vec2::ONE) * rf;
    let mut q = s.floor().min(Vec2::splat(rf - 1.0)).max(Vec2::ZERO);
    let f = s - q;
    let mut upper = f.x + f.y >= 1.0;
    // On the hypotenuse's squares, past the triangle (rounding): the lower half inside.
    if q.x + q.y >= rf - 1.0 && upper {
        upper = false;
        if q.x + q.y > rf - 1.0 {
            q = Vec2::new(q.x.min(rf - 1.0 - q.y), q.y).max(Vec2::ZERO);
        }
    }
    (q.as_uvec2(), upper)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exponents_size_cells_from_world_area() {
        assert_eq!(exponent(0.0, 0.1), 0);
        assert_eq!(exponent(f32::NAN, 0.1), 0);
        // A right triangle with legs 1: sqrt(2 * 0.5) = 1 over cells of 0.1: 10 -> 16.
        assert_eq!(exponent(0.5, 0.1), 4);
        assert_eq!(exponent(0.5, 0.125), 3);
        assert_eq!(exponent(1e30, 1e-30), MAX_EXPONENT);
    }

    /// Every point of the triangle falls in a cell whose centroid is inside the triangle, and
    /// the cells of resolution `r` are `r^2` distinct ones, each the cell of its own centroid.
    #[test]
    fn cells_tile_the_triangle() {
        for r in [1u32, 2, 3, 8] {
            let mut seen = std::collections::HashSet::new();
            let n = 97;
            for a in 0..=n {
                for b in 0..=(n - a) {
                    let p = Vec2::new(a as f32, b as f32) / n as f32;
                    let (q, upper) = locate(p, r);
                    let centroid = (q.as_vec2()
                        + Vec2::splat(if upper { 2.0 / 3.0 } else { 1.0 / 3.0 }))
                        / r as f32;
                    assert!(centroid.x + centroid.y < 1.0 + 1e-6, "{p} -> {centroid}");
                    assert_eq!(locate(centroid, r), (q, upper), "r {r}, {p}");
                    seen.insert((q, upper));
                }
            }
            assert_eq!(seen.len() as u32, r * r, "resolution {r}");
        }
    }

    #[test]
    fn keys_differ_with_every_part_of_the_cell() {
        let c = Cell {
            instance: 3,
            triangle: 70,
            back: false,
            level: 2,
            square: UVec2::new(5, 1),
            upper: false,
        };
        let others = [
            Cell { instance: 4, ..c },
            Cell { triangle: 71, ..c },
            Cell { back: true, ..c },
            Cell { level: 3, ..c },
            Cell {
                square: UVec2::new(1, 5),
                ..c
            },
            Cell { upper: true, ..c },
        ];
        for o in others {
            assert_ne!(o.key(), c.key(), "{o:?}");
        }
        assert_eq!(c.key(), c.key());
    }
}
