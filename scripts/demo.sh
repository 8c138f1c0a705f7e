#!/usr/bin/env bash
# The main job on the built-in default input: set-up and build, then match the vendored
# Middlebury Teddy pair with the Hopfield network on the OpenCL (PoCL) device, writing
# matches, a report and an overlay image into out/ (or $1), and printing a short summary.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh >/dev/null
BUILD_DIR=${BUILD_DIR:-build}
OUT=${1:-out}
mkdir -p "$OUT"
export POCL_CACHE_DIR="$PWD/$BUILD_DIR/pocl-cache"
DATA=tests/data/middlebury2003_teddy
"$BUILD_DIR/hnnstereo" match --left "$DATA/im2.png" --right "$DATA/im6.png" --rectified \
  --max-disparity 64 --max-features 5000 \
  --out "$OUT/matches.csv" --report "$OUT/report.json" --overlay "$OUT/overlay.png"
