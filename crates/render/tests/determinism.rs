//! The same seed and settings give the same image whatever the thread count, and a render
//! stopped part-way (between passes or in the middle of one) and resumed from its checkpoint
//! ends bit-identical to an uninterrupted one.

mod common;

use common::{cornell, in_pool};
use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};

use pathlight_render::checkpoint::{self, Header};
use pathlight_render::renderer::{render, render_pass};
use pathlight_render::{Config, Film};

fn config() -> Config {
    Config {
        width: 40,
        height: 30,
        spp: 12,
        seed: 7,
        ..Config::default()
    }
}

#[test]
fn one_and_two_threads_give_the_same_film() {
    let world = cornell();
    let cfg = config();
    let camera = cfg.render_camera(&world);
    let one = in_pool(1, || render(&world, &camera, &cfg));
    let two = in_pool(2, || render(&world, &camera, &cfg));
    assert!(one == two, "films differ between 1 and 2 threads");
    let other_seed = render(
        &world,
        &camera,
        &Config {
            seed: 8,
            ..cfg.clone()
        },
    );
    assert!(one != other_seed, "the seed changes nothing");
}

#[test]
fn stopped_and_resumed_render_equals_an_uninterrupted_one() {
    let world = cornell();
    let cfg = config();
    let camera = cfg.render_camera(&world);
    let straight = render(&world, &camera, &cfg);

    // Stop in the middle of the second pass (after three bands), checkpoint, reload, resume.
    let mut film = Film::new(cfg.width, cfg.height);
    let cancel = AtomicBool::new(false);
    assert!(render_pass(
        &world,
        &camera,
        &cfg,
        &mut film,
        5,
        &cancel,
        &|_| {}
    ));
    let bands = AtomicU32::new(0);
    let finished = in_pool(1, || {
        render_pass(&world, &camera, &cfg, &mut film, 9, &cancel, &|_| {
            if bands.fetch_add(1, Ordering::SeqCst) == 2 {
                cancel.store(true, Ordering::SeqCst);
            }
        })
    });
    assert!(!finished);
    assert!(film.min_samples() == 5 && film.pixels.iter().any(|p| p.n == 9));

    let dir = std::env::temp_dir().join(format!("pathlight-resume-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("render.checkpoint");
    let header = Header {
        config: cfg.clone(),
        scene: "cornell".into(),
        width: cfg.width,
        height: cfg.height,
        samples: None,
    };
    checkpoint::save(&path, &header, &film).unwrap();
    let (loaded_header, mut resumed) = checkpoint::load(&path).unwrap();
    assert_eq!(loaded_header, header);
    assert!(resumed == film);
    // More samples may be asked for; other settings may not change.
    assert!(header.compatible(&Header {
        config: Config {
            spp: 64,
            ..cfg.clone()
        },
        ..header.clone()
    }));
    assert!(!header.compatible(&Header {
        config: Config {
            seed: 1,
            ..cfg.clone()
        },
        ..header.clone()
    }));

    let cancel = AtomicBool::new(false);
    assert!(render_pass(
        &world,
        &camera,
        &cfg,
        &mut resumed,
        cfg.spp,
        &cancel,
        &|_| {}
    ));
    assert!(
        resumed == straight,
        "resumed film differs from the uninterrupted one"
    );

    // Damaged checkpoints are refused with the file's name.
    let bytes = std::fs::read(&path).unwrap();
    std::fs::write(&path, &bytes[..bytes.len() - 4]).unwrap();
    let err = checkpoint::load(&path).unwrap_err().to_string();
    assert!(
        err.contains("render.checkpoint") && err.contains("bytes of pixel data"),
        "{err}"
    );
    std::fs::write(&path, b"hello").unwrap();
    assert!(checkpoint::load(&path)
        .unwrap_err()
        .to_string()
        .contains("not a pathlight checkpoint"));
    std::fs::remove_dir_all(&dir).unwrap();
}
