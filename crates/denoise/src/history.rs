//! SVGF's per-pixel history, what its temporal pass carries to the next frame, kept in planes
//! row by row: row `y` holds [`FIELDS`] planes of the row's pixels, one per `f32` of a
//! [`State`]. The lanes' temporal pass reads a group's fields with one load each where its
//! pixels reproject to consecutive pixels of one row (a still camera, or one whose motion
//! moves a group by the same whole pixels), gathers elsewhere, and writes them with one store
//! each, past the caches (`simd::stream_first`: the next frame reads them only after the
//! a-trous passes' tens of megabytes, and the stores need not read the lines first; the
//! planes begin on a cache line for it); the scalar passes read and write a pixel's [`State`].

use glam::Vec3;

/// A pixel's history (the scalar passes' form).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct State {
    /// The integrated (after the first a-trous pass) demodulated light.
    pub light: [Vec3; 2],
    /// The integrated luminance moments (first and second, direct and indirect).
    pub m: [f32; 4],
    /// The history's length in frames (0: none).
    pub length: f32,
    pub depth: f32,
    pub normal: Vec3,
    /// The sum of the squares of the weights of the frames the history's mean holds (1 for
    /// one frame; `1 / n` for a plain mean of n; `SvgfParams::converge`).
    pub weights2: f32,
}

/// The planes of a [`State`]'s fields: its light's six (two signals' three channels), ...
pub(crate) const LIGHT: usize = 0;
/// ... the four moments, ...
pub(crate) const MOMENTS: usize = 6;
pub(crate) const LENGTH: usize = 10;
pub(crate) const DEPTH: usize = 11;
/// ... the normal's three, ...
pub(crate) const NORMAL: usize = 12;
pub(crate) const WEIGHTS2: usize = 15;
/// ... of a row's.
pub(crate) const FIELDS: usize = 16;

/// Every pixel's [`State`] in planes, row by row.
#[derive(Debug, Default)]
pub(crate) struct History {
    width: usize,
    height: usize,
    /// The planes from `start` on (so that they begin on a cache line: [`ALIGN`]).
    storage: Vec<f32>,
    start: usize,
}

/// The floats the planes may begin after the storage's start: 64 bytes.
const ALIGN: usize = 16;

impl History {
    /// `width x height` pixels without a history (as `State::default()`).
    pub fn reset(&mut self, width: usize, height: usize) {
        (self.width, self.height) = (width, height);
        self.storage.clear();
        self.storage.resize(FIELDS * width * height + ALIGN, 0.0);
        self.start = self
            .storage
            .as_ptr()
            .cast::<u8>()
            .align_offset(4 * ALIGN)
            .div_ceil(4)
            .min(ALIGN);
    }

    /// The planes' floats.
    fn len_floats(&self) -> usize {
        FIELDS * self.width * self.height
    }

    /// The planes.
    fn data(&self) -> &[f32] {
        &self.storage[self.start..][..self.len_floats()]
    }

    /// The planes to write.
    fn data_mut(&mut self) -> &mut [f32] {
        let len = self.len_floats();
        &mut self.storage[self.start..][..len]
    }

    /// No pixels.
    pub fn clear(&mut self) {
        self.reset(0, 0);
    }

    /// Made `width x height` pixels, their fields left as they are if it was (they are all
    /// to be written).
    pub fn fit(&mut self, width: usize, height: usize) {
        if (self.width, self.height) != (width, height)
            || self.storage.len() != FIELDS * width * height + ALIGN
        {
            self.reset(width, height);
        }
    }

    /// The pixels.
    pub fn len(&self) -> usize {
        self.width * self.height
    }

    /// The planes, row by row (row `y`'s field `k` from `(y * FIELDS + k) * width` on).
    pub fn planes(&self) -> &[f32] {
        self.data()
    }

    /// [`Self::planes`] to write (a row's `FIELDS * width` at a time).
    pub fn planes_mut(&mut self) -> &mut [f32] {
        self.data_mut()
    }

    /// Where pixel `i`'s field 0 is in [`Self::planes`] (field `k` is `k * width` further).
    fn at(&self, i: usize) -> usize {
        let (x, y) = (i % self.width, i / self.width);
        y * FIELDS * self.width + x
    }

    /// Field `k` of pixel `i`'s state.
    pub fn field(&self, i: usize, k: usize) -> f32 {
        self.data()[self.at(i) + k * self.width]
    }

    /// Field `k` of row `y`'s pixels.
    pub fn row_field(&self, y: usize, k: usize) -> &[f32] {
        let at = (y * FIELDS + k) * self.width;
        &self.data()[at..at + self.width]
    }

    /// Pixel `i`'s luminance moments.
    pub fn moments(&self, i: usize) -> [f32; 4] {
        std::array::from_fn(|k| self.field(i, MOMENTS + k))
    }

    /// Pixel `i`'s state.
    pub fn get(&self, i: usize) -> State {
        let (at, w) = (self.at(i), self.width);
        let data = self.data();
        let f = |k: usize| data[at + k * w];
        let v = |k: usize| Vec3::new(f(k), f(k + 1), f(k + 2));
        State {
            light: [v(LIGHT), v(LIGHT + 3)],
            m: std::array::from_fn(|k| f(MOMENTS + k)),
            length: f(LENGTH),
            depth: f(DEPTH),
            normal: v(NORMAL),
            weights2: f(WEIGHTS2),
        }
    }

    /// Sets pixel `i`'s light.
    pub fn set_light(&mut self, i: usize, light: &[Vec3; 2]) {
        let (at, w) = (self.at(i), self.width);
        let data = self.data_mut();
        for (c, light) in light.iter().enumerate() {
            for (k, &x) in light.to_array().iter().enumerate() {
                data[at + (LIGHT + 3 * c + k) * w] = x;
            }
        }
    }

    /// Sets pixel `i`'s state.
    pub fn set(&mut self, i: usize, s: &State) {
        self.set_light(i, &s.light);
        let (at, w) = (self.at(i), self.width);
        let data = self.data_mut();
        let mut put = |k: usize, value: f32| data[at + k * w] = value;
        for (k, &m) in s.m.iter().enumerate() {
            put(MOMENTS + k, m);
        }
        put(LENGTH, s.length);
        put(DEPTH, s.depth);
        for (k, &x) in s.normal.to_array().iter().enumerate() {
            put(NORMAL + k, x);
        }
        put(WEIGHTS2, s.weights2);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_state_set_is_the_state_got() {
        let mut h = History::default();
        h.reset(5, 3);
        assert_eq!(h.get(7), State::default());
        let s = |i: usize| {
            let x = i as f32;
            State {
                light: [Vec3::new(x, 1.0, 2.0), Vec3::new(3.0, 4.0, x)],
                m: [5.0, x, 7.0, 8.0],
                length: 9.0 + x,
                depth: 10.0,
                normal: Vec3::new(11.0, x, 13.0),
                weights2: 14.0 - x,
            }
        };
        for i in 0..15 {
            h.set(i, &s(i));
        }
        for i in 0..15 {
            assert_eq!(h.get(i), s(i), "pixel {i}");
        }
        // Row 1's length plane holds pixels 5..10's.
        let row = &h.planes()[FIELDS * 5..2 * FIELDS * 5];
        assert_eq!(
            &row[LENGTH * 5..LENGTH * 5 + 5],
            &[14.0, 15.0, 16.0, 17.0, 18.0]
        );
        assert_eq!(h.row_field(1, LENGTH), &[14.0, 15.0, 16.0, 17.0, 18.0]);
        assert_eq!(h.row_field(2, MOMENTS + 1), &[10.0, 11.0, 12.0, 13.0, 14.0]);
    }
}
