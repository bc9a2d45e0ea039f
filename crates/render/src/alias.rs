//! Walker / Vose alias tables: O(1) sampling of a discrete distribution.

/// A discrete distribution over `0..len` proportional to the weights it was built from.
#[derive(Debug, Clone)]
pub struct AliasTable {
    pmf: Vec<f32>,
}

impl AliasTable {
    /// `None` when no weight is positive. Negative and non-finite weights count as 0.
    pub fn new(weights: &[f32]) -> Option<Self> {
        let _ = weights;
        todo!("alias")
    }

    /// The index chosen by `u` in [0, 1) and its probability.
    pub fn sample(&self, u: f32) -> (usize, f32) {
        let _ = u;
        todo!("alias")
    }

    pub fn pmf(&self, index: usize) -> f32 {
        self.pmf[index]
    }

    pub fn len(&self) -> usize {
        self.pmf.len()
    }

    pub fn is_empty(&self) -> bool {
        self.pmf.is_empty()
    }
}
