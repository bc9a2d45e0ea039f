//! The frame's stages, listed once, in the frame's order. From this list come the pipeline's
//! stages ([`Stages`], one field each), the list of them the display pass, the memory report
//! and the viewer's menu read ([`Stages::all`]), each stage's rule at a new epoch
//! ([`Stage::start_epoch`], called on all of them), the views that parsing checks names
//! against ([`views`]) and the order of the passes in a report ([`passes`]).
//!
//! A new stage is its module, its line here, its settings' line in the list that makes
//! [`FrameConfig`](crate::config::FrameConfig), and its pass's call in the driver
//! ([`super::pipeline::Pipeline::render_frame`]).

use std::sync::LazyLock;

use super::adaptive::Adaptive;
use super::display::{View, DISPLAY};
use super::filter::Filter;
use super::history::History;
use super::reprojection::Reprojection;
use super::restir::Restir;
use super::stage::Stage;
use super::state::Change;
use super::texture_cache::TextureCache;
use super::trace::{Lighting, Primary};
use super::upsample::Upsample;

/// Makes [`Stages`] from the list of its fields and their types, in the frame's order.
macro_rules! stages {
    ($($field:ident: $stage:ty,)*) => {
        /// Every stage's own state, in the frame's order.
        #[derive(Default)]
        pub struct Stages {
            $(pub $field: $stage,)*
        }

        impl Stages {
            /// The stages, in the frame's order.
            pub fn all(&self) -> Vec<&dyn Stage> {
                vec![$(&self.$field),*]
            }

            /// The stages, in the frame's order, to change.
            fn all_mut(&mut self) -> Vec<&mut dyn Stage> {
                vec![$(&mut self.$field),*]
            }
        }
    };
}

stages! {
    reprojection: Reprojection,   // seed 000
    adaptive: Adaptive,           // seed 000
    primary: Primary,
    restir: Restir,               // seed 004
    texture_cache: TextureCache,  // seed 002
    lighting: Lighting,
    history: History,
    filter: Filter,               // seed 001
    upsample: Upsample,           // issue 60
}

impl Stages {
    /// A new epoch after `change`: each stage's own rule.
    pub fn start_epoch(&mut self, change: Change) {
        for stage in self.all_mut() {
            stage.start_epoch(change);
        }
    }
}

/// Each stage's name and views, in the frame's order.
pub fn views() -> &'static [(&'static str, &'static [View])] {
    static VIEWS: LazyLock<Vec<(&str, &[View])>> = LazyLock::new(|| {
        let stages = Stages::default();
        stages.all().iter().map(|s| (s.name(), s.views())).collect()
    });
    &VIEWS
}

/// Every pass, in the order a frame runs them: the stages', then the display pass.
pub fn passes() -> &'static [&'static str] {
    static PASSES: LazyLock<Vec<&str>> = LazyLock::new(|| {
        let stages = Stages::default();
        let passes = stages.all().into_iter().flat_map(|s| s.passes());
        passes.chain([DISPLAY]).collect()
    });
    &PASSES
}
