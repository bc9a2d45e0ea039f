//! The single-sample weighted reservoir (streaming resampled importance sampling).

use pathlight_core::rng::Rng;

use crate::light::LightPoint;

/// A single-sample weighted reservoir (weighted reservoir sampling, streaming RIS).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Reservoir {
    /// The surviving sample.
    pub sample: LightPoint,
    /// Sum of the resampling weights seen.
    pub w_sum: f32,
    /// Candidates behind it (M).
    pub m: f32,
    /// The target function of the sample at the pixel that owns the reservoir.
    pub target: f32,
    /// The contribution weight W (0: no usable sample).
    pub weight: f32,
}

impl Reservoir {
    /// Streams in a candidate of resampling weight `w` standing for `m` candidates, `u`
    /// uniform in [0, 1): it survives with probability `w / w_sum`. Returns whether it did.
    #[inline]
    pub fn update(&mut self, sample: LightPoint, w: f32, target: f32, m: f32, u: f32) -> bool {
        let survives = self.admit(w, target, m, u);
        if survives {
            self.sample = sample;
        }
        survives
    }

    /// [`update`](Self::update) but for the sample itself, which the caller keeps when this
    /// returns true; without branches (whether a candidate survives is a coin toss a branch
    /// predictor cannot learn).
    #[inline]
    pub(super) fn admit(&mut self, w: f32, target: f32, m: f32, u: f32) -> bool {
        self.m += m;
        let valid = w > 0.0 && w.is_finite();
        self.w_sum = if valid { self.w_sum + w } else { self.w_sum };
        let survives = valid && u * self.w_sum < w;
        self.target = if survives { target } else { self.target };
        survives
    }

    /// Sets `W = w_sum / (z p_hat(y))` (0 without a sample or with `z` = 0).
    #[inline]
    pub fn finish(&mut self, z: f32) {
        let w = self.w_sum / (z * self.target);
        self.weight = if self.target > 0.0 && z > 0.0 && w.is_finite() {
            w
        } else {
            0.0
        };
    }

    /// Resampled importance sampling: `candidates` draws of `draw` (a sample and its source
    /// density), resampled in proportion to `target / density`; `W` set with `Z = M`.
    pub fn resample(
        candidates: u32,
        rng: &mut Rng,
        mut draw: impl FnMut(&mut Rng) -> Option<(LightPoint, f32)>,
        mut target: impl FnMut(&LightPoint) -> f32,
    ) -> Self {
        let mut r = Self::default();
        for _ in 0..candidates {
            match draw(rng) {
                Some((point, density)) if density > 0.0 => {
                    let t = target(&point);
                    r.update(point, t / density, t, 1.0, rng.next_f32());
                }
                _ => r.m += 1.0,
            }
        }
        r.finish(r.m);
        r
    }
}
