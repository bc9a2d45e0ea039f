//! The render thread: runs the frame pipeline with the configuration the window asks for and
//! hands each finished frame (8-bit RGBA and its report) back, so that the window stays
//! responsive while frames render.

use std::sync::{Arc, Condvar, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

use pathlight_render::frame::{FrameReport, Pipeline};
use pathlight_render::{Config, World};

/// A rendered frame.
pub struct Frame {
    pub width: u32,
    pub height: u32,
    pub rgba: Vec<u8>,
    pub report: FrameReport,
}

#[derive(Default)]
struct State {
    /// What the window wants rendered.
    config: Option<Config>,
    paused: bool,
    quit: bool,
    /// Clear the history at the next frame.
    reset: bool,
    /// The newest finished frame, not yet taken by the window.
    frame: Option<Frame>,
    /// A buffer the window gave back, reused for the next frame.
    spare: Option<Vec<u8>>,
}

/// The render thread and what it shares with the window.
pub struct Worker {
    shared: Arc<(Mutex<State>, Condvar)>,
    thread: Option<JoinHandle<()>>,
}

impl Worker {
    /// Starts rendering `world` with `config`; `repaint` is called after every frame (to wake
    /// the window).
    pub fn start(world: World, config: Config, repaint: impl Fn() + Send + 'static) -> Self {
        let shared = Arc::new((
            Mutex::new(State {
                config: Some(config.clone()),
                ..State::default()
            }),
            Condvar::new(),
        ));
        let thread_shared = shared.clone();
        let thread = std::thread::Builder::new()
            .name("pathlight-render".into())
            .spawn(move || run(world, config, &thread_shared, &repaint))
            .expect("starting the render thread");
        Self {
            shared,
            thread: Some(thread),
        }
    }

    fn with<R>(&self, f: impl FnOnce(&mut State) -> R) -> R {
        let (lock, cvar) = &*self.shared;
        let r = f(&mut lock.lock().expect("render state"));
        cvar.notify_all();
        r
    }

    /// Asks for frames of `config` from now on (the pipeline decides whether that resets the
    /// history).
    pub fn set_config(&self, config: &Config) {
        self.with(|s| s.config = Some(config.clone()));
    }

    pub fn set_paused(&self, paused: bool) {
        self.with(|s| s.paused = paused);
    }

    /// Clears the accumulated history.
    pub fn reset(&self) {
        self.with(|s| s.reset = true);
    }

    /// The newest finished frame, if there is one the window has not taken.
    pub fn take_frame(&self) -> Option<Frame> {
        self.with(|s| s.frame.take())
    }

    /// Gives a frame's buffer back for reuse.
    pub fn give_back(&self, rgba: Vec<u8>) {
        self.with(|s| s.spare = Some(rgba));
    }
}

impl Drop for Worker {
    fn drop(&mut self) {
        self.with(|s| s.quit = true);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

fn run(mut world: World, config: Config, shared: &(Mutex<State>, Condvar), repaint: &dyn Fn()) {
    let (lock, cvar) = shared;
    let mut pipeline = Pipeline::new(config);
    pipeline.prepare_world(&world);
    loop {
        {
            let mut s = lock.lock().expect("render state");
            while s.paused && !s.quit {
                s = cvar.wait(s).expect("render state");
            }
            if s.quit {
                return;
            }
            if let Some(c) = s.config.take() {
                world.set_light_selection(c.light_selection);
                pipeline.set_config(&c);
            }
            if std::mem::take(&mut s.reset) {
                pipeline.reset();
            }
        }
        let mut report = pipeline.render_frame(&world);
        pipeline.display(&mut report);
        let traced = report.traced;
        {
            let mut s = lock.lock().expect("render state");
            let mut rgba = s.spare.take().unwrap_or_default();
            rgba.clear();
            rgba.extend_from_slice(&pipeline.rgba);
            let c = pipeline.config();
            s.frame = Some(Frame {
                width: c.width,
                height: c.height,
                rgba,
                report,
            });
            if !traced {
                // Accumulation reached its frame limit: wait for a change instead of
                // spinning (display settings still apply within a tenth of a second).
                let _ = cvar
                    .wait_timeout(s, Duration::from_millis(100))
                    .expect("render state");
            }
        }
        repaint();
    }
}
