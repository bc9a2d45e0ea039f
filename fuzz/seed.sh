#!/usr/bin/env bash
# Writes the seed corpora (fuzz/corpus/<target>/, not committed) from the shared scenes and
# generated images. Usage: fuzz/seed.sh [SCENES_DIR]   (default: ../shared/scenes next to the repo)
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
scenes="${1:-$here/../../shared/scenes}"
cd "$here"
cargo run --quiet --example make_seeds -- "$scenes" "$here/corpus"
