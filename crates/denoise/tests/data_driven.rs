//! The data-driven filter on synthetic frames with a known answer: a straightforward
//! per-pixel evaluation of the thesis's formulas (f64, the standard exp) agrees with the
//! vectorised filter; a constant image stays constant; a feature edge is not blurred across;
//! noise of known variance on a flat region falls by the window's pixel count; the sky passes
//! through; a NaN stays in its pixel; the thread count changes nothing; bad parameters and
//! buffers are refused.

use glam::Vec3;
use pathlight_denoise::{
    ColourUnits, ColourWeights, DataDriven, DataDrivenConfig, ErrorPair, Features, FilterError,
};

/// A frame's buffers, owned.
#[derive(Clone)]
struct Frame {
    width: usize,
    height: usize,
    direct: Vec<Vec3>,
    indirect: Vec<Vec3>,
    depth: Vec<f32>,
    normal: Vec<Vec3>,
    albedo: Vec<Vec3>,
    texture2: Vec<Vec3>,
    variance: Vec<[f32; 5]>,
    light_variance: Vec<[f32; 2]>,
    roughness: Vec<f32>,
    metallic: Vec<f32>,
}

impl Frame {
    /// A flat grey wall facing the camera at depth 2.
    fn flat(width: usize, height: usize, direct: Vec3, indirect: Vec3) -> Self {
        let n = width * height;
        Self {
            width,
            height,
            direct: vec![direct; n],
            indirect: vec![indirect; n],
            depth: vec![2.0; n],
            normal: vec![Vec3::Z; n],
            albedo: vec![Vec3::splat(0.5); n],
            texture2: vec![Vec3::splat(0.5); n],
            variance: vec![[0.0; 5]; n],
            light_variance: vec![[f32::NAN; 2]; n],
            roughness: vec![1.0; n],
            metallic: vec![0.0; n],
        }
    }

    fn features(&self) -> Features<'_> {
        Features {
            width: self.width,
            height: self.height,
            direct: &self.direct,
            indirect: &self.indirect,
            depth: &self.depth,
            normal: &self.normal,
            albedo: &self.albedo,
            texture2: &self.texture2,
            variance: &self.variance,
            light_variance: &self.light_variance,
            roughness: &self.roughness,
            metallic: &self.metallic,
        }
    }

    fn filter(&self, config: &DataDrivenConfig) -> Vec<Vec3> {
        self.filter_with(config, "widest")
    }

    /// With lanes no wider than `lanes` (`portable`, `avx2` or the widest).
    fn filter_with(&self, config: &DataDrivenConfig, lanes: &str) -> Vec<Vec3> {
        let mut out = vec![Vec3::ZERO; self.width * self.height];
        let mut filter = DataDriven::new();
        filter.set_lanes(lanes);
        filter.filter(&self.features(), config, &mut out).unwrap();
        out
    }
}

/// The filter with colour differences relative to the light's luminance, whose weights on
/// small noise are known (within 0.1% of 1): the synthetic tests below need that.
fn data_driven() -> DataDrivenConfig {
    DataDrivenConfig {
        colour_units: ColourUnits::Relative,
        sigma_direct: 0.75,
        sigma_indirect: 0.5,
        ..DataDrivenConfig::default()
    }
}

/// The filter as pathlight configures it by default (colour differences in the light's
/// standard errors), and [`data_driven`]: the known-answer tests whose answer holds whatever
/// the colour test's weights run both.
fn both() -> [DataDrivenConfig; 2] {
    [
        DataDrivenConfig {
            ..DataDrivenConfig::default()
        },
        data_driven(),
    ]
}

/// pathlight's generator, with normal deviates (Box-Muller).
struct Rng(pathlight_core::rng::Rng);

impl Rng {
    fn new(seed: u64) -> Self {
        Self(pathlight_core::rng::Rng::new(seed, 0))
    }

    fn uniform(&mut self) -> f64 {
        self.0.next_f32() as f64
    }

    fn normal(&mut self) -> f64 {
        let (u, v) = (self.uniform().max(1e-300), self.uniform());
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }

    fn vec3(&mut self, lo: f32, hi: f32) -> Vec3 {
        let mut c = || lo + (hi - lo) * self.uniform() as f32;
        Vec3::new(c(), c(), c())
    }

    /// Three normal deviates.
    fn normal3(&mut self) -> Vec3 {
        Vec3::new(
            self.normal() as f32,
            self.normal() as f32,
            self.normal() as f32,
        )
    }
}

/// The standard deviation of the red channel over the pixels `xs` x `ys` of a `width`-wide
/// image.
fn spread(
    img: &[Vec3],
    width: usize,
    xs: std::ops::Range<usize>,
    ys: std::ops::Range<usize>,
) -> f32 {
    let v: Vec<f32> = ys
        .flat_map(|y| xs.clone().map(move |x| img[y * width + x].x))
        .collect();
    let m = v.iter().sum::<f32>() / v.len() as f32;
    (v.iter().map(|x| (x - m) * (x - m)).sum::<f32>() / v.len() as f32).sqrt()
}

/// A frame with everything varying: two surfaces (a depth and normal edge), texture
/// patches, noisy light, feature variances, a sky corner and a row of sky.
fn busy(width: usize, height: usize, seed: u64) -> Frame {
    let mut rng = Rng::new(seed);
    let mut f = Frame::flat(width, height, Vec3::ZERO, Vec3::ZERO);
    for y in 0..height {
        for x in 0..width {
            let i = y * width + x;
            let right = x > width / 2;
            f.depth[i] = if right { 3.0 + 0.01 * y as f32 } else { 1.5 };
            f.normal[i] = if right {
                Vec3::new(0.6, 0.0, 0.8)
            } else {
                Vec3::Z
            };
            f.albedo[i] = if (x / 5 + y / 4) % 2 == 0 {
                Vec3::new(0.7, 0.6, 0.5)
            } else {
                Vec3::new(0.7, 0.65, 0.5)
            };
            f.texture2[i] = f.albedo[i] * 0.9 + rng.vec3(0.0, 0.05);
            f.direct[i] = rng.vec3(0.0, 1.5);
            f.indirect[i] = rng.vec3(0.0, 0.4);
            f.variance[i] = [
                rng.uniform() as f32 * 0.01,
                rng.uniform() as f32 * 0.5,
                rng.uniform() as f32 * 0.2,
                rng.uniform() as f32,
                rng.uniform() as f32 * 0.3,
            ];
            f.light_variance[i] = [rng.uniform() as f32 * 0.01, rng.uniform() as f32 * 0.002];
            // Metal of every kind, glossy to rough, and plain dielectrics.
            f.roughness[i] = rng.uniform() as f32;
            f.metallic[i] = if y % 3 == 0 {
                0.0
            } else {
                rng.uniform() as f32
            };
            // A sky corner, and a row of sky (whole groups of lanes that skip the window).
            if (x < 3 && y < 2) || y == height - 3 {
                f.depth[i] = f32::INFINITY;
            }
        }
    }
    f
}

/// The thesis's formulas pixel by pixel, in f64 with the standard exp.
fn reference(f: &Frame, c: &DataDrivenConfig) -> Vec<Vec3> {
    let k = |s: f32| 1.0 / (2.0 * s as f64 * s as f64);
    let r = (c.kernel / 2) as i64;
    let step = if c.holes { 2 } else { 1 };
    let sq = |a: Vec3, b: Vec3| (a - b).as_dvec3().length_squared();
    let mut out = vec![Vec3::ZERO; f.width * f.height];
    // Demodulation: the light over the albedo (each channel at least 0.01).
    let albedo = |i: usize| {
        if c.demodulate {
            f.albedo[i].max(Vec3::splat(0.01))
        } else {
            Vec3::ONE
        }
    };
    let direct: Vec<Vec3> = (0..f.direct.len())
        .map(|i| f.direct[i] / albedo(i))
        .collect();
    let indirect: Vec<Vec3> = (0..f.direct.len())
        .map(|i| f.indirect[i] / albedo(i))
        .collect();
    for y in 0..f.height as i64 {
        for x in 0..f.width as i64 {
            let p = (y * f.width as i64 + x) as usize;
            if !f.depth[p].is_finite() {
                out[p] = f.direct[p] + f.indirect[p];
                continue;
            }
            let v = f.variance[p];
            let s = c.variance_scale;
            let depth_scale = 1.0 / f.depth[p] as f64;
            let low =
                |kk: f64, var: f64, scale: f32| kk * (1.0 - (var * scale as f64).clamp(0.0, 1.0));
            let c_depth = low(
                k(c.sigma_depth),
                v[0] as f64 * depth_scale * depth_scale,
                s[0],
            );
            // A metallic pixel's normal sigma: toward the lobe's alpha times the factor.
            let m = (f.metallic[p] as f64).clamp(0.0, 1.0);
            let alpha = (f.roughness[p] as f64).powi(2).max(0.01);
            let sigma_normal = if c.sigma_normal_lobe > 0.0 {
                let lobe = (c.sigma_normal_lobe as f64 * alpha).min(c.sigma_normal as f64);
                c.sigma_normal as f64 + m * (lobe - c.sigma_normal as f64)
            } else {
                c.sigma_normal as f64
            };
            let c_normal = low(0.5 / (sigma_normal * sigma_normal), v[1] as f64, s[1]);
            let c_texture = low(k(c.sigma_texture), v[2] as f64, s[2]);
            let c_texture2 = if c.texture2_test {
                low(k(c.sigma_texture2), v[4] as f64, s[4])
            } else {
                0.0
            };
            let lum3 = |c: Vec3| c.dot(Vec3::new(0.2126, 0.7152, 0.0722)) as f64;
            // The colour test's channel weights: (a_c / L(a))^2 of the centre's albedo.
            let weights = match c.colour_weights {
                ColourWeights::Equal => glam::DVec3::ONE,
                ColourWeights::Albedo => {
                    let r = albedo(p).as_dvec3() / lum3(albedo(p));
                    r * r
                }
            };
            let colour_sq = |a: Vec3, b: Vec3| {
                let d = (a - b).as_dvec3();
                (weights * d * d).element_sum()
            };
            let lum = |i: usize| lum3(direct[i] + indirect[i]).max(0.0);
            // The colour differences' scales of pixel i, direct and indirect: a factor, or
            // the standard error of its mean light.
            let scales = |i: usize| -> [f64; 2] {
                match c.colour_units {
                    ColourUnits::Linear => [1.0; 2],
                    ColourUnits::Relative => [1.0 / (1.0 + lum(i)); 2],
                    ColourUnits::Variance => {
                        let a = lum3(albedo(i));
                        let floor = 0.01 * (1.0 + lum(i));
                        f.light_variance[i].map(|v| (v as f64 / (a * a)).sqrt().max(floor))
                    }
                }
            };
            // A squared colour difference's coefficient between pixels p and q.
            let colour = |sigma: f32, sp: f64, sq: f64| match c.colour_units {
                ColourUnits::Variance => match c.error_pair {
                    ErrorPair::Sum => k(sigma) / (sp * sp + sq * sq),
                    ErrorPair::Product => k(sigma) / (sp * sq),
                },
                _ => k(sigma) * sp * sq,
            };
            let (mut wd_sum, mut wi_sum) = (0.0, 0.0);
            let (mut d_sum, mut i_sum) = (glam::DVec3::ZERO, glam::DVec3::ZERO);
            // The window's taps: every `step`-th pixel from its corner, and its centre (which
            // the holes of an odd radius skip).
            let mut taps: Vec<(i64, i64)> = (-r..=r)
                .step_by(step)
                .flat_map(|dy| (-r..=r).step_by(step).map(move |dx| (dx, dy)))
                .collect();
            if !taps.contains(&(0, 0)) {
                taps.push((0, 0));
            }
            {
                for (dx, dy) in taps {
                    let (qx, qy) = (x + dx, y + dy);
                    if qx < 0 || qy < 0 || qx >= f.width as i64 || qy >= f.height as i64 {
                        continue;
                    }
                    let q = (qy * f.width as i64 + qx) as usize;
                    if !f.depth[q].is_finite() {
                        continue;
                    }
                    let dd = (f.depth[q] - f.depth[p]) as f64 * depth_scale;
                    let feat = c_depth * dd * dd
                        + c_normal * sq(f.normal[q], f.normal[p])
                        + c_texture * sq(f.albedo[q], f.albedo[p]);
                    let (sp, sq_) = (scales(p), scales(q));
                    let (c_direct, c_indirect) = (
                        colour(c.sigma_direct, sp[0], sq_[0]),
                        colour(c.sigma_indirect, sp[1], sq_[1]),
                    );
                    let wd = (-(c_direct * colour_sq(direct[q], direct[p]) + feat)).exp();
                    let wi = (-(c_indirect * colour_sq(indirect[q], indirect[p])
                        + feat
                        + c_texture2 * sq(f.texture2[q], f.texture2[p])))
                    .exp();
                    wd_sum += wd;
                    wi_sum += wi;
                    d_sum += wd * direct[q].as_dvec3();
                    i_sum += wi * indirect[q].as_dvec3();
                }
            }
            out[p] = (d_sum / wd_sum + i_sum / wi_sum).as_vec3() * albedo(p);
        }
    }
    out
}

#[test]
fn agrees_with_the_formulas_evaluated_pixel_by_pixel() {
    // A width that is not a multiple of the 16 lanes, windows cut by every border; every
    // kind of lanes in turn (those this processor lacks fall back to narrower ones).
    let f = busy(37, 23, 7);
    // The channel weights on a saturated surface (reds of two shades).
    let mut red = f.clone();
    for a in &mut red.albedo {
        *a *= Vec3::new(1.0, 0.2, 0.05);
    }
    let (sum, product) = (ErrorPair::Sum, ErrorPair::Product);
    for case in [
        (1, false, true, ColourUnits::Relative, sum, false, "widest"),
        (5, false, true, ColourUnits::Variance, sum, true, "avx2"),
        (
            5,
            false,
            true,
            ColourUnits::Variance,
            product,
            false,
            "avx2",
        ),
        (9, true, false, ColourUnits::Linear, sum, true, "portable"),
        (7, true, true, ColourUnits::Variance, sum, false, "widest"),
        (21, false, true, ColourUnits::Relative, sum, true, "widest"),
        (21, true, false, ColourUnits::Variance, sum, false, "avx2"),
        (
            21,
            false,
            true,
            ColourUnits::Variance,
            sum,
            false,
            "portable",
        ),
        (
            21,
            false,
            true,
            ColourUnits::Variance,
            product,
            true,
            "portable",
        ),
        (21, false, true, ColourUnits::Variance, sum, false, "widest"),
        (
            21,
            true,
            true,
            ColourUnits::Variance,
            product,
            true,
            "widest",
        ),
    ]
    .into_iter()
    .flat_map(|case| [(case, ColourWeights::Equal), (case, ColourWeights::Albedo)])
    {
        let ((kernel, holes, demodulate, colour_units, error_pair, texture2_test, lanes), weights) =
            case;
        let c = DataDrivenConfig {
            kernel,
            holes,
            demodulate,
            colour_units,
            error_pair,
            texture2_test,
            colour_weights: weights,
            // The glossy normal test off, the default, wider.
            sigma_normal_lobe: match kernel {
                9 => 0.0,
                5 => 2.5,
                _ => 1.0,
            },
            ..data_driven()
        };
        let f = match weights {
            ColourWeights::Equal => &f,
            ColourWeights::Albedo => &red,
        };
        let (got, want) = (f.filter_with(&c, lanes), reference(f, &c));
        let mut worst = 0.0f32;
        for (g, w) in got.iter().zip(&want) {
            worst = worst.max((*g - *w).abs().max_element() / w.abs().max_element().max(0.01));
        }
        assert!(
            worst < 1e-4,
            "kernel {kernel} holes {holes} demodulate {demodulate} {error_pair:?} texture2 \
             {texture2_test} {weights:?} lanes {lanes} lobe {}: {worst}",
            c.sigma_normal_lobe
        );
        // The filter does something here (but for the 1x1 window).
        let moved = got
            .iter()
            .zip(f.direct.iter().zip(&f.indirect))
            .any(|(g, (d, i))| (*g - (*d + *i)).abs().max_element() > 0.01);
        assert_eq!(moved, kernel > 1, "kernel {kernel}");
    }
}

#[test]
fn a_constant_image_stays_constant() {
    let (d, i) = (Vec3::new(0.3, 0.5, 0.7), Vec3::new(0.05, 0.1, 0.02));
    let f = Frame::flat(50, 30, d, i);
    for holes in [false, true] {
        for config in both() {
            let out = f.filter(&DataDrivenConfig { holes, ..config });
            for o in out {
                assert!((o - (d + i)).abs().max_element() < 1e-5, "{o}");
            }
        }
    }
}

/// Pixels outside the image and the sky's are nobody's neighbours, however loose the tests:
/// with every sigma huge a neighbour that counted would weigh about 1 and pull its pixel
/// toward its own light (0 for the padding, the environment's for the sky).
#[test]
fn the_border_and_the_sky_are_nobodys_neighbours_however_loose_the_tests() {
    let (d, i) = (Vec3::new(0.3, 0.5, 0.7), Vec3::new(0.05, 0.1, 0.02));
    let mut f = Frame::flat(40, 24, d, i);
    for y in 8..14 {
        for x in 15..22 {
            f.depth[y * 40 + x] = f32::INFINITY;
            f.direct[y * 40 + x] = Vec3::splat(20.0);
        }
    }
    let loose = DataDrivenConfig {
        sigma_direct: 1e4,
        sigma_indirect: 1e4,
        sigma_depth: 1e4,
        sigma_normal: 1e4,
        sigma_texture: 1e4,
        ..data_driven()
    };
    for (holes, lanes) in [
        (false, "widest"),
        (true, "widest"),
        (true, "avx2"),
        (true, "portable"),
    ] {
        let out = f.filter_with(&DataDrivenConfig { holes, ..loose }, lanes);
        for (k, o) in out.iter().enumerate() {
            let want = if f.depth[k].is_finite() {
                d + i
            } else {
                f.direct[k] + f.indirect[k]
            };
            assert!(
                (*o - want).abs().max_element() < 1e-5,
                "({}, {}) {o} with {lanes} lanes",
                k % 40,
                k / 40
            );
        }
    }
}

#[test]
fn a_feature_edge_is_not_blurred_across() {
    // Left: a wall facing the camera lit at 0.2; right: a wall at a right angle lit at 0.9.
    // Each side's light is flat, so the filter must give each side its own value exactly
    // (up to the edge weights of the normal test, exp(-16) per neighbour).
    let mut f = Frame::flat(40, 20, Vec3::splat(0.2), Vec3::ZERO);
    for y in 0..20 {
        for x in 20..40 {
            f.normal[y * 40 + x] = Vec3::X;
            f.direct[y * 40 + x] = Vec3::splat(0.9);
        }
    }
    for config in both() {
        let out = f.filter(&config);
        for y in 0..20 {
            for x in 0..40 {
                let want = if x < 20 { 0.2 } else { 0.9 };
                let got = out[y * 40 + x];
                assert!(
                    (got - Vec3::splat(want)).abs().max_element() < 1e-4,
                    "({x},{y}) {got} ({:?} units)",
                    config.colour_units
                );
            }
        }
    }
    // The same light edge without a feature edge is blurred: the features are what keeps it.
    let mut flat = f.clone();
    flat.normal.fill(Vec3::Z);
    let blurred = flat.filter(&data_driven());
    assert!(blurred[10 * 40 + 19].x > 0.25, "{}", blurred[10 * 40 + 19]);
}

/// A wire one pixel wide keeps its light under every window, the holes of an odd radius too
/// (7x7 and 15x15: they skip the window's centre, which counts all the same).
#[test]
fn a_wire_one_pixel_wide_keeps_its_light() {
    let mut f = Frame::flat(41, 21, Vec3::splat(0.2), Vec3::ZERO);
    for y in 0..21 {
        f.normal[y * 41 + 20] = Vec3::X;
        f.direct[y * 41 + 20] = Vec3::splat(0.9);
    }
    for (kernel, holes) in [(7, true), (15, true), (21, true), (7, false)] {
        let out = f.filter(&DataDrivenConfig {
            kernel,
            holes,
            ..data_driven()
        });
        for y in 0..21 {
            for x in 0..41 {
                let want = if x == 20 { 0.9 } else { 0.2 };
                let got = out[y * 41 + x];
                assert!(
                    (got - Vec3::splat(want)).abs().max_element() < 1e-4,
                    "kernel {kernel} holes {holes} ({x},{y}) {got}"
                );
            }
        }
    }
}

#[test]
fn a_glossy_metal_keeps_its_reflections_apart() {
    // Two halves of one metal wall whose normals differ by 0.2 radians, each reflecting
    // another flat light (0.2, 0.9). The thesis's normal test (sigma 0.25) lets the other
    // half in; at a glossy metallic pixel the test is as tight as the lobe (alpha = 0.04 at
    // roughness 0.2: a weight of exp(-12.5) across the edge), so each half keeps its own light.
    let tilted = Vec3::new(0.2f32.sin(), 0.0, 0.2f32.cos());
    let mut f = Frame::flat(40, 20, Vec3::splat(0.2), Vec3::ZERO);
    for y in 0..20 {
        for x in 20..40 {
            f.normal[y * 40 + x] = tilted;
            f.direct[y * 40 + x] = Vec3::splat(0.9);
        }
    }
    f.roughness.fill(0.2);
    f.metallic.fill(1.0);
    let edge = |out: &[Vec3]| [out[10 * 40 + 19].x, out[10 * 40 + 20].x];
    let [left, right] = edge(&f.filter(&data_driven()));
    assert!(
        (left - 0.2).abs() < 1e-4 && (right - 0.9).abs() < 1e-4,
        "{left} {right}"
    );
    // The thesis's test, a dielectric, a rough metal: the edge is blurred.
    let thesis = DataDrivenConfig {
        sigma_normal_lobe: 0.0,
        ..data_driven()
    };
    let mut dielectric = f.clone();
    dielectric.metallic.fill(0.0);
    let mut rough = f.clone();
    rough.roughness.fill(1.0);
    for (name, out) in [
        ("thesis", f.filter(&thesis)),
        ("dielectric", dielectric.filter(&data_driven())),
        ("rough", rough.filter(&data_driven())),
    ] {
        let [left, right] = edge(&out);
        assert!(left > 0.25 && right < 0.85, "{name}: {left} {right}");
    }
}

#[test]
fn noise_on_a_flat_region_falls_by_the_window_size() {
    // Independent noise of standard deviation 0.02 (direct) and 0.01 (indirect) on a flat
    // wall: the colour tests then weigh every neighbour within 0.1% of 1, so the output is the
    // window's mean and its variance the input's over the window's pixel count.
    let (w, h) = (400, 300);
    let mut rng = Rng::new(11);
    let mut f = Frame::flat(w, h, Vec3::ZERO, Vec3::ZERO);
    let (sd, si) = (0.02f64, 0.01f64);
    for p in 0..w * h {
        f.direct[p] = Vec3::splat(0.5) + rng.normal3() * sd as f32;
        f.indirect[p] = Vec3::splat(0.1) + rng.normal3() * si as f32;
    }
    for (kernel, holes, taps) in [(7, false, 49.0), (21, false, 441.0), (21, true, 121.0)] {
        let out = f.filter(&DataDrivenConfig {
            kernel,
            holes,
            ..data_driven()
        });
        let r = kernel as usize / 2;
        let mut values = Vec::new();
        for y in r..h - r {
            for x in r..w - r {
                let o = out[y * w + x];
                values.extend([o.x as f64, o.y as f64, o.z as f64]);
            }
        }
        let mean = values.iter().sum::<f64>() / values.len() as f64;
        let var =
            values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (values.len() - 1) as f64;
        let expected = (sd * sd + si * si) / taps;
        let ratio = var / expected;
        // About 100-700 independent windows per channel: a few percent of spread.
        assert!(
            (ratio - 1.0).abs() < 0.2,
            "kernel {kernel} holes {holes}: variance {var:.3e}, expected {expected:.3e}"
        );
        assert!((mean - 0.6).abs() < 1e-3, "{mean}");
    }
}

#[test]
fn sky_pixels_pass_through_and_light_nobody() {
    let mut f = Frame::flat(30, 20, Vec3::splat(0.3), Vec3::splat(0.1));
    for y in 0..20 {
        for x in 0..10 {
            let i = y * 30 + x;
            f.depth[i] = f32::INFINITY;
            f.direct[i] = Vec3::new(5.0 + x as f32, 2.0, 1.0);
            f.indirect[i] = Vec3::ZERO;
        }
    }
    for config in both() {
        let out = f.filter(&config);
        for y in 0..20 {
            for x in 0..30 {
                let i = y * 30 + x;
                let want = if x < 10 {
                    f.direct[i]
                } else {
                    Vec3::splat(0.4)
                };
                assert!(
                    (out[i] - want).abs().max_element() < 1e-5,
                    "({x},{y}) {} ({:?} units)",
                    out[i],
                    config.colour_units
                );
            }
        }
    }
}

#[test]
fn a_nan_or_infinite_sample_stays_in_its_pixel() {
    for bad in [f32::NAN, f32::INFINITY, 1e30] {
        let mut f = Frame::flat(30, 20, Vec3::splat(0.3), Vec3::splat(0.1));
        f.direct[10 * 30 + 15].y = bad;
        f.normal[5 * 30 + 5].x = bad;
        f.variance[3 * 30 + 20][1] = bad;
        f.roughness[7 * 30 + 3] = bad;
        f.metallic[7 * 30 + 3] = 1.0;
        f.metallic[8 * 30 + 9] = bad;
        f.light_variance[4 * 30 + 25][0] = bad;
        for config in both() {
            let out = f.filter(&config);
            for (i, o) in out.iter().enumerate() {
                if i == 10 * 30 + 15 {
                    continue;
                }
                assert!(
                    (*o - Vec3::splat(0.4)).abs().max_element() < 1e-5,
                    "{bad}: pixel {i} {o} ({:?} units)",
                    config.colour_units
                );
            }
        }
    }
}

#[test]
fn the_thread_count_changes_nothing() {
    let f = busy(91, 47, 3);
    let c = DataDrivenConfig {
        holes: true,
        ..data_driven()
    };
    let run = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| f.filter(&c))
    };
    let one = run(1);
    for threads in [2, 3, 8] {
        assert!(
            run(threads)
                .iter()
                .zip(&one)
                .all(|(a, b)| a.to_array().map(f32::to_bits) == b.to_array().map(f32::to_bits)),
            "{threads} threads"
        );
    }
}

#[test]
fn bad_parameters_and_buffers_are_refused() {
    let f = Frame::flat(8, 4, Vec3::ONE, Vec3::ZERO);
    let mut out = vec![Vec3::ZERO; 32];
    let mut filter = DataDriven::new();
    for c in [
        DataDrivenConfig {
            kernel: 4,
            ..data_driven()
        },
        DataDrivenConfig {
            sigma_texture: -0.1,
            ..data_driven()
        },
        DataDrivenConfig {
            sigma_indirect: f32::NAN,
            ..data_driven()
        },
    ] {
        assert!(matches!(
            filter.filter(&f.features(), &c, &mut out),
            Err(FilterError::Parameter { .. })
        ));
    }
    let mut short = f.clone();
    short.albedo.pop();
    let e = filter
        .filter(&short.features(), &data_driven(), &mut out)
        .unwrap_err();
    assert!(e.to_string().contains("albedo"), "{e}");
    let e = filter
        .filter(&f.features(), &data_driven(), &mut out[..31])
        .unwrap_err();
    assert!(e.to_string().contains("output"), "{e}");
    // An empty frame is nothing to do.
    let empty = Frame::flat(0, 0, Vec3::ONE, Vec3::ZERO);
    filter
        .filter(&empty.features(), &data_driven(), &mut [])
        .unwrap();
}

#[test]
fn a_filter_kept_across_frames_gives_what_a_new_one_gives() {
    let c = data_driven();
    let mut kept = DataDriven::new();
    let mut run = |f: &Frame, c: &DataDrivenConfig| {
        let mut out = vec![Vec3::ZERO; f.width * f.height];
        kept.filter(&f.features(), c, &mut out).unwrap();
        out
    };
    let first = busy(37, 23, 1);
    run(&first, &c);
    // The next frame: pixels that were valid are now sky or bad, then another size and window.
    let mut second = busy(37, 23, 2);
    second.depth[100] = f32::INFINITY;
    second.direct[200].x = f32::NAN;
    let bits = |v: &[Vec3]| {
        v.iter()
            .map(|p| p.to_array().map(f32::to_bits))
            .collect::<Vec<_>>()
    };
    assert_eq!(bits(&run(&second, &c)), bits(&second.filter(&c)));
    let small = DataDrivenConfig { kernel: 5, ..c };
    let third = busy(20, 9, 3);
    assert_eq!(bits(&run(&third, &small)), bits(&third.filter(&small)));
    assert_eq!(bits(&run(&second, &c)), bits(&second.filter(&c)));
}

#[test]
fn demodulation_keeps_a_texture_under_even_light() {
    // A wall in even light whose albedo alternates in 2-pixel stripes of 0.5 and 0.56 (within
    // the texture test's reach): demodulated, the illumination is flat and the texture comes
    // back exactly; without, the stripes are blurred into each other.
    let mut f = Frame::flat(48, 24, Vec3::ZERO, Vec3::ZERO);
    for y in 0..24 {
        for x in 0..48 {
            let a = if (x / 2) % 2 == 0 { 0.5 } else { 0.56 };
            let i = y * 48 + x;
            f.albedo[i] = Vec3::splat(a);
            f.direct[i] = Vec3::splat(0.8 * a);
            f.indirect[i] = Vec3::splat(0.2 * a);
        }
    }
    let kept = f.filter(&data_driven());
    let blurred = f.filter(&DataDrivenConfig {
        demodulate: false,
        ..data_driven()
    });
    let contrast = |img: &[Vec3]| (img[12 * 48 + 26].x - img[12 * 48 + 24].x).abs();
    assert!((contrast(&kept) - 0.06).abs() < 1e-5, "{}", contrast(&kept));
    assert!(contrast(&blurred) < 0.04, "{}", contrast(&blurred));
}

/// A flat wall whose direct light steps from 0.4 to 0.6 halfway across (a shadow's edge, no
/// feature edge), with noise of standard deviation 0.2 per sample averaged over `n` samples
/// (the standard error given as the light's variance).
fn shadow_step(w: usize, h: usize, n: f32, seed: u64) -> Frame {
    let mut rng = Rng::new(seed);
    let mut f = Frame::flat(w, h, Vec3::ZERO, Vec3::ZERO);
    let error = 0.2 / n.sqrt();
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            let light = if x < w / 2 { 0.4 } else { 0.6 };
            f.direct[i] = Vec3::splat(light + error * rng.normal() as f32);
            f.light_variance[i] = [error * error, 0.0];
        }
    }
    f
}

#[test]
fn variance_units_follow_the_noise() {
    // A flat wall whose light steps from 0.4 to 0.6 halfway (a shadow's edge, no feature edge),
    // with noise of standard deviation 0.2 per sample averaged over n samples. In variance
    // units the colour test scales with the standard error: at 4 samples the flat parts are
    // smoothed; at 4096 the step (100 standard errors) is kept where relative units blur it.
    let (w, h) = (64, 32);
    let image = |n: f32| shadow_step(w, h, n, 5);
    let variance = DataDrivenConfig {
        colour_units: ColourUnits::Variance,
        sigma_direct: 3.0,
        sigma_indirect: 3.0,
        ..data_driven()
    };
    // Spread of a flat 8x8 patch away from the step.
    let noise = |img: &[Vec3]| spread(img, w, 4..12, 10..18);
    let few = image(4.0);
    let out = few.filter(&variance);
    assert!(
        noise(&out) < 0.4 * noise(&few.direct),
        "{} vs {}",
        noise(&out),
        noise(&few.direct)
    );
    let many = image(4096.0);
    let step = |img: &[Vec3]| img[16 * w + w / 2].x - img[16 * w + w / 2 - 1].x;
    let kept = step(&many.filter(&variance));
    assert!((kept - 0.2).abs() < 0.02, "step {kept}");
    let blurred = step(&many.filter(&data_driven()));
    assert!(blurred < 0.1, "relative units: step {blurred}");
    // Unknown variances (NaN) are estimated from the 3x3 neighbourhood: the flat parts of the
    // 4-sample image are still smoothed.
    let mut unknown = few.clone();
    unknown.light_variance.fill([f32::NAN; 2]);
    let out = unknown.filter(&variance);
    assert!(noise(&out) < 0.5 * noise(&few.direct), "{}", noise(&out));
}

#[test]
fn blurred_errors_filter_a_pixel_whose_few_samples_agreed() {
    // A flat wall at 0.5 whose pixels' means have a standard error of 1 (demodulated), but one
    // pixel whose few samples happened to agree (variance 0) and which sits at 2 (3 above the
    // rest once demodulated).
    // With the errors' product in the colour test its own error (the floor) makes it a wall
    // to every neighbour, and it stays as it is. With `error_blur` its error is its
    // neighbourhood's (the root of the mean of the squares: sqrt(8/9)), and the window
    // averages it with the wall like any pixel.
    let (w, h) = (33, 33);
    let mut f = Frame::flat(w, h, Vec3::splat(0.5), Vec3::ZERO);
    // The variance of the mean of the (not demodulated) luminance: 0.5^2 for an error of 1
    // once divided by the albedo's 0.5.
    f.light_variance.fill([0.25, 0.0]);
    let centre = 16 * w + 16;
    f.direct[centre] = Vec3::splat(2.0);
    f.light_variance[centre] = [0.0, 0.0];
    let variance = DataDrivenConfig {
        colour_units: ColourUnits::Variance,
        error_pair: ErrorPair::Product,
        sigma_direct: 3.0,
        sigma_indirect: 3.0,
        ..data_driven()
    };
    let blur = DataDrivenConfig {
        error_blur: true,
        ..variance
    };
    let (plain, blurred) = (f.filter(&variance), f.filter(&blur));
    assert!(
        (plain[centre].x - 2.0).abs() < 1e-3,
        "without the blur: {}",
        plain[centre]
    );
    assert!(
        (blurred[centre].x - 0.5).abs() < 0.03,
        "with the blur: {}",
        blurred[centre]
    );
    // Away from it the wall is the wall either way.
    let far = 4 * w + 4;
    assert!((plain[far] - Vec3::splat(0.5)).abs().max_element() < 1e-5);
    assert!((blurred[far] - Vec3::splat(0.5)).abs().max_element() < 1e-5);
}

#[test]
fn a_firefly_joins_its_wall_when_the_errors_add() {
    // A flat grey wall at 0.5 (1 demodulated by its albedo of 0.5) whose pixels' means have a
    // standard error of 0.1 (demodulated), and one pixel at 2 whose samples held a firefly:
    // a standard error of 3. Demodulated it is 3 above the wall in each channel, a squared
    // difference of 27. Over the sum of the squared errors (9.01) and 2 sigma^2 (4.5) each
    // neighbour weighs e^-0.67 and the 440 of them pull it to the wall; over their product
    // (0.3) the weight is e^-20: no neighbour counts and the firefly stays.
    let (w, h) = (33, 33);
    let mut f = Frame::flat(w, h, Vec3::splat(0.5), Vec3::ZERO);
    // Variances of the means of the luminance before demodulation (errors 0.05 and 1.5).
    f.light_variance.fill([0.05 * 0.05, 0.0]);
    let centre = 16 * w + 16;
    f.direct[centre] = Vec3::splat(2.0);
    f.light_variance[centre] = [1.5 * 1.5, 0.0];
    let config = |error_pair| DataDrivenConfig {
        colour_units: ColourUnits::Variance,
        error_pair,
        sigma_direct: 1.5,
        sigma_indirect: 1.5,
        ..data_driven()
    };
    let (sum, product) = (
        f.filter(&config(ErrorPair::Sum)),
        f.filter(&config(ErrorPair::Product)),
    );
    let weight = (-27.0f32 / (4.5 * 9.01)).exp();
    let want = 0.5 * (4.0 + 440.0 * weight) / (1.0 + 440.0 * weight);
    assert!(
        (sum[centre].x - want).abs() < 1e-3,
        "{} vs {want}",
        sum[centre]
    );
    assert!(sum[centre].x < 0.51, "{}", sum[centre]);
    assert!(
        (product[centre].x - 2.0).abs() < 1e-3,
        "{}",
        product[centre]
    );
    // Its neighbours take a little of it with the sum (its 3 at its weight among 441), none
    // with the product; the wall outside its window is the wall.
    let next = centre + 1;
    let lent = sum[next].x - 0.5;
    let most = 0.5 * 3.0 * weight / (440.0 + weight);
    assert!(lent > 0.5 * most && lent < most + 1e-5, "{lent} vs {most}");
    assert!((product[next].x - 0.5).abs() < 1e-5, "{}", product[next]);
    let far = 2 * w + 2;
    for out in [&sum, &product] {
        assert!((out[far] - Vec3::splat(0.5)).abs().max_element() < 1e-5);
    }
}

#[test]
fn texture2_noise_refuses_neighbours_only_with_the_thesis_test() {
    // A flat wall whose indirect light is 0.5 plus noise of deviation 0.05 and whose texture2
    // (the mean albedo of a pixel's few second hits) is uniform noise in [0, 1]^3. Without
    // the texture2 test the 21x21 window averages 441 pixels: the noise falls to about
    // 0.05 / 21. With the thesis's test (sigma 0.1) a neighbour's weight is
    // exp(-50 |dT2|^2), on average (sqrt(pi / 50) - 1 / 50)^3 = 0.012 for the difference of
    // two uniform colours: the window counts about 1 + 441 x 0.012 = 6.4 pixels' worth and
    // the noise falls only to about 0.05 / 2.5.
    let (w, h) = (41, 41);
    let mut f = Frame::flat(w, h, Vec3::ZERO, Vec3::splat(0.5));
    let mut rng = Rng::new(3);
    for i in 0..w * h {
        f.indirect[i] += Vec3::splat(0.05 * rng.normal() as f32);
        f.texture2[i] = rng.vec3(0.0, 1.0);
    }
    // Spread of the 21x21 block of pixels whose windows lie inside the image.
    let inside = |img: &[Vec3]| spread(img, w, 10..31, 10..31);
    let before = inside(&f.indirect);
    let without = inside(&f.filter(&data_driven()));
    let with = inside(&f.filter(&DataDrivenConfig {
        texture2_test: true,
        ..data_driven()
    }));
    assert!((before - 0.05).abs() < 0.005, "{before}");
    assert!(without < 2.0 * 0.05 / 21.0, "without the test: {without}");
    assert!(
        with > before / 4.0 && with < before / 2.0,
        "with the test: {with} against {before}"
    );
}

#[test]
fn the_sure_blend_keeps_a_step_a_loose_test_blurs_and_still_smooths_noise() {
    // The wall of `variance_units_follow_the_noise`: light stepping from 0.4 to 0.6 halfway
    // (a shadow's edge, no feature edge), noise of standard deviation 0.2 per sample over n
    // samples. With a loose colour test (sigma 30 standard errors) the filter blurs the step
    // even at 4096 samples (64 standard errors); blended by SURE the pixels by the step take
    // their own light back, and the flat parts of a 4-sample image are still smoothed.
    let (w, h) = (64, 32);
    let image = |n: f32| shadow_step(w, h, n, 7);
    let loose = DataDrivenConfig {
        colour_units: ColourUnits::Variance,
        sigma_direct: 30.0,
        sigma_indirect: 30.0,
        ..DataDrivenConfig::default()
    };
    let sure = DataDrivenConfig {
        sure: true,
        sure_radius: 3,
        ..loose
    };
    let step = |img: &[Vec3]| img[16 * w + w / 2].x - img[16 * w + w / 2 - 1].x;
    let many = image(4096.0);
    let blurred = step(&many.filter(&loose));
    assert!(blurred < 0.15, "without the blend: step {blurred}");
    let kept = step(&many.filter(&sure));
    assert!((kept - 0.2).abs() < 0.02, "with the blend: step {kept}");
    // Every pixel within a few standard errors of the truth.
    let out = many.filter(&sure);
    for y in 0..h {
        for x in 0..w {
            let truth = if x < w / 2 { 0.4 } else { 0.6 };
            let e = (out[y * w + x].x - truth).abs();
            assert!(e < 5.0 * 0.2 / 64.0, "pixel ({x}, {y}) off by {e}");
        }
    }
    let few = image(4.0);
    let noise = |img: &[Vec3]| spread(img, w, 4..12, 10..18);
    let (before, loose_noise, after) = (
        noise(&few.direct),
        noise(&few.filter(&loose)),
        noise(&few.filter(&sure)),
    );
    // The filter alone takes the noise down 34x; blended, a little of the pixels' own noise
    // comes back where the estimates' own noise lets a share of it through (7.7x measured
    // with seed 7).
    assert!(
        after < 0.15 * before,
        "flat part: {after} with the blend, {loose_noise} without, {before} unfiltered"
    );
    // The thread count changes nothing.
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let one = pool.install(|| many.filter(&sure));
    assert_eq!(one, out);
    // A pixel whose variance is finite but so large that its estimates are not numbers
    // (`-v + 2 v / W`) counts for nothing and keeps its filtered light: every pixel is
    // written, and finite.
    let mut hostile = many.clone();
    hostile.light_variance[5 * w + 5] = [1e38, 0.0];
    let mut filter = DataDriven::new();
    let mut o = vec![Vec3::NAN; w * h];
    filter.filter(&hostile.features(), &sure, &mut o).unwrap();
    assert!(o.iter().all(|v| v.is_finite()));
    // The blend needs standard errors, and a bounded neighbourhood.
    for bad in [
        DataDrivenConfig {
            colour_units: ColourUnits::Relative,
            ..sure
        },
        DataDrivenConfig {
            sure_radius: 1000,
            ..sure
        },
    ] {
        let err = filter.filter(&many.features(), &bad, &mut o).unwrap_err();
        assert!(matches!(err, FilterError::Parameter { .. }), "{err}");
    }
}

#[test]
fn albedo_weights_keep_a_step_in_the_channel_a_saturated_wall_shows() {
    // A red wall (albedo 0.8, 0.05, 0.05) whose illumination's red channel steps from 0.7 to
    // 1 halfway across (its green and blue stay 1), with noise of standard deviation 0.1 in
    // each channel of the illumination, the light's variance given as the colour weights
    // measure it. Demodulated, the green and blue channels' noise is as large as the red's,
    // but the wall shows them at a sixteenth of it: tested alike, their noise hides the step
    // and the filter blurs it; weighted by the albedo, the test sees the step the pixel shows
    // (three standard deviations) and keeps it, and still smooths the flat parts.
    let (w, h) = (64, 32);
    let albedo = Vec3::new(0.8, 0.05, 0.05);
    let sigma = 0.1f32;
    let image = |weights: ColourWeights| {
        let mut rng = Rng::new(11);
        let mut f = Frame::flat(w, h, Vec3::ZERO, Vec3::ZERO);
        let variance = albedo * albedo * sigma * sigma;
        let measured = match weights {
            ColourWeights::Equal => pathlight_core::color::luminance(variance),
            ColourWeights::Albedo => variance.element_sum() / 3.0,
        };
        for y in 0..h {
            for x in 0..w {
                let i = y * w + x;
                let red = if x < w / 2 { 0.7 } else { 1.0 };
                let light = Vec3::new(red, 1.0, 1.0) + sigma * rng.normal3();
                f.direct[i] = albedo * light;
                f.albedo[i] = albedo;
                f.light_variance[i] = [measured, 0.0];
            }
        }
        f
    };
    let config = |weights| DataDrivenConfig {
        colour_weights: weights,
        ..DataDrivenConfig::default()
    };
    // The red step between the two middle columns, averaged over the rows (0.24 shown).
    let step = |img: &[Vec3]| {
        (0..h)
            .map(|y| img[y * w + w / 2].x - img[y * w + w / 2 - 1].x)
            .sum::<f32>()
            / h as f32
    };
    let noise = |img: &[Vec3]| spread(img, w, 4..12, 10..18);
    let equal = image(ColourWeights::Equal);
    let weighted = image(ColourWeights::Albedo);
    let (blurred, kept) = (
        step(&equal.filter(&config(ColourWeights::Equal))),
        step(&weighted.filter(&config(ColourWeights::Albedo))),
    );
    assert!(blurred < 0.16, "channels alike: step {blurred}");
    assert!((kept - 0.24).abs() < 0.03, "weighted: step {kept}");
    let (before, after) = (
        noise(&weighted.direct),
        noise(&weighted.filter(&config(ColourWeights::Albedo))),
    );
    // 0.49 measured (a grey wall of the same illumination's noise under the plain test:
    // 0.24; with its noise in one channel, the test picks neighbours whose noise is like the
    // centre's more often).
    assert!(after < 0.6 * before, "flat part: {after} against {before}");
    // Unknown variances (one sample): the neighbourhood's errors (which the step itself
    // raises beside it), scaled to the channels' mean, keep most of the step.
    let unknown = |f: &Frame, weights| {
        let mut f = f.clone();
        f.light_variance.fill([f32::NAN; 2]);
        step(&f.filter(&config(weights)))
    };
    let (blurred, kept) = (
        unknown(&equal, ColourWeights::Equal),
        unknown(&weighted, ColourWeights::Albedo),
    );
    assert!(
        blurred < 0.16,
        "channels alike, unknown variances: step {blurred}"
    );
    assert!(kept > 0.18, "weighted, unknown variances: step {kept}");
}
