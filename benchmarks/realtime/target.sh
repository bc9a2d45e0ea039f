#!/bin/sh
# Issue 60: what a user gets without a configuration. For each scene with light, `play` along
# its orbit (a full turn in 120 steps, 3 degrees a frame, from a cold start) with the
# defaults: the preset the rule chooses and the frame-time target (33 ms), at the real-time
# commands' default size (640x360; SIZE="--width W --height H" for another). One line per
# scene: the preset, the frames after the first over the target, the 95th percentile, the
# render scale at the end and the lowest, the median frame and the upsampling pass's median.
# BENCHMARKS.md, "Temporal upsampling and the frame-time target".
#
# Run from the repository's root after `cargo build --release`:
#   sh benchmarks/realtime/target.sh
#   B=/path/to/other/pathlight TARGET="--target-ms 33" sh benchmarks/realtime/target.sh
# (TARGET: extra flags, e.g. for a build whose defaults hold no target.)
set -e
B=${B:-./target/release/pathlight}
S=../shared/scenes
SIZE=${SIZE:-}
TARGET=${TARGET:-}
APT="$S/extras_meshopt/dream-apartment.glb"
APT_VIEW="--look-from 9.25,1.5,-4.3 --look-at 6.4,1.1,-7.1 --up 0,1,0 --fov-y 70"

# name | arguments
scenes() {
  echo "cornell|"
  echo "interior|$APT --env $S/hdri/noon_grass_1k.hdr $APT_VIEW"
  echo "garden|$S/japanese-bridge-garden/scene.glb --env $S/hdri/kloppenheim_05_1k.hdr"
  echo "helmet|$S/DamagedHelmet/glTF/DamagedHelmet.gltf --env $S/hdri/brown_photostudio_02_1k.hdr"
  echo "interior-500-lights|$APT --point-lights 500 $APT_VIEW"
  echo "hotel|$S/hotel-room-lotus-carpet/scene.glb"
  echo "diorama|$S/sd-macross-city-standoff-diorama/scene.glb"
}

scenes | while IFS='|' read -r name args; do
  # shellcheck disable=SC2086
  $B play $args --max-bounces 2 $SIZE $TARGET --path orbit --frames 120 --json 2>/dev/null |
    tail -1 | python3 -c "
import json, sys
d = json.loads(sys.stdin.read())
t = d.get('target') or {}
print('$name', (d.get('preset') or {}).get('name'), 'over', t.get('frames_over_target'),
      'of', t.get('frames'), 'p95', t.get('p95_ms') and round(t['p95_ms'], 1),
      'scale', t.get('scale') and round(t['scale'], 2),
      'lowest', t.get('lowest_scale') and round(t['lowest_scale'], 2),
      'median', round(d['ms_per_frame'], 1),
      'upsample', round(d['passes'].get('upsample', 0), 1))"
done
