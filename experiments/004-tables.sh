#!/usr/bin/env bash
# Seed 004: the thesis's tables 6.3-6.8 re-measured here: frame time (median of 30 frames of
# `pathlight bench frame`, the camera orbiting, 640x360, direct light only) with ReSTIR's
# parameters varied one at a time around the defaults (32 candidates, visibility, temporal and
# spatial reuse on, 4 neighbours, 2 iterations), on the interior with 500 random point lights
# and on DamagedHelmet with 100. Prints one markdown table per scene.
# Run: experiments/004-tables.sh [PATHLIGHT] [SHARED]   (defaults: target/release/pathlight, ../shared)
set -euo pipefail
B=${1:-target/release/pathlight}
SHARED=${2:-../shared}
FRAMES=${FRAMES:-30}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

variant() { # name, then TOML lines for [frame.restir]
    local name=$1
    shift
    {
        echo "max_bounces = 1"
        echo "[frame.restir]"
        echo "enabled = true"
        printf '%s\n' "$@"
    } >"$tmp/$name.toml"
    echo "$name"
}

variants=(
    "$(variant candidates-8 'candidates = 8')"
    "$(variant candidates-32)"
    "$(variant candidates-128 'candidates = 128')"
    "$(variant candidates-512 'candidates = 512')"
    "$(variant visibility-off 'visibility_reuse = false')"
    "$(variant temporal-off 'temporal = false')"
    "$(variant spatial-off 'spatial = false')"
    "$(variant neighbours-2 'neighbours = 2')"
    "$(variant neighbours-8 'neighbours = 8')"
    "$(variant neighbours-16 'neighbours = 16')"
    "$(variant iterations-1 'iterations = 1')"
    "$(variant iterations-3 'iterations = 3')"
    "$(variant iterations-4 'iterations = 4')"
    "$(variant unbiased 'unbiased = true')"
)
printf 'max_bounces = 1\n' >"$tmp/nee.toml"

scene() { # title, file, point lights, camera flags...
    local title=$1 file=$2 lights=$3
    shift 3
    echo
    echo "$title"
    echo
    echo "| configuration | frame ms | restir | temporal | spatial | lighting |"
    echo "|---|---|---|---|---|---|"
    for v in nee "${variants[@]}"; do
        "$B" bench frame "$file" --point-lights "$lights" --width 640 --height 360 \
            --frames "$FRAMES" --config "$tmp/$v.toml" "$@" --json 2>/dev/null | tail -1 |
            python3 -c '
import json, sys
r = json.load(sys.stdin); p = r["passes"]; name = sys.argv[1]
f = lambda k: "%.1f" % p[k] if k in p else ""
print("| %s | %.1f | %s | %s | %s | %s |" % (name if name != "nee" else "next event estimation",
      r["ms_per_frame"], f("restir"), f("restir temporal"), f("restir spatial"), f("lighting")))
' "$v"
    done
}

scene "Interior, 500 point lights" "$SHARED/scenes/extras_meshopt/dream-apartment.glb" 500 \
    --look-from 9.25,1.5,-4.3 --look-at 6.4,1.1,-7.1 --fov-y 70
scene "DamagedHelmet, 100 point lights" "$SHARED/scenes/DamagedHelmet/glTF/DamagedHelmet.gltf" 100
