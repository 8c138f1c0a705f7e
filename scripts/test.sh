#!/usr/bin/env bash
# The whole test suite: set-up and build, then every test through CTest (OpenCL kernel tests
# run under both POCL_WORK_GROUP_METHOD=loopvec and =cbs).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
BUILD_DIR=${BUILD_DIR:-build}
export POCL_CACHE_DIR="$PWD/$BUILD_DIR/pocl-cache"
mkdir -p "$POCL_CACHE_DIR"
ctest --test-dir "$BUILD_DIR" --output-on-failure -j "${TEST_JOBS:-2}" "$@"
