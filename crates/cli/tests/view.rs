//! The viewer in a real window: `pathlight view` runs under Xvfb (software OpenGL), renders a
//! few frames of the Cornell box and freezes; the test takes a screenshot of the X screen (the
//! XWD file Xvfb keeps with `-fbdir`) and checks that the window shows the rendered image
//! where the viewer says it is, pixel for pixel (within rounding), and that the image is a
//! Cornell box (red wall left, green wall right), not blank or garbage.
//!
//! Needs `Xvfb` (Debian: xvfb) and Mesa's OpenGL; without Xvfb the test prints a note and
//! passes, except under CI (`CI` set), where `.ci/run` installs them.

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

fn xvfb() -> Option<PathBuf> {
    let path = std::env::var_os("PATH")?;
    std::env::split_paths(&path)
        .map(|d| d.join("Xvfb"))
        .find(|p| p.is_file())
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
    let Some(xvfb) = xvfb() else {
        assert!(
            std::env::var_os("CI").is_none(),
            "CI must install xvfb (.ci/run does)"
        );
        eprintln!("note: no Xvfb on PATH; viewer test skipped");
        return;
    };
    let dir = std::env::temp_dir().join(format!("pathlight-view-test-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    // A display number nobody uses.
    let display = (90..140)
        .find(|n| !Path::new(&format!("/tmp/.X{n}-lock")).exists())
        .expect("a free X display");
    let _server = Killer(
        Command::new(xvfb)
            .args([
                &format!(":{display}"),
                "-screen",
                "0",
                "1280x800x24",
                "-nolisten",
                "tcp",
                "-fbdir",
            ])
            .arg(&dir)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap(),
    );
    let fb = dir.join("Xvfb_screen0");
    let deadline = Instant::now() + Duration::from_secs(20);
    while !fb.exists() {
        assert!(Instant::now() < deadline, "Xvfb did not start");
        std::thread::sleep(Duration::from_millis(100));
    }

    let report = dir.join("report.json");
    let _viewer = Killer(
        Command::new(env!("CARGO_BIN_EXE_pathlight"))
            .args([
                "view",
                "--window",
                "900x560",
                "--scale",
                "1",
                "--exit-after-frames",
                "4",
                "--close-after",
                "60",
                "--report",
            ])
            .arg(&report)
            .env("DISPLAY", format!(":{display}"))
            .env("LIBGL_ALWAYS_SOFTWARE", "1")
            .stdout(Stdio::null())
            .stderr(Stdio::inherit())
            .spawn()
            .unwrap(),
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
    let rect: Vec<f64> = r["image_rect"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    let window: Vec<f64> = r["window_inner"].as_array().map_or(vec![0.0; 4], |a| {
        a.iter().map(|v| v.as_f64().unwrap()).collect()
    });
    assert_eq!(
        (rect[2].round() as usize, rect[3].round() as usize),
        (fw, fh)
    );

    // The frame itself is a Cornell box: the left wall red, the right wall green.
    let mean =
        |x0: usize, x1: usize, y0: usize, y1: usize, px: &dyn Fn(usize, usize) -> [u8; 3]| {
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
        };
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
