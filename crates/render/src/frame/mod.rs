//! The real-time frame pipeline: a frame is a sequence of stages over screen-sized buffers,
//! each a module that owns its state, its passes (functions from named inputs to named
//! outputs), its rule for a camera move, a settings change and a resize, its timings, its
//! memory and its views (display modes). The driver ([`pipeline`]) calls them in this order:
//!
//! ```text
//! stage         pass              inputs                              -> outputs
//! (epoch)                         what changed since the last frame   -> each stage's rule
//! reprojection  reproject         states, previous camera, camera     -> states, history and
//!   (seed 000)                                                           probabilities in the
//!                                                                        new view
//! adaptive      (prepare)         history, probabilities               -> the frame's schedule
//!   (seed 000)
//! plan                            schedule, states, history           -> which pixels are
//!                                                                        traced, from which
//!                                                                        sample index
//! primary       primary           camera, previous camera, plan       -> G-buffer (features,
//!                                                                        motion), first hits
//! restir        restir (3)        first hits of the whole frame,      -> reservoirs, each
//!   (seed 004)                    lights, last frame's reservoirs        pixel's direct light
//! lighting      lighting          first hits, plan, direct light      -> lighting (direct /
//!                                                                        indirect statistics,
//!                                                                        first bounce)
//! texture-cache (in lighting)     a cached first hit's footprint,     -> its texel's light
//!   (seed 002)                    the sample and texel caches            (shaded, filtered on
//!                                                                        demand), the caches
//! reprojection  repair            states, G-buffer, lighting          -> lighting (fresh_spp)
//! history       accumulate        lighting, history (states)          -> history
//! adaptive      (end of frame)    history                             -> probabilities
//! filter        filter            history, G-buffer, lighting         -> filtered image
//!   (seed 001)
//! upsample      upsample          this frame's samples, their film    -> the output (output
//!   (issue 60,                    positions, motion, its history         size; the filter
//!   scale < 1)                                                           stands aside)
//! (target)                        the frame's time                    -> the next render scale
//! display       display           a stage's view                      -> 8-bit RGBA
//! ```
//!
//! The lighting pass asks one trait for the light at each pixel's first hit,
//! [`trace::FirstHitLight`], called once per run of pixels (its code within a run
//! monomorphised). The plain lighting's is next event estimation ([`trace::NextEvent`]), and
//! the primary and lighting passes are then fused by runs of pixels ([`trace`]). ReSTIR's frame
//! implements it with each pixel's reservoir as its direct light, after its own passes over the
//! whole frame's first hits; the texture cache's ([`texture_cache::TextureCache::begin`])
//! looks each pixel's light up and takes its direct light from the light beneath it (next
//! event estimation or ReSTIR's), so the two compose. With either, the primary pass runs over
//! the whole frame first. The driver builds the chain from the stages' frames and hands it to
//! the passes as a `&mut dyn FirstHitLight`, naming none of their types. The *plan* ([`plan`]) says which pixels they trace and from which sample
//! index: every pixel from `frames * spp` in the plain pipeline; with seed 000's techniques,
//! each pixel from its own sample count, and with adaptive sampling ([`adaptive`]) only the
//! pixels its schedule picks. The state the stages share (buffers, cameras, counters, the
//! passes' times) is [`state::FrameState`]; what every stage has in common (its name, views
//! and memory) is [`stage::Stage`].
//!
//! One [`Config`](crate::Config) drives it: the resolution, samples per frame, bounces, the
//! stages' switches and parameters ([`crate::config::FrameConfig`], each technique's settings
//! type beside its stage) and the display. While the camera and the settings stay the same,
//! frames accumulate (progressive refinement); any change starts a new *epoch*
//! ([`state::Change`]), at which each stage applies its own rule (forward reprojection carries
//! the history into the new view after a camera move; ReSTIR's reservoirs survive it; the
//! others start afresh). Frame `f` of an epoch takes sample indices `f * spp ..`, and epoch 0
//! uses the configuration's seed unchanged, so `N` still frames of one sample are the
//! reference path tracer's image at `N` samples per pixel. Later epochs use seeds hashed from
//! it, so every frame is deterministic for a given scene, configuration and sequence of camera
//! moves, whatever the thread count. With the techniques' switches off, frames are bit for
//! bit those of the plain pipeline (`tests/frame_hashes.rs` holds their hashes).
//!
//! Adding a stage: its module here (its settings with `validate()`, its state, passes, rules
//! and views, `impl Stage`), and three lines elsewhere: its line in the list of stages
//! ([`stages`], from which the pipeline's stages, its views, its passes' order and its rule at
//! a new epoch come), its settings' line in the list that makes `FrameConfig` (its default and check come
//! with it), and its pass's call in the driver.
//! A stage that gives the light at the first hits implements [`trace::FirstHitLight`] on its
//! frame's state (its passes in `prepare`, the pixels' direct light in `direct` or whole runs
//! in `light_run`, its end of frame in `finish`), taking the light beneath it if it composes,
//! and its call in the driver puts it in the chain. Adding a view: its stage's file only.
//!
//! Buffers live across frames and are reallocated only when the resolution changes.

pub mod accumulation;
pub mod adaptive;
pub mod display;
pub mod filter;
pub mod gbuffer;
pub mod history;
pub mod lighting;
pub mod ping_pong;
pub mod pipeline;
pub mod plan;
pub mod reprojection;
pub mod restir;
pub mod stage;
pub mod stages;
pub mod state;
pub mod target;
pub mod texture_cache;
pub mod trace;
pub mod upsample;
pub mod views;

pub use display::DISPLAY;
pub use filter::FILTER;
pub use history::ACCUMULATE;
pub use pipeline::{FrameReport, Pipeline};
pub use reprojection::REPROJECT;
pub use restir::{RESTIR, RESTIR_SPATIAL, RESTIR_TEMPORAL};
pub use stages::{passes, Stages};
pub use state::PassTime;
pub use texture_cache::TEXTURE_CACHE;
pub use trace::{LIGHTING, PRIMARY};
