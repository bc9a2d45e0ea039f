//! Environment maps: values survive a round trip through files written by an independent
//! encoder (the `image` crate's Radiance HDR and OpenEXR writers), and the shared HDRIs load.

use std::path::PathBuf;

use glam::Vec3;
use pathlight_scene::{Environment, Limits};

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("pathlight-env-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// An 8x4 gradient with values over 1 (HDR) and a recognisable texel at (5, 1).
fn gradient() -> image::Rgb32FImage {
    image::ImageBuffer::from_fn(8, 4, |x, y| {
        if (x, y) == (5, 1) {
            image::Rgb([12.5, 0.25, 3.0])
        } else {
            image::Rgb([x as f32 * 0.5, y as f32 * 2.0, 0.125])
        }
    })
}

fn round_trip(ext: &str) {
    let dir = temp_dir(ext);
    let path = dir.join(format!("g.{ext}"));
    image::DynamicImage::ImageRgb32F(gradient())
        .save(&path)
        .unwrap();
    let env = Environment::load(&path, 90.0, 2.0, &Limits::default()).unwrap();
    assert_eq!((env.width, env.height), (8, 4));
    assert!((env.rotation - std::f32::consts::FRAC_PI_2).abs() < 1e-6);
    assert_eq!(env.intensity, 2.0);
    let expect = gradient();
    // RGBE keeps 8 bits of mantissa per channel relative to the largest: 1% is honest.
    let tol = if ext == "hdr" { 0.01 } else { 1e-6 };
    for (i, t) in env.texels.iter().enumerate() {
        let e = Vec3::from_slice(&expect.as_raw()[3 * i..3 * i + 3]);
        let scale = e.max_element().max(1e-3);
        assert!(
            ((*t - e).abs() / scale).max_element() <= tol,
            "{ext} texel {i}: {t} vs {e}"
        );
    }
    // radiance() looks up the texel seen in a direction, times intensity.
    let uv = glam::Vec2::new(5.5 / 8.0, 1.5 / 4.0);
    let r = env.radiance(env.uv_to_direction(uv));
    assert!((r - env.texels[8 + 5] * 2.0).length() < 1e-5, "{r}");
    std::fs::remove_dir_all(dir).ok();
}

#[test]
fn hdr_round_trip() {
    round_trip("hdr");
}

#[test]
fn exr_round_trip() {
    round_trip("exr");
}

#[test]
fn shared_hdris_load() {
    let dir = pathlight_core::shared_data::dir(env!("CARGO_MANIFEST_DIR")).join("scenes/hdri");
    if !pathlight_core::shared_data::present(&dir) {
        return;
    }
    let entries = std::fs::read_dir(&dir).unwrap();
    let mut n = 0;
    for e in entries {
        let p = e.unwrap().path();
        if p.extension().is_some_and(|x| x == "hdr") {
            let env = Environment::load(&p, 0.0, 1.0, &Limits::default()).unwrap();
            assert_eq!((env.width, env.height), (1024, 512), "{}", p.display());
            let mean: Vec3 = env.texels.iter().copied().sum::<Vec3>() / env.texels.len() as f32;
            assert!(
                mean.min_element() > 0.0 && mean.is_finite(),
                "{}: mean {mean}",
                p.display()
            );
            n += 1;
        }
    }
    assert_eq!(n, 3);
}
