//! What every stage of the frame has in common: a name, its views (the display modes it
//! brings), its passes' names, its rule at a new epoch and the memory it holds. Each stage's
//! passes are its own methods, called in order by the driver ([`super::pipeline`]) with
//! explicit inputs and outputs; this trait is what the display pass, the viewer's menu,
//! `--display`, the reports and the memory report read of all of them, and what the driver
//! calls on all of them at a new epoch ([`super::stages`]).

use glam::Vec3;
use rayon::prelude::*;

use super::display::{encode, DisplayConfig, View};
use super::state::{Change, FrameState};

/// A stage of the frame: a technique, or one of the plain pipeline's passes.
pub trait Stage: Sync {
    /// Its name: the heading of its views in the viewer's menu and in `--display`'s list.
    fn name(&self) -> &'static str;

    /// Its views, in menu order.
    fn views(&self) -> &'static [View];

    /// The names of its passes, in the order it runs them (the times a frame reports): its
    /// own name by default.
    fn passes(&self) -> Vec<&'static str> {
        vec![self.name()]
    }

    /// Its rule at a new epoch after `change` (nothing by default: a stage that keeps
    /// nothing across frames).
    fn start_epoch(&mut self, change: Change) {
        let _ = change;
    }

    /// The linear value of its view number `view` (an index into [`views`](Self::views)) at
    /// pixel `pixel` of `frame`: radiance, a feature, a statistic, as the view's documentation
    /// says.
    fn value(&self, frame: &FrameState, view: usize, pixel: usize) -> Vec3;

    /// The colour of a [`ViewKind::Painted`](super::display::ViewKind::Painted) view at `pixel`.
    fn paint(&self, frame: &FrameState, view: usize, pixel: usize) -> [u8; 3] {
        let _ = (frame, view, pixel);
        [0; 3]
    }

    /// Bytes of the per-pixel buffers it holds (not the frame state's: none by default).
    fn bytes(&self) -> usize {
        0
    }

    /// View number `view` as 8-bit RGBA into `out` (the display pass).
    fn rgba8(&self, frame: &FrameState, view: usize, display: &DisplayConfig, out: &mut Vec<u8>) {
        encode(
            self.views()[view].kind,
            frame.pixels(),
            |i| self.value(frame, view, i),
            |i| self.paint(frame, view, i),
            display,
            out,
        );
    }

    /// View number `view`'s linear values, row-major (EXR frames, tests).
    fn linear(&self, frame: &FrameState, view: usize) -> Vec<Vec3> {
        (0..frame.pixels())
            .into_par_iter()
            .map(|i| self.value(frame, view, i))
            .collect()
    }
}

/// The index of the view named `name` among `views`.
pub fn view_index(views: &[View], name: &str) -> Option<usize> {
    views.iter().position(|v| v.name == name)
}
