//! The rough specular reflection's directional albedo, tabulated: what a surface's microfacet
//! layer reflects toward `wo` of a uniform surround, for Schlick's Fresnel.
//!
//! With `F(c) = F0 + (F90 - F0) w(c)`, `w(c) = (1 - c)^5` at `c = |wo.m|`, the albedo
//! `∫ F D G2 |wo.m| / (wo.z pdf(m)) pdf(m) dm` splits into `F0 A + F90 B`, where
//! `A = E[(1 - w) g]` and `B = E[w g]` with `g = D G2 |wo.m| / (wo.z pdf(m))`: two numbers
//! per cosine `wo.z` and roughness (Karis 2013's split sum, without its environment). Both
//! are tabulated over [`COSINES`] cosines (equal steps in `wo.z` up to 1: the albedo of rough
//! surfaces varies fastest near normal incidence as a function of the cosine) and
//! [`ROUGHNESSES`] perceptual roughnesses `sqrt(alpha)` from 0 to 1 (equal steps), per
//! microfacet distribution, by the BSDF's own estimator ([`Ndf::sample_m`] and its density)
//! over a stratified grid of [`SAMPLES`] x [`SAMPLES`] microfacet normals, at first use; a
//! lookup interpolates bilinearly (clamped at the table's edges).
//!
//! It holds where `F` is Schlick's with the macro normal's cosine unchanged, reflection from
//! the side of the lower index or without refraction (`etap >= 1`); the BSDF uses it there.

use std::sync::OnceLock;

use glam::{Vec2, Vec3};

use super::fresnel::schlick_weight;
use super::microfacet::{reflect, Ndf};
use super::{Microfacet, DELTA_ALPHA};

/// Cosines `wo.z` per table.
pub const COSINES: usize = 32;
/// Perceptual roughnesses per table.
pub const ROUGHNESSES: usize = 32;
/// Microfacet normals per side of the stratified grid of each entry.
const SAMPLES: usize = 32;

/// `(A, B)` per entry, row-major over roughness then cosine.
struct Table(Vec<[f32; 2]>);

static TABLES: [OnceLock<Table>; 2] = [OnceLock::new(), OnceLock::new()];

/// `(A, B)` for cosine `mu` (of `wo` with the normal, in (0, 1]) and microfacet
/// roughness `alpha` of distribution `kind`: the rough specular albedo is `F0 A + F90 B`.
#[inline]
pub fn scale_and_bias(kind: Microfacet, mu: f32, alpha: f32) -> (f32, f32) {
    let table = table(kind);
    // Node i of the cosines is at (i + 1) / COSINES; node j of the roughnesses at
    // j / (ROUGHNESSES - 1).
    let x = (mu * COSINES as f32 - 1.0).clamp(0.0, (COSINES - 1) as f32);
    let y = (alpha.max(0.0).sqrt() * (ROUGHNESSES - 1) as f32).clamp(0.0, (ROUGHNESSES - 1) as f32);
    let (x0, y0) = (x as usize, y as usize);
    let (x1, y1) = ((x0 + 1).min(COSINES - 1), (y0 + 1).min(ROUGHNESSES - 1));
    let (fx, fy) = (x - x0 as f32, y - y0 as f32);
    let at = |i: usize, j: usize| Vec2::from(table.0[j * COSINES + i]);
    let v = (at(x0, y0) * (1.0 - fx) + at(x1, y0) * fx) * (1.0 - fy)
        + (at(x0, y1) * (1.0 - fx) + at(x1, y1) * fx) * fy;
    (v.x, v.y)
}

/// The table of `kind`, built at its first use.
fn table(kind: Microfacet) -> &'static Table {
    TABLES[kind as usize].get_or_init(|| Table::new(kind))
}

/// Builds the table of `kind` now if it is not built (a renderer's set-up, so that no frame
/// waits for it).
pub fn prepare(kind: Microfacet) {
    table(kind);
}

impl Table {
    /// The table of `kind`, its entries in parallel (about 1M samples: 10-20 ms on two
    /// threads, once per run).
    fn new(kind: Microfacet) -> Self {
        use rayon::prelude::*;
        let entries = (0..COSINES * ROUGHNESSES)
            .into_par_iter()
            .map(|k| {
                let (i, j) = (k % COSINES, k / COSINES);
                let r = j as f32 / (ROUGHNESSES - 1) as f32;
                let ndf = Ndf::new(kind, (r * r).max(DELTA_ALPHA));
                entry(&ndf, (i + 1) as f32 / COSINES as f32)
            })
            .collect();
        Self(entries)
    }
}

/// `(A, B)` of `ndf` at `wo.z = mu` (`wo` in the xz plane), by the stratified grid.
fn entry(ndf: &Ndf, mu: f32) -> [f32; 2] {
    let wo = Vec3::new((1.0 - mu * mu).max(0.0).sqrt(), 0.0, mu);
    let lambda_o = ndf.lambda(wo);
    let (mut a, mut b) = (0.0f64, 0.0f64);
    for k in 0..SAMPLES * SAMPLES {
        let u = Vec2::new(
            ((k % SAMPLES) as f32 + 0.5) / SAMPLES as f32,
            ((k / SAMPLES) as f32 + 0.5) / SAMPLES as f32,
        );
        let m = ndf.sample_m(wo, u);
        if m.z <= 0.0 {
            continue;
        }
        let c = wo.dot(m);
        let wi = reflect(wo, m);
        let pdf = ndf.pdf_m_with(wo, lambda_o, m);
        if c <= 0.0 || wi.z <= 0.0 || pdf <= 0.0 || !pdf.is_finite() {
            continue;
        }
        let g = (ndf.d(m) * ndf.g2_with(lambda_o, wi) * c / (wo.z * pdf)) as f64;
        if !g.is_finite() {
            continue;
        }
        let w = schlick_weight(c.min(1.0)) as f64;
        a += (1.0 - w) * g;
        b += w * g;
    }
    let n = (SAMPLES * SAMPLES) as f64;
    [(a / n) as f32, (b / n) as f32]
}
