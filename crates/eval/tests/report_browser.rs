//! The report in a real browser: a small experiment is published, headless Chromium loads
//! `report.html`, every image on the page must have loaded (the page's own counter, read from
//! the DOM Chromium dumps), and its screenshot must show the charts (the first series' colour,
//! many colours, little blank page). The screenshot is kept beside the report for a person to
//! look at (its path is printed).
//!
//! Chromium comes from `PATHLIGHT_CHROMIUM` or the PATH (`chromium`, `chromium-browser`,
//! `google-chrome`). Without one the test prints a note and passes, except under CI (`CI`
//! set), where `.ci/run` installs Debian's `chromium` and a missing browser is a failure.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

use pathlight_eval::experiment::{Progress, Runner};
use pathlight_eval::plot::PALETTE;
use pathlight_eval::publish::publish;
use pathlight_eval::reference::ReferenceCache;
use pathlight_eval::spec::Spec;

const SPEC: &str = r#"
name = "browser"
description = "A small experiment for the browser test."
width = 48
height = 40
metrics = ["mse", "ssim", "flip"]
repetitions = 1
[budget]
spp = [1, 4, 16]
time_ms = [10]
[reference]
spp = 64
[[configuration]]
name = "independent"
[configuration.config]
sampler = "independent"
max_bounces = 3
[[configuration]]
name = "sobol"
[configuration.config]
max_bounces = 3
"#;

fn chromium() -> Option<PathBuf> {
    if let Some(p) = std::env::var_os("PATHLIGHT_CHROMIUM") {
        return Some(PathBuf::from(p));
    }
    let path = std::env::var_os("PATH")?;
    ["chromium", "chromium-browser", "google-chrome"]
        .iter()
        .flat_map(|name| std::env::split_paths(&path).map(move |d| d.join(name)))
        .find(|p| p.is_file())
}

/// Runs Chromium headless on `page` with `args`, killed after two minutes; returns stdout.
fn run_chromium(exe: &Path, profile: &Path, page: &Path, args: &[&str]) -> String {
    let url = format!("file://{}", page.canonicalize().unwrap().display());
    let mut child = Command::new(exe)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-quic",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--hide-scrollbars",
            "--allow-file-access-from-files",
        ])
        .arg(format!("--user-data-dir={}", profile.display()))
        .args(args)
        .arg(&url)
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap_or_else(|e| panic!("starting {}: {e}", exe.display()));
    let mut stdout = child.stdout.take().unwrap();
    let reader = std::thread::spawn(move || {
        let mut s = String::new();
        std::io::Read::read_to_string(&mut stdout, &mut s).unwrap();
        s
    });
    let deadline = Instant::now() + Duration::from_secs(120);
    loop {
        if let Some(status) = child.try_wait().unwrap() {
            assert!(status.success(), "chromium {args:?} failed: {status}");
            break;
        }
        if Instant::now() > deadline {
            let _ = child.kill();
            panic!("chromium {args:?} did not finish in two minutes");
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    reader.join().unwrap()
}

fn attribute(html: &str, name: &str) -> Option<usize> {
    let start = html.find(&format!("{name}=\""))? + name.len() + 2;
    html[start..][..html[start..].find('"')?].parse().ok()
}

#[test]
fn the_report_shows_its_images_and_plots_in_chromium() {
    let Some(exe) = chromium() else {
        assert!(
            std::env::var_os("CI").is_none(),
            "CI must install chromium (.ci/run does)"
        );
        eprintln!("note: no chromium on PATH (set PATHLIGHT_CHROMIUM); browser test skipped");
        return;
    };
    let dir = std::env::temp_dir().join(format!("pathlight-report-browser-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let spec = Spec::parse(SPEC).unwrap();
    let cancel = AtomicBool::new(false);
    let outcome = Runner {
        spec: &spec,
        spec_dir: PathBuf::from("."),
        cache: ReferenceCache::new(dir.join("cache")),
        progress: &|_: &Progress| {},
        cancel: &cancel,
    }
    .run()
    .unwrap();
    let out = dir.join("out");
    let report = publish(&outcome, &out).unwrap();
    let html = std::fs::read_to_string(&report).unwrap();
    let images_in_page = html.matches("<img ").count();
    assert!(images_in_page >= 20, "{images_in_page} images in the page");

    // Every image loaded: the page counts them once loaded.
    let dom = run_chromium(
        &exe,
        &dir.join("profile-dom"),
        &report,
        &["--virtual-time-budget=10000", "--dump-dom"],
    );
    assert_eq!(
        attribute(&dom, "data-images-total"),
        Some(images_in_page),
        "the page's image counter did not run"
    );
    assert_eq!(
        attribute(&dom, "data-images-loaded"),
        Some(images_in_page),
        "some images did not load"
    );

    // The screenshot shows charts and images, not a blank or broken page.
    let shot = out.join("screenshot.png");
    run_chromium(
        &exe,
        &dir.join("profile-shot"),
        &report,
        &[
            "--window-size=1280,2400",
            "--virtual-time-budget=10000",
            &format!("--screenshot={}", shot.display()),
        ],
    );
    let img = image::open(&shot).unwrap().to_rgb8();
    assert_eq!((img.width(), img.height()), (1280, 2400));
    let pixels: Vec<[u8; 3]> = img.pixels().map(|p| p.0).collect();
    let blank = pixels.iter().filter(|p| **p == [255, 255, 255]).count();
    let inked = 1.0 - blank as f64 / pixels.len() as f64;
    assert!(
        inked > 0.05,
        "only {:.1}% of the page is not white",
        inked * 100.0
    );
    let colours: std::collections::HashSet<[u8; 3]> = pixels.iter().copied().collect();
    assert!(colours.len() > 500, "{} colours on the page", colours.len());
    // The first configuration's lines (palette colour 0) are on screen.
    let (r, g, b) = PALETTE[0];
    let near = |p: &[u8; 3]| {
        (p[0] as i32 - r as i32).abs() <= 6
            && (p[1] as i32 - g as i32).abs() <= 6
            && (p[2] as i32 - b as i32).abs() <= 6
    };
    let line_pixels = pixels.iter().filter(|p| near(p)).count();
    assert!(
        line_pixels > 500,
        "{line_pixels} pixels of the first series' colour"
    );
    eprintln!("screenshot of the report: {}", shot.display());
    if std::env::var_os("PATHLIGHT_KEEP_REPORT").is_none() {
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
