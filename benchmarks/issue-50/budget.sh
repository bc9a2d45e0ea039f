#!/bin/sh
# Seed 002's budget sweep: cells shaded per frame (and blocks shaded without the cache, their
# set full) against the cache's memory in bytes per pixel, on the interior along the built-in
# orbit (3 degrees per frame), the cache's defaults but for young cells' samples and the clamp
# (the paper's protocol: each cell shaded once per frame it is needed; since 5ef8d42 the
# defaults bring young cells up to 16 samples after each frame). BENCHMARKS.md, "Seed 002" /
# Budget.
# Run from the repository's root: sh benchmarks/issue-50/budget.sh
# W, H (default 320x180), BPPS (bytes per pixel, default "1 4 16 64 256 4096"; a budget is
# capped at 4096 MB) and FRAMES (default 12) choose the sweep, e.g.
#   W=1920 H=1080 BPPS="1 16 256" FRAMES=6 sh benchmarks/issue-50/budget.sh
set -e
S=../shared/scenes/extras_meshopt/dream-apartment.glb
E=../shared/scenes/hdri/noon_grass_1k.hdr
W=${W:-320}
H=${H:-180}
BPPS=${BPPS:-1 4 16 64 256 4096}
FRAMES=${FRAMES:-12}
OUT=${OUT:-/tmp/pathlight-budget}
mkdir -p "$OUT"
printf '[frame.texture_cache]\nfresh_spp = 1\nclamp = 0.0\n' > "$OUT/paper.toml"
for bpp in $BPPS; do
  mb=$(python3 -c "print(min($bpp * $W * $H / 2**20, 4096))")
  ./target/release/pathlight play "$S" --env "$E" --look-from 9.25,1.5,-4.3 --look-at 6.4,1.1,-7.1 \
    --fov-y 70 --max-bounces 2 --width "$W" --height "$H" --config "$OUT/paper.toml" \
    --texture-cache --texture-cache-budget "$mb" \
    --path orbit --frames "$FRAMES" --out "$OUT/${W}x$H-b$bpp" > /dev/null 2>&1
  python3 - "$OUT/${W}x$H-b$bpp/frames.json" "$bpp" "$mb" <<'PY'
import json, statistics, sys
d = json.load(open(sys.argv[1]))
tc = [f["texture_cache"] for f in d]
print(f"{sys.argv[2]:>5} B/pixel ({float(sys.argv[3]):.2f} MB): cells shaded frame 1 {tc[0]['cells_shaded']}, "
      f"median of frames 2-{len(d)} {statistics.median(t['cells_shaded'] for t in tc[1:])}, uncached blocks median "
      f"{statistics.median(t['uncached'] for t in tc)}, ms median {statistics.median(f['ms'] for f in d):.1f}")
PY
done
