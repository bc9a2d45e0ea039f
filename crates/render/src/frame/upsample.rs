//! Temporal upsampling (issue 60): the frame is traced at a fraction of the output's size
//! (`[frame.upsample] scale` per axis) and the output is reconstructed at its own size from
//! the traced samples and its own history, so a frame costs about `scale^2` of its rays.
//!
//! ```text
//! this frame's samples (render size), their film positions, motion -> output image (output size)
//! output history (colour, sample count)                            -> output history
//! ```
//!
//! Each traced sample lands at a known point of the film (its camera sample's position,
//! which the primary pass keeps in the G-buffer), and so in one output pixel. An output pixel
//! keeps the mean of the samples that landed in it (its colour and their count): while the
//! camera and the settings stay the same it adds every new sample to that mean, so a still
//! view converges to the output-size image with the output's own pixel filter (a box), as a
//! render at the output size would, only `1 / scale^2` times slower. After a camera move it
//! fetches its history where its surface was (the motion vector of the render pixel that
//! holds it; 4x4 Catmull-Rom taps, which blur less than bilinear ones over many moves),
//! clamps it to the box of the 3x3 render pixels around it (their mean plus and minus `gamma`
//! standard deviations, in light compressed by its luminance and in YCoCg, stretched to hold
//! the pixel's new estimate: the temporal antialiasing filter's variance clipping), and lets
//! this frame's samples around it (weighed by their distance, a bump of 1.5 pixels)
//! make at least `alpha` of its new value, so a disocclusion or a change of light takes the
//! new samples. A pixel that no sample reached and that has no history takes the mean of the
//! render pixels around it, weighted by their samples' distance (and counts as no sample: the
//! next one replaces it).
//!
//! At `scale = 1` the stage does nothing and every frame is the pipeline's own, bit for bit.
//! While it works, the render size's reconstruction filters stand aside (the output's
//! history is the temporal filter), and the frame's other views are shown at the output size
//! by their nearest render pixel.

use glam::{Vec2, Vec3, Vec3A, Vec4, Vec4Swizzles};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use pathlight_denoise::taa::{compress, expand, rgb, ycocg};

use super::display::{View, ViewKind};
use super::gbuffer::GBuffer;
use super::stage::Stage;
use super::state::{Change, FrameState};
use crate::error::ConfigError;

/// The stage's name and its pass's.
pub const UPSAMPLE: &str = "upsample";

/// Temporal upsampling's settings (`[frame.upsample]`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct UpsampleConfig {
    /// The render size over the output size, per axis: 1 traces the output's pixels (the
    /// stage is off), 0.5 a quarter of them.
    pub scale: f32,
    /// After a camera move, this frame's samples weigh at least `alpha` of a pixel's new
    /// value (the history at most `1 / alpha - 1` times their weight).
    pub alpha: f32,
    /// The neighbourhood box's half-width in standard deviations.
    pub gamma: f32,
}

impl Default for UpsampleConfig {
    fn default() -> Self {
        Self {
            scale: 1.0,
            alpha: 0.3,
            gamma: 1.0,
        }
    }
}

/// The smallest `scale`.
pub const MIN_SCALE: f32 = 0.25;

impl UpsampleConfig {
    pub fn validate(&self) -> Result<(), ConfigError> {
        let s = self.scale;
        if !(MIN_SCALE..=1.0).contains(&s) {
            let want = format!("between {MIN_SCALE} and 1");
            return Err(ConfigError::new("frame.upsample.scale", s, want));
        }
        if !(self.alpha > 0.0 && self.alpha <= 1.0) {
            return Err(ConfigError::new(
                "frame.upsample.alpha",
                self.alpha,
                "in (0, 1]",
            ));
        }
        if !(self.gamma.is_finite() && self.gamma > 0.0) {
            return Err(ConfigError::new(
                "frame.upsample.gamma",
                self.gamma,
                "finite and > 0",
            ));
        }
        Ok(())
    }
}

/// The size traced at render scale `scale` for an output of `width` x `height` (each side at
/// least 1).
pub fn render_size(scale: f32, width: u32, height: u32) -> (u32, u32) {
    if scale >= 1.0 {
        return (width, height);
    }
    let side = |n: u32| ((n as f32 * scale).round() as u32).clamp(1, n.max(1));
    (side(width), side(height))
}

/// One output pixel's history: the mean of its samples and how many samples it weighs (laid
/// out as one SIMD register, which [`fetch`] reads at once).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
#[repr(C, align(16))]
struct Texel {
    colour: Vec3,
    count: f32,
}

/// The stage: the output's history.
#[derive(Debug, Default)]
pub struct Upsample {
    /// The output's size (0 x 0: off).
    width: usize,
    height: usize,
    /// The output, row-major (what `final` shows while the stage works).
    history: Vec<Texel>,
    next: Vec<Texel>,
    /// What the next frame's history must do: nothing (the camera stayed), follow a move
    /// (`Some(false)`) or start afresh (`Some(true)`).
    change: Option<bool>,
}

impl Upsample {
    pub const VIEWS: &'static [View] = &[View {
        name: "upsample-samples",
        about: "how many samples each output pixel's history weighs (heat map to the largest)",
        kind: ViewKind::HeatOfLargest,
    }];

    /// True when the last frame was reconstructed here (the output is this stage's).
    pub fn active(&self) -> bool {
        self.width > 0
    }

    /// The output's size (while [`active`](Self::active)).
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// Stands aside: the next frame at the output size is the pipeline's own.
    pub fn clear(&mut self) {
        *self = Self::default();
    }

    /// The pass: `samples` (this frame's, one per render pixel of `gbuffer`, at the film
    /// positions it keeps) into the output of `width` x `height`.
    pub fn pass(
        &mut self,
        config: &UpsampleConfig,
        samples: &[Vec3],
        gbuffer: &GBuffer,
        (width, height): (usize, usize),
    ) {
        let fresh = (self.width, self.height) != (width, height) || self.change == Some(true);
        if fresh {
            self.history.clear();
            self.history.resize(width * height, Texel::default());
            (self.width, self.height) = (width, height);
        }
        let moved = !fresh && self.change == Some(false);
        self.change = None;
        let (rw, rh) = (gbuffer.width as usize, gbuffer.height as usize);
        let to_output = Vec2::new(width as f32 / rw as f32, height as f32 / rh as f32);
        let points: Vec<Point> = (samples.par_iter().zip(&gbuffer.pixels))
            .map(|(c, g)| Point {
                c: (*c).into(),
                compressed: compress(*c).into(),
                film: g.film * to_output,
            })
            .collect();
        let boxes = boxes(&points, rw, rh);
        let input = Input {
            points: &points,
            gbuffer,
            boxes: &boxes,
            render: (rw, rh),
            output: (width, height),
            to_output,
        };
        let history = &self.history;
        let cap = 1.0 / config.alpha - 1.0;
        self.next.resize(width * height, Texel::default());
        // (Each output column's render column, the same for every row.)
        let columns: Vec<usize> = (0..width)
            .map(|x| render_index(x, to_output.x, rw))
            .collect();
        self.next
            .par_chunks_mut(width)
            .enumerate()
            .for_each(|(y, row)| {
                let ry = render_index(y, to_output.y, rh);
                for ((x, out), &rx) in row.iter_mut().enumerate().zip(&columns) {
                    *out = input.pixel(history, (x, y), (rx, ry), moved, (cap, config.gamma));
                }
            });
        std::mem::swap(&mut self.history, &mut self.next);
    }

    /// The output at pixel `i`.
    pub fn colour(&self, i: usize) -> Vec3 {
        self.history[i].colour
    }
}

/// Each render pixel's 3x3 neighbourhood's mean and standard deviation in compressed YCoCg
/// (the box a moved history is clamped to), and its largest value per channel in linear
/// light (the box's corners, expanded back, may lie far above every sample near a light).
fn boxes(points: &[Point], w: usize, h: usize) -> Vec<Neighbourhood> {
    let values: Vec<Vec3> = (points.par_iter())
        .map(|p| ycocg(p.compressed.into()))
        .collect();
    (0..w * h)
        .into_par_iter()
        .map(|i| {
            let (x, y) = (i % w, i / w);
            let (mut sum, mut square, mut n) = (Vec3::ZERO, Vec3::ZERO, 0.0f32);
            let mut max = Vec3A::ZERO;
            for qy in y.saturating_sub(1)..(y + 2).min(h) {
                for qx in x.saturating_sub(1)..(x + 2).min(w) {
                    let v = values[qy * w + qx];
                    if v.is_finite() {
                        (sum, square, n) = (sum + v, square + v * v, n + 1.0);
                        max = max.max(points[qy * w + qx].c);
                    }
                }
            }
            let mean = sum / n.max(1.0);
            let sigma = (square / n.max(1.0) - mean * mean).max(Vec3::ZERO).sqrt();
            Neighbourhood {
                mean,
                sigma,
                max: max.into(),
            }
        })
        .collect()
}

/// A render pixel's sample: its value, compressed by its luminance, and its film position in
/// output pixels (the values in SIMD registers' layout: one operation a sum).
#[derive(Debug, Clone, Copy)]
struct Point {
    c: Vec3A,
    compressed: Vec3A,
    film: Vec2,
}

/// A render pixel's 3x3 neighbourhood: [`boxes`].
#[derive(Debug, Clone, Copy)]
struct Neighbourhood {
    mean: Vec3,
    sigma: Vec3,
    max: Vec3,
}

/// What every output pixel reads.
struct Input<'a> {
    /// Each render pixel's sample.
    points: &'a [Point],
    gbuffer: &'a GBuffer,
    boxes: &'a [Neighbourhood],
    render: (usize, usize),
    output: (usize, usize),
    /// Output pixels per render pixel, per axis.
    to_output: Vec2,
}

impl Input<'_> {
    /// Output pixel `at`'s new history, from `history` (the camera `moved` since it was made;
    /// a moved history weighs at most `cap` times this frame's samples, clamped to its box
    /// widened by `gamma`); (`rx`, `ry`) is the render pixel that holds its centre
    /// ([`render_index`] of each axis).
    fn pixel(
        &self,
        history: &[Texel],
        at: (usize, usize),
        (rx, ry): (usize, usize),
        moved: bool,
        (cap, gamma): (f32, f32),
    ) -> Texel {
        let (rw, rh) = self.render;
        let centre = Vec2::new(at.0 as f32 + 0.5, at.1 as f32 + 0.5);
        // This frame's samples: while the camera stays, those that landed in the pixel (a box,
        // the output's own pixel filter: a still view converges to the output-size image);
        // after a move, every sample around by its distance, so every pixel has some, and
        // in compressed light, as the temporal antialiasing filter blends (a firefly among
        // them weighs as a white sample, not its radiance's worth, while the view moves).
        let (mut sum, mut weight) = (Vec3A::ZERO, 0.0f32);
        if moved {
            self.around(rx, ry, |p| {
                let d = (p.film - centre).length_squared();
                let t = (1.0 - d * (1.0 / (RADIUS * RADIUS))).max(0.0);
                (sum, weight) = (sum + p.compressed * (t * t), weight + t * t);
            });
            let sum = Vec3::from(sum);
            let (old, count) = self.moved(history, centre, (rx, ry), (sum, weight), cap, gamma);
            let total = count + weight;
            if total > 0.0 {
                let blend = (old * count + sum) / total;
                // The largest of the samples around (the render pixel's 3x3, whose samples
                // the bump weighs are some of).
                let max = self.boxes[ry * rw + rx].max;
                return Texel {
                    colour: expand(blend).clamp(Vec3::ZERO, max),
                    count: total,
                };
            }
        } else {
            let first = Vec2::new(at.0 as f32, at.1 as f32) / self.to_output;
            let last = (first + Vec2::ONE / self.to_output).min(Vec2::new(rw as f32, rh as f32));
            for qy in first.y as usize..(last.y.ceil() as usize).min(rh) {
                for qx in first.x as usize..(last.x.ceil() as usize).min(rw) {
                    let p = self.points[qy * rw + qx];
                    if p.c.is_finite() && (p.film.x as usize, p.film.y as usize) == at {
                        (sum, weight) = (sum + p.c, weight + 1.0);
                    }
                }
            }
        }
        let old = match moved {
            false => history[at.1 * self.output.0 + at.0],
            true => Texel::default(),
        };
        let total = old.count + weight;
        if total > 0.0 {
            return Texel {
                colour: (old.colour * old.count + Vec3::from(sum)) / total,
                count: total,
            };
        }
        // Nothing here yet (still, and no sample landed): the samples around, nearer ones
        // weighing more, counting as none (the first sample replaces them).
        let (mut near, mut weight) = (Vec3A::ZERO, 0.0f32);
        self.around(rx, ry, |p| {
            let w = 1.0 / (1.0 + (p.film - centre).length_squared());
            (near, weight) = (near + p.c * w, weight + w);
        });
        Texel {
            colour: (near / weight.max(1e-12)).into(),
            count: 0.0,
        }
    }

    /// The history of the output pixel at `centre` after a move, in compressed light, and the
    /// samples it weighs: fetched where its surface was (the motion of render pixel `render`),
    /// clamped to that render pixel's box stretched to hold this frame's estimate (its
    /// samples' weighted sum in compressed light and weight), weighing at most `cap` times
    /// their weight; none where the surface was not in the image.
    fn moved(
        &self,
        history: &[Texel],
        centre: Vec2,
        (rx, ry): (usize, usize),
        (sum, weight): (Vec3, f32),
        cap: f32,
        gamma: f32,
    ) -> (Vec3, f32) {
        let rw = self.render.0;
        let motion = self.gbuffer.pixels[ry * rw + rx].motion * self.to_output;
        let (w, h) = self.output;
        let Some(old) = fetch(history, centre - Vec2::splat(0.5) + motion, w, h) else {
            return (Vec3::ZERO, 0.0);
        };
        let b = self.boxes[ry * rw + rx];
        let (mut low, mut high) = (b.mean - gamma * b.sigma, b.mean + gamma * b.sigma);
        if weight > 0.0 {
            let c = ycocg(sum / weight);
            (low, high) = (low.min(c), high.max(c));
        }
        let c = ycocg(compress(old.colour)).clamp(low, high);
        // (A pixel with no sample near keeps its history, as if it had a quarter of one.)
        (rgb(c), old.count.min(weight.max(0.25) * cap))
    }

    /// Calls `f` with the finite samples of the 3x3 render pixels around (`rx`, `ry`).
    #[inline(always)]
    fn around(&self, rx: usize, ry: usize, mut f: impl FnMut(&Point)) {
        let (rw, rh) = self.render;
        if rx >= 1 && ry >= 1 && rx + 1 < rw && ry + 1 < rh {
            // (Inside: rows of three.)
            for qy in ry - 1..ry + 2 {
                let row: &[Point; 3] = (self.points[qy * rw + rx - 1..qy * rw + rx + 2])
                    .try_into()
                    .expect("three");
                for p in row {
                    if p.c.is_finite() {
                        f(p);
                    }
                }
            }
            return;
        }
        for qy in ry.saturating_sub(1)..(ry + 2).min(rh) {
            for qx in rx.saturating_sub(1)..(rx + 2).min(rw) {
                let p = &self.points[qy * rw + qx];
                if p.c.is_finite() {
                    f(p);
                }
            }
        }
    }
}

/// The render pixel index (of `n` along an axis) that holds output pixel `i`'s centre, at
/// `to_output` output pixels per render pixel.
fn render_index(i: usize, to_output: f32, n: usize) -> usize {
    (((i as f32 + 0.5) / to_output) as usize).min(n - 1)
}

/// After a move, a sample weighs `(1 - d^2 / RADIUS^2)^2` at `d` output pixels from a pixel's
/// centre (a smooth bump, nought from `RADIUS` on: about a Gaussian of 0.6 pixels).
const RADIUS: f32 = 1.5;

/// The history at output position `p` (pixels, 0 at the first pixel's centre): its count from
/// its bilinear taps that fall inside the image and hold samples (`None` if none does), its
/// colour from the 4x4 Catmull-Rom taps that do (resampled every frame, bilinear taps would
/// blur the history a little more at each move), or the bilinear one where those weigh too
/// little.
fn fetch(history: &[Texel], p: Vec2, w: usize, h: usize) -> Option<Texel> {
    if !p.is_finite() {
        return None;
    }
    let (x0, y0) = (p.x.floor(), p.y.floor());
    let (fx, fy) = (p.x - x0, p.y - y0);
    // The 4x4 texels around, read once (those outside the image count no sample), each its
    // colour and count in one SIMD register: the bilinear taps are the middle 2x2.
    let (ix, iy) = (x0 as i64 - 1, y0 as i64 - 1);
    let lanes = |t: &Texel| t.colour.extend(t.count);
    let mut taps = [Vec4::ZERO; 16];
    if ix >= 0 && iy >= 0 && ix + 4 <= w as i64 && iy + 4 <= h as i64 {
        for (j, row) in taps.chunks_exact_mut(4).enumerate() {
            let start = (iy as usize + j) * w + ix as usize;
            for (tap, t) in row.iter_mut().zip(&history[start..start + 4]) {
                *tap = lanes(t);
            }
        }
    } else {
        for (k, tap) in taps.iter_mut().enumerate() {
            let (qx, qy) = (ix + (k % 4) as i64, iy + (k / 4) as i64);
            if qx >= 0 && qy >= 0 && qx < w as i64 && qy < h as i64 {
                *tap = lanes(&history[qy as usize * w + qx as usize]);
            }
        }
    }
    // (Colour and count summed together, lane by lane: the same sums as apart.)
    let (mut sum, mut weight) = (Vec4::ZERO, 0.0f32);
    let bilinear = [
        (5, (1.0 - fx) * (1.0 - fy)),
        (6, fx * (1.0 - fy)),
        (9, (1.0 - fx) * fy),
        (10, fx * fy),
    ];
    for (k, t) in bilinear {
        let old = taps[k];
        if t > 0.0 && old.w > 0.0 {
            (sum, weight) = (sum + old * t, weight + t);
        }
    }
    if weight < 1e-3 {
        return None;
    }
    let bilinear = sum / weight;
    let (kx, ky) = (catmull_rom(fx), catmull_rom(fy));
    let (mut sharp, mut total) = (Vec4::ZERO, 0.0f32);
    for (row, wy) in taps.chunks_exact(4).zip(ky) {
        for (old, wx) in row.iter().zip(kx) {
            if old.w > 0.0 {
                (sharp, total) = (sharp + *old * (wx * wy), total + wx * wy);
            }
        }
    }
    Some(Texel {
        colour: match total > 0.5 {
            true => (sharp.xyz() / total).max(Vec3::ZERO),
            false => bilinear.xyz(),
        },
        count: bilinear.w,
    })
}

/// The Catmull-Rom spline's weights of the four taps around a point `t` in [0, 1) past the
/// second.
fn catmull_rom(t: f32) -> [f32; 4] {
    let (t2, t3) = (t * t, t * t * t);
    [
        0.5 * (-t3 + 2.0 * t2 - t),
        0.5 * (3.0 * t3 - 5.0 * t2 + 2.0),
        0.5 * (-3.0 * t3 + 4.0 * t2 + t),
        0.5 * (t3 - t2),
    ]
}

impl Stage for Upsample {
    fn name(&self) -> &'static str {
        UPSAMPLE
    }

    fn views(&self) -> &'static [View] {
        Self::VIEWS
    }

    /// After a move of the camera alone (or a frame that does not accumulate), the history
    /// follows the move; after any other change it starts afresh.
    fn start_epoch(&mut self, change: Change) {
        let fresh = change == Change::Settings || self.change == Some(true);
        self.change = Some(fresh);
    }

    /// The samples each output pixel's history weighs (its own pixels: the output's).
    fn value(&self, _: &FrameState, _: usize, i: usize) -> Vec3 {
        Vec3::splat(self.history.get(i).map_or(0.0, |t| t.count))
    }

    fn bytes(&self) -> usize {
        (self.history.capacity() + self.next.capacity()) * std::mem::size_of::<Texel>()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use pathlight_core::rng::Rng;

    /// `fetch` reads the 4x4 texels once, whole rows where they are inside the image and
    /// one by one at its borders: a constant history gives itself back wherever its taps land,
    /// and a random one with holes gives at its borders what the same history padded with
    /// empty texels gives inside (the border read is the inside read with no sample outside).
    #[test]
    fn fetch_reads_the_same_texels_inside_and_at_the_borders() {
        let (w, h) = (7, 5);
        let constant = vec![
            Texel {
                colour: Vec3::new(0.3, 0.5, 0.7),
                count: 4.0,
            };
            w * h
        ];
        let mut rng = Rng::new(3, 4);
        for _ in 0..500 {
            let p = Vec2::new(rng.next_f32() * 9.0 - 1.5, rng.next_f32() * 7.0 - 1.5);
            match fetch(&constant, p, w, h) {
                Some(t) => {
                    assert!(
                        (t.colour - constant[0].colour).abs().max_element() < 1e-5,
                        "{p}"
                    );
                    assert!((t.count - 4.0).abs() < 1e-4, "{p}: {t:?}");
                }
                // The taps inside the image weigh less than 1e-3: the point is within that of
                // a pixel's width outside the image's first or last pixel centre.
                None => assert!(
                    p.x < -0.99 || p.y < -0.99 || p.x > w as f32 - 0.01 || p.y > h as f32 - 0.01,
                    "{p}"
                ),
            }
        }
        // A random history with holes, embedded in a larger image: a point's fetch reads the
        // same texels there (all inside) as in the small one (at its borders, outside texels
        // holding no sample).
        let mut small = vec![Texel::default(); w * h];
        for t in &mut small {
            if rng.next_f32() < 0.8 {
                *t = Texel {
                    colour: Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()),
                    count: 1.0 + rng.next_f32() * 8.0,
                };
            }
        }
        let (big_w, big_h, pad) = (w + 6, h + 6, 3);
        let mut big = vec![Texel::default(); big_w * big_h];
        for y in 0..h {
            for x in 0..w {
                big[(y + pad) * big_w + x + pad] = small[y * w + x];
            }
        }
        for _ in 0..500 {
            let p = Vec2::new(
                rng.next_f32() * (w - 1) as f32,
                rng.next_f32() * (h - 1) as f32,
            );
            // (The shifted point's fraction rounds a little differently.)
            let inside = fetch(&big, p + Vec2::splat(pad as f32), big_w, big_h);
            match (fetch(&small, p, w, h), inside) {
                (Some(a), Some(b)) => {
                    assert!(
                        (a.colour - b.colour).abs().max_element() < 1e-4,
                        "{p}: {a:?} {b:?}"
                    );
                    assert!(
                        (a.count - b.count).abs() < 1e-3 * b.count,
                        "{p}: {a:?} {b:?}"
                    );
                }
                (a, b) => assert_eq!(a, b, "{p}"),
            }
        }
    }
}
