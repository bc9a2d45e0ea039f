"""A pathlight render split over a Dask cluster.

Each task renders one range of sample indices (`pathlight render ... --samples A..B`) on a
worker, in a temporary folder of its own, and returns the partial render's bytes: workers need
the `pathlight` binary and the scene, but no shared filesystem. The driver writes the parts it
receives to a temporary folder and `pathlight merge` combines them exactly. A worker that dies
loses only the ranges it held: the scheduler gives them to another worker (Dask's
`allowed-failures`), and a range whose command fails is retried `retries` times.
"""

from __future__ import annotations

import subprocess
import tempfile
import uuid
from pathlib import Path
from typing import Callable, Optional, Sequence


def ranges(spp: int, chunks: int) -> list[tuple[int, int]]:
    """`chunks` contiguous ranges of nearly equal size covering 0..spp (fewer if spp is small)."""
    if spp < 1:
        raise ValueError(f"spp {spp}: at least 1")
    chunks = max(1, min(chunks, spp))
    bounds = [spp * i // chunks for i in range(chunks + 1)]
    return [(a, b) for a, b in zip(bounds, bounds[1:])]


def render_range(binary: str, render_args: Sequence[str], start: int, end: int) -> bytes:
    """Runs on a worker: renders samples start..end and returns the .part file's bytes."""
    with tempfile.TemporaryDirectory(prefix="pathlight-farm-") as folder:
        out = Path(folder) / f"{start}-{end}.part"
        command = [
            binary,
            "render",
            *render_args,
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
    from distributed import Client, LocalCluster, as_completed

    cluster = None
    if scheduler is None:
        cluster = LocalCluster(
            n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None
        )
        client = Client(cluster)
    else:
        client = Client(scheduler)
    try:
        args = [*render_args, "--spp", str(spp)]
        run = uuid.uuid4().hex[:8]
        futures = {
            client.submit(
                render_range,
                worker_binary or binary,
                args,
                a,
                b,
                pure=False,
                retries=retries,
                key=f"pathlight-{run}-{a}-{b}",
            ): (a, b)
            for a, b in ranges(spp, chunks)
        }
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
            done = subprocess.run(command, capture_output=True, text=True)
            if done.returncode != 0:
                raise RuntimeError(f"pathlight merge failed: {done.stderr.strip()}")
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
