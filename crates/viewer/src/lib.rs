//! `pathlight view`: the frame pipeline live in a window (eframe, OpenGL), with a side panel
//! holding a toggle and the parameters of every pass, the display modes (the final image, the
//! noisy input, each pass's buffers), camera control (orbit and fly), the time per pass and
//! the frame rate, and a resolution scale.
//!
//! Frames render on their own thread ([`worker`]); the window shows the newest one. The
//! keyboard shortcuts are [`SHORTCUTS`].

pub mod navigation;
mod panel;
pub mod worker;

use std::path::PathBuf;
use std::time::{Duration, Instant};

use eframe::egui;
use glam::Vec3;
use pathlight_render::frame::display::DisplayMode;
use pathlight_render::frame::FrameReport;
use pathlight_render::{Config, World};

use navigation::{Mode, Navigation};
use worker::Worker;

/// Keys and what they do (also shown in the side panel and the README).
pub const SHORTCUTS: &[(&str, &str)] = &[
    ("Tab", "show or hide the side panel"),
    ("F", "switch between orbit and fly"),
    (
        "W A S D, Q E",
        "fly forward, left, back, right, down, up (Shift: faster)",
    ),
    ("drag", "orbit around the target (fly: look around)"),
    ("right drag, Shift drag", "pan"),
    ("wheel", "move closer or farther"),
    ("Home", "back to the starting view"),
    (
        "1 ... 9, 0",
        "display: final, noisy, direct, indirect, variance, albedo, normal, depth, motion, samples",
    ),
    ("+ / -", "exposure up or down half a stop"),
    ("[ / ]", "resolution scale down or up"),
    ("Space", "pause or resume rendering"),
    ("C", "accumulation on or off"),
    ("R", "restart accumulation"),
    (
        "G",
        "reconstruction filter (seed 001): none, data-driven, SVGF, TAA alone in turn",
    ),
    ("T", "texture-space shading cache (seed 002) on or off"),
    ("P", "save the shown frame as a PNG in the current folder"),
    ("Esc", "quit"),
];

/// The start of the panel's message about a configuration the pipeline refuses.
const NOT_APPLIED: &str = "settings not applied: ";

/// The display modes on the number keys 1 ... 9, 0.
const NUMBER_MODES: [DisplayMode; 10] = [
    DisplayMode::FINAL,
    DisplayMode::named("noisy"),
    DisplayMode::named("direct"),
    DisplayMode::named("indirect"),
    DisplayMode::named("variance"),
    DisplayMode::named("albedo"),
    DisplayMode::named("normal"),
    DisplayMode::named("depth"),
    DisplayMode::named("motion"),
    DisplayMode::named("samples"),
];

/// How the window starts, and hooks for automated tests.
#[derive(Debug, Clone)]
pub struct ViewerOptions {
    pub title: String,
    /// Initial window size in logical pixels.
    pub window: [f32; 2],
    /// Image resolution relative to the image area (1: one rendered pixel per screen pixel).
    pub scale: f32,
    /// Test hook: after this many frames have been shown, stop taking new frames, write
    /// [`report`](Self::report) and close after `close_after`.
    pub exit_after_frames: Option<u64>,
    /// Test hook: a JSON file with where the image is in the window (physical pixels) and the
    /// frame shown, saved as `<report>.png`.
    pub report: Option<PathBuf>,
    pub close_after: Duration,
    /// Test hook: a JSON file rewritten whenever the window's state changes (display mode,
    /// camera, pause, frames shown, where the image is), so that a test driving the mouse and
    /// keyboard can see what they did.
    pub state: Option<PathBuf>,
    /// The preset the scene's lights chose (the configuration is it, with the command line's
    /// flags), and why; `None` when the command line gave the configuration.
    pub choice: Option<pathlight_render::preset::Choice>,
}

impl Default for ViewerOptions {
    fn default() -> Self {
        Self {
            title: "pathlight".into(),
            window: [1280.0, 720.0],
            scale: 1.0,
            exit_after_frames: None,
            report: None,
            close_after: Duration::from_secs(10),
            state: None,
            choice: None,
        }
    }
}

#[derive(Debug, thiserror::Error)]
pub enum ViewerError {
    #[error("the window could not be opened: {0}")]
    Window(String),
}

/// Opens the viewer on `world` with `config` and returns when the window closes.
pub fn run(world: World, config: Config, options: ViewerOptions) -> Result<(), ViewerError> {
    let native = eframe::NativeOptions {
        viewport: egui::ViewportBuilder::default()
            .with_inner_size(options.window)
            .with_title(options.title.clone()),
        ..Default::default()
    };
    let title = options.title.clone();
    eframe::run_native(
        &title,
        native,
        Box::new(move |cc| {
            let ctx = cc.egui_ctx.clone();
            Ok(Box::new(Viewer::new(world, config, options, move || {
                ctx.request_repaint()
            })))
        }),
    )
    .map_err(|e| ViewerError::Window(e.to_string()))
}

/// The window's state.
pub struct Viewer {
    worker: Worker,
    /// The configuration the window asks for (the camera from `navigation`, the resolution
    /// from the image area and `scale`).
    config: Config,
    navigation: Navigation,
    options: ViewerOptions,
    scale: f32,
    show_panel: bool,
    paused: bool,
    texture: Option<egui::TextureHandle>,
    /// The last frame shown: its report and pixels.
    shown: Option<(FrameReport, u32, u32)>,
    shown_rgba: Vec<u8>,
    frames_shown: u64,
    /// Frames shown that took longer than the frame-time target (`[frame] target_ms`).
    over_target: u64,
    /// Smoothed frames per second of the frames shown.
    fps: f32,
    last_frame_at: Option<Instant>,
    /// Set once the test hook has written its report.
    frozen_at: Option<Instant>,
    screenshots: u32,
    message: String,
    /// The preset applied last (its name; with the rule's reason when the rule chose it) and
    /// the configuration it gave.
    preset: Option<(String, Config)>,
    /// What the state hook last wrote.
    last_state: String,
}

impl Viewer {
    pub fn new(
        world: World,
        config: Config,
        options: ViewerOptions,
        repaint: impl Fn() + Send + 'static,
    ) -> Self {
        let scene_camera = config.camera.apply(&world.scene_camera());
        let b = world.scene.bounds();
        let size = if b.is_empty() {
            1.0
        } else {
            b.diagonal().length()
        };
        let navigation = Navigation::new(&scene_camera, world.scene_centre(), size);
        let mut config = config;
        config.camera = navigation.camera(&config.camera);
        let worker = Worker::start(world, config.clone(), repaint);
        let preset = options.choice.as_ref().map(|c| {
            let name = format!("{} (chosen: {})", c.preset.name(), c.reason);
            (name, config.clone())
        });
        Self {
            worker,
            config,
            navigation,
            scale: options.scale.clamp(0.1, 2.0),
            options,
            show_panel: true,
            paused: false,
            texture: None,
            shown: None,
            shown_rgba: Vec::new(),
            frames_shown: 0,
            over_target: 0,
            fps: 0.0,
            last_frame_at: None,
            frozen_at: None,
            screenshots: 0,
            message: String::new(),
            preset,
            last_state: String::new(),
        }
    }

    /// The keyboard: shortcuts and flying.
    fn keys(&mut self, ctx: &egui::Context) {
        if ctx.egui_wants_keyboard_input() {
            return;
        }
        use egui::Key;
        let (pressed, down, dt, shift) = ctx.input(|i| {
            let pressed: Vec<Key> = i
                .events
                .iter()
                .filter_map(|e| match e {
                    egui::Event::Key {
                        key,
                        pressed: true,
                        repeat: false,
                        ..
                    } => Some(*key),
                    _ => None,
                })
                .collect();
            let down = |k| i.key_down(k);
            let mv = Vec3::new(
                f32::from(down(Key::D)) - f32::from(down(Key::A)),
                f32::from(down(Key::E)) - f32::from(down(Key::Q)),
                f32::from(down(Key::W)) - f32::from(down(Key::S)),
            );
            (pressed, mv, i.stable_dt.min(0.1), i.modifiers.shift)
        });
        if self.navigation.mode == Mode::Fly && down != Vec3::ZERO {
            let boost = if shift { 4.0 } else { 1.0 };
            self.navigation.fly(down, dt * boost);
            ctx.request_repaint();
        }
        for key in pressed {
            match key {
                Key::Tab => self.show_panel = !self.show_panel,
                Key::F => {
                    self.navigation.mode = match self.navigation.mode {
                        Mode::Orbit => Mode::Fly,
                        Mode::Fly => Mode::Orbit,
                    }
                }
                Key::Home => self.navigation.home(),
                Key::Space => self.set_paused(!self.paused),
                // (Not A, which flies left.)
                Key::C => self.config.frame.accumulate = !self.config.frame.accumulate,
                Key::R => self.worker.reset(),
                Key::G => {
                    use pathlight_render::denoise::Method;
                    let f = &mut self.config.frame.filter;
                    f.method = match f.method {
                        Method::None => Method::DataDriven,
                        Method::DataDriven => Method::Svgf,
                        Method::Svgf => Method::Taa,
                        Method::Taa | Method::Rpf => Method::None,
                    };
                }
                Key::T => {
                    let t = &mut self.config.frame.texture_cache;
                    t.enabled = !t.enabled;
                }
                Key::P => self.save_screenshot(),
                Key::Plus | Key::Equals => self.config.display.exposure *= 2f32.sqrt(),
                Key::Minus => self.config.display.exposure /= 2f32.sqrt(),
                Key::OpenBracket => self.scale = (self.scale / 2f32.sqrt()).max(0.1),
                Key::CloseBracket => self.scale = (self.scale * 2f32.sqrt()).min(2.0),
                Key::Escape => ctx.send_viewport_cmd(egui::ViewportCommand::Close),
                // ReSTIR's candidates, halved and doubled within 1..1024 (the thesis's keys).
                Key::Comma | Key::Period => {
                    let r = &mut self.config.frame.restir;
                    r.candidates = if key == Key::Comma {
                        r.candidates / 2
                    } else {
                        r.candidates.saturating_mul(2)
                    }
                    .clamp(1, pathlight_render::frame::restir::MAX_CANDIDATES);
                }
                k => {
                    let numbers = [
                        Key::Num1,
                        Key::Num2,
                        Key::Num3,
                        Key::Num4,
                        Key::Num5,
                        Key::Num6,
                        Key::Num7,
                        Key::Num8,
                        Key::Num9,
                        Key::Num0,
                    ];
                    if let Some(i) = numbers.iter().position(|n| *n == k) {
                        self.config.display.mode = NUMBER_MODES[i].clone();
                    }
                }
            }
        }
    }

    fn set_paused(&mut self, paused: bool) {
        self.paused = paused;
        self.worker.set_paused(paused);
    }

    fn save_screenshot(&mut self) {
        let Some((_, w, h)) = self.shown else { return };
        self.screenshots += 1;
        let path = PathBuf::from(format!("pathlight-view-{}.png", self.screenshots));
        let png = pathlight_render::output::encode_rgba8_png(w, h, &self.shown_rgba);
        self.message = match pathlight_render::output::write_atomic(&path, &png) {
            Ok(()) => format!("saved {}", path.display()),
            Err(e) => e.to_string(),
        };
    }

    /// Takes the newest frame from the render thread into the texture.
    fn take_frame(&mut self, ctx: &egui::Context) {
        if self.frozen_at.is_some() {
            return;
        }
        let Some(frame) = self.worker.take_frame() else {
            return;
        };
        let image = egui::ColorImage::from_rgba_unmultiplied(
            [frame.width as usize, frame.height as usize],
            &frame.rgba,
        );
        match &mut self.texture {
            Some(t) => t.set(image, egui::TextureOptions::NEAREST),
            None => {
                self.texture = Some(ctx.load_texture("frame", image, egui::TextureOptions::NEAREST))
            }
        }
        let now = Instant::now();
        if let Some(last) = self.last_frame_at {
            let f = 1.0 / now.duration_since(last).as_secs_f32().max(1e-6);
            self.fps = if self.fps == 0.0 {
                f
            } else {
                0.9 * self.fps + 0.1 * f
            };
        }
        self.last_frame_at = Some(now);
        self.frames_shown += 1;
        let target = self.config.frame.target_ms as f64;
        self.over_target += u64::from(target > 0.0 && frame.report.ms > target);
        self.shown = Some((frame.report, frame.width, frame.height));
        let old = std::mem::replace(&mut self.shown_rgba, frame.rgba);
        self.worker.give_back(old);
    }

    /// The image area: the frame scaled to fill it, with the mouse controlling the camera.
    fn image(&mut self, ui: &mut egui::Ui) -> egui::Rect {
        let ppp = ui.ctx().pixels_per_point();
        let available = ui.available_rect_before_wrap();
        // The resolution follows the image area: whole screen pixels, from a whole-pixel
        // corner, so that at scale 1 each rendered pixel is exactly one screen pixel.
        let min = (available.min.to_vec2() * ppp).ceil() / ppp;
        let screen = ((available.max.to_vec2() - min) * ppp).floor();
        let w = ((screen.x * self.scale).floor() as u32).clamp(16, 8192);
        let h = ((screen.y * self.scale).floor() as u32).clamp(16, 8192);
        self.config.width = w;
        self.config.height = h;
        let rect = egui::Rect::from_min_size(
            min.to_pos2(),
            egui::vec2(w as f32, h as f32) / (self.scale * ppp),
        );
        let area = rect.size();
        ui.allocate_rect(available, egui::Sense::hover());
        let response = match &self.texture {
            Some(t) => ui.put(
                rect,
                egui::Image::new((t.id(), area))
                    .fit_to_exact_size(area)
                    .sense(egui::Sense::click_and_drag()),
            ),
            None => ui.allocate_rect(rect, egui::Sense::click_and_drag()),
        };
        let shift = ui.input(|i| i.modifiers.shift);
        if response.dragged_by(egui::PointerButton::Secondary)
            || (shift && response.dragged_by(egui::PointerButton::Primary))
        {
            let d = response.drag_delta() * ppp;
            self.navigation.pan(d.x, d.y, area.y * ppp);
        } else if response.dragged_by(egui::PointerButton::Primary) {
            let d = response.drag_delta() * ppp;
            self.navigation.drag(d.x, d.y);
        }
        if response.hovered() {
            let scroll = ui.input(|i| i.smooth_scroll_delta.y);
            if scroll != 0.0 {
                self.navigation.zoom(scroll / 50.0);
            }
        }
        response.rect
    }

    /// The state hook: the window's state as JSON in [`ViewerOptions::state`] when it changed.
    fn write_state(&mut self, ctx: &egui::Context, image_rect: egui::Rect) {
        let Some(path) = &self.options.state else {
            return;
        };
        let (image, window) = placement(ctx, image_rect);
        let n = &self.navigation;
        let json = serde_json::json!({
            "frames_shown": self.frames_shown,
            "display": self.config.display.mode.name(),
            "paused": self.paused,
            "accumulate": self.config.frame.accumulate,
            "navigation": match n.mode { Mode::Orbit => "orbit", Mode::Fly => "fly" },
            "position": n.position.to_array(),
            "target": n.target().to_array(),
            "image_rect": image,
            "window_inner": window,
        })
        .to_string();
        if json != self.last_state {
            let _ = pathlight_render::output::write_atomic(path, json.as_bytes());
            self.last_state = json;
        }
    }

    /// The test hook: once enough frames are shown, freeze, report and close later.
    fn test_hook(&mut self, ctx: &egui::Context, image_rect: egui::Rect) {
        let Some(n) = self.options.exit_after_frames else {
            return;
        };
        if let Some(at) = self.frozen_at {
            if at.elapsed() >= self.options.close_after {
                ctx.send_viewport_cmd(egui::ViewportCommand::Close);
            }
            ctx.request_repaint_after(Duration::from_millis(100));
            return;
        }
        // Two more passes after the n-th frame, so that it is surely on screen.
        if self.frames_shown < n + 2 {
            return;
        }
        self.frozen_at = Some(Instant::now());
        self.set_paused(true);
        if let (Some(path), Some((report, w, h))) = (&self.options.report, &self.shown) {
            let ppp = ctx.pixels_per_point();
            let (image, window) = placement(ctx, image_rect);
            let png = path.with_extension("png");
            let _ = pathlight_render::output::write_atomic(
                &png,
                &pathlight_render::output::encode_rgba8_png(*w, *h, &self.shown_rgba),
            );
            let json = serde_json::json!({
                "image_rect": image,
                "window_inner": window,
                "pixels_per_point": ppp,
                "frame_png": png,
                "width": w,
                "height": h,
                "frames_shown": self.frames_shown,
                "last_frame_ms": report.ms,
            });
            let _ = pathlight_render::output::write_atomic(path, json.to_string().as_bytes());
        }
    }
}

/// Where the image is in the window and where the window is on the screen (when the platform
/// tells), as `[x, y, width, height]` in physical pixels: what the test hooks report.
fn placement(ctx: &egui::Context, image_rect: egui::Rect) -> ([f32; 4], Option<[f32; 4]>) {
    let ppp = ctx.pixels_per_point();
    let pixels = |r: egui::Rect| [r.min.x, r.min.y, r.width(), r.height()].map(|v| v * ppp);
    let inner = ctx.input(|i| i.viewport().inner_rect);
    (pixels(image_rect), inner.map(pixels))
}

impl eframe::App for Viewer {
    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
        let ctx = ui.ctx().clone();
        self.keys(&ctx);
        self.take_frame(&ctx);
        if self.show_panel {
            egui::Panel::left("controls")
                .resizable(true)
                .default_size(320.0)
                .show(ui, |ui| {
                    egui::ScrollArea::vertical().show(ui, |ui| panel::show(self, ui));
                });
        }
        let rect = egui::CentralPanel::no_frame()
            .show(ui, |ui| self.image(ui))
            .inner;
        // Everything the window changed this pass goes to the render thread, if it is a
        // configuration the pipeline accepts (else the panel says why, and the last one stays).
        self.config.camera = self.navigation.camera(&self.config.camera);
        match self.config.validate() {
            Ok(()) => {
                if self.message.starts_with(NOT_APPLIED) {
                    self.message.clear();
                }
                self.worker.set_config(&self.config);
            }
            Err(e) => self.message = format!("{NOT_APPLIED}{e}"),
        }
        self.write_state(&ctx, rect);
        self.test_hook(&ctx, rect);
    }
}
