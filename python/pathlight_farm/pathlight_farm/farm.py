"""pathlight renders split over a Dask cluster: one image (`render`), or the references an
experiment needs, into `pathlight eval`'s cache (`eval_references`).

Each task renders one range of sample indices (`pathlight render ... --samples A..B`) on a
worker, in a temporary folder of its own, and returns the partial render's bytes: workers need
the `pathlight` binary and the scene, but no shared filesystem. The driver writes the parts it
receives to a temporary folder and `pathlight merge` combines them exactly. A worker that dies
loses only the ranges it held: the scheduler gives them to another worker (Dask's
`allowed-failures`), and a range whose command fails is retried `retries` times.
"""

from __future__ import annotations

import contextlib
import json
import subprocess
import tempfile
import time
import uuid
from pathlib import Path
from typing import Callable, Iterator, Optional, Sequence


def ranges(spp: int, chunks: int) -> list[tuple[int, int]]:
    """`chunks` contiguous ranges of nearly equal size covering 0..spp (fewer if spp is small)."""
    if spp < 1:
        raise ValueError(f"spp {spp}: at least 1")
    chunks = max(1, min(chunks, spp))
    bounds = [spp * i // chunks for i in range(chunks + 1)]
    return [(a, b) for a, b in zip(bounds, bounds[1:])]


def render_range(
    binary: str, render_args: Sequence[str], start: int, end: int, config: Optional[str] = None
) -> bytes:
    """Runs on a worker: renders samples start..end and returns the .part file's bytes.
    `config`, when given, is the text of a `--config` file (written next to the part)."""
    with tempfile.TemporaryDirectory(prefix="pathlight-farm-") as folder:
        out = Path(folder) / f"{start}-{end}.part"
        extra = []
        if config is not None:
            path = Path(folder) / "config.toml"
            path.write_text(config)
            extra = ["--config", str(path)]
        command = [
            binary,
            "render",
            *render_args,
            *extra,
            "--samples",
            f"{start}..{end}",
            "--out",
            str(out),
            "--quiet",
            "--checkpoint-every",
            "0",
        ]
        done = subprocess.run(command, capture_output=True, text=True)
        if done.returncode != 0:
            raise RuntimeError(f"{' '.join(command)} failed: {done.stderr.strip()}")
        return out.read_bytes()


@contextlib.contextmanager
def client_for(scheduler: Optional[str], workers: int) -> Iterator:
    """A Dask client of the cluster at `scheduler`, or of a local cluster of `workers`
    single-thread worker processes without one."""
    from distributed import Client, LocalCluster

    cluster = None
    if scheduler is None:
        cluster = LocalCluster(
            n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None
        )
        client = Client(cluster)
    else:
        client = Client(scheduler)
    try:
        yield client
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def submit_ranges(client, binary: str, args: Sequence[str], spp: int, chunks: int,
                  retries: int, config: Optional[str] = None) -> dict:
    """One task per sample range of 0..spp: {future: (start, end)}."""
    run = uuid.uuid4().hex[:8]
    return {
        client.submit(
            render_range,
            binary,
            list(args),
            a,
            b,
            config,
            pure=False,
            retries=retries,
            key=f"pathlight-{run}-{a}-{b}",
        ): (a, b)
        for a, b in ranges(spp, chunks)
    }


def run_pathlight(command: Sequence[str], what: str) -> str:
    """Runs a pathlight command here; its standard output."""
    done = subprocess.run(list(command), capture_output=True, text=True)
    if done.returncode != 0:
        raise RuntimeError(f"{what} failed: {done.stderr.strip()}")
    return done.stdout


def render(
    render_args: Sequence[str],
    spp: int,
    chunks: int,
    out: str | Path,
    scheduler: Optional[str] = None,
    binary: str = "pathlight",
    worker_binary: Optional[str] = None,
    aovs: bool = False,
    workers: int = 2,
    retries: int = 3,
    progress: Callable[[str], None] = print,
) -> None:
    """Renders `pathlight render RENDER_ARGS --spp SPP` split into `chunks` sample ranges over
    the cluster at `scheduler` (a local cluster of `workers` single-thread workers without
    one) and writes the merged image to `out` (.exr or .png; `aovs` for the EXR layers).
    `binary` runs `merge` here; `worker_binary` (default: `binary`) runs on the workers."""
    from distributed import as_completed

    with client_for(scheduler, workers) as client:
        args = [*render_args, "--spp", str(spp)]
        futures = submit_ranges(client, worker_binary or binary, args, spp, chunks, retries)
        with tempfile.TemporaryDirectory(prefix="pathlight-farm-parts-") as folder:
            paths = []
            samples = 0
            for future in as_completed(futures):
                a, b = futures[future]
                path = Path(folder) / f"{a:010d}-{b:010d}.part"
                path.write_bytes(future.result())
                paths.append(path)
                samples += b - a
                progress(f"{samples}/{spp} spp ({len(paths)}/{len(futures)} ranges)")
            command = [binary, "merge", *map(str, sorted(paths)), "--out", str(out)]
            if aovs:
                command.append("--aovs")
            run_pathlight(command, "pathlight merge")


def eval_references(
    spec: str | Path,
    cache: str | Path,
    chunks: int = 16,
    only: Sequence[str] = (),
    scheduler: Optional[str] = None,
    binary: str = "pathlight",
    worker_binary: Optional[str] = None,
    workers: int = 2,
    retries: int = 3,
    progress: Callable[[str], None] = print,
) -> int:
    """Renders the references of the experiment `spec` that `pathlight eval`'s cache `cache`
    lacks over the cluster (`chunks` sample ranges each, all references at once) and imports
    each into the cache as soon as its ranges are in, so a later `pathlight eval SPEC --cache
    CACHE` finds them. Returns how many it rendered."""
    from distributed import as_completed

    base = [binary, "eval", str(spec), "--cache", str(cache)]
    for name in only:
        base += ["--only", name]
    listed = json.loads(
        run_pathlight([*base, "--missing-references"], "pathlight eval --missing-references")
    )["references"]
    if not listed:
        progress("every reference is in the cache")
        return 0
    with client_for(scheduler, workers) as client, tempfile.TemporaryDirectory(
        prefix="pathlight-farm-references-"
    ) as folder:
        start = time.monotonic()
        owner = {}
        for i, reference in enumerate(listed):
            futures = submit_ranges(
                client, worker_binary or binary, reference["render_args"], reference["spp"],
                chunks, retries, reference["config"],
            )
            owner.update({f: (i, a, b) for f, (a, b) in futures.items()})
            reference["parts"] = []
            reference["ranges"] = len(futures)
        done = 0
        for future in as_completed(owner):
            i, a, b = owner[future]
            reference = listed[i]
            path = Path(folder) / f"{i:04d}-{a:010d}-{b:010d}.part"
            path.write_bytes(future.result())
            reference["parts"].append(str(path))
            if len(reference["parts"]) < reference["ranges"]:
                continue
            run_pathlight(
                [*base, "--import-references", *sorted(reference["parts"]),
                 "--render-seconds", f"{time.monotonic() - start:.3f}"],
                "pathlight eval --import-references",
            )
            for part in reference["parts"]:
                Path(part).unlink()
            done += 1
            name = f"{reference['entry']}, " if reference["entry"] else ""
            progress(f"reference {done}/{len(listed)} ({name}view {reference['view'] + 1}) in the cache")
    return done
