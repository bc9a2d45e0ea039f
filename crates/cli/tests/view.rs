//! The viewer in a real window: `pathlight view` runs under Xvfb (software OpenGL), renders a
//! few frames of the Cornell box and freezes; the test takes a screenshot of the X screen (the
//! XWD file Xvfb keeps with `-fbdir`) and checks that the window shows the rendered image
//! where the viewer says it is, pixel for pixel (within rounding), and that the image is a
//! Cornell box (red wall left, green wall right), not blank or garbage.
//!
//! A second test drives the live viewer with the mouse and the keyboard through `xdotool`
//! (X's XTEST extension, as a user's devices would) and checks what each input did: a display
//! mode key changes the image on screen, a drag orbits the camera around its target, Home
//! brings it back, F and W fly, Space pauses and Esc quits.
//!
//! Needs `Xvfb` (Debian: xvfb), `xdotool` and Mesa's OpenGL; without them the tests print a
//! note and pass, except under CI (`CI` set), where `.ci/run` installs them.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// Kills a child process when dropped.
struct Killer(Child);

impl Drop for Killer {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// The program `name` on the PATH.
fn program(name: &str) -> Option<PathBuf> {
    let path = std::env::var_os("PATH")?;
    std::env::split_paths(&path)
        .map(|d| d.join(name))
        .find(|p| p.is_file())
}

/// `program(name)`, or `None` after a note (a failure under CI, which must install it).
fn needed(name: &str) -> Option<PathBuf> {
    let found = program(name);
    if found.is_none() {
        assert!(
            std::env::var_os("CI").is_none(),
            "CI must install {name} (.ci/run does)"
        );
        eprintln!("note: no {name} on PATH; viewer test skipped");
    }
    found
}

/// A running X server (Xvfb) keeping its screen in an XWD file.
struct XServer {
    _server: Killer,
    /// The display number (`:N`).
    display: u32,
    /// The screen's framebuffer file.
    fb: PathBuf,
}

impl XServer {
    /// Starts Xvfb with a 1280x800 screen whose framebuffer is written in `dir`, on a display
    /// number it picks itself (`-displayfd`: tests running at once get different ones).
    fn start(xvfb: &Path, dir: &Path) -> Self {
        let mut server = Killer(
            Command::new(xvfb)
                .args([
                    "-displayfd",
                    "1",
                    "-screen",
                    "0",
                    "1280x800x24",
                    "-nolisten",
                    "tcp",
                    "-fbdir",
                ])
                .arg(dir)
                .stdout(Stdio::piped())
                .stderr(Stdio::null())
                .spawn()
                .unwrap(),
        );
        // Xvfb writes the display number once it accepts clients.
        let mut line = String::new();
        std::io::BufRead::read_line(
            &mut std::io::BufReader::new(server.0.stdout.take().unwrap()),
            &mut line,
        )
        .unwrap();
        let display = line
            .trim()
            .parse()
            .unwrap_or_else(|_| panic!("Xvfb did not start: {line:?}"));
        let fb = dir.join("Xvfb_screen0");
        let deadline = Instant::now() + Duration::from_secs(20);
        while !fb.exists() {
            assert!(Instant::now() < deadline, "Xvfb wrote no framebuffer");
            std::thread::sleep(Duration::from_millis(100));
        }
        Self {
            _server: server,
            display,
            fb,
        }
    }

    /// `pathlight view` with `args` on this display.
    fn viewer(&self, args: &[&str], extra: &Path) -> Killer {
        Killer(
            Command::new(env!("CARGO_BIN_EXE_pathlight"))
                .arg("view")
                .args(args)
                .arg(extra)
                .env("DISPLAY", format!(":{}", self.display))
                .env("LIBGL_ALWAYS_SOFTWARE", "1")
                .stdout(Stdio::null())
                .stderr(Stdio::inherit())
                .spawn()
                .unwrap(),
        )
    }
}

/// A fresh folder for one test's files.
fn test_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("pathlight-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// An RGB screenshot.
struct Screen {
    width: usize,
    height: usize,
    rgb: Vec<[u8; 3]>,
}

/// Reads an XWD file (what Xvfb writes with -fbdir): a big-endian header, a colour map, then
/// the pixels (32 bits per pixel, depth 24, least significant byte first: B, G, R, X).
fn read_xwd(path: &Path) -> Screen {
    let d = std::fs::read(path).unwrap();
    let word = |i: usize| u32::from_be_bytes(d[4 * i..4 * i + 4].try_into().unwrap()) as usize;
    let (header, width, height) = (word(0), word(4), word(5));
    let (byte_order, bits_per_pixel, bytes_per_line, colours) =
        (word(7), word(11), word(12), word(19));
    assert_eq!(
        bits_per_pixel, 32,
        "XWD with {bits_per_pixel} bits per pixel"
    );
    let start = header + 12 * colours;
    let mut rgb = Vec::with_capacity(width * height);
    for y in 0..height {
        for x in 0..width {
            let p = &d[start + y * bytes_per_line + 4 * x..][..4];
            rgb.push(if byte_order == 0 {
                [p[2], p[1], p[0]]
            } else {
                [p[1], p[2], p[3]]
            });
        }
    }
    Screen { width, height, rgb }
}

#[test]
fn the_viewer_window_shows_the_rendered_image() {
    let Some(xvfb) = needed("Xvfb") else {
        return;
    };
    let dir = test_dir("view-test");
    let x = XServer::start(&xvfb, &dir);
    let fb = x.fb.clone();
    let report = dir.join("report.json");
    let _viewer = x.viewer(
        &[
            "--window",
            "900x560",
            "--scale",
            "1",
            "--exit-after-frames",
            "4",
            "--close-after",
            "60",
            "--report",
        ],
        &report,
    );
    let deadline = Instant::now() + Duration::from_secs(180);
    while !report.exists() {
        assert!(
            Instant::now() < deadline,
            "the viewer showed no frames in 3 minutes"
        );
        std::thread::sleep(Duration::from_millis(200));
    }
    // The frozen frame stays on screen; give the X server a moment to have it.
    std::thread::sleep(Duration::from_millis(1500));
    let screen = read_xwd(&fb);
    let r: serde_json::Value = serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap();
    let frame = image::open(r["frame_png"].as_str().unwrap())
        .unwrap()
        .to_rgb8();
    let (fw, fh) = (frame.width() as usize, frame.height() as usize);
    let (rect, window) = placement(&r);
    assert_eq!(
        (rect[2].round() as usize, rect[3].round() as usize),
        (fw, fh)
    );

    // The frame itself is a Cornell box: the left wall red, the right wall green.
    let in_frame = |x: usize, y: usize| frame.get_pixel(x as u32, y as u32).0;
    let left = mean(fw / 20, fw / 8, fh / 3, 2 * fh / 3, &in_frame);
    let right = mean(fw - fw / 8, fw - fw / 20, fh / 3, 2 * fh / 3, &in_frame);
    assert!(left[0] > 2.0 * left[1], "left wall {left:?}");
    assert!(right[1] > 1.25 * right[0], "right wall {right:?}");

    // The screen shows that frame where the viewer put it: find the offset (the window may
    // sit anywhere) near the reported place that matches best, then compare every pixel.
    let (ox, oy) = (
        (window[0] + rect[0]).round() as i64,
        (window[1] + rect[1]).round() as i64,
    );
    let error_at = |dx: i64, dy: i64, step: usize| -> f64 {
        let mut sum = 0f64;
        let mut n = 0f64;
        for y in (0..fh).step_by(step) {
            for x in (0..fw).step_by(step) {
                let (sx, sy) = (ox + dx + x as i64, oy + dy + y as i64);
                if sx < 0 || sy < 0 || sx as usize >= screen.width || sy as usize >= screen.height {
                    return f64::INFINITY;
                }
                let s = screen.rgb[sy as usize * screen.width + sx as usize];
                let f = in_frame(x, y);
                sum += (0..3)
                    .map(|c| (s[c] as f64 - f[c] as f64).abs())
                    .sum::<f64>();
                n += 3.0;
            }
        }
        sum / n
    };
    let (mut best, mut at) = (f64::INFINITY, (0, 0));
    for dy in -40..=40 {
        for dx in -40..=40 {
            let e = error_at(dx, dy, 8);
            if e < best {
                (best, at) = (e, (dx, dy));
            }
        }
    }
    let full = error_at(at.0, at.1, 1);
    let save = dir.join("screenshot.ppm");
    let mut ppm = format!("P6 {} {} 255\n", screen.width, screen.height).into_bytes();
    ppm.extend(screen.rgb.iter().flatten());
    std::fs::write(&save, ppm).unwrap();
    eprintln!(
        "screenshot {} ; image at +{:?} from the reported place, mean error {full:.3} levels",
        save.display(),
        at
    );
    assert!(
        full < 2.0,
        "the window does not show the rendered frame: mean difference {full:.2} levels (best offset {at:?})"
    );
    // And the rest of the window is the viewer's panel, not the image again: the screen left
    // of the image differs from it.
    let panel = mean(2, 200, 2, 200, &|x, y| screen.rgb[y * screen.width + x]);
    assert!(
        (panel[0] - left[0]).abs() + (panel[1] - left[1]).abs() > 20.0,
        "no side panel? {panel:?}"
    );
    if std::env::var_os("PATHLIGHT_KEEP_SCREENSHOT").is_none() {
        let _ = std::fs::remove_dir_all(&dir);
    }
}

/// The viewer's state as its `--state` hook last wrote it.
fn read_state(path: &Path) -> Option<serde_json::Value> {
    serde_json::from_slice(&std::fs::read(path).ok()?).ok()
}

/// The `N` numbers of a JSON array.
fn numbers<const N: usize>(v: &serde_json::Value) -> [f64; N] {
    let a = v
        .as_array()
        .unwrap_or_else(|| panic!("an array of {N} numbers: {v}"));
    std::array::from_fn(|k| a[k].as_f64().unwrap())
}

fn vec3(v: &serde_json::Value) -> [f64; 3] {
    numbers(v)
}

fn distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>().sqrt()
}

/// The mean colour of the pixels `px(x, y)` for `x` in `x0..x1` and `y` in `y0..y1`.
fn mean(
    x0: usize,
    x1: usize,
    y0: usize,
    y1: usize,
    px: &dyn Fn(usize, usize) -> [u8; 3],
) -> [f64; 3] {
    let mut s = [0f64; 3];
    let n = ((x1 - x0) * (y1 - y0)) as f64;
    for y in y0..y1 {
        for x in x0..x1 {
            let p = px(x, y);
            for c in 0..3 {
                s[c] += p[c] as f64 / n;
            }
        }
    }
    s
}

/// Where a hook's JSON says the image is in the window and the window on the screen
/// (`[x, y, width, height]`, physical pixels; the window at the origin when unknown).
fn placement(v: &serde_json::Value) -> ([f64; 4], [f64; 4]) {
    let window = &v["window_inner"];
    (
        numbers(&v["image_rect"]),
        if window.is_array() {
            numbers(window)
        } else {
            [0.0; 4]
        },
    )
}

/// Spread (the largest, over the channels, of the largest minus the smallest level) and mean
/// of the screen's pixels in a square of half-size `r` around (`cx`, `cy`).
fn patch(screen: &Screen, cx: usize, cy: usize, r: usize) -> (u8, [f64; 3]) {
    let px = |x: usize, y: usize| screen.rgb[y * screen.width + x];
    let (mut lo, mut hi) = ([255u8; 3], [0u8; 3]);
    for y in cy - r..cy + r {
        for x in cx - r..cx + r {
            let p = px(x, y);
            for c in 0..3 {
                lo[c] = lo[c].min(p[c]);
                hi[c] = hi[c].max(p[c]);
            }
        }
    }
    let spread = (0..3).map(|c| hi[c] - lo[c]).max().unwrap();
    (spread, mean(cx - r, cx + r, cy - r, cy + r, &px))
}

#[test]
fn mouse_and_keys_drive_the_viewer() {
    let (Some(xvfb), Some(xdotool)) = (needed("Xvfb"), needed("xdotool")) else {
        return;
    };
    let dir = test_dir("view-input-test");
    let x = XServer::start(&xvfb, &dir);
    let state = dir.join("state.json");
    let mut viewer = x.viewer(
        &["--window", "900x560", "--scale", "0.5", "--state"],
        &state,
    );

    let wait_for = |what: &str, done: &dyn Fn(&serde_json::Value) -> bool| {
        let deadline = Instant::now() + Duration::from_secs(120);
        loop {
            let s = read_state(&state);
            if let Some(s) = s.as_ref().filter(|s| done(s)) {
                return s.clone();
            }
            assert!(Instant::now() < deadline, "{what}: not seen; state {s:?}");
            std::thread::sleep(Duration::from_millis(100));
        }
    };
    let frames = |s: &serde_json::Value| s["frames_shown"].as_u64().unwrap();
    let xdo = |args: &[&str]| {
        let out = Command::new(&xdotool)
            .args(args)
            .env("DISPLAY", format!(":{}", x.display))
            .output()
            .unwrap();
        assert!(out.status.success(), "xdotool {args:?}: {out:?}");
        String::from_utf8_lossy(&out.stdout).into_owned()
    };

    let s = wait_for("the first frames", &|s| frames(s) >= 3);
    // The keyboard goes to the viewer's window (there is no window manager to give it).
    let window = xdo(&["search", "--sync", "--name", "^pathlight"]);
    let window = window
        .lines()
        .next()
        .expect("the viewer's window")
        .to_owned();
    xdo(&["windowfocus", "--sync", &window]);
    // The image's centre on the screen (the window sits at the screen's origin, or where
    // the viewer says).
    let (rect, inner) = placement(&s);
    let (cx, cy) = (
        (inner[0] + rect[0] + rect[2] / 2.0) as usize,
        (inner[1] + rect[1] + rect[3] / 2.0) as usize,
    );

    // Key 6: the albedo display mode. The back wall, shaded (and noisy) before, is then one
    // flat colour on screen, its base colour.
    let (_, before) = patch(&read_xwd(&x.fb), cx, cy - 40, 12);
    xdo(&["key", "6"]);
    let s = wait_for("key 6: albedo", &|s| s["display"] == "albedo");
    let n = frames(&s);
    wait_for("albedo frames", &|s| frames(s) >= n + 3);
    std::thread::sleep(Duration::from_millis(500));
    let (spread_after, colour) = patch(&read_xwd(&x.fb), cx, cy - 40, 12);
    assert!(
        spread_after <= 2,
        "the albedo view of the back wall is flat: {spread_after} ({colour:?})"
    );
    let change = (0..3)
        .map(|c| (colour[c] - before[c]).abs())
        .fold(0.0, f64::max);
    assert!(
        change > 30.0,
        "the screen did not change to the albedo view: {before:?} -> {colour:?}"
    );

    // A drag orbits: the camera moves, its target and its distance to it stay.
    let start = wait_for("still", &|_| true);
    let (p0, t0) = (vec3(&start["position"]), vec3(&start["target"]));
    xdo(&["mousemove", &cx.to_string(), &cy.to_string()]);
    xdo(&["mousedown", "1"]);
    for k in 1..=10 {
        xdo(&["mousemove", &(cx + 12 * k).to_string(), &cy.to_string()]);
        std::thread::sleep(Duration::from_millis(30));
    }
    xdo(&["mouseup", "1"]);
    let s = wait_for("the drag", &|s| distance(vec3(&s["position"]), p0) > 0.05);
    let (p1, t1) = (vec3(&s["position"]), vec3(&s["target"]));
    assert!(
        distance(t1, t0) < 1e-4,
        "the target moved: {t0:?} -> {t1:?}"
    );
    let (r0, r1) = (distance(p0, t0), distance(p1, t1));
    assert!((r1 - r0).abs() < 1e-3 * r0, "orbit radius {r0} -> {r1}");

    // Home: back to the start.
    xdo(&["key", "Home"]);
    wait_for("Home", &|s| distance(vec3(&s["position"]), p0) < 1e-4);

    // F: fly; holding W moves forward (toward the old target).
    xdo(&["key", "f"]);
    wait_for("F: fly", &|s| s["navigation"] == "fly");
    xdo(&["keydown", "w"]);
    std::thread::sleep(Duration::from_millis(400));
    xdo(&["keyup", "w"]);
    let s = wait_for("W", &|s| distance(vec3(&s["position"]), p0) > 1e-3);
    let p2 = vec3(&s["position"]);
    let (ahead, moved) = (distance(p0, t0), distance(p2, t0));
    assert!(
        moved < ahead,
        "W flew away from the view direction: {p0:?} -> {p2:?}"
    );

    // A flies left and leaves accumulation as it was; C switches accumulation.
    let accumulate = s["accumulate"].clone();
    xdo(&["keydown", "a"]);
    std::thread::sleep(Duration::from_millis(300));
    xdo(&["keyup", "a"]);
    let s = wait_for("A", &|s| distance(vec3(&s["position"]), p2) > 1e-3);
    assert_eq!(s["accumulate"], accumulate, "A switched accumulation");
    xdo(&["key", "c"]);
    wait_for("C: accumulation", &|s| s["accumulate"] != accumulate);

    // Space pauses; Esc closes the window and ends the program.
    xdo(&["key", "space"]);
    wait_for("Space: pause", &|s| s["paused"] == true);
    xdo(&["key", "Escape"]);
    let deadline = Instant::now() + Duration::from_secs(30);
    let status = loop {
        if let Some(status) = viewer.0.try_wait().unwrap() {
            break status;
        }
        assert!(Instant::now() < deadline, "Esc did not close the viewer");
        std::thread::sleep(Duration::from_millis(100));
    };
    assert!(status.success(), "the viewer exited with {status}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// A resolution scale outside the viewer's range is refused with the range, not clamped
/// without a word (before any window opens).
#[test]
fn a_scale_out_of_range_is_refused() {
    for scale in ["0.05", "5", "nan"] {
        let o = common::pathlight(&["view", "--scale", scale]);
        assert_eq!(o.status.code(), Some(2), "--scale {scale}");
        let err = common::stderr(&o);
        assert!(
            err.contains("between 0.1 and 2") || err.contains("not a number"),
            "--scale {scale}: {err}"
        );
    }
}
