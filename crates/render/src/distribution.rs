//! Piecewise-constant 2D distributions over [0,1]^2 (environment map importance sampling).

use glam::Vec2;

/// A density over [0,1]^2, constant on each cell of a `width` x `height` grid and proportional
/// to the cell weights (row-major, row 0 at v = 0).
#[derive(Debug, Clone)]
pub struct Distribution2D {
    width: usize,
    height: usize,
}

impl Distribution2D {
    /// `None` when no weight is positive. Negative and non-finite weights count as 0.
    pub fn new(weights: &[f32], width: usize, height: usize) -> Option<Self> {
        let _ = weights;
        let _ = (width, height);
        todo!("distribution")
    }

    /// A point and its density with respect to area on [0,1]^2.
    pub fn sample(&self, u: Vec2) -> (Vec2, f32) {
        let _ = u;
        let _ = (self.width, self.height);
        todo!("distribution")
    }

    /// The density at `p` with respect to area on [0,1]^2.
    pub fn pdf(&self, p: Vec2) -> f32 {
        let _ = p;
        todo!("distribution")
    }
}
