//! The spatio-temporal filter on synthetic frames: a constant image stays constant; on a still
//! wall with fresh noise every frame its output settles (flicker at least 10x lower than the
//! input's) around the right mean; a frame's noise on a flat wall falls by the a-trous kernel's
//! squared weights; a normal edge is not blurred across; history is dropped where the surface
//! behind a pixel changed (no ghosting); the sky passes through; the thread count changes
//! nothing; a sample that is not finite does not spread; bad parameters and buffers are
//! refused.

use glam::{Vec2, Vec3};
use pathlight_core::color::luminance;
use pathlight_core::rng::Rng;
use pathlight_denoise::{Svgf, SvgfFrame, SvgfParams};

#[derive(Clone)]
struct Frame {
    w: usize,
    h: usize,
    direct: Vec<Vec3>,
    indirect: Vec<Vec3>,
    albedo: Vec<Vec3>,
    normal: Vec<Vec3>,
    depth: Vec<f32>,
    motion: Vec<Vec2>,
    emitter: Vec<bool>,
}

impl Frame {
    fn flat(w: usize, h: usize, light: f32) -> Self {
        let n = w * h;
        Self {
            w,
            h,
            direct: vec![Vec3::splat(light); n],
            indirect: vec![Vec3::splat(0.1 * light); n],
            albedo: vec![Vec3::splat(0.5); n],
            normal: vec![Vec3::Z; n],
            depth: vec![2.0; n],
            motion: vec![Vec2::ZERO; n],
            emitter: vec![false; n],
        }
    }

    fn run(&self, svgf: &mut Svgf) -> Vec<Vec3> {
        self.run_with(svgf, 5)
    }

    /// With a-trous kernels `kernel` pixels wide.
    fn run_with(&self, svgf: &mut Svgf, kernel: u32) -> Vec<Vec3> {
        self.run_params(
            svgf,
            &SvgfParams {
                kernel,
                ..SvgfParams::default()
            },
        )
    }

    fn view(&self) -> SvgfFrame<'_> {
        SvgfFrame {
            width: self.w,
            height: self.h,
            direct: &self.direct,
            indirect: &self.indirect,
            albedo: &self.albedo,
            normal: &self.normal,
            depth: &self.depth,
            motion: &self.motion,
            emitter: &self.emitter,
        }
    }

    fn run_params(&self, svgf: &mut Svgf, p: &SvgfParams) -> Vec<Vec3> {
        let mut out = vec![Vec3::ZERO; self.w * self.h];
        svgf.filter(&self.view(), p, &mut out).unwrap();
        out
    }
}

/// A flat wall lit at 0.5 (direct) with uniform noise of +-0.4 per frame, frame `k`.
fn noisy(k: u64) -> Frame {
    let mut f = Frame::flat(48, 32, 0.5);
    let mut rng = Rng::new(0x9e37_79b9 + k, 0);
    for d in &mut f.direct {
        *d = Vec3::splat(0.5 + 0.4 * (2.0 * rng.next_f32() - 1.0));
    }
    f
}

fn mean_abs_diff(a: &[Vec3], b: &[Vec3]) -> f32 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (*x - *y).abs().element_sum() / 3.0)
        .sum::<f32>()
        / a.len() as f32
}

#[test]
fn a_constant_image_stays_constant() {
    let f = Frame::flat(40, 24, 0.3);
    for kernel in [5, 3] {
        let mut svgf = Svgf::new();
        for _ in 0..6 {
            for o in f.run_with(&mut svgf, kernel) {
                assert!((o - Vec3::splat(0.33)).abs().max_element() < 1e-5, "{o}");
            }
        }
    }
}

#[test]
fn images_without_pixels_or_one_pixel_wide_are_filtered() {
    for (w, h) in [(0, 0), (0, 7), (7, 0), (1, 1), (1, 9), (9, 1), (17, 2)] {
        let f = Frame::flat(w, h, 0.3);
        for kernel in [5, 3] {
            let mut svgf = Svgf::new();
            for _ in 0..3 {
                for o in f.run_with(&mut svgf, kernel) {
                    assert!(
                        (o - Vec3::splat(0.33)).abs().max_element() < 1e-5,
                        "{w}x{h}: {o}"
                    );
                }
            }
        }
    }
}

#[test]
fn a_still_wall_settles_with_fresh_noise_every_frame() {
    for kernel in [5, 3] {
        a_still_wall_settles(kernel);
    }
}

fn a_still_wall_settles(kernel: u32) {
    let mut svgf = Svgf::new();
    let frames: Vec<Frame> = (0..40).map(noisy).collect();
    let outputs: Vec<Vec<Vec3>> = frames
        .iter()
        .map(|f| f.run_with(&mut svgf, kernel))
        .collect();
    // Flicker over the last 10 frames, against the input's.
    let flicker = |v: &[Vec<Vec3>]| {
        (30..40)
            .map(|k| mean_abs_diff(&v[k], &v[k - 1]))
            .sum::<f32>()
            / 10.0
    };
    let inputs: Vec<Vec<Vec3>> = frames
        .iter()
        .map(|f| {
            f.direct
                .iter()
                .zip(&f.indirect)
                .map(|(d, i)| *d + *i)
                .collect()
        })
        .collect();
    let (input, output) = (flicker(&inputs), flicker(&outputs));
    assert!(
        output * 10.0 < input,
        "{kernel}x{kernel}: flicker {output} vs input {input}"
    );
    // Around the right mean (0.5 + 0.05).
    let mean = outputs[39].iter().map(|o| o.x).sum::<f32>() / outputs[39].len() as f32;
    assert!((mean - 0.55).abs() < 0.01, "{mean}");
}

/// Pixel `pixel` of `out` has red `expected` within 1e-3.
fn assert_red(out: &[Vec3], pixel: usize, expected: f32) {
    assert!(
        (out[pixel].x - expected).abs() < 1e-3,
        "pixel {pixel}: {}",
        out[pixel]
    );
}

/// A wall facing the camera beside one at a right angle, lit in two colours of the same
/// luminance (so the luminance test, which sees no edge, cannot be what keeps them apart):
/// each side keeps its own colour; the same light on one flat wall is blurred across.
#[test]
fn a_normal_edge_is_not_blurred_across() {
    let (w, h) = (40, 20);
    let left = Vec3::new(0.9, 0.2, 0.5);
    // Red 0.1 and the green that gives the same luminance.
    let green = (luminance(left) - 0.2126 * 0.1 - 0.0722 * 0.5) / 0.7152;
    let right = Vec3::new(0.1, green, 0.5);
    assert!((luminance(left) - luminance(right)).abs() < 1e-6);
    let mut f = Frame::flat(w, h, 0.0);
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            f.direct[i] = if x < w / 2 { left } else { right };
            f.indirect[i] = Vec3::splat(0.05);
            if x >= w / 2 {
                f.normal[i] = Vec3::X;
            }
        }
    }
    let mut flat = f.clone();
    flat.normal.fill(Vec3::Z);
    for kernel in [5, 3] {
        let (mut svgf, mut blurs) = (Svgf::new(), Svgf::new());
        for _ in 0..3 {
            let out = f.run_with(&mut svgf, kernel);
            for y in 0..h {
                assert_red(&out, y * w + w / 2 - 1, 0.95);
                assert_red(&out, y * w + w / 2, 0.15);
            }
            let blurred = flat.run_with(&mut blurs, kernel);
            let mixed = blurred[10 * w + w / 2 - 1].x;
            assert!(mixed < 0.9, "{kernel}x{kernel} without the edge: {mixed}");
        }
    }
}

#[test]
fn history_is_dropped_where_the_surface_changed() {
    // Ten frames of a wall at depth 2 lit at 0.2, then the left half is a new surface at depth
    // 1 lit at 0.8: its pixels must show 0.8 at once (no ghost of the old wall), the right
    // half keeps its history.
    let mut svgf = Svgf::new();
    let old = Frame::flat(40, 20, 0.2);
    for _ in 0..10 {
        old.run(&mut svgf);
    }
    let mut new = old.clone();
    for y in 0..20 {
        for x in 0..20 {
            let i = y * 40 + x;
            new.depth[i] = 1.0;
            new.direct[i] = Vec3::splat(0.8);
            new.indirect[i] = Vec3::splat(0.08);
        }
    }
    let out = new.run(&mut svgf);
    assert_red(&out, 10 * 40 + 5, 0.88);
    assert_red(&out, 10 * 40 + 35, 0.22);
}

#[test]
fn the_normal_width_test_keeps_bumpy_history_and_drops_a_turned_wall() {
    // A still wall with fresh noise every frame whose normals change from pixel to pixel and
    // frame to frame (a normal-mapped leaf sampled at a new point of the pixel each frame):
    // the cosine test (at least 0.9) refuses much of its history, the width test keeps it, so
    // its output flickers less.
    let bumpy = |k: u64| {
        let mut f = noisy(k);
        let mut rng = Rng::new(0xb0b + k, 1);
        for n in &mut f.normal {
            let (u, v) = (2.0 * rng.next_f32() - 1.0, 2.0 * rng.next_f32() - 1.0);
            *n = (Vec3::Z + 0.5 * Vec3::new(u, v, 0.0)).normalize();
        }
        f
    };
    let flicker = |normal_width: f32| {
        let p = SvgfParams {
            kernel: 3,
            normal_width,
            ..SvgfParams::default()
        };
        let mut svgf = Svgf::new();
        let out: Vec<Vec<Vec3>> = (0..30)
            .map(|k| bumpy(k).run_params(&mut svgf, &p))
            .collect();
        (20..30)
            .map(|k| mean_abs_diff(&out[k], &out[k - 1]))
            .sum::<f32>()
            / 10.0
    };
    let (cosine, width) = (flicker(0.0), flicker(16.0));
    assert!(width < 0.5 * cosine, "flicker {width} against {cosine}");
    // A flat wall that turns (the same depth, another normal): its normal width is 0, so its
    // history goes (the normals 1.4 apart, the test's reach 0.16), as with the cosine test.
    // (The left half turns, the right half stays.)
    for normal_width in [0.0, 16.0] {
        let p = SvgfParams {
            normal_width,
            ..SvgfParams::default()
        };
        let mut svgf = Svgf::new();
        let old = Frame::flat(40, 20, 0.2);
        for _ in 0..10 {
            old.run_params(&mut svgf, &p);
        }
        let mut new = old.clone();
        for y in 0..20 {
            for x in 0..20 {
                let i = y * 40 + x;
                new.normal[i] = Vec3::X;
                new.direct[i] = Vec3::splat(0.8);
                new.indirect[i] = Vec3::splat(0.08);
            }
        }
        let out = new.run_params(&mut svgf, &p);
        assert_red(&out, 10 * 40 + 5, 0.88);
        assert_red(&out, 10 * 40 + 35, 0.22);
        // Nor on either side of the edge between the turned half and the other, whose normal
        // width is 0 too (each of them has a neighbour on its own surface along both axes).
        assert_red(&out, 10 * 40 + 19, 0.88);
        assert_red(&out, 10 * 40 + 20, 0.22);
    }
}

#[test]
fn temporal_antialiasing_lowers_the_flicker_of_a_still_noisy_wall() {
    // SVGF with its output's temporal antialiasing (`taa`) against without, on the still wall
    // with fresh noise every frame: the output, already smooth, flickers less (0.84x; the box
    // is half a standard deviation of this frame's smooth neighbourhood) and the mean holds.
    let run = |taa: bool| {
        let p = SvgfParams {
            taa,
            ..SvgfParams::default()
        };
        let mut svgf = Svgf::new();
        let out: Vec<Vec<Vec3>> = (0..40)
            .map(|k| noisy(k).run_params(&mut svgf, &p))
            .collect();
        let flicker = (30..40)
            .map(|k| mean_abs_diff(&out[k], &out[k - 1]))
            .sum::<f32>()
            / 10.0;
        let mean = out[39].iter().map(|o| o.x).sum::<f32>() / out[39].len() as f32;
        (flicker, mean)
    };
    let ((without, _), (with, mean)) = (run(false), run(true));
    assert!(with < 0.9 * without, "flicker {with} against {without}");
    assert!((mean - 0.55).abs() < 0.01, "{mean}");
}

#[test]
fn motion_vectors_carry_the_history() {
    // A step in the light (a shadow edge on one wall) that moves right by 2 pixels a frame,
    // with motion vectors saying so: the output follows the step without trailing it.
    let mut svgf = Svgf::new();
    let frame = |k: usize| {
        let mut f = Frame::flat(64, 16, 0.2);
        for y in 0..16 {
            for x in 0..64 {
                let i = y * 64 + x;
                if x >= 20 + 2 * k {
                    f.direct[i] = Vec3::splat(0.8);
                    f.indirect[i] = Vec3::splat(0.08);
                }
                f.motion[i] = if k > 0 {
                    Vec2::new(-2.0, 0.0)
                } else {
                    Vec2::ZERO
                };
            }
        }
        f
    };
    let mut out = Vec::new();
    for k in 0..8 {
        out = frame(k).run(&mut svgf);
    }
    // At frame 7 the step is at x = 34.
    let row = |x: usize| out[8 * 64 + x].x;
    assert!((row(30) - 0.22).abs() < 0.02, "{}", row(30));
    assert!((row(38) - 0.88).abs() < 0.02, "{}", row(38));
}

#[test]
fn one_signal_settles_like_two_and_switching_starts_afresh() {
    // Direct and indirect light as one signal: a still noisy wall settles around the same
    // mean as with two. A filter switched between the two starts its history afresh: its
    // next frame is a new filter's first.
    let one = SvgfParams {
        split: false,
        ..SvgfParams::default()
    };
    let (mut a, mut b) = (Svgf::new(), Svgf::new());
    let mut last = (Vec::new(), Vec::new());
    for k in 0..24 {
        last = (noisy(k).run_params(&mut a, &one), noisy(k).run(&mut b));
    }
    let mean = |img: &[Vec3]| img.iter().map(|c| c.x).sum::<f32>() / img.len() as f32;
    assert!(
        (mean(&last.0) - mean(&last.1)).abs() < 0.01,
        "{} {}",
        mean(&last.0),
        mean(&last.1)
    );
    assert!((mean(&last.0) - 0.55).abs() < 0.02, "{}", mean(&last.0));
    let switched = noisy(24).run(&mut a);
    let fresh = noisy(24).run(&mut Svgf::new());
    assert_eq!(switched, fresh);
}

#[test]
fn the_sky_passes_through_and_the_thread_count_changes_nothing() {
    let mut f = noisy(1);
    for y in 0..32 {
        for x in 0..8 {
            let i = y * 48 + x;
            f.depth[i] = f32::INFINITY;
            f.direct[i] = Vec3::new(3.0, 2.0, 1.0);
        }
    }
    let run = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| {
                let mut svgf = Svgf::new();
                let mut out = Vec::new();
                for k in 0..3 {
                    let mut g = noisy(k);
                    g.depth.clone_from(&f.depth);
                    for y in 0..32 {
                        for x in 0..8 {
                            g.direct[y * 48 + x] = f.direct[y * 48 + x];
                        }
                    }
                    out = g.run(&mut svgf);
                }
                out
            })
    };
    let one = run(1);
    for y in 0..32 {
        assert_eq!(
            one[y * 48 + 3],
            Vec3::new(3.0, 2.0, 1.0) + Vec3::splat(0.05)
        );
    }
    assert_eq!(one, run(2));
    assert_eq!(one, run(3));
}

/// The vectorised passes (the temporal one and the a-trous ones) against the scalar ones they
/// replace, on frames with every kind of pixel (depth steps of 20% and more, a normal edge,
/// an emitter, sky, noise of two scales, motion; light and motion that are not finite):
/// the same image within float rounding (the vectorised exponential may use fused
/// multiply-adds), over frames that carry history, for 1 to 5 passes and those that reach
/// the planes' widest padding (6 of the 5x5 kernel, 7 of the 3x3 one), and for 7 passes of
/// the 5x5 kernel and 8 of the 3x3 one, where the scalar passes run in both.
#[test]
fn the_vectorised_passes_agree_with_the_scalar_ones() {
    let (w, h) = (53, 37);
    let frame = |k: u64| {
        let mut f = Frame::flat(w, h, 0.5);
        let mut rng = Rng::new(0x5eed + k, 3);
        for y in 0..h {
            for x in 0..w {
                let i = y * w + x;
                let right = x > w / 2;
                f.depth[i] = if right {
                    3.0 + 0.02 * y as f32
                } else if x > w / 4 {
                    1.8
                } else {
                    1.5
                };
                f.normal[i] = if y > 2 * h / 3 {
                    Vec3::new(0.0, 0.6, 0.8)
                } else if x > w / 4 && x <= w / 2 && y < h / 3 {
                    // Bumpy (for the normal width test).
                    let (u, v) = (rng.next_f32() - 0.5, rng.next_f32() - 0.5);
                    (Vec3::Z + Vec3::new(u, v, 0.0)).normalize()
                } else {
                    Vec3::Z
                };
                f.direct[i] = Vec3::new(0.6, 0.5, 0.4) * (2.0 * rng.next_f32());
                f.indirect[i] = Vec3::splat(0.05 * rng.next_f32());
                f.albedo[i] = if (x / 5 + y / 5) % 2 == 0 {
                    Vec3::splat(0.7)
                } else {
                    Vec3::new(0.2, 0.3, 0.1)
                };
                // The top rows still (for `converge`); then motion that varies along a row
                // but keeps a group's taps on one row of the previous frame (read as loads
                // permuted), motion whose taps fall on several rows (gathered), and motion
                // that moves whole groups alike (loads).
                f.motion[i] = if y < h / 4 {
                    Vec2::ZERO
                } else if y < h / 2 {
                    Vec2::new(0.3 * k as f32 + 0.7 * (x % 5) as f32, -0.2)
                } else if y < 2 * h / 3 {
                    Vec2::new(0.3 * k as f32, -0.2 + 0.6 * (x % 3) as f32)
                } else {
                    Vec2::new(0.3 * k as f32, -0.2)
                };
                // A strip and a row of sky (whole groups of lanes that skip the kernel).
                if x < 4 || y == 2 {
                    f.depth[i] = f32::INFINITY;
                }
                f.emitter[i] = (20..24).contains(&x) && y < 4;
            }
        }
        match k {
            1 => f.direct[5 * w + 30] = Vec3::new(f32::NAN, 0.5, 0.5),
            2 => f.indirect[6 * w + 31] = Vec3::splat(f32::INFINITY),
            3 => f.motion[7 * w + 32] = Vec2::new(f32::NAN, 0.0),
            _ => (),
        }
        f
    };
    for (iterations, kernel, split, normal_width, converge) in [
        (1, 5, true, 16.0, false),
        (2, 5, true, 16.0, false),
        (3, 5, true, 0.0, false),
        (5, 5, true, 16.0, true),
        (6, 5, true, 16.0, false),
        (7, 5, true, 0.0, true),
        (1, 3, true, 16.0, true),
        (5, 3, true, 16.0, false),
        (7, 3, true, 16.0, false),
        (8, 3, false, 16.0, false),
        (4, 3, true, 0.0, false),
        (1, 3, false, 16.0, false),
        (5, 3, false, 4.0, true),
        (5, 5, false, 0.0, false),
        (7, 5, false, 16.0, false),
        (0, 3, true, 16.0, true),
    ] {
        let p = SvgfParams {
            iterations,
            kernel,
            split,
            normal_width,
            taa: false,
            taa_alpha: 0.3,
            taa_gamma: 0.5,
            converge,
        };
        let (mut fast, mut slow) = (Svgf::new(), Svgf::new());
        slow.set_scalar(true);
        // Every kind of lanes in turn (those this processor lacks fall back to narrower ones).
        fast.set_lanes(["avx512", "avx2", "portable"][iterations as usize % 3]);
        // (With `converge`, enough frames for the still rows' luminance test to narrow.)
        for k in 0..if converge { 14 } else { 4 } {
            let f = frame(k);
            let mut a = vec![Vec3::ZERO; w * h];
            let mut b = vec![Vec3::ZERO; w * h];
            let input = SvgfFrame {
                width: w,
                height: h,
                direct: &f.direct,
                indirect: &f.indirect,
                albedo: &f.albedo,
                normal: &f.normal,
                depth: &f.depth,
                motion: &f.motion,
                emitter: &f.emitter,
            };
            fast.filter(&input, &p, &mut a).unwrap();
            slow.filter(&input, &p, &mut b).unwrap();
            for (i, (p, q)) in a.iter().zip(&b).enumerate() {
                let tolerance = 1e-4 * (1.0 + q.abs().max_element());
                assert!(
                    (*p - *q).abs().max_element() <= tolerance,
                    "{iterations} passes of {kernel}x{kernel} (split {split}, normal width {normal_width}, converge {converge}), frame {k}, pixel ({}, {}): {p} against {q}",
                    i % w,
                    i / w
                );
            }
        }
    }
}

/// A still wall whose light has stripes (0.2 and 0.8, two pixels wide) under uniform noise of
/// +-0.4, frame `k`; and the true output (light times albedo 0.5 over 0.5, plus the
/// indirect 0.05).
fn striped(k: u64) -> (Frame, Vec<Vec3>) {
    let mut f = noisy(k);
    let mut truth = vec![Vec3::ZERO; f.w * f.h];
    let mut rng = Rng::new(0x5717 + k, 2);
    for (i, (d, t)) in f.direct.iter_mut().zip(&mut truth).enumerate() {
        let base = if ((i % f.w) / 2).is_multiple_of(2) {
            0.2
        } else {
            0.8
        };
        *d = Vec3::splat(base + 0.4 * (2.0 * rng.next_f32() - 1.0));
        *t = Vec3::splat(base + 0.05);
    }
    (f, truth)
}

#[test]
fn converging_a_still_view_approaches_the_truth() {
    // The paper's filter blurs the stripes into their mean for ever (its luminance test is as
    // wide as the light's noise per frame, and its history is the first pass's output); with
    // `converge` the history is the plain mean of the frames and the test narrows with its
    // noise, so the error falls frame after frame, below that of the plain mean of the frames
    // (what accumulation gives).
    let frames = 400;
    let run = |converge: bool| {
        let p = SvgfParams {
            kernel: 3,
            converge,
            ..SvgfParams::default()
        };
        let mut svgf = Svgf::new();
        let mut errors = Vec::new();
        for k in 0..frames {
            let (f, truth) = striped(k);
            errors.push(mean_abs_diff(&f.run_params(&mut svgf, &p), &truth));
        }
        errors
    };
    let (paper, converged) = (run(false), run(true));
    let (mut sum, mut truth) = (vec![Vec3::ZERO; 48 * 32], Vec::new());
    for k in 0..frames {
        let (f, t) = striped(k);
        for ((s, d), i) in sum.iter_mut().zip(&f.direct).zip(&f.indirect) {
            *s += *d + *i;
        }
        truth = t;
    }
    let mean: Vec<Vec3> = sum.iter().map(|s| *s / frames as f32).collect();
    let accumulated = mean_abs_diff(&mean, &truth);
    let last = frames as usize - 1;
    // (Measured: the paper's 0.28 from frame 10 on; converging 0.17, 0.0021, 0.0022 at
    // frames 10, 100, 400; the plain mean 0.009 at 400.)
    assert!(paper[last] > 0.25, "{}", paper[last]);
    assert!(
        converged[99] < 0.05 * converged[9] && converged[last] < 0.02 * paper[last],
        "{} {} {}",
        converged[9],
        converged[99],
        converged[last]
    );
    assert!(
        converged[last] < accumulated,
        "{} against {accumulated}",
        converged[last]
    );
}

#[test]
fn converging_changes_nothing_where_the_camera_moves() {
    // A noisy wall with a step that moves one pixel a frame, every pixel moving after the
    // first frame: the same images bit for bit with and without `converge`.
    let frame = |k: usize| {
        let mut f = noisy(k as u64);
        for (i, m) in f.motion.iter_mut().enumerate() {
            // (The first frame's motion 0, as a camera path's first frame has.)
            *m = Vec2::new(if k > 0 { -1.0 } else { 0.0 }, 0.0);
            if i % 48 >= 20 + k {
                f.direct[i] += Vec3::splat(0.5);
            }
        }
        f
    };
    let (mut a, mut b) = (Svgf::new(), Svgf::new());
    let converge = SvgfParams {
        converge: true,
        ..SvgfParams::default()
    };
    for k in 0..8 {
        let f = frame(k);
        assert_eq!(f.run_params(&mut a, &converge), f.run(&mut b), "frame {k}");
    }
}

/// The a-trous passes' kernel across a row (one axis of the separable 2D kernel): the
/// spline's weights at holes of 1, 2, 4, ... pixels, convolved.
fn atrous_kernel_1d(kernel: u32, passes: u32) -> Vec<f64> {
    let h: &[f64] = if kernel == 3 {
        &[0.25, 0.5, 0.25]
    } else {
        &[1.0 / 16.0, 0.25, 3.0 / 8.0, 0.25, 1.0 / 16.0]
    };
    let r = h.len() / 2;
    let mut k = vec![1.0];
    for pass in 0..passes {
        let step = 1 << pass;
        let mut next = vec![0.0; k.len() + 2 * r * step];
        for (i, a) in k.iter().enumerate() {
            for (j, b) in h.iter().enumerate() {
                next[i + j * step] += a * b;
            }
        }
        k = next;
    }
    k
}

/// On a flat wall whose every test weighs 1 (one depth and normal; noise that leaves the
/// luminance flat, so the luminance test has no edge to see), the passes are a fixed
/// linear filter: a pixel's noise variance falls by the sum of its combined kernel's squared
/// weights (the product of the 1D kernel's for the two axes). Measured over 96 independent
/// first frames at each pixel far enough from the border.
#[test]
fn noise_on_a_flat_wall_falls_by_the_kernels_squared_weights() {
    let (w, h) = (64, 64);
    // A direction of no luminance (0.2126 r + 0.7152 g + 0.0722 b = 0).
    let d = Vec3::new(0.7152, -0.2126, 0.0);
    for (kernel, passes) in [(5, 2), (3, 3), (5, 3)] {
        let k = atrous_kernel_1d(kernel, passes);
        let squares: f64 = k.iter().map(|w| w * w).sum();
        let expected = squares * squares;
        let reach = k.len() / 2;
        let p = SvgfParams {
            iterations: passes,
            kernel,
            ..SvgfParams::default()
        };
        let trials = 96;
        let (mut sum, mut sum2) = (vec![0.0f64; w * h], vec![0.0f64; w * h]);
        let mut input = 0.0;
        for t in 0..trials {
            let mut f = Frame::flat(w, h, 0.5);
            let mut rng = Rng::new(0xf1a7 + t, 4);
            for c in &mut f.direct {
                let n = 0.4 * (2.0 * rng.next_f32() - 1.0);
                *c = Vec3::splat(0.5) + d * n;
            }
            input += f
                .direct
                .iter()
                .map(|c| (c.x as f64 - 0.5).powi(2))
                .sum::<f64>();
            // A first frame: no history.
            let out = f.run_params(&mut Svgf::new(), &p);
            for (i, o) in out.iter().enumerate() {
                sum[i] += o.x as f64;
                sum2[i] += (o.x as f64).powi(2);
            }
        }
        let input = input / (trials as usize * w * h) as f64;
        let (mut var, mut count) = (0.0, 0);
        for y in reach..h - reach {
            for x in reach..w - reach {
                let i = y * w + x;
                let n = trials as f64;
                var += (sum2[i] - sum[i] * sum[i] / n) / (n - 1.0);
                count += 1;
            }
        }
        let ratio = var / count as f64 / input;
        // About 1200 pixels' variances of 96 draws each, correlated within the kernel's
        // reach: a few percent of spread.
        assert!(
            (ratio / expected - 1.0).abs() < 0.1,
            "{passes} passes of {kernel}x{kernel}: the variance fell by {ratio:.4}, the \
             kernel's squared weights sum to {expected:.4}"
        );
    }
}

/// A sample that is not finite (NaN or infinite light) gives its pixel no light and history,
/// and is nobody's neighbour: every pixel stays finite, and the others differ from the same
/// frames without it by no more than one neighbour's share of the light.
#[test]
fn a_nan_or_infinite_sample_does_not_spread() {
    for kernel in [5, 3] {
        let (mut clean, mut dirty) = (Svgf::new(), Svgf::new());
        for k in 0..6 {
            let f = noisy(k);
            let mut g = f.clone();
            let (a, b) = (10 * f.w + 20, 20 * f.w + 30);
            g.direct[a] = Vec3::new(f32::NAN, 0.5, 0.5);
            g.indirect[b] = Vec3::splat(f32::INFINITY);
            let (want, got) = (
                f.run_with(&mut clean, kernel),
                g.run_with(&mut dirty, kernel),
            );
            for (i, (p, q)) in got.iter().zip(&want).enumerate() {
                assert!(
                    p.is_finite(),
                    "{kernel}x{kernel}, frame {k}, pixel {i}: {p}"
                );
                if i != a && i != b {
                    assert!(
                        (*p - *q).abs().max_element() < 0.1,
                        "{kernel}x{kernel}, frame {k}, pixel {i}: {p} against {q}"
                    );
                }
            }
        }
    }
}

#[test]
fn bad_parameters_and_buffers_are_refused() {
    let f = Frame::flat(8, 6, 0.3);
    let mut svgf = Svgf::new();
    for (p, field) in [
        (
            SvgfParams {
                kernel: 4,
                ..SvgfParams::default()
            },
            "frame.filter.svgf.atrous_kernel",
        ),
        (
            SvgfParams {
                iterations: 17,
                ..SvgfParams::default()
            },
            "frame.filter.svgf.atrous_iterations",
        ),
        (
            SvgfParams {
                normal_width: f32::NAN,
                ..SvgfParams::default()
            },
            "frame.filter.svgf.normal_width",
        ),
        (
            SvgfParams {
                normal_width: -1.0,
                ..SvgfParams::default()
            },
            "frame.filter.svgf.normal_width",
        ),
    ] {
        let mut out = vec![Vec3::ZERO; 48];
        let e = svgf.filter(&f.view(), &p, &mut out).unwrap_err();
        assert!(e.to_string().contains(field), "{p:?}: {e}");
    }
    // A buffer of the wrong size, named.
    let mut short = f.clone();
    short.depth.pop();
    let mut out = vec![Vec3::ZERO; 48];
    let e = svgf
        .filter(&short.view(), &SvgfParams::default(), &mut out)
        .unwrap_err();
    assert!(e.to_string().contains("`depth` holds 47"), "{e}");
    // The temporal pass alone is a filter.
    let p = SvgfParams {
        iterations: 0,
        ..SvgfParams::default()
    };
    for o in f.run_params(&mut svgf, &p) {
        assert!((o - Vec3::splat(0.33)).abs().max_element() < 1e-5, "{o}");
    }
}
