"""pathlight-farm against a real Dask cluster on localhost (a `dask scheduler` and two `dask
worker` processes): a render split into ranges equals the single-machine render to float
rounding (EXR with AOVs, and PNG), also when a worker is killed during the run.

Needs the pathlight binary: PATHLIGHT_BINARY, or target/release or target/debug of the
repository."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import OpenEXR
import pytest
from PIL import Image

from pathlight_farm import ranges, render

ROOT = Path(__file__).resolve().parents[3]


def binary() -> str:
    env = os.environ.get("PATHLIGHT_BINARY")
    if env:
        return env
    for profile in ("release", "debug"):
        p = ROOT / "target" / profile / "pathlight"
        if p.exists():
            return str(p)
    pytest.skip("no pathlight binary: build it or set PATHLIGHT_BINARY")


def dask_command(*args: str) -> list[str]:
    return [sys.executable, "-m", "distributed.cli." + args[0], *args[1:]]


class Cluster:
    """A scheduler and `workers` worker processes (each in its own process group)."""

    def __init__(self, folder: Path, workers: int):
        self.file = folder / "scheduler.json"
        self.procs = [
            subprocess.Popen(
                dask_command(
                    "dask_scheduler", "--scheduler-file", str(self.file), "--port", "0",
                    "--dashboard-address", ":0", "--host", "127.0.0.1",
                ),
                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True,
            )
        ]
        deadline = time.time() + 60
        while not self.file.exists() and time.time() < deadline:
            time.sleep(0.1)
        assert self.file.exists(), "the scheduler did not start"
        time.sleep(0.5)
        self.address = json.loads(self.file.read_text())["address"]
        self.workers = [
            subprocess.Popen(
                dask_command(
                    "dask_worker", self.address, "--nthreads", "1", "--nworkers", "1",
                    "--no-nanny", "--dashboard-address", ":0", "--host", "127.0.0.1",
                ),
                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True,
            )
            for _ in range(workers)
        ]
        self.procs += self.workers
        from distributed import Client

        with Client(self.address) as c:
            c.wait_for_workers(workers, timeout=60)

    def kill_worker(self, i: int) -> None:
        os.killpg(self.workers[i].pid, signal.SIGKILL)

    def close(self) -> None:
        for p in self.procs:
            try:
                os.killpg(p.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            p.wait()


@pytest.fixture
def cluster(tmp_path):
    c = Cluster(tmp_path, 2)
    yield c
    c.close()


ARGS = ["--width", "32", "--height", "24", "--seed", "9"]


def single(tmp_path: Path, spp: int, name: str, aovs: bool = True) -> Path:
    out = tmp_path / name
    command = [binary(), "render", *ARGS, "--spp", str(spp), "--out", str(out), "--quiet"]
    if aovs:
        command.append("--aovs")
    subprocess.run(command, check=True, capture_output=True)
    return out


def assert_same_exr(a: Path, b: Path, aovs: bool = True) -> None:
    x, y = OpenEXR.File(str(a)).channels(), OpenEXR.File(str(b)).channels()
    assert sorted(x) == sorted(y)
    assert len(x) >= (8 if aovs else 1), sorted(x)  # RGB and the AOVs
    for k in x:
        p, q = x[k].pixels.astype(np.float64), y[k].pixels.astype(np.float64)
        assert np.max(np.abs(p - q) / (1 + np.abs(q))) <= 1e-5, k


def test_ranges_cover_the_samples_once():
    for spp, chunks in [(1, 8), (64, 8), (100, 7), (5, 5)]:
        r = ranges(spp, chunks)
        assert r[0][0] == 0 and r[-1][1] == spp
        assert all(a < b for a, b in r) and all(r[i][1] == r[i + 1][0] for i in range(len(r) - 1))
        assert len(r) == min(spp, chunks)


def test_eight_ranges_over_two_workers_equal_the_single_render(cluster, tmp_path):
    for name in ("farm.exr", "farm.png"):
        render(ARGS, 64, 8, tmp_path / name, scheduler=cluster.address, binary=binary(),
               aovs=name.endswith(".exr"), progress=lambda _: None)
    assert_same_exr(tmp_path / "farm.exr", single(tmp_path, 64, "single.exr"))
    a = np.asarray(Image.open(tmp_path / "farm.png"), dtype=np.int32)
    b = np.asarray(Image.open(single(tmp_path, 64, "single.png", aovs=False)), dtype=np.int32)
    # 8-bit: equal, but for a rare pixel on a rounding boundary.
    assert np.max(np.abs(a - b)) <= 1 and np.mean(a != b) < 0.01


def test_a_worker_killed_during_the_run_loses_only_its_ranges(cluster, tmp_path):
    from distributed import Client

    seen = []
    held = []

    def progress(line: str) -> None:
        seen.append(line)
        if len(seen) == 2:
            # What the worker holds, asked of the scheduler just before the kill: the range it
            # runs (one thread) and the finished ranges whose bytes the driver has not fetched.
            with Client(cluster.address) as c:
                pids = c.run(os.getpid)
                address = next(a for a, pid in pids.items() if pid == cluster.workers[0].pid)
                held.append(len(c.processing()[address]) + len(c.has_what()[address]))
            # Kill the worker (its whole process) while ranges are still running.
            cluster.kill_worker(0)

    # The workers run the binary through a wrapper that logs every range it starts.
    log = tmp_path / "ranges.log"
    wrapper = tmp_path / "pathlight-logged"
    wrapper.write_text(f'#!/bin/sh\necho "$@" >> "{log}"\nexec "{binary()}" "$@"\n')
    wrapper.chmod(0o755)
    spp, chunks = 256, 16
    render(ARGS, spp, chunks, tmp_path / "farm.exr", scheduler=cluster.address,
           binary=binary(), worker_binary=str(wrapper), aovs=True, progress=progress)
    assert cluster.workers[0].poll() is not None, "the worker was not killed"
    assert seen[-1].startswith(f"{spp}/{spp} spp")
    assert_same_exr(tmp_path / "farm.exr", single(tmp_path, spp, "single.exr"))
    # Work lost: at most the ranges the killed worker held (running, or finished and not yet
    # fetched): every other range ran once.
    started = [line for line in log.read_text().splitlines() if "--samples" in line]
    assert held and chunks <= len(started) <= chunks + held[0], (held, started)


def test_the_command_line_renders_on_a_local_cluster(tmp_path):
    out = tmp_path / "cli.exr"
    done = subprocess.run(
        [sys.executable, "-m", "pathlight_farm.cli", "render", *ARGS, "--spp", "16", "--chunks",
         "4", "--out", str(out), "--aovs", "--binary", binary()],
        capture_output=True, text=True,
    )
    assert done.returncode == 0, done.stderr
    assert "16/16 spp" in done.stderr
    assert_same_exr(out, single(tmp_path, 16, "single.exr"))
    bad = subprocess.run(
        [sys.executable, "-m", "pathlight_farm.cli", "render", "--spp", "8", "--out",
         str(tmp_path / "x.exr"), "--binary", binary(), "--no-such-option"],
        capture_output=True, text=True,
    )
    assert bad.returncode == 1 and "no-such-option" in bad.stderr


SPEC = """
name = "cluster"
width = 24
height = 16
metrics = ["mse"]
point_lights = 2
measure = "every"
[camera]
path = "orbit"
steps = 1
degrees = 10
[budget]
spp = [1, 2]
[reference]
spp = 48
[reference.config]
max_bounces = 4
[[configuration]]
name = "plain"
"""


def test_eval_cluster_renders_the_references_into_the_cache(cluster, tmp_path):
    spec = tmp_path / "spec.toml"
    spec.write_text(SPEC)
    # `pathlight eval --cluster` runs the driver it finds in $PATHLIGHT_FARM.
    driver = tmp_path / "pathlight-farm"
    driver.write_text(f'#!/bin/sh\nexec "{sys.executable}" -m pathlight_farm.cli "$@"\n')
    driver.chmod(0o755)
    env = {**os.environ, "PATHLIGHT_FARM": str(driver),
           "PYTHONPATH": str(ROOT / "python" / "pathlight_farm")}

    def evaluate(cache: str, out: str, *extra: str) -> dict:
        done = subprocess.run(
            [binary(), "eval", str(spec), "--cache", str(tmp_path / cache), "--out",
             str(tmp_path / out), "--quiet", *extra],
            capture_output=True, text=True, env=env,
        )
        assert done.returncode == 0, done.stderr
        return json.loads((tmp_path / out / "results.json").read_text())

    farmed = evaluate("cache", "out", "--cluster", cluster.address, "--cluster-chunks", "5")
    # Both references came from the cluster: the run found them in the cache.
    assert [r["cached"] for r in farmed["references"]] == [True, True]
    assert all(r["render_seconds"] > 0 for r in farmed["references"])
    local = evaluate("local-cache", "out-local")
    assert [r["cached"] for r in local["references"]] == [False, False]
    for f, l in zip(farmed["references"], local["references"]):
        assert f["key"] == l["key"]
        assert_same_exr(Path(f["path"]), Path(l["path"]), aovs=False)
    # A second run has nothing to render.
    again = subprocess.run(
        [sys.executable, "-m", "pathlight_farm.cli", "eval-references", str(spec), "--cache",
         str(tmp_path / "cache"), "--scheduler", cluster.address, "--binary", binary()],
        capture_output=True, text=True, env=env,
    )
    assert again.returncode == 0 and "every reference is in the cache" in again.stderr
