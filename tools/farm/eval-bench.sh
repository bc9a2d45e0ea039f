#!/bin/bash
# Run: tools/farm/eval-bench.sh [PATHLIGHT] [PYTHON]   (experiments/convergence.toml's reference:
# the built-in Cornell box, 128x128, 2048 spp; two rounds)
# `pathlight eval --cluster local` (a local Dask cluster of 2 workers x 1 thread, 16 ranges;
# end to end: the listing, the cluster's start, the scene loads of every task, the import)
# against the reference render of a plain `pathlight eval` with 2 threads (its render_seconds,
# the render loop alone).
B=$(realpath "${1:-target/release/pathlight}")
PY=${2:-target/farm-venv/bin/python}; PY="$(cd "$(dirname "$PY")" && pwd)/$(basename "$PY")"
ROOT=$(pwd); D=$(mktemp -d); trap 'rm -rf "$D"' EXIT
printf '#!/bin/sh\nexec "%s" -m pathlight_farm.cli "$@"\n' "$PY" > "$D/farm"; chmod +x "$D/farm"
export PATHLIGHT_FARM="$D/farm" PYTHONPATH="$ROOT/python/pathlight_farm"
SPEC="$ROOT/experiments/convergence.toml"
for round in 1 2; do
  rm -rf "$D/c1" "$D/c2"
  t0=$(date +%s.%N)
  "$PATHLIGHT_FARM" eval-references "$SPEC" --cache "$D/c1" --binary "$B" --workers 2 --chunks 16 2>/dev/null
  t1=$(date +%s.%N)
  "$B" eval "$SPEC" --cache "$D/c2" --out "$D/out" --threads 2 --quiet >/dev/null 2>&1
  local_s=$(python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['references'][0]['render_seconds'])" "$D/out/results.json")
  echo "round $round: cluster (2 workers x 1 thread) $(awk "BEGIN{print $t1-$t0}") s; local reference (2 threads) $local_s s"
done
