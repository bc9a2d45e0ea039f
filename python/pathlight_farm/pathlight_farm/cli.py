"""`pathlight-farm render [SCENE] --spp N --chunks K [--scheduler tcp://HOST:8786] --out FILE`:
a pathlight render split over a Dask cluster. Options it does not know (`--width`, `--env`,
`--max-bounces`, ...) go to `pathlight render` unchanged.

`pathlight-farm eval-references SPEC --cache DIR [--scheduler ...]`: the references of a
`pathlight eval` experiment that the cache lacks, rendered over the cluster into the cache
(what `pathlight eval SPEC --cluster ADDRESS` runs first)."""

from __future__ import annotations

import argparse
import sys

from .farm import eval_references, render


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="pathlight-farm", description=__doc__)
    commands = parser.add_subparsers(dest="command", required=True)
    r = commands.add_parser(
        "render",
        help="render an image over a Dask cluster",
        description="Renders [SCENE] (the built-in Cornell box without one) over a Dask "
        "cluster; other options go to `pathlight render`.",
    )
    r.add_argument("--spp", type=int, default=64, help="samples per pixel (default 64)")
    r.add_argument("--out", required=True, help="output image (.exr or .png)")
    r.add_argument("--aovs", action="store_true", help="with .exr: also the AOV layers")
    e = commands.add_parser(
        "eval-references",
        help="render an experiment's missing references over a Dask cluster",
        description="Renders the references of the `pathlight eval` experiment SPEC that the "
        "cache lacks over a Dask cluster and stores them in the cache.",
    )
    e.add_argument("spec", help="the experiment spec (TOML)")
    e.add_argument("--cache", default=".pathlight-cache", help="pathlight eval's cache (default .pathlight-cache)")
    e.add_argument("--only", action="append", default=[], help="only this [[scenes]] entry (repeatable)")
    for p in (r, e):
        p.add_argument("--chunks", type=int, default=16, help="sample ranges, one task each (default 16)")
        p.add_argument("--scheduler", help="Dask scheduler address, e.g. tcp://HOST:8786 (default: a local cluster)")
        p.add_argument("--workers", type=int, default=2, help="local cluster: workers of one thread (default 2)")
        p.add_argument("--binary", default="pathlight", help="the pathlight binary here (default: on PATH)")
        p.add_argument("--worker-binary", help="the pathlight binary on the workers (default: --binary)")
        p.add_argument("--retries", type=int, default=3, help="retries of a failing range (default 3)")
    args, passthrough = parser.parse_known_args(argv)
    progress = lambda line: print(line, file=sys.stderr, flush=True)  # noqa: E731
    # The options both commands share.
    cluster = dict(
        chunks=args.chunks,
        scheduler=args.scheduler,
        binary=args.binary,
        worker_binary=args.worker_binary,
        workers=args.workers,
        retries=args.retries,
        progress=progress,
    )
    if args.command == "eval-references":
        if passthrough:
            parser.error(f"eval-references: unknown arguments {' '.join(passthrough)}")
        job = lambda: eval_references(args.spec, args.cache, only=args.only, **cluster)  # noqa: E731
    else:
        # The scene (if any) and every option this driver does not know go to `pathlight render`.
        job = lambda: render(passthrough, args.spp, out=args.out, aovs=args.aovs, **cluster)  # noqa: E731
    try:
        job()
    except (RuntimeError, ValueError, OSError, ImportError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    return 0

if __name__ == "__main__":
    sys.exit(main())
