//! BSDF tests: chi-square goodness of fit of `sample` against `pdf`, sample/eval/pdf
//! consistency, white furnace, reciprocity, normalisation of the distributions and closed
//! forms. Fixed seeds throughout.

use super::fresnel::{f0_from_ior, schlick, schlick_cos};
use super::microfacet::Ndf;
use super::*;
use pathlight_core::rng::Rng;
use std::f64::consts::PI as PI64;

// ---------------------------------------------------------------------------------------
// Helpers
// ---------------------------------------------------------------------------------------

fn sph(theta: f64, phi: f64) -> Vec3 {
    let (st, ct) = theta.sin_cos();
    let (sp, cp) = phi.sin_cos();
    Vec3::new((st * cp) as f32, (st * sp) as f32, ct as f32)
}

/// A direction at `deg` degrees from the normal (negative: from below), azimuth 0.3 rad so
/// that the specular peaks do not sit on bin boundaries.
fn wo_at(deg: f64) -> Vec3 {
    let t = deg.abs().to_radians();
    let w = sph(t, 0.3);
    if deg < 0.0 {
        Vec3::new(w.x, w.y, -w.z)
    } else {
        w
    }
}

fn metal(dist: Microfacet, roughness: f32, color: Vec3) -> BsdfParams {
    BsdfParams {
        base_color: color,
        metallic: 1.0,
        roughness,
        specular: 1.0,
        specular_color: Vec3::ONE,
        ior: 1.5,
        transmission: 0.0,
        thin_walled: true,
        distribution: dist,
    }
}

/// An opaque dielectric ("plastic"): diffuse base under a Schlick specular layer.
fn plastic(dist: Microfacet, roughness: f32, color: Vec3) -> BsdfParams {
    BsdfParams {
        metallic: 0.0,
        ..metal(dist, roughness, color)
    }
}

fn glass(dist: Microfacet, roughness: f32, thin_walled: bool) -> BsdfParams {
    BsdfParams {
        transmission: 1.0,
        thin_walled,
        ..plastic(dist, roughness, Vec3::ONE)
    }
}

/// Adaptive Simpson quadrature over [a, b], subdividing at least `min_depth` times.
fn simpson(f: &mut dyn FnMut(f64) -> f64, a: f64, b: f64, eps: f64, min_depth: u32) -> f64 {
    #[allow(clippy::too_many_arguments)]
    fn rec(
        f: &mut dyn FnMut(f64) -> f64,
        a: f64,
        b: f64,
        fa: f64,
        fm: f64,
        fb: f64,
        whole: f64,
        eps: f64,
        depth: u32,
        min_depth: u32,
    ) -> f64 {
        let m = 0.5 * (a + b);
        let lm = 0.5 * (a + m);
        let rm = 0.5 * (m + b);
        let flm = f(lm);
        let frm = f(rm);
        let left = (m - a) / 6.0 * (fa + 4.0 * flm + fm);
        let right = (b - m) / 6.0 * (fm + 4.0 * frm + fb);
        let delta = left + right - whole;
        if depth >= 14 || (depth >= min_depth && delta.abs() <= 15.0 * eps) {
            return left + right + delta / 15.0;
        }
        rec(f, a, m, fa, flm, fm, left, 0.5 * eps, depth + 1, min_depth)
            + rec(f, m, b, fm, frm, fb, right, 0.5 * eps, depth + 1, min_depth)
    }
    let fa = f(a);
    let fm = f(0.5 * (a + b));
    let fb = f(b);
    let whole = (b - a) / 6.0 * (fa + 4.0 * fm + fb);
    rec(f, a, b, fa, fm, fb, whole, eps, 0, min_depth)
}

/// The integral of `g(theta, phi) sin(theta)` over a (theta, phi) rectangle.
fn integrate_sphere(
    g: &mut dyn FnMut(f64, f64) -> f64,
    t0: f64,
    t1: f64,
    p0: f64,
    p1: f64,
    eps: f64,
    min_depth: u32,
) -> f64 {
    let inner_eps = eps / (t1 - t0);
    simpson(
        &mut |t: f64| {
            let s = t.sin();
            if s <= 0.0 {
                return 0.0;
            }
            s * simpson(&mut |p: f64| g(t, p), p0, p1, inner_eps, min_depth)
        },
        t0,
        t1,
        eps,
        min_depth,
    )
}

/// ln Gamma(x) for x > 0 (Lanczos, g = 7, n = 9).
fn ln_gamma(x: f64) -> f64 {
    const C: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    if x < 0.5 {
        return (PI64 / (PI64 * x).sin()).ln() - ln_gamma(1.0 - x);
    }
    let x = x - 1.0;
    let mut a = C[0];
    let t = x + 7.5;
    for (i, c) in C.iter().enumerate().skip(1) {
        a += c / (x + i as f64);
    }
    0.5 * (2.0 * PI64).ln() + (x + 0.5) * t.ln() - t + a.ln()
}

/// The regularised upper incomplete gamma function Q(a, x) = 1 - P(a, x) (series for
/// x < a + 1, Lentz's continued fraction otherwise; Numerical Recipes 6.2).
fn gamma_q(a: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 1.0;
    }
    let log_pre = -x + a * x.ln() - ln_gamma(a);
    if x < a + 1.0 {
        let mut ap = a;
        let mut del = 1.0 / a;
        let mut sum = del;
        for _ in 0..10_000 {
            ap += 1.0;
            del *= x / ap;
            sum += del;
            if del.abs() < sum.abs() * 1e-15 {
                break;
            }
        }
        1.0 - sum * log_pre.exp()
    } else {
        let tiny = 1e-300;
        let mut b = x + 1.0 - a;
        let mut c = 1.0 / tiny;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..10_000 {
            let an = -(i as f64) * (i as f64 - a);
            b += 2.0;
            d = an * d + b;
            if d.abs() < tiny {
                d = tiny;
            }
            c = b + an / c;
            if c.abs() < tiny {
                c = tiny;
            }
            d = 1.0 / d;
            let del = d * c;
            h *= del;
            if (del - 1.0).abs() < 1e-15 {
                break;
            }
        }
        log_pre.exp() * h
    }
}

/// Monte Carlo directional albedo: the mean of f |cos| / pdf over `n` samples (delta lobes
/// included). Refracted weights are multiplied by eta^2 to undo the radiance scaling.
/// Returns (mean, standard error of the mean of the channel average).
fn albedo_mc(bsdf: &Bsdf, wo: Vec3, n: usize, seed: u64) -> (Vec3, f64) {
    let mut rng = Rng::new(seed, 7);
    let mut sum = [0f64; 3];
    let mut sum2 = 0f64;
    let refracts = !bsdf.params().thin_walled;
    let etap = if wo.z > 0.0 {
        bsdf.params().ior
    } else {
        1.0 / bsdf.params().ior
    };
    for _ in 0..n {
        let ul = rng.next_f32();
        let u = Vec2::new(rng.next_f32(), rng.next_f32());
        let Some(s) = bsdf.sample(wo, ul, u) else {
            continue;
        };
        let mut w = s.f * s.wi.z.abs() / s.pdf;
        assert!(w.is_finite() && w.min_element() >= 0.0, "{w:?} {s:?}");
        if s.transmitted && refracts {
            w *= etap * etap;
        }
        for (acc, c) in sum.iter_mut().zip(w.to_array()) {
            *acc += c as f64;
        }
        let a = avg(w) as f64;
        sum2 += a * a;
    }
    let n = n as f64;
    let mean = Vec3::new(
        (sum[0] / n) as f32,
        (sum[1] / n) as f32,
        (sum[2] / n) as f32,
    );
    let m = avg(mean) as f64;
    let var = (sum2 / n - m * m).max(0.0);
    (mean, (var / n).sqrt())
}

// ---------------------------------------------------------------------------------------
// Chi-square goodness of fit (after pbrt-v3's / Mitsuba's chi2 tests)
// ---------------------------------------------------------------------------------------

const THETA_RES: usize = 10;
const PHI_RES: usize = 20;
const CHI2_SAMPLES: usize = 600_000;
const MIN_EXPECTED: f64 = 5.0;
const SIGNIFICANCE: f64 = 0.01;

fn chi2_configs() -> Vec<(String, BsdfParams, Vec3)> {
    use Microfacet::{Beckmann, Ggx};
    let mut v = Vec::new();
    let grey = Vec3::new(0.8, 0.6, 0.4);
    for deg in [0.0, 80.0] {
        v.push((
            format!("lambert {deg}"),
            BsdfParams::lambertian(grey),
            wo_at(deg),
        ));
    }
    for dist in [Ggx, Beckmann] {
        for r in [0.1, 0.3, 0.7, 1.0] {
            for deg in [10.0, 75.0] {
                v.push((
                    format!("metal {dist:?} r{r} {deg}"),
                    metal(dist, r, grey),
                    wo_at(deg),
                ));
            }
            v.push((
                format!("plastic {dist:?} r{r} 45"),
                plastic(dist, r, grey),
                wo_at(45.0),
            ));
            v.push((
                format!("glass {dist:?} r{r} 30"),
                glass(dist, r, false),
                wo_at(30.0),
            ));
            v.push((
                format!("glass {dist:?} r{r} from inside -20"),
                glass(dist, r, false),
                wo_at(-20.0),
            ));
        }
        for r in [0.3, 0.7] {
            v.push((
                format!("glass {dist:?} r{r} grazing 85"),
                glass(dist, r, false),
                wo_at(85.0),
            ));
            v.push((
                format!("glass {dist:?} r{r} from inside beyond critical -60"),
                glass(dist, r, false),
                wo_at(-60.0),
            ));
            v.push((
                format!("thin {dist:?} r{r} 40"),
                glass(dist, r, true),
                wo_at(40.0),
            ));
            v.push((
                format!("thin {dist:?} r{r} from below -70"),
                glass(dist, r, true),
                wo_at(-70.0),
            ));
        }
    }
    // Mixtures: diffuse + metal + transmission, coloured specular, and a smooth coat over a
    // diffuse base (the delta lobe is excluded from the histogram).
    v.push((
        "mix GGX m0.4 t0.3 r0.4".into(),
        BsdfParams {
            metallic: 0.4,
            transmission: 0.3,
            thin_walled: false,
            ..plastic(Ggx, 0.4, grey)
        },
        wo_at(50.0),
    ));
    v.push((
        "mix Beckmann m0.3 t0.5 thin r0.5 coloured specular".into(),
        BsdfParams {
            metallic: 0.3,
            transmission: 0.5,
            specular_color: Vec3::new(1.0, 0.5, 0.2),
            specular: 0.7,
            ..glass(Beckmann, 0.5, true)
        },
        wo_at(20.0),
    ));
    v.push((
        "smooth coat over diffuse".into(),
        plastic(Ggx, 0.0, grey),
        wo_at(60.0),
    ));
    v.push((
        "smooth glass + diffuse -30".into(),
        BsdfParams {
            transmission: 0.5,
            base_color: grey,
            ..glass(Ggx, 0.0, false)
        },
        wo_at(-30.0),
    ));
    v
}

/// Runs one chi-square test; Err with a description on failure.
fn chi2_test(
    name: &str,
    params: &BsdfParams,
    wo: Vec3,
    seed: u64,
    n_tests: usize,
) -> Result<f64, String> {
    let bsdf = Bsdf::new(params);
    let dt = PI64 / THETA_RES as f64;
    let dp = 2.0 * PI64 / PHI_RES as f64;
    let mut observed = vec![0f64; THETA_RES * PHI_RES];
    let mut rng = Rng::new(seed, 11);
    let mut in_bins = 0usize;
    for _ in 0..CHI2_SAMPLES {
        let ul = rng.next_f32();
        let u = Vec2::new(rng.next_f32(), rng.next_f32());
        let Some(s) = bsdf.sample(wo, ul, u) else {
            continue;
        };
        if s.delta {
            continue;
        }
        if !(s.pdf > 0.0 && s.pdf.is_finite() && s.f.is_finite()) {
            return Err(format!("{name}: bad sample {s:?}"));
        }
        let wi = s.wi;
        let theta = (wi.z as f64).clamp(-1.0, 1.0).acos();
        let mut phi = (wi.y as f64).atan2(wi.x as f64);
        if phi < 0.0 {
            phi += 2.0 * PI64;
        }
        let i = ((theta / dt) as usize).min(THETA_RES - 1);
        let j = ((phi / dp) as usize).min(PHI_RES - 1);
        observed[i * PHI_RES + j] += 1.0;
        in_bins += 1;
    }
    let n = CHI2_SAMPLES as f64;
    let mut expected = vec![0f64; THETA_RES * PHI_RES];
    for i in 0..THETA_RES {
        for j in 0..PHI_RES {
            let mut g = |t: f64, p: f64| bsdf.pdf(wo, sph(t, p)) as f64;
            let e = integrate_sphere(
                &mut g,
                i as f64 * dt,
                (i + 1) as f64 * dt,
                j as f64 * dp,
                (j + 1) as f64 * dp,
                1e-6,
                4,
            );
            expected[i * PHI_RES + j] = e * n;
        }
    }
    // The "no direction / delta" category completes the multinomial.
    let exp_total: f64 = expected.iter().sum();
    let mut cells: Vec<(f64, f64)> = expected
        .iter()
        .copied()
        .zip(observed.iter().copied())
        .collect();
    cells.push(((n - exp_total).max(0.0), (CHI2_SAMPLES - in_bins) as f64));
    cells.sort_by(|a, b| a.0.total_cmp(&b.0));
    let (mut pool_e, mut pool_o) = (0.0, 0.0);
    let mut chsq = 0.0;
    let mut dof = 0usize;
    for &(e, o) in &cells {
        if e <= 0.0 {
            if o > 0.0 {
                return Err(format!("{name}: {o} samples where the pdf integrates to 0"));
            }
            continue;
        }
        if e < MIN_EXPECTED || pool_e > 0.0 && pool_e < MIN_EXPECTED {
            pool_e += e;
            pool_o += o;
            if pool_e < MIN_EXPECTED {
                continue;
            }
            chsq += (pool_o - pool_e) * (pool_o - pool_e) / pool_e;
            dof += 1;
            pool_e = 0.0;
            pool_o = 0.0;
            continue;
        }
        chsq += (o - e) * (o - e) / e;
        dof += 1;
    }
    if pool_e > 0.0 {
        // A leftover pool below the threshold (only when every cell is small).
        chsq += (pool_o - pool_e) * (pool_o - pool_e) / pool_e;
        dof += 1;
    }
    let dof = dof.saturating_sub(1);
    if dof == 0 {
        return Ok(1.0);
    }
    let p = gamma_q(dof as f64 / 2.0, chsq / 2.0);
    // Šidák correction for the number of tests.
    let alpha = 1.0 - (1.0 - SIGNIFICANCE).powf(1.0 / n_tests as f64);
    if p < alpha || !p.is_finite() {
        let mut worst: Vec<(usize, f64, f64)> = expected
            .iter()
            .zip(&observed)
            .enumerate()
            .map(|(k, (&e, &o))| (k, e, o))
            .collect();
        worst.sort_by(|a, b| {
            let da = (a.2 - a.1).powi(2) / a.1.max(1.0);
            let db = (b.2 - b.1).powi(2) / b.1.max(1.0);
            db.total_cmp(&da)
        });
        worst.truncate(5);
        return Err(format!(
            "{name}: chi2 {chsq:.1} dof {dof} p {p:.3e} < {alpha:.3e}; expected total {exp_total:.0} \
             observed {in_bins}; worst (bin, expected, observed): {worst:?}"
        ));
    }
    Ok(p)
}

fn run_chi2_part(part: usize, parts: usize) {
    let configs = chi2_configs();
    let n_tests = configs.len();
    let mut failures = Vec::new();
    for (k, (name, params, wo)) in configs.iter().enumerate() {
        if k % parts != part {
            continue;
        }
        match chi2_test(name, params, *wo, 1000 + k as u64, n_tests) {
            Ok(p) => eprintln!("chi2 ok  {name}: p = {p:.3}"),
            Err(e) => {
                eprintln!("chi2 FAIL {e}");
                failures.push(e);
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

#[test]
fn chi2_part_0() {
    run_chi2_part(0, 4);
}

#[test]
fn chi2_part_1() {
    run_chi2_part(1, 4);
}

#[test]
fn chi2_part_2() {
    run_chi2_part(2, 4);
}

#[test]
fn chi2_part_3() {
    run_chi2_part(3, 4);
}

#[test]
fn incomplete_gamma_closed_forms() {
    // Q(1, x) = exp(-x); Q(1/2, x) = erfc(sqrt(x)); chi2 with 2k dof: Q(k, x) = e^-x sum x^i/i!.
    for x in [0.1, 1.0, 3.0, 10.0] {
        assert!((gamma_q(1.0, x) - (-x).exp()).abs() < 1e-12);
        let q3 = (-x).exp() * (1.0 + x + x * x / 2.0);
        assert!((gamma_q(3.0, x) - q3).abs() < 1e-12, "{x}");
    }
    // erfc(1) = 0.157299207050285...
    assert!((gamma_q(0.5, 1.0) - 0.157_299_207_050_285_1).abs() < 1e-12);
    // Large a (100 dof, chi2 = 100): e^-50 sum_{i<50} 50^i / i! = 0.481191684527956...
    assert!((gamma_q(50.0, 50.0) - 0.481_191_684_527_956_7).abs() < 1e-10);
}

// ---------------------------------------------------------------------------------------
// Consistency, energy, reciprocity
// ---------------------------------------------------------------------------------------

fn assorted_materials() -> Vec<BsdfParams> {
    use Microfacet::{Beckmann, Ggx};
    let c = Vec3::new(0.9, 0.5, 0.3);
    let mut v = vec![BsdfParams::lambertian(c)];
    for dist in [Ggx, Beckmann] {
        for r in [0.05, 0.3, 1.0] {
            v.push(metal(dist, r, c));
            v.push(plastic(dist, r, c));
            v.push(glass(dist, r, false));
            v.push(glass(dist, r, true));
            v.push(BsdfParams {
                metallic: 0.5,
                transmission: 0.5,
                specular_color: Vec3::new(0.3, 1.0, 0.6),
                ..plastic(dist, r, c)
            });
        }
    }
    v
}

#[test]
fn sample_agrees_with_eval_and_pdf() {
    let mut rng = Rng::new(5, 1);
    for params in assorted_materials() {
        let bsdf = Bsdf::new(&params);
        for k in 0..2000 {
            let z = if k % 2 == 0 { 1.0 } else { -1.0 } * (0.02 + 0.98 * rng.next_f32());
            let wo = sph((z as f64).acos(), 2.0 * PI64 * rng.next_f32() as f64);
            let Some(s) = bsdf.sample(
                wo,
                rng.next_f32(),
                Vec2::new(rng.next_f32(), rng.next_f32()),
            ) else {
                continue;
            };
            assert!((s.wi.length() - 1.0).abs() < 1e-4, "{params:?} {s:?}");
            assert_eq!(s.transmitted, s.wi.z * wo.z < 0.0);
            assert!(s.pdf > 0.0 && s.f.is_finite() && s.f.min_element() >= 0.0);
            if s.delta {
                continue;
            }
            let (f, pdf) = bsdf.eval_pdf(wo, s.wi);
            assert_eq!(f, bsdf.eval(wo, s.wi));
            // Seeing the BSDF from `wo` once changes no value.
            assert_eq!(f, bsdf.eval_at(&bsdf.at(wo), s.wi));
            let other = sph(2.0, 1.0);
            assert_eq!(bsdf.eval(wo, other), bsdf.eval_at(&bsdf.at(wo), other));
            assert_eq!(pdf, bsdf.pdf(wo, s.wi));
            let w_sample = s.f * s.wi.z.abs() / s.pdf;
            let w_eval = f * s.wi.z.abs() / pdf;
            assert!(
                (w_sample - w_eval).abs().max_element() <= 1e-5 * (1.0 + w_eval.max_element()),
                "{params:?} wo {wo:?}: {w_sample:?} vs {w_eval:?}"
            );
        }
    }
}

#[test]
fn lambertian_is_exact() {
    let c = Vec3::new(0.7, 0.2, 0.05);
    let bsdf = Bsdf::new(&BsdfParams::lambertian(c));
    assert!(!bsdf.is_delta());
    let mut rng = Rng::new(1, 2);
    for _ in 0..10_000 {
        let wo = sph(
            0.5 * PI64 * rng.next_f32() as f64,
            2.0 * PI64 * rng.next_f32() as f64,
        );
        if wo.z <= 0.0 {
            continue;
        }
        let s = bsdf
            .sample(
                wo,
                rng.next_f32(),
                Vec2::new(rng.next_f32(), rng.next_f32()),
            )
            .unwrap();
        assert!(!s.delta && !s.transmitted && s.wi.z > 0.0);
        assert_eq!(s.f, c * FRAC_1_PI);
        assert_eq!(s.pdf, s.wi.z * FRAC_1_PI);
        assert_eq!(bsdf.eval(wo, s.wi), c * FRAC_1_PI);
        // Opposite sides: nothing.
        let below = Vec3::new(s.wi.x, s.wi.y, -s.wi.z);
        assert_eq!(bsdf.eval(wo, below), Vec3::ZERO);
        assert_eq!(bsdf.pdf(wo, below), 0.0);
    }
}

#[test]
fn white_lambertian_furnace() {
    let bsdf = Bsdf::new(&BsdfParams::lambertian(Vec3::ONE));
    for deg in [0.0, 45.0, 89.0, -30.0] {
        let (a, _) = albedo_mc(&bsdf, wo_at(deg), 100_000, 3);
        assert!((a - Vec3::ONE).abs().max_element() < 1e-3, "{deg}: {a:?}");
    }
}

#[test]
fn white_furnace_never_gains_energy() {
    use Microfacet::{Beckmann, Ggx};
    let mut cases = Vec::new();
    for dist in [Ggx, Beckmann] {
        for r in [0.0, 0.1, 0.3, 0.7, 1.0] {
            cases.push(metal(dist, r, Vec3::ONE));
            cases.push(plastic(dist, r, Vec3::ONE));
            cases.push(glass(dist, r, false));
            cases.push(glass(dist, r, true));
            cases.push(BsdfParams {
                metallic: 0.3,
                transmission: 0.4,
                ..glass(dist, r, false)
            });
        }
    }
    for params in cases {
        let bsdf = Bsdf::new(&params);
        for deg in [0.0, 60.0, 85.0, -15.0, -70.0] {
            let (a, se) = albedo_mc(&bsdf, wo_at(deg), 20_000, 9);
            assert!(
                a.max_element() as f64 <= 1.0 + 1e-3 + 4.0 * se,
                "{params:?} at {deg}: albedo {a:?} (se {se:.2e})"
            );
        }
    }
}

#[test]
fn smooth_dielectric_conserves_energy() {
    // R + T = 1 exactly for a white smooth dielectric once the 1/eta^2 radiance scaling is
    // undone, from outside, from inside (including total internal reflection) and thin.
    for thin in [false, true] {
        for ior in [1.33, 1.5, 2.4] {
            let params = BsdfParams {
                ior,
                ..glass(Microfacet::Ggx, 0.0, thin)
            };
            let bsdf = Bsdf::new(&params);
            assert!(bsdf.is_delta());
            for deg in [0.0, 30.0, 60.0, 89.0, -10.0, -40.0, -80.0] {
                let (a, _) = albedo_mc(&bsdf, wo_at(deg), 20_000, 4);
                assert!(
                    (a - Vec3::ONE).abs().max_element() < 1e-4,
                    "thin {thin} ior {ior} at {deg}: {a:?}"
                );
            }
        }
    }
}

/// E(mu) of a white single-scattering microfacet reflector by quadrature:
/// integral of D(h) G2 / (4 |wo.z|) over the hemisphere of wi.
fn metal_albedo_quadrature(dist: Microfacet, alpha: f32, wo: Vec3) -> f64 {
    let ndf = Ndf::new(dist, alpha);
    let mut g = |t: f64, p: f64| {
        let wi = sph(t, p);
        if wi.z <= 0.0 {
            return 0.0;
        }
        let h = (wo + wi).normalize();
        (ndf.d(h) * ndf.g2(wo, wi) / (4.0 * wo.z)) as f64
    };
    integrate_sphere(&mut g, 0.0, 0.5 * PI64, 0.0, 2.0 * PI64, 1e-6, 5)
}

#[test]
fn rough_metal_albedo_matches_single_scattering_theory() {
    // Single-scattering microfacet models lose the energy of multiple bounces. For GGX at
    // alpha = 1 and normal incidence there is a closed form: D = 1/pi, Lambda(wo) = 0 and
    // G1(wi) = 2 mu / (1 + mu), so E = 1/2 int_0^1 2 mu / (1 + mu) * 2 dmu / 2 = 1 - ln 2
    // = 0.3069 (half the visible normals reflect below the horizon). The Monte Carlo estimate
    // through `sample` must match quadrature of the same integrand.
    let cases = [
        (
            Microfacet::Ggx,
            1.0f32,
            0.0,
            Some(1.0 - std::f64::consts::LN_2),
        ),
        (Microfacet::Ggx, 1.0, 60.0, None),
        (Microfacet::Ggx, 1.0, 85.0, None),
        (Microfacet::Ggx, 0.5, 0.0, None),
        (Microfacet::Ggx, 0.5, 85.0, None),
        (Microfacet::Beckmann, 1.0, 0.0, None),
        (Microfacet::Beckmann, 1.0, 85.0, None),
    ];
    for (dist, alpha, deg, exact) in cases {
        let wo = wo_at(deg);
        let bsdf = Bsdf::new(&metal(dist, alpha.sqrt(), Vec3::ONE));
        let (mc, se) = albedo_mc(&bsdf, wo, 400_000, 17);
        let q = metal_albedo_quadrature(dist, alpha, wo);
        eprintln!(
            "{dist:?} alpha {alpha} at {deg} deg: E = {q:.4} (quadrature), {:.4} +- {se:.4} (MC)",
            mc.x
        );
        assert!(
            (mc.x as f64 - q).abs() < 4.0 * se + 1e-3,
            "{dist:?} {deg}: {mc:?} vs {q}"
        );
        assert!(q < 1.0);
        if let Some(e) = exact {
            assert!((q - e).abs() < 1e-4, "{q} vs {e}");
        }
    }
}

#[test]
fn reciprocity() {
    let mut rng = Rng::new(77, 3);
    for params in assorted_materials() {
        let bsdf = Bsdf::new(&params);
        for _ in 0..2000 {
            let a = sph(
                (rng.next_f32() as f64 * 0.98 + 0.01).acos(),
                2.0 * PI64 * rng.next_f32() as f64,
            );
            let b = sph(
                (rng.next_f32() as f64 * 0.98 + 0.01).acos(),
                2.0 * PI64 * rng.next_f32() as f64,
            );
            let below = rng.next_f32() < 0.5;
            let (a, b) = if below { (-a, -b) } else { (a, b) };
            // Reflection (same side) and thin-walled transmission are symmetric.
            let pairs = [(a, b), (a, Vec3::new(b.x, b.y, -b.z))];
            for (k, (wo, wi)) in pairs.into_iter().enumerate() {
                let fwd = bsdf.eval(wo, wi);
                let bwd = bsdf.eval(wi, wo);
                let refracting = k == 1 && !params.thin_walled;
                let (fwd, bwd) = if refracting {
                    // Radiance transport: f(wo, wi) eta_o'^2 = f(wi, wo), eta_o' = etap(wo).
                    let etap = if wo.z > 0.0 {
                        params.ior
                    } else {
                        1.0 / params.ior
                    };
                    (fwd * etap * etap, bwd)
                } else {
                    (fwd, bwd)
                };
                assert!(
                    (fwd - bwd).abs().max_element() <= 2e-4 * fwd.max_element().max(1.0),
                    "{params:?}: {wo:?} {wi:?}: {fwd:?} vs {bwd:?}"
                );
            }
        }
    }
}

// ---------------------------------------------------------------------------------------
// Distributions and closed forms
// ---------------------------------------------------------------------------------------

#[test]
fn ndf_is_normalised_and_projects_to_the_macro_surface() {
    for dist in [Microfacet::Ggx, Microfacet::Beckmann] {
        for alpha in [0.05, 0.1, 0.3, 0.7, 1.0] {
            let ndf = Ndf::new(dist, alpha);
            // Integral of D(m) m.z over the hemisphere (isotropic: one dimension).
            let norm = 2.0
                * PI64
                * simpson(
                    &mut |t: f64| {
                        let m = sph(t, 0.0);
                        ndf.d(m) as f64 * t.cos() * t.sin()
                    },
                    0.0,
                    0.5 * PI64,
                    1e-9,
                    6,
                );
            assert!((norm - 1.0).abs() < 1e-3, "{dist:?} {alpha}: {norm}");
            // Integral of G1(wo) max(0, wo.m) D(m) dm = wo.z. Exact for GGX; Walter's
            // rational G1 for Beckmann is an approximation (error below 1%).
            let tol = match dist {
                Microfacet::Ggx => 2e-3,
                Microfacet::Beckmann => 1e-2,
            };
            for deg in [0.0, 30.0, 60.0, 80.0, 88.0] {
                let wo = wo_at(deg);
                let g1 = ndf.g1(wo) as f64;
                let mut g = |t: f64, p: f64| {
                    let m = sph(t, p);
                    ndf.d(m) as f64 * (wo.dot(m).max(0.0) as f64)
                };
                let proj = g1 * integrate_sphere(&mut g, 0.0, 0.5 * PI64, 0.0, 2.0 * PI64, 1e-7, 5);
                assert!(
                    (proj - wo.z as f64).abs() < tol * wo.z as f64 + 1e-4,
                    "{dist:?} alpha {alpha} at {deg}: {proj} vs {}",
                    wo.z
                );
            }
        }
    }
}

#[test]
fn fresnel_closed_forms() {
    let f0 = Vec3::new(0.9, 0.6, 0.3);
    assert_eq!(schlick(f0, 1.0, 1.0), f0);
    assert_eq!(schlick(f0, 1.0, 0.0), Vec3::ONE);
    assert!((f0_from_ior(1.5) - 0.04).abs() < 1e-7);
    assert!((f0_from_ior(1.0 / 1.5) - 0.04).abs() < 1e-7);
    assert_eq!(f0_from_ior(0.0), 1.0);
    assert_eq!(f0_from_ior(f32::INFINITY), 1.0);
    // From the denser side: the transmitted cosine, 0 past the critical angle.
    let crit = (1.0f32 / 1.5).asin();
    assert_eq!(schlick_cos((crit + 0.01).cos(), 1.0 / 1.5), 0.0);
    assert!((schlick_cos(1.0, 1.0 / 1.5) - 1.0).abs() < 1e-6);

    // A smooth glass at normal incidence reflects 4% and transmits 96% / eta^2.
    let bsdf = Bsdf::new(&glass(Microfacet::Ggx, 0.0, false));
    let wo = Vec3::Z;
    let r = bsdf.sample(wo, 0.0, Vec2::splat(0.5)).unwrap();
    assert!(r.delta && !r.transmitted && (r.pdf - 0.04).abs() < 1e-6);
    assert!((r.f * r.wi.z - Vec3::splat(0.04)).abs().max_element() < 1e-6);
    let t = bsdf.sample(wo, 0.99, Vec2::splat(0.5)).unwrap();
    assert!(t.delta && t.transmitted && (t.wi + wo).length() < 1e-6);
    assert!(
        (t.f * t.wi.z.abs() - Vec3::splat(0.96 / 2.25))
            .abs()
            .max_element()
            < 1e-6
    );
    // Total internal reflection from inside past the critical angle.
    let wo = wo_at(-60.0);
    for ul in [0.0, 0.5, 0.999] {
        let s = bsdf.sample(wo, ul, Vec2::splat(0.5)).unwrap();
        assert!(!s.transmitted && s.delta && s.pdf == 1.0);
        assert!((s.f * s.wi.z.abs() - Vec3::ONE).abs().max_element() < 1e-6);
    }
    // A smooth metal: Schlick with f0 = base colour.
    let bsdf = Bsdf::new(&metal(Microfacet::Ggx, 0.0, f0));
    let s = bsdf.sample(Vec3::Z, 0.3, Vec2::splat(0.5)).unwrap();
    assert!(s.delta && (s.f * s.wi.z - f0).abs().max_element() < 1e-6);
    assert!(bsdf.is_delta());
    // specular = 0 removes the dielectric reflection: exactly the Lambertian.
    let p = BsdfParams {
        specular: 0.0,
        ..plastic(Microfacet::Ggx, 0.4, f0)
    };
    let wo = wo_at(40.0);
    let wi = wo_at(-70.0) * Vec3::new(1.0, 1.0, -1.0);
    assert_eq!(Bsdf::new(&p).eval(wo, wi), f0 * FRAC_1_PI);
}

#[test]
fn delta_classification() {
    assert!(!Bsdf::new(&plastic(Microfacet::Ggx, 0.0, Vec3::ONE)).is_delta());
    assert!(Bsdf::new(&glass(Microfacet::Ggx, 0.0, true)).is_delta());
    assert!(!Bsdf::new(&glass(Microfacet::Ggx, 0.2, true)).is_delta());
    assert!(!Bsdf::new(&metal(Microfacet::Beckmann, 0.05, Vec3::ONE)).is_delta());
    assert!(Bsdf::new(&metal(Microfacet::Beckmann, 0.03, Vec3::ONE)).is_delta());
}

/// The Lambertian short path gives exactly the general path's values and samples.
#[test]
fn lambertian_short_path_equals_the_general_one() {
    let mut rng = pathlight_core::rng::Rng::new(17, 4);
    for albedo in [Vec3::ONE, Vec3::new(0.7, 0.2, 0.05)] {
        let fast = Bsdf::new(&BsdfParams::lambertian(albedo));
        assert!(fast.lambertian);
        let mut general = fast;
        general.lambertian = false;
        for _ in 0..2000 {
            let dir = |rng: &mut pathlight_core::rng::Rng| {
                let z = rng.next_f32() * 2.0 - 1.0;
                let phi = rng.next_f32() * std::f32::consts::TAU;
                let r = (1.0 - z * z).max(0.0).sqrt();
                Vec3::new(r * phi.cos(), r * phi.sin(), z)
            };
            let (wo, wi) = (dir(&mut rng), dir(&mut rng));
            assert_eq!(fast.eval_pdf(wo, wi), general.eval_pdf(wo, wi), "{wo} {wi}");
            let (ul, u) = (rng.next_f32(), Vec2::new(rng.next_f32(), rng.next_f32()));
            assert_eq!(fast.sample(wo, ul, u), general.sample(wo, ul, u), "{wo}");
        }
    }
    // A specular layer or metal takes the general path.
    let coated = BsdfParams {
        specular: 1.0,
        ..BsdfParams::lambertian(Vec3::ONE)
    };
    assert!(!Bsdf::new(&coated).lambertian);
}

#[test]
fn lanes_evaluate_the_bsdf_bit_for_bit() {
    // `eval_lane` (no branch on `wi`) against `eval_at`, over random directions on both
    // sides of the surface, grazing ones and `wi.z = 0` included; and which BSDFs have lanes.
    let mut rng = Rng::new(5, 11);
    let unit = |rng: &mut Rng| {
        let z = 2.0 * rng.next_f32() - 1.0;
        let phi = TAU * rng.next_f32();
        let r = (1.0 - z * z).max(0.0).sqrt();
        Vec3::new(r * phi.cos(), r * phi.sin(), z)
    };
    let mut params = Vec::new();
    for (metallic, roughness, specular) in [
        (0.0, 0.5, 0.0),
        (0.0, 0.3, 0.5),
        (1.0, 0.1, 0.5),
        (0.4, 0.8, 1.0),
        (0.0, 0.0, 0.5),
    ] {
        let mut p = BsdfParams::lambertian(Vec3::new(0.8, 0.5, 0.3));
        (p.metallic, p.roughness, p.specular) = (metallic, roughness, specular);
        params.push(p);
    }
    params.push(BsdfParams::lambertian(Vec3::splat(0.5)));
    let mut evaluated = 0;
    for p in &params {
        let bsdf = Bsdf::new(p);
        assert!(bsdf.has_lanes(), "{p:?}");
        for _ in 0..200 {
            let mut wo = unit(&mut rng);
            if evaluated % 17 == 0 {
                wo.z = 1e-4;
            }
            let at = bsdf.at(wo.normalize());
            for k in 0..50 {
                let mut wi = unit(&mut rng);
                if k == 0 {
                    wi.z = 0.0;
                }
                let (a, b) = (bsdf.eval_lane(&at, wi), bsdf.eval_at(&at, wi));
                assert_eq!(
                    a.to_array().map(f32::to_bits),
                    b.to_array().map(f32::to_bits)
                );
                evaluated += usize::from(b.max_element() > 0.0);
            }
        }
    }
    assert!(evaluated > 10_000, "{evaluated}");
    // Beckmann, refraction and transmission lobes have no lanes.
    let mut beckmann = params[1];
    beckmann.distribution = Microfacet::Beckmann;
    let mut glass = params[1];
    glass.transmission = 1.0;
    let mut thin = glass;
    thin.thin_walled = true;
    for p in [beckmann, glass, thin] {
        assert!(!Bsdf::new(&p).has_lanes(), "{p:?}");
    }
}

/// `directional_albedo` (the diffuse lobe exactly, the specular lobe by its microfacet
/// normals) against the Monte Carlo mean of `f |cos| / pdf` over the whole BSDF's own samples,
/// for rough and smooth dielectrics and metals under GGX and Beckmann, at normal and grazing
/// angles.
#[test]
fn directional_albedo_matches_the_bsdfs_own_samples() {
    use Microfacet::{Beckmann, Ggx};
    let u: Vec<Vec2> = (0..4096)
        .map(|k| {
            Vec2::new(
                (k as f32 + 0.5) / 4096.0,
                ((k as f64 * 0.618_033_988_75).fract()) as f32,
            )
        })
        .collect();
    for dist in [Ggx, Beckmann] {
        for roughness in [0.0, 0.3, 0.93] {
            for p in [
                plastic(dist, roughness, Vec3::new(0.8, 0.5, 0.2)),
                metal(dist, roughness, Vec3::new(0.9, 0.6, 0.3)),
            ] {
                let bsdf = Bsdf::new(&p);
                for deg in [0.0, 45.0, 80.0] {
                    let wo = wo_at(deg);
                    let a = bsdf.directional_albedo(wo, &u);
                    let (mc, se) = albedo_mc(&bsdf, wo, 400_000, 11);
                    let tol = 5.0 * se + 2e-3;
                    assert!(
                        (a - mc).abs().max_element() < tol as f32,
                        "{dist:?} roughness {roughness} {p:?} at {deg} deg: {a} vs {mc} (se {se})"
                    );
                }
            }
        }
    }
}

/// The tabulated directional albedo ([`Bsdf::directional_albedo_tabulated`]) against the
/// BSDF's own sampling (the mean of f |cos| / pdf over 200,000 samples of `sample`, every
/// lobe): within 4 standard errors plus 0.006 (the table's bilinear interpolation between
/// its nodes), over both distributions, roughness 0.1-1, metallic 0-1, a coloured base and
/// angles from 0 to 85 degrees.
#[test]
fn the_tabulated_albedo_agrees_with_sampling() {
    for dist in [Microfacet::Ggx, Microfacet::Beckmann] {
        for roughness in [0.1, 0.25, 0.45, 0.7, 1.0] {
            for metallic in [0.0, 0.5, 1.0] {
                let params = BsdfParams {
                    metallic,
                    ..metal(dist, roughness, Vec3::new(0.9, 0.5, 0.2))
                };
                let bsdf = Bsdf::new(&params);
                for deg in [0.0, 30.0, 60.0, 75.0, 85.0] {
                    let wo = wo_at(deg);
                    let table = bsdf.directional_albedo_tabulated(wo, &[]);
                    let (mc, se) = albedo_mc(&bsdf, wo, 200_000, 3);
                    let err = (table - mc).abs().max_element();
                    let bound = 4.0 * se as f32 + 0.006;
                    assert!(
                        err <= bound,
                        "{dist:?} roughness {roughness} metallic {metallic} at {deg} degrees: \
                         table {table} against sampling {mc} (standard error {se})"
                    );
                }
            }
        }
    }
}
