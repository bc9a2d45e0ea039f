//! The Dask driver (`python/pathlight_farm`, issue 19) against a real cluster on localhost: runs
//! its pytest suite (a `dask scheduler` and two `dask worker` processes; a split render equal to
//! the single render, also with a worker killed mid-run) with this build's `pathlight`. Needs a
//! Python with the driver's test dependencies: `PATHLIGHT_FARM_PYTHON`, or
//! `target/farm-venv/bin/python` (which `.ci/run` makes). Without one the test prints a note and
//! skips, except under CI.

use std::path::PathBuf;
use std::process::Command;

#[test]
fn the_dask_driver_passes_its_tests_on_a_local_cluster() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..");
    let python = std::env::var_os("PATHLIGHT_FARM_PYTHON")
        .map(PathBuf::from)
        .unwrap_or_else(|| root.join("target/farm-venv/bin/python"));
    if !python.is_file() {
        assert!(
            std::env::var_os("CI").is_none(),
            "CI must make {} (.ci/run does)",
            python.display()
        );
        eprintln!(
            "note: no {} (see python/pathlight_farm/README.md); Dask driver test skipped",
            python.display()
        );
        return;
    }
    let package = root.join("python/pathlight_farm");
    let out = Command::new(&python)
        .args(["-m", "pytest", "-q", "-p", "no:cacheprovider", "tests"])
        .current_dir(&package)
        .env("PATHLIGHT_BINARY", env!("CARGO_BIN_EXE_pathlight"))
        .env("PYTHONPATH", &package)
        .output()
        .expect("python runs");
    assert!(
        out.status.success(),
        "pytest failed:\n{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}
