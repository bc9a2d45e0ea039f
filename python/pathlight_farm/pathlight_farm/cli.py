"""`pathlight-farm render [SCENE] --spp N --chunks K [--scheduler tcp://HOST:8786] --out FILE`:
a pathlight render split over a Dask cluster. Options it does not know (`--width`, `--env`,
`--max-bounces`, ...) go to `pathlight render` unchanged."""

from __future__ import annotations

import argparse
import sys

from .farm import render


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
    r.add_argument("--chunks", type=int, default=16, help="sample ranges, one task each (default 16)")
    r.add_argument("--scheduler", help="Dask scheduler address, e.g. tcp://HOST:8786 (default: a local cluster)")
    r.add_argument("--workers", type=int, default=2, help="local cluster: workers of one thread (default 2)")
    r.add_argument("--out", required=True, help="output image (.exr or .png)")
    r.add_argument("--aovs", action="store_true", help="with .exr: also the AOV layers")
    r.add_argument("--binary", default="pathlight", help="the pathlight binary here (default: on PATH)")
    r.add_argument("--worker-binary", help="the pathlight binary on the workers (default: --binary)")
    r.add_argument("--retries", type=int, default=3, help="retries of a failing range (default 3)")
    args, passthrough = parser.parse_known_args(argv)
    # The scene (if any) and every option this driver does not know go to `pathlight render`.
    render_args = passthrough
    try:
        render(
            render_args,
            args.spp,
            args.chunks,
            args.out,
            scheduler=args.scheduler,
            binary=args.binary,
            worker_binary=args.worker_binary,
            aovs=args.aovs,
            workers=args.workers,
            retries=args.retries,
            progress=lambda line: print(line, file=sys.stderr, flush=True),
        )
    except (RuntimeError, ValueError, OSError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
