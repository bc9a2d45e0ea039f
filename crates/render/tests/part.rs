//! Partial renders (seed-independent sample ranges) and their merging: any split of 0..spp
//! merged is the single render to float rounding, and `merge` refuses parts that do not make
//! one render, naming the file, without panicking.

mod common;

use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;

use common::cornell;
use pathlight_render::checkpoint::Header;
use pathlight_render::film::Film;
use pathlight_render::part::{self, PartHeader};
use pathlight_render::renderer::{render, render_range_pass};
use pathlight_render::{Config, World};

fn config() -> Config {
    Config {
        width: 24,
        height: 18,
        spp: 8,
        seed: 5,
        ..Config::default()
    }
}

fn header(cfg: &Config) -> Header {
    Header {
        config: cfg.clone(),
        scene: "cornell".into(),
        width: cfg.width,
        height: cfg.height,
        samples: None,
    }
}

/// Samples `start..end` of `cfg`'s render.
fn range(world: &World, cfg: &Config, start: u32, end: u32) -> Film {
    let mut film = Film::new(cfg.width, cfg.height);
    let camera = cfg.render_camera(world);
    let cancel = AtomicBool::new(false);
    assert!(render_range_pass(
        world,
        &camera,
        cfg,
        &mut film,
        start,
        end - start,
        &cancel,
        &|_| {}
    ));
    film
}

fn dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("pathlight-part-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Writes the parts of `cfg`'s render for `ranges` into `d`.
fn write_parts(world: &World, cfg: &Config, d: &Path, ranges: &[(u32, u32)]) -> Vec<PathBuf> {
    ranges
        .iter()
        .map(|&(a, b)| {
            let path = d.join(format!("{a}-{b}.part"));
            part::save(
                &path,
                &PartHeader::new(&header(cfg), a, b),
                &range(world, cfg, a, b),
            )
            .unwrap();
            path
        })
        .collect()
}

#[test]
fn any_split_merges_to_the_single_render() {
    let world = cornell();
    let cfg = config();
    let whole = render(&world, &cfg.render_camera(&world), &cfg);
    let d = dir("split");
    for split in [
        vec![(0, 8)],
        vec![(0, 3), (3, 8)],
        vec![(5, 8), (0, 1), (1, 2), (2, 5)],
        (0..8).map(|i| (i, i + 1)).collect::<Vec<_>>(),
    ] {
        let paths = write_parts(&world, &cfg, &d, &split);
        let (h, merged) = part::merge(&paths).unwrap();
        assert_eq!(h, header(&cfg));
        for (m, w) in merged.pixels.iter().zip(&whole.pixels) {
            assert_eq!(m.n, w.n);
            let close = |a: glam::Vec3, b: glam::Vec3| {
                (a - b).abs().max_element() <= 1e-5 * (1.0 + b.abs().max_element())
            };
            assert!(close(m.mean, w.mean), "{split:?}: {} vs {}", m.mean, w.mean);
            assert!(close(m.variance(), w.variance()), "{split:?}");
            for (a, b) in [
                (m.direct, w.direct),
                (m.indirect, w.indirect),
                (m.albedo, w.albedo),
                (m.normal, w.normal),
            ] {
                assert!(close(a, b), "{split:?}: {a} vs {b}");
            }
            assert!((m.depth - w.depth).abs() <= 1e-5 * (1.0 + w.depth.abs()));
        }
        for p in paths {
            std::fs::remove_file(p).unwrap();
        }
    }
}

/// `merge`'s error for `paths`, which must name `file`.
fn refused(paths: &[PathBuf], file: &Path, what: &str) {
    let e = part::merge(paths).unwrap_err().to_string();
    assert!(
        e.contains(&file.display().to_string()) && e.contains(what),
        "{e:?} should name {} and say {what:?}",
        file.display()
    );
}

#[test]
fn merge_refuses_parts_that_do_not_make_one_render() {
    let world = cornell();
    let cfg = config();
    let d = dir("bad");
    let p = write_parts(&world, &cfg, &d, &[(0, 3), (3, 8), (2, 5), (5, 8)]);
    // Overlapping and missing ranges.
    refused(
        &[p[0].clone(), p[2].clone(), p[3].clone()],
        &p[2],
        "overlaps",
    );
    refused(&[p[3].clone(), p[0].clone()], &p[3], "missing before");
    refused(&[p[0].clone()], &p[0], "missing after");
    // Another render (another seed).
    let other = Config {
        seed: 6,
        ..cfg.clone()
    };
    let q = write_parts(&world, &other, &dir("other"), &[(3, 8)]);
    refused(&[p[0].clone(), q[0].clone()], &q[0], "another render");
    // Truncated pixels, a truncated header, not a part at all.
    let bytes = std::fs::read(&p[1]).unwrap();
    let cut = d.join("cut.part");
    std::fs::write(&cut, &bytes[..bytes.len() - 7]).unwrap();
    refused(&[p[0].clone(), cut.clone()], &cut, "bytes of pixel data");
    std::fs::write(&cut, &bytes[..20]).unwrap();
    refused(&[p[0].clone(), cut.clone()], &cut, "truncated header");
    std::fs::write(&cut, b"P3\n1 1\n255\n0 0 0\n").unwrap();
    refused(
        &[p[0].clone(), cut.clone()],
        &cut,
        "not a pathlight partial render",
    );
    // A header edited by hand (its hash no longer matches), a corrupt sample count.
    let json_len = u64::from_le_bytes(bytes[8..16].try_into().unwrap()) as usize;
    let json = String::from_utf8(bytes[16..16 + json_len].to_vec()).unwrap();
    let edited = json.replace("\"seed\":5", "\"seed\":7");
    assert_eq!(edited.len(), json.len());
    let mut tampered = bytes.clone();
    tampered[16..16 + json_len].copy_from_slice(edited.as_bytes());
    std::fs::write(&cut, &tampered).unwrap();
    let e = part::load(&cut).unwrap_err().to_string();
    assert!(e.contains("cut.part") && e.contains("settings hash"), "{e}");
    let mut corrupt = bytes.clone();
    let first_pixel = 16 + json_len;
    corrupt[first_pixel..first_pixel + 4].copy_from_slice(&3u32.to_le_bytes());
    std::fs::write(&cut, &corrupt).unwrap();
    refused(&[p[0].clone(), cut.clone()], &cut, "incomplete or corrupt");
    // A huge header length is refused before any allocation.
    let mut huge = bytes.clone();
    huge[8..16].copy_from_slice(&u64::MAX.to_le_bytes());
    std::fs::write(&cut, &huge).unwrap();
    refused(std::slice::from_ref(&cut), &cut, "corrupt header length");
    assert!(part::merge(&[]).is_err());
}
