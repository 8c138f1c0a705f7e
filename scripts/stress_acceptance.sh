#!/usr/bin/env bash
# The stress acceptance of position sensing (docs/sensing.md): scenes from
# `render`'s distribution on unseen seeds, calibrated from their target images, sensed with the
# library defaults (what `pick` runs), results split by factor in a markdown table.
#
#   scripts/stress_acceptance.sh [BUILD_DIR] [PROFILE] [SCENES] [FIRST_SEED]
#     PROFILE: default | hard | gap0 | mixed (see tests/vision/position_sensing_stress_test.cc)
#   e.g. scripts/stress_acceptance.sh build default 200 5000
# The per-scene lines and the table go to stdout; exit status non-zero when a target is missed.
set -euo pipefail
build=${1:-build}
export HNNSTEREO_STRESS=1
export HNNSTEREO_STRESS_PROFILE=${2:-default}
export HNNSTEREO_STRESS_SCENES=${3:-200}
export HNNSTEREO_STRESS_FIRST_SEED=${4:-5000}
export POCL_CACHE_DIR=${POCL_CACHE_DIR:-$build/pocl-cache}
exec "$build/tests/vision/vision_position_sensing_stress_test" \
  --gtest_filter='PositionSensingStress.ScenesFromTheRenderersDistribution'
