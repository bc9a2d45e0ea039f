//! A buffer and its twin: a temporal technique reads last frame's state while it writes this
//! frame's (kajiya's `PingPongTemporalResource`). Every history the frame's stages keep
//! across frames is one: forward reprojection's per-pixel states, ReSTIR's reservoirs and
//! receivers. (SVGF's history lives in the filter crate, in its own planes.)

/// Two buffers of one kind: `current` is this frame's, `previous` last frame's.
#[derive(Debug, Clone, Default)]
pub struct PingPong<T> {
    pub current: Vec<T>,
    pub previous: Vec<T>,
}

impl<T> PingPong<T> {
    /// After a frame wrote `previous` as its new state: that becomes `current`.
    pub fn swap(&mut self) {
        std::mem::swap(&mut self.current, &mut self.previous);
    }

    /// Both buffers at `len` elements (new ones `value`).
    pub fn resize(&mut self, len: usize, value: T)
    where
        T: Clone,
    {
        self.current.resize(len, value.clone());
        self.previous.resize(len, value);
    }

    /// Bytes held by both buffers.
    pub fn bytes(&self) -> usize {
        (self.current.capacity() + self.previous.capacity()) * std::mem::size_of::<T>()
    }
}
