//! Random Parameter Filtering on synthetic sample sets with a known answer: a constant image
//! stays constant; noise that comes from a random parameter on a flat region is averaged away
//! (by at least the factor a box of neighbours gives); colour edges that the features see are
//! not blurred across (and are without them); a colour edge that depends on the screen
//! position alone is kept; a NaN sample does not spread; sky samples pass through and lend
//! nothing to their neighbours; the thread count changes nothing; bad parameters and sizes
//! are refused.

use std::sync::atomic::AtomicBool;

use pathlight_core::rng::Rng;
use pathlight_denoise::rpf::{filter, FeatureKind, RpfParams, SampleSet};
use pathlight_denoise::FilterError;

/// Random parameters per sample (lens u, v and a bounce direction's three coordinates, as
/// pathlight's path tracer fills them).
const RANDOM: usize = 5;

static NO: AtomicBool = AtomicBool::new(false);

/// A `size` x `size` image at `spp` with one position feature (3 values) and one texture
/// feature (3 values); `colour(x, y, r)` gives a sample's colour from its pixel and its first
/// random parameter, `texture(x, y)` the texture feature.
fn synthetic(
    size: usize,
    spp: usize,
    colour: impl Fn(usize, usize, f32) -> [f32; 3],
    texture: impl Fn(usize, usize) -> f32,
) -> SampleSet {
    let kinds = [FeatureKind::Position; 3]
        .into_iter()
        .chain([FeatureKind::Other; 3])
        .collect();
    let mut set = SampleSet::new(size, size, spp, RANDOM, kinds).unwrap();
    let mut rng = Rng::new(7, 1);
    for y in 0..size {
        for x in 0..size {
            for s in 0..spp {
                let (jx, jy) = (rng.next_f32(), rng.next_f32());
                let r: Vec<f32> = (0..RANDOM).map(|_| rng.next_f32()).collect();
                let v = set.sample_mut(y * size + x, s);
                v[0] = x as f32 + jx;
                v[1] = y as f32 + jy;
                v[2..2 + RANDOM].copy_from_slice(&r);
                let f = 2 + RANDOM;
                // A flat wall: position (x, y, 0) in world units of 0.01 per pixel.
                v[f] = (x as f32 + jx) * 0.01;
                v[f + 1] = (y as f32 + jy) * 0.01;
                v[f + 2] = 0.0;
                let t = texture(x, y);
                v[f + 3..f + 6].copy_from_slice(&[t, t, t]);
                v[f + 6..f + 9].copy_from_slice(&colour(x, y, r[0]));
            }
        }
    }
    set
}

fn small_boxes() -> RpfParams {
    RpfParams {
        boxes: vec![15, 7],
        ..RpfParams::default()
    }
}

fn variance(values: impl Iterator<Item = f32> + Clone) -> f64 {
    let n = values.clone().count() as f64;
    let mean = values.clone().map(f64::from).sum::<f64>() / n;
    values.map(|v| (v as f64 - mean).powi(2)).sum::<f64>() / (n - 1.0)
}

#[test]
fn a_constant_image_stays_constant() {
    let set = synthetic(16, 8, |_, _, _| [0.25, 0.5, 1.0], |_, _| 0.5);
    let out = filter(&set, &RpfParams::default(), &NO, &|_| {})
        .unwrap()
        .unwrap();
    for p in &out {
        for (k, want) in [0.25, 0.5, 1.0].iter().enumerate() {
            assert!((p[k] - want).abs() < 1e-6, "{p:?}");
        }
    }
}

#[test]
fn noise_from_a_random_parameter_is_averaged_away_on_a_flat_region() {
    // Colour 0.5 +- 0.4 driven by the first random parameter: pure Monte Carlo noise.
    let (size, spp) = (24, 8);
    let set = synthetic(size, spp, |_, _, r| [0.1 + 0.8 * r; 3], |_, _| 0.5);
    let before = set.mean_image();
    let out = filter(&set, &small_boxes(), &NO, &|_| {}).unwrap().unwrap();
    // The interior, away from the borders' smaller neighbourhoods.
    let inner = |img: &[[f32; 3]]| -> Vec<f32> {
        (4..size - 4)
            .flat_map(|y| (4..size - 4).map(move |x| (x, y)))
            .map(|(x, y)| img[y * size + x][0])
            .collect::<Vec<_>>()
    };
    let (vb, va) = (
        variance(inner(&before).into_iter()),
        variance(inner(&out).into_iter()),
    );
    // The last pass alone averages a 7x7 box's draws (up to 7 * 7 * 8 / 2 = 196 samples, a
    // Gaussian of sigma 7/4 pixels: about 40 effectively independent pixels' worth); the
    // neighbourhoods overlap, so the pixels stay correlated. Ask for a factor of 10.
    assert!(va < vb / 10.0, "variance {vb} -> {va}");
    let mean: f32 = inner(&out).iter().sum::<f32>() / inner(&out).len() as f32;
    assert!((mean - 0.5).abs() < 0.02, "mean {mean}");
}

/// A checkerboard of base colours 0.2 and 0.8.
fn checker(x: usize, y: usize) -> f32 {
    if (x + y).is_multiple_of(2) {
        0.2
    } else {
        0.8
    }
}

/// The [`checker`] base colour (the texture feature, index 3 of the features) times
/// `light(r)` from the first random parameter.
fn textured(size: usize, light: impl Fn(f32) -> f32) -> SampleSet {
    let mut set = synthetic(size, 8, |x, y, r| [checker(x, y) * light(r); 3], checker);
    set.albedo = Some(3);
    set
}

#[test]
fn demodulation_keeps_texture_detail_and_filters_the_light_under_it() {
    let size = 16;
    let demodulate = RpfParams {
        demodulate: true,
        ..small_boxes()
    };
    let t = |p: usize| checker(p % size, p / size);
    // Constant light under the texture: divided by the base colour the image is constant, so
    // multiplied back every pixel is its base colour times the light, exactly.
    let set = textured(size, |_| 0.7);
    let out = filter(&set, &demodulate, &NO, &|_| {}).unwrap().unwrap();
    for (p, c) in out.iter().enumerate() {
        assert!((c[0] - 0.7 * t(p)).abs() < 1e-5, "pixel {p}: {c:?}");
    }
    // Noisy light (0.1 to 0.9, from a random parameter): the light under each pixel is
    // averaged, the texture kept.
    let set = textured(size, |r| 0.1 + 0.8 * r);
    let before = set.mean_image();
    let out = filter(&set, &demodulate, &NO, &|_| {}).unwrap().unwrap();
    let light = |img: &[[f32; 3]]| -> Vec<f32> {
        (4..size - 4)
            .flat_map(|y| (4..size - 4).map(move |x| y * size + x))
            .map(|p| img[p][0] / t(p))
            .collect()
    };
    let (vb, va) = (
        variance(light(&before).into_iter()),
        variance(light(&out).into_iter()),
    );
    assert!(va < vb / 10.0, "variance of the light {vb} -> {va}");
    let mean = light(&out).iter().sum::<f32>() / light(&out).len() as f32;
    assert!((mean - 0.5).abs() < 0.03, "mean light {mean}");
    // Demodulating needs the base colour among the features.
    let mut set = textured(size, |_| 0.7);
    set.albedo = Some(4);
    let e = filter(&set, &demodulate, &NO, &|_| {}).unwrap_err();
    assert!(e.to_string().contains("albedo"), "{e}");
}

/// Edges no screen coordinate predicts (a checkerboard of pixels, dark and bright, with noise
/// from a random parameter) that the texture feature sees are kept; the same colours over a
/// flat texture are blurred: the feature is what keeps them.
#[test]
fn an_edge_the_features_see_is_not_blurred() {
    let size = 24;
    let base = |x, y| if checker(x, y) < 0.5 { 0.1 } else { 0.9 };
    let colour = |x, y, r| [base(x, y) + 0.1 * (r - 0.5); 3];
    let seen = synthetic(size, 8, colour, checker);
    let out = filter(&seen, &RpfParams::default(), &NO, &|_| {})
        .unwrap()
        .unwrap();
    let flat = synthetic(size, 8, colour, |_, _| 0.5);
    let blurred = filter(&flat, &RpfParams::default(), &NO, &|_| {})
        .unwrap()
        .unwrap();
    let mut worst = 0.0f32;
    for y in 0..size {
        for x in 0..size {
            let (got, want) = (out[y * size + x][0], base(x, y));
            assert!(
                (got - want).abs() < 0.03,
                "({x}, {y}): {got} against {want}"
            );
            worst = worst.max((blurred[y * size + x][0] - want).abs());
        }
    }
    assert!(
        worst > 0.2,
        "without the feature the pattern stays: {worst}"
    );
}

#[test]
fn a_colour_edge_that_depends_on_the_screen_position_alone_is_kept() {
    // A step in the colour only (the features are flat, as for a texture the features miss):
    // the colour depends on the position and on no random parameter, so alpha stays near 1
    // and the colour test keeps the two sides apart. (A pattern whose colour no single screen
    // coordinate predicts, e.g. a fine checkerboard, is blurred: RPF measures dependencies one
    // coordinate at a time.)
    let size = 16;
    let step = |x: usize| if x < size / 2 { 0.2 } else { 0.8 };
    let set = synthetic(size, 8, |x, _, _| [step(x); 3], |_, _| 0.5);
    let out = filter(&set, &RpfParams::default(), &NO, &|_| {})
        .unwrap()
        .unwrap();
    for y in 0..size {
        for x in 0..size {
            let got = out[y * size + x][0];
            assert!(
                (got - step(x)).abs() < 0.02,
                "({x}, {y}): {got} against {}",
                step(x)
            );
        }
    }
}

#[test]
fn sky_samples_pass_through_and_lend_nothing_to_their_neighbours() {
    // Left half sky: no features (as the path tracer leaves a miss's), a pattern of colours
    // that is detail, not noise; right half a wall with noise from a random parameter.
    let (size, spp) = (16, 8);
    let is_sky = |x: usize| x < size / 2;
    let pattern = |x: usize, y: usize| [0.1 + 0.1 * ((x * 7 + y * 3) % 5) as f32, 0.5, 2.0];
    let mut set = synthetic(
        size,
        spp,
        |x, y, r| {
            if is_sky(x) {
                pattern(x, y)
            } else {
                [0.1 + 0.8 * r; 3]
            }
        },
        |_, _| 0.5,
    );
    let f = 2 + RANDOM;
    set.sky = vec![false; size * size * spp];
    for p in (0..size * size).filter(|p| is_sky(p % size)) {
        for s in 0..spp {
            set.sample_mut(p, s)[f..f + 6].fill(0.0);
            set.sky[p * spp + s] = true;
        }
    }
    let params = small_boxes();
    let before = set.mean_image();
    let out = filter(&set, &params, &NO, &|_| {}).unwrap().unwrap();
    for (p, c) in out.iter().enumerate() {
        let (x, y) = (p % size, p / size);
        if is_sky(x) {
            assert_eq!(*c, before[p], "sky pixel ({x}, {y})");
        } else {
            // The wall's mean light is 0.5 and the sky's blue channel 2: a wall pixel that
            // took the sky's samples would show it.
            assert!((c[0] - 0.5).abs() < 0.15, "wall pixel ({x}, {y}): {c:?}");
            assert!((c[2] - c[0]).abs() < 1e-5, "wall pixel ({x}, {y}): {c:?}");
        }
    }
    // The paper's RPF (`sky` off) sees one featureless region and averages some of the
    // sky's pattern; off, the flags change nothing.
    let paper = RpfParams {
        sky: false,
        ..params.clone()
    };
    let blurred = filter(&set, &paper, &NO, &|_| {}).unwrap().unwrap();
    let sky_change = (0..size * size)
        .filter(|p| is_sky(p % size))
        .map(|p| (blurred[p][0] - before[p][0]).abs())
        .fold(0.0, f32::max);
    assert!(
        sky_change > 0.05,
        "the sky's pattern changed by {sky_change} at most"
    );
    let unflagged = SampleSet {
        sky: Vec::new(),
        ..set.clone()
    };
    assert_eq!(
        blurred,
        filter(&unflagged, &paper, &NO, &|_| {}).unwrap().unwrap()
    );
    set.sky.pop();
    assert!(matches!(
        filter(&set, &params, &NO, &|_| {}),
        Err(FilterError::Size { .. })
    ));
}

#[test]
fn a_nan_sample_does_not_spread_and_threads_change_nothing() {
    let size = 16;
    let mut set = synthetic(size, 4, |_, _, r| [r, 0.5, 1.0 - r], |x, _| (x % 3) as f32);
    let params = small_boxes();
    let run = |set: &SampleSet, threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| filter(set, &params, &NO, &|_| {}).unwrap().unwrap())
    };
    let one = run(&set, 1);
    assert_eq!(one, run(&set, 3), "1 thread against 3");
    let stride = set.stride();
    let c = stride - 3;
    let mut zeroed = set.clone();
    zeroed.sample_mut(5 * size + 5, 1)[c..].copy_from_slice(&[0.0; 3]);
    let v = set.sample_mut(5 * size + 5, 1);
    v[c] = f32::NAN;
    v[c + 1] = f32::INFINITY;
    v[c + 2] = f32::NEG_INFINITY;
    v[3] = f32::NAN; // a random parameter too
    let mut zeroed2 = zeroed.clone();
    zeroed2.sample_mut(5 * size + 5, 1)[3] = 0.0;
    let bad = run(&set, 2);
    assert!(bad.iter().flatten().all(|v| v.is_finite()));
    assert_eq!(bad, run(&zeroed2, 2), "a non-finite value reads as 0");
}

#[test]
fn bad_parameters_and_sizes_are_refused() {
    let set = synthetic(4, 2, |_, _, r| [r; 3], |_, _| 0.0);
    for (params, field) in [
        (
            RpfParams {
                boxes: vec![55, 34],
                ..RpfParams::default()
            },
            "rpf.boxes",
        ),
        (
            RpfParams {
                boxes: vec![],
                ..RpfParams::default()
            },
            "rpf.boxes",
        ),
        (
            RpfParams {
                noise: f32::NAN,
                ..RpfParams::default()
            },
            "rpf.noise",
        ),
        (
            RpfParams {
                noise: -0.02,
                ..RpfParams::default()
            },
            "rpf.noise",
        ),
    ] {
        let e = filter(&set, &params, &NO, &|_| {}).unwrap_err().to_string();
        assert!(e.contains(field), "{e}");
    }
    let mut short = set.clone();
    short.data.pop();
    assert!(matches!(
        filter(&short, &RpfParams::default(), &NO, &|_| {}),
        Err(FilterError::Size { .. })
    ));
    assert!(SampleSet::new(4, 4, 0, RANDOM, vec![]).is_err());
    assert!(SampleSet::new(4, 4, 65, RANDOM, vec![]).is_err());
    assert!(SampleSet::new(usize::MAX / 2, 4, 8, RANDOM, vec![]).is_err());
}
