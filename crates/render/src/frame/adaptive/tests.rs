use super::*;

/// The thesis's measure and frames (Eq. 12, one iteration a frame, no cap): the tests of
/// the schedule's mechanics were written for them (the defaults since issue 49 are the
/// `error` measure with `budget` and `cap`).
fn thesis() -> AdaptiveConfig {
    AdaptiveConfig {
        measure: Measure::Luminance,
        budget: false,
        cap: false,
        ..AdaptiveConfig::default()
    }
}

/// The statistics of `samples` (grey values), one at a time (Eqs. 9 and 10).
fn stats_of(samples: &[Vec3]) -> PixelStats {
    let mut s = PixelStats::default();
    for &v in samples {
        s.add(v, Vec3::ZERO);
    }
    s
}

#[test]
fn welford_and_eq_12_match_sequences_of_known_mean_and_variance() {
    // 1, 2, ..., 10 in every channel: mean 5.5, sample variance 55/6 (n - 1).
    let seq: Vec<Vec3> = (1..=10).map(|i| Vec3::splat(i as f32)).collect();
    let s = stats_of(&seq);
    assert!((s.mean().x - 5.5).abs() < 1e-6);
    assert!((pixel_variance(&s) - 55.0 / 6.0).abs() < 1e-5);
    let v = deviation(&s, Measure::Luminance, 0.0);
    let expected = ((55.0f32 / 6.0).sqrt() + EPSILON) / (5.5 + EPSILON);
    assert!((v - expected).abs() < 1e-6, "{v} {expected}");

    // Channels of different variance: Eq. 11 averages them. Red alternates 0 and 2
    // (variance n/(n-1) with mean 1), green is constant 1, blue alternates 0 and 4
    // (variance 4 n/(n-1)).
    let n = 8;
    let seq: Vec<Vec3> = (0..n)
        .map(|i| {
            let odd = (i % 2) as f32;
            Vec3::new(2.0 * odd, 1.0, 4.0 * odd)
        })
        .collect();
    let s = stats_of(&seq);
    let k = n as f32 / (n - 1) as f32;
    assert!((pixel_variance(&s) - (k + 0.0 + 4.0 * k) / 3.0).abs() < 1e-5);
    // Luminance of the mean (1, 1, 2).
    let l = luminance(Vec3::new(1.0, 1.0, 2.0));
    let expected = (((5.0 * k) / 3.0).sqrt() + EPSILON) / (l + EPSILON);
    assert!((deviation(&s, Measure::Luminance, 0.0) - expected).abs() < 1e-5);

    // A large offset does not break the running statistics (Welford, not sum of squares).
    let seq: Vec<Vec3> = (0..1000)
        .map(|i| Vec3::splat(1e4 + (i % 2) as f32))
        .collect();
    let s = stats_of(&seq);
    assert!((pixel_variance(&s) - 0.25 * 1000.0 / 999.0).abs() < 1e-2);

    // One sample has no variance; a black pixel has V = 1.
    assert_eq!(pixel_variance(&stats_of(&[Vec3::ONE])), 0.0);
    assert_eq!(
        deviation(&stats_of(&[Vec3::ZERO; 3]), Measure::Luminance, 0.0),
        1.0
    );

    // Tone-mapped: the deviation of L / (1 + L) to first order, checked against the
    // deviation of tone-mapped samples of small spread around 3 (grey: L = the value).
    let seq: Vec<Vec3> = (0..1000)
        .map(|i| Vec3::splat(3.0 + 0.01 * ((i % 2) as f32 * 2.0 - 1.0)))
        .collect();
    let tm: Vec<f32> = seq.iter().map(|v| v.x / (1.0 + v.x)).collect();
    let mean = tm.iter().sum::<f32>() / tm.len() as f32;
    let sd = (tm.iter().map(|t| (t - mean).powi(2)).sum::<f32>() / 999.0).sqrt();
    let v = deviation(&stats_of(&seq), Measure::Tonemapped, 0.0);
    assert!(
        (v - (2.0 * sd + EPSILON)).abs() < 1e-2 * v,
        "{v} vs {}",
        2.0 * sd
    );
    // Unlike Eq. 12, a dark pixel's noise is not inflated, a bright one's is damped.
    let dark = stats_of(&[Vec3::splat(0.01), Vec3::splat(0.03)]);
    let bright = stats_of(&[Vec3::splat(9.0), Vec3::splat(11.0)]);
    assert!(
        deviation(&dark, Measure::Luminance, 0.0) > deviation(&bright, Measure::Luminance, 0.0)
    );
    assert!(deviation(&dark, Measure::Tonemapped, 0.0) < 0.05);
    assert!(deviation(&bright, Measure::Tonemapped, 0.0) < 0.05);
    assert!(deviation(&stats_of(&[Vec3::ZERO; 3]), Measure::Tonemapped, 0.0) <= EPSILON);
}

/// [`Measure::Absolute`]: each pixel's deviation is the square root of the mean variance
/// over its window (pixels below two samples left out; [`Measure::Error`]: over the
/// pixel's sample count), the reference their mean over the
/// image, the same for any thread count; a pixel at `ABSOLUTE_SPAN` times the mean is
/// sampled at every iteration, one at the mean from about `1 / ABSOLUTE_SPAN` of the
/// schedule on.
#[test]
fn the_absolute_measure_is_the_windows_deviation_over_the_images() {
    let (w, h) = (23, 11);
    // Variance 4 on the right of x = 12, 0 on the left, 9 along row 2; a column of
    // one-sample pixels.
    let var_at = |x: usize, y: usize| match (x, y) {
        (_, 2) => 9.0f32,
        (x, _) if x > 12 => 4.0,
        _ => 0.0,
    };
    let history: Vec<PixelStats> = (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            let var = var_at(x, y);
            let n = if x == 5 { 1 } else { 8 };
            PixelStats {
                n,
                radiance_m2: Vec3::splat(var * (n - 1) as f32),
                ..PixelStats::default()
            }
        })
        .collect();
    let measured = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        let mut a = Adaptive::default();
        pool.install(|| a.measure_image(Measure::Absolute, &history, w));
        a
    };
    let a = measured(1);
    for t in [2, 3, 7] {
        let b = measured(t);
        assert_eq!(a.regional, b.regional);
        assert_eq!(a.reference.to_bits(), b.reference.to_bits());
    }
    // By brute force: every window of every pixel, clipped at the image's edges.
    let mut sum = 0.0f64;
    for y in 0..h {
        for x in 0..w {
            let (mut v, mut c) = (0.0f64, 0.0f64);
            for yy in y.saturating_sub(REGION)..(y + REGION + 1).min(h) {
                for xx in x.saturating_sub(REGION)..(x + REGION + 1).min(w) {
                    if xx != 5 {
                        v += f64::from(var_at(xx, yy));
                        c += 1.0;
                    }
                }
            }
            let expected = (v / c).sqrt();
            sum += expected;
            let got = a.regional[y * w + x];
            assert!(
                (f64::from(got) - expected).abs() < 1e-5,
                "({x}, {y}): {got} vs {expected}"
            );
        }
    }
    assert!((f64::from(a.reference) - sum / (w * h) as f64).abs() < 1e-5);
    assert_eq!(a.regional[(h - 1) * w + 3], 0.0);
    assert!((a.regional[(h - 1) * w + w - 1] - 2.0).abs() < 1e-6);

    // The error measure: the same over each pixel's sample count.
    let mut e = Adaptive::default();
    e.measure_image(Measure::Error, &history, w);
    for (i, h) in history.iter().enumerate() {
        assert_eq!(e.regional[i], a.regional[i] / h.n as f32);
    }

    // Other measures do not need it.
    let mut b = a.clone();
    b.measure_image(Measure::Tonemapped, &history, w);
    assert!(b.regional.is_empty() && b.reference == 0.0);

    // Through the schedule: V is the regional deviation over ABSOLUTE_SPAN references.
    let config = AdaptiveConfig {
        enabled: true,
        measure: Measure::Absolute,
        ..thesis()
    };
    let at = |sigma: f32, iteration: u32| {
        let regional = [sigma];
        let mut s = Schedule::new(&config, iteration, false, 1);
        s.regional = &regional;
        s.reference = 0.5;
        s.wants(0, &history[0], NO_PROBABILITY)
    };
    let (min, max) = (config.min_spp, config.max_spp);
    for i in min..max {
        assert!(at(ABSOLUTE_SPAN * 0.5, i), "every iteration at the span");
        assert!(!at(0.0, i), "no variance: only min_spp samples");
    }
    // At the mean: sampled from 1 - 1 / ABSOLUTE_SPAN of the schedule on.
    let first = (min..max).find(|&i| at(0.5, i)).unwrap();
    let expected = min as f32 + (1.0 - 1.0 / ABSOLUTE_SPAN) * (max - min) as f32;
    assert!(
        (first as f32 - expected).abs() <= 1.0,
        "{first} vs {expected}"
    );
    assert!((first..max).all(|i| at(0.5, i)));
}

#[test]
fn the_threshold_falls_from_one_between_min_and_max() {
    let (min, max) = (4, 32);
    for i in 0..=min {
        assert_eq!(threshold(i, min, max), 1.0);
    }
    assert!((threshold(min + 1, min, max) - (1.0 - 1.0 / 28.0)).abs() < 1e-6);
    assert!((threshold(max - 1, min, max) - 1.0 / 28.0).abs() < 1e-6);
    // Strictly falling in between.
    for i in min..max - 1 {
        assert!(threshold(i + 1, min, max) < threshold(i, min, max));
    }
    assert_eq!(threshold(10, 8, 8), 1.0);
}

/// Runs the schedule on a synthetic map of fixed V values: pixel `i` has `V = vs[i]`
/// whatever its samples (their statistics are faked to give it). Returns each pixel's
/// sample count after `iterations` iterations and the probabilities.
fn run(vs: &[f32], config: &AdaptiveConfig, iterations: u32) -> (Vec<u32>, Vec<f32>) {
    // A pixel of mean luminance 1 and standard deviation s has V = (s + eps) / (1 + eps).
    let stats_for = |v: f32, n: u32| {
        let s = v * (1.0 + EPSILON) - EPSILON;
        let mut p = PixelStats {
            n,
            ..PixelStats::default()
        };
        p.direct.mean = Vec3::ONE;
        p.radiance_m2 = Vec3::splat(s * s * (n.max(2) - 1) as f32);
        p
    };
    let mut counts = vec![0u32; vs.len()];
    let mut adaptive = Adaptive::default();
    adaptive.reset(vs.len());
    for it in 0..iterations {
        let schedule = Schedule::new(config, it, false, 99);
        let chosen: Vec<bool> = vs
            .iter()
            .enumerate()
            .map(|(i, &v)| schedule.wants(i, &stats_for(v, counts[i]), adaptive.probability[i]))
            .collect();
        for (c, chose) in counts.iter_mut().zip(chosen) {
            *c += u32::from(chose);
        }
        if it + 1 == config.max_spp {
            let history: Vec<PixelStats> = vs
                .iter()
                .zip(&counts)
                .map(|(&v, &n)| stats_for(v, n))
                .collect();
            adaptive.fix_probabilities(&history, config.max_spp, config.cap);
        }
    }
    (counts, adaptive.probability)
}

#[test]
fn the_schedule_gives_samples_by_v_and_fixes_probabilities() {
    let config = AdaptiveConfig {
        enabled: true,
        min_spp: 4,
        max_spp: 32,
        ..thesis()
    };
    // V = 0 (never above tau), 1 (always), 0.5, and 2.
    let vs = [0.0, 1.0, 0.5, 2.0, 0.25];
    let (counts, probability) = run(&vs, &config, 32);
    // Iteration i >= 4 samples a pixel when V >= 1 - (i - 4) / 28, i.e. i >= 4 + 28 (1 - V).
    let expected = |v: f32| 4 + (4..32).filter(|&i| v >= threshold(i, 4, 32)).count() as u32;
    assert_eq!(counts[0], 4);
    assert_eq!(counts[1], 32);
    assert_eq!(counts[3], 32);
    assert_eq!(counts[2], expected(0.5));
    assert!((17..=19).contains(&counts[2]), "{}", counts[2]);
    assert_eq!(counts[4], expected(0.25));
    for (c, p) in counts.iter().zip(&probability) {
        assert_eq!(*p, *c as f32 / 32.0);
    }
    // Probabilities span [min / max, 1].
    assert_eq!(probability[0], 4.0 / 32.0);
    assert_eq!(probability[1], 1.0);

    // After the schedule each pixel is sampled with its probability: over 4000 more
    // iterations, counts within 4 standard deviations of P N.
    let extra = 4000;
    let (more, _) = run(&vs, &config, 32 + extra);
    for (i, p) in probability.iter().enumerate() {
        let got = (more[i] - counts[i]) as f64;
        let (p, n) = (*p as f64, extra as f64);
        let sd = (n * p * (1.0 - p)).sqrt();
        assert!(
            (got - n * p).abs() <= 4.0 * sd + 1e-9,
            "pixel {i}: {got} of {n} at P {p}"
        );
    }
}

#[test]
fn a_frame_of_several_iterations_counts_what_they_would_sample() {
    // `budget`: a frame running iterations i..j gives a pixel the samples those
    // iterations would, its V frozen at the frame's start (here V is fixed anyway, and
    // the sample count grows as the iterations go). From 2 samples on: below, V is not
    // defined yet (no variance) and the frame's frozen V is not the one the thesis's
    // later iterations would see.
    let config = AdaptiveConfig {
        enabled: true,
        min_spp: 4,
        max_spp: 32,
        ..thesis()
    };
    let stats_for = |v: f32, n: u32| {
        let s = v * (1.0 + EPSILON) - EPSILON;
        let mut p = PixelStats {
            n,
            ..PixelStats::default()
        };
        p.direct.mean = Vec3::ONE;
        p.radiance_m2 = Vec3::splat(s * s * (n.max(2) - 1) as f32);
        p
    };
    for cap in [false, true] {
        for &v in &[0.0, 0.05, 0.3, 0.5, 0.77, 1.0, 2.0] {
            for n0 in [2, 3, 4, 9, 30] {
                for i in 0..32 {
                    for j in i + 1..=33 {
                        let mut n = n0;
                        for k in i..j.min(32) {
                            let one = Schedule::new(
                                &AdaptiveConfig {
                                    cap,
                                    ..config.clone()
                                },
                                k,
                                false,
                                1,
                            );
                            n += u32::from(one.wants(0, &stats_for(v, n), NO_PROBABILITY));
                        }
                        let mut frame = Schedule::new(
                            &AdaptiveConfig {
                                cap,
                                ..config.clone()
                            },
                            i,
                            false,
                            1,
                        );
                        frame.end = j;
                        assert_eq!(
                            frame.count(0, &stats_for(v, n0), NO_PROBABILITY),
                            n - n0,
                            "V {v}, n {n0}, iterations {i}..{j}, cap {cap}"
                        );
                    }
                }
            }
        }
    }
}

#[test]
fn budget_frames_take_a_uniform_frames_samples_by_probability() {
    // Probabilities fixed: scale = 1 / mean(P), and a pixel takes P scale samples per
    // frame on average, so a frame takes one per pixel on average.
    let config = AdaptiveConfig {
        enabled: true,
        min_spp: 4,
        max_spp: 32,
        budget: true,
        ..thesis()
    };
    let pixels = 4000;
    let history: Vec<PixelStats> = (0..pixels)
        .map(|i| PixelStats {
            n: [4, 8, 32][i % 3],
            ..PixelStats::default()
        })
        .collect();
    let mut adaptive = Adaptive::default();
    adaptive.reset(pixels);
    adaptive.fix_probabilities(&history, 32, false);
    let mean = (4.0 + 8.0 + 32.0) / 3.0 / 32.0;
    assert!(
        (adaptive.scale - 1.0 / mean).abs() < 1e-3,
        "{}",
        adaptive.scale
    );
    let frames = 50;
    let mut per_class = [0u64; 3];
    let mut total = 0;
    for f in 0..frames {
        let mut s = Schedule::new(&config, 32 + f, false, 5);
        s.scale = adaptive.scale;
        let mut frame = 0;
        for (i, h) in history.iter().enumerate() {
            let c = s.count(i, h, adaptive.probability[i]);
            per_class[i % 3] += u64::from(c);
            frame += u64::from(c);
        }
        // Within 4 standard deviations of the frame's pixel count (each pixel's count is
        // its integer part plus a Bernoulli draw of variance at most 1/4).
        let sd = (pixels as f64 * 0.25).sqrt();
        assert!((frame as f64 - pixels as f64).abs() < 4.0 * sd, "{frame}");
        total += frame;
    }
    assert!((total as f64 / (frames as f64 * pixels as f64) - 1.0).abs() < 0.01);
    // Each class in proportion to its P.
    for (c, n) in [4.0, 8.0, 32.0].iter().enumerate() {
        let expected = frames as f64 * (pixels / 3) as f64 * (n / 32.0) * adaptive.scale as f64;
        let got = per_class[c] as f64;
        assert!(
            (got - expected).abs() < 0.03 * expected,
            "class {c}: {got} vs {expected}"
        );
    }
}

#[test]
fn the_budget_picks_the_last_iteration_that_fits() {
    // V spread evenly over [0, 1.2): a frame from iteration i samples, per pixel, the
    // iterations whose threshold is at most its V; the end is the last one within the
    // budget.
    let config = AdaptiveConfig {
        enabled: true,
        min_spp: 4,
        max_spp: 32,
        measure: Measure::Luminance,
        budget: true,
        ..thesis()
    };
    let pixels = 600;
    let history: Vec<PixelStats> = (0..pixels)
        .map(|i| {
            let v = 1.2 * i as f32 / pixels as f32;
            let s = v * (1.0 + EPSILON) - EPSILON;
            let mut p = PixelStats {
                n: 4,
                ..PixelStats::default()
            };
            p.direct.mean = Vec3::ONE;
            p.radiance_m2 = Vec3::splat(s.max(0.0).powi(2) * 3.0);
            p
        })
        .collect();
    let mut adaptive = Adaptive::default();
    adaptive.reset(pixels);
    let samples = |i: u32, end: u32| -> u64 {
        let mut s = Schedule::new(&config, i, false, 3);
        s.end = end;
        history
            .iter()
            .enumerate()
            .map(|(k, h)| u64::from(s.count(k, h, NO_PROBABILITY)))
            .sum()
    };
    for i in [4, 10, 20, 31] {
        for budget in [1, 300, 600, 2000, 100_000] {
            let s = Schedule::new(&config, i, false, 3);
            let end = adaptive.budget_end(&s, &history, budget);
            assert!(end > i && end <= 32, "{i} {budget}: {end}");
            assert!(
                end == i + 1 || samples(i, end) <= budget,
                "{i} {budget}: {end}"
            );
            assert!(
                end == 32 || samples(i, end + 1) > budget,
                "{i} {budget}: {end}"
            );
        }
    }
}

#[test]
fn with_min_spp_every_pixel_keeps_converging() {
    // Whatever V, every pixel's probability is at least min / max, so the sample count of
    // each grows without bound (here: past 100 over 2000 iterations for P = 1/8).
    let config = AdaptiveConfig {
        enabled: true,
        min_spp: 2,
        max_spp: 16,
        ..thesis()
    };
    let vs = [0.0, 0.01, 1e-9, 3.0];
    let (counts, probability) = run(&vs, &config, 2000);
    assert!(probability.iter().all(|&p| p >= 2.0 / 16.0));
    assert!(counts.iter().all(|&c| c > 100), "{counts:?}");
}

#[test]
fn reprojected_pixels_wait_or_keep_sampling_with_their_probability() {
    // Algorithm 2: during the schedule a pixel that brought a probability takes nothing;
    // with `keep_sampling` it takes a sample with that probability at each iteration
    // from `keep_sampling_after` on.
    let stats = stats_of(&[Vec3::ONE; 8]);
    for (keep_sampling, after) in [(false, 0), (true, 0), (true, 10), (true, 40)] {
        let config = AdaptiveConfig {
            enabled: true,
            keep_sampling,
            keep_sampling_after: after,
            ..thesis()
        };
        let (pixels, p) = (20_000, 0.3);
        let mut expected = 0.0;
        let taken = (0..pixels)
            .filter(|&i| {
                let iteration = 1 + i as u32 % 30;
                if keep_sampling && iteration >= after {
                    expected += f64::from(p);
                }
                let s = Schedule::new(&config, iteration, true, 9);
                s.wants(i, &stats, p)
            })
            .count() as f64;
        let sd = (expected * (1.0 - f64::from(p))).sqrt();
        assert!(
            (taken - expected).abs() <= 4.0 * sd,
            "keep {keep_sampling} after {after}: {taken} against {expected}"
        );
        if !keep_sampling || after >= 30 {
            assert_eq!(taken, 0.0);
        } else {
            assert!(taken > 1000.0);
        }
        // One that brought a probability but kept fewer than `min_spp` samples (its
        // states dropped) is new again: sampled at every iteration until it has them.
        let lost = PixelStats::one(Vec3::ONE, Vec3::ZERO);
        for iteration in 0..32 {
            let s = Schedule::new(&config, iteration, true, 9);
            assert!(s.wants(0, &lost, p) && s.wants(1, &PixelStats::default(), p));
        }
    }
}

#[test]
fn skipping_stops_at_the_iteration_reprojected_pixels_resume() {
    // Every new pixel converged (V far below any threshold before the schedule's end),
    // half the pixels carried: empty iterations are skipped up to `keep_sampling_after`
    // (with `keep_sampling`), up to `max_spp` without it.
    let flat = stats_of(&[Vec3::ONE; 8]);
    let history = vec![flat; 8];
    let mut adaptive = Adaptive::default();
    adaptive.reset(history.len());
    for p in adaptive.probability.iter_mut().step_by(2) {
        *p = 0.5;
    }
    adaptive.iteration = 5;
    for (keep_sampling, after, busy) in [(false, 10, 32), (true, 10, 10), (true, 3, 5)] {
        let config = AdaptiveConfig {
            enabled: true,
            keep_sampling,
            keep_sampling_after: after,
            ..thesis()
        };
        assert_eq!(adaptive.first_busy(&config, &history, true), busy);
        // Without the combination the probabilities do not matter.
        assert_eq!(adaptive.first_busy(&config, &history, false), 32);
    }
}

#[test]
fn bad_settings_are_refused() {
    for (min, max) in [(0, 32), (8, 4), (4, 1 << 20)] {
        let c = AdaptiveConfig {
            min_spp: min,
            max_spp: max,
            ..thesis()
        };
        assert!(c.validate().is_err(), "{min} {max}");
    }
    assert!(AdaptiveConfig::default().validate().is_ok());
}
