#!/bin/sh
# Real time (issue 59): each configuration's frame against its rays, and its stalls, side by
# side with another build. BENCHMARKS.md, "Real time: the frame against its rays".
#
# For each configuration, REPS alternated runs of `bench frame --json` (60 frames along its
# 30-degree orbit, after two warm-up frames) with this build and with OLD (when given), and
# one `play --path orbit --json` (a full turn in 120 steps, 3 degrees per frame, from a cold
# start) per build for the first frame and the slowest later one against the median.
# Prints one line per run; the medians are for the reader (or summary.py).
#
# Run from the repository's root after `cargo build --release`:
#   sh benchmarks/realtime/goals.sh                       # this build alone
#   OLD=/path/to/old/pathlight sh benchmarks/realtime/goals.sh
# REPS (default 3) and FRAMES (default 40, play's frames) choose the effort; ONLY (a pattern
# over the names) the configurations. An OLD build from
# before the filter's settings moved into per-method tables (912ec0e) cannot read today's
# presets: give it its own with OLD_EXPERIMENTS=DIR (e.g. `git archive 70c60e8 experiments |
# tar -x -C /tmp/old`, then OLD_EXPERIMENTS=/tmp/old/experiments).
set -e
NEW=./target/release/pathlight
OLD=${OLD:-}
OLD_EXPERIMENTS=${OLD_EXPERIMENTS:-}
REPS=${REPS:-3}
FRAMES=${FRAMES:-40}
S=../shared/scenes
APT="$S/extras_meshopt/dream-apartment.glb --env $S/hdri/noon_grass_1k.hdr"
APT="$APT --look-from 9.25,1.5,-4.3 --look-at 6.4,1.1,-7.1 --up 0,1,0 --fov-y 70 --max-bounces 2"
SMALL="--width 320 --height 180"

# name | threads | arguments
configs() {
  echo "plain-interior|1|$APT $SMALL"
  echo "plain-interior|2|$APT $SMALL"
  echo "plain-cornell-640x360|2|--width 640 --height 360"
  echo "sun-preset-interior|2|$APT $SMALL --config experiments/realtime-sun.toml"
  echo "svgf-preset-interior|2|$APT $SMALL --config experiments/realtime.toml"
  # The moonshot: the sun preset at 640x360.
  echo "sun-preset-interior-640x360|2|$APT --width 640 --height 360 --config experiments/realtime-sun.toml"
}

# The plain pipeline's configurations say so to builds that choose a preset by default (those
# with --plain); older builds ran the plain pipeline without a configuration.
plain() { # build name
  case "$2" in plain-*) "$1" bench frame --help 2>/dev/null | grep -q -- '--plain' && echo --plain ;; esac
}

frame() { # build name threads args...
  b=$1; n=$2; t=$3; shift 3
  set -- "$@" $(plain "$b" "$n")
  if [ "$b" = "$OLD" ] && [ -n "$OLD_EXPERIMENTS" ]; then
    # shellcheck disable=SC2046
    set -- $(printf '%s\n' "$@" | sed "s|^experiments/|$OLD_EXPERIMENTS/|")
  fi
  # (A build older than the floor measures no floor: its fields are then empty.)
  $b bench frame "$@" --threads "$t" --frames 60 --json 2>/dev/null | tail -1 |
    python3 -c "import json,sys; d=json.loads(sys.stdin.read()); \
print('frame $n threads $t', '$b', 'ms', round(d['ms_per_frame'], 2), 'floor', \
d.get('floor_ms') and round(d['floor_ms'], 2), 'frame/floor', \
d.get('frame_over_floor') and round(d['frame_over_floor'], 2))"
}

stalls() { # build name args...
  b=$1; n=$2; shift 2
  set -- "$@" $(plain "$b" "$n")
  $b play "$@" --path orbit --frames "$FRAMES" --quiet --json 2>/dev/null | tail -1 |
    python3 -c "import json,sys; d=json.loads(sys.stdin.read()); \
print('stalls $n', '$b', 'median', round(d['ms_per_frame'], 1), 'first', \
d.get('first_frame_ms') and round(d['first_frame_ms'], 1), 'first/median', \
d.get('first_over_median') and round(d['first_over_median'], 2), 'worst later/median', \
d.get('worst_later_over_median') and round(d['worst_later_over_median'], 2))"
}

configs | grep -E "^(${ONLY:-.})" | while IFS='|' read -r name threads args; do
  for r in $(seq "$REPS"); do
    # shellcheck disable=SC2086
    [ -n "$OLD" ] && frame "$OLD" "$name" "$threads" $args
    # shellcheck disable=SC2086
    frame "$NEW" "$name" "$threads" $args
  done
  if [ "$threads" = 2 ]; then
    # shellcheck disable=SC2086
    stalls "$NEW" "$name" $args
  fi
done
