#!/usr/bin/env bash
# Builds the libFuzzer targets (HNNSTEREO_FUZZ=ON, clang, ASan+UBSan, folder build-fuzz/) and runs
# each for SECONDS on a copy of its seed corpus (fuzz/corpus/<what>/), printing the executions
# and the coverage each reached. A crash stops that fuzzer and leaves its reproducer
# (crash-<sha>) in build-fuzz/fuzz/findings/<what>/; the script then exits non-zero.
#   bash scripts/fuzz.sh [SECONDS]      (default 60)
set -euo pipefail
cd "$(dirname "$0")/.."
SECONDS_EACH=${1:-60}
BUILD_DIR=${BUILD_DIR:-build-fuzz}
# The Debian packages, clang included (scripts/setup.sh installs it only when asked).
HNNSTEREO_FUZZ=1 HNNSTEREO_SETUP_PACKAGES_ONLY=1 bash scripts/setup.sh
# HNNSTEREO_BUILD_CLI=ON for the robot library and app/cli_support.cc (FRAME.yml, Modbus,
# vision-server, --config); the tests and the perf harness stay off.
if [ ! -f "$BUILD_DIR/CMakeCache.txt" ]; then
  launcher=()
  if command -v ccache >/dev/null; then launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache); fi
  cmake -S . -B "$BUILD_DIR" -G Ninja -DCMAKE_BUILD_TYPE=Release -DCMAKE_CXX_COMPILER=clang++ \
    -DHNNSTEREO_FUZZ=ON -DHNNSTEREO_BUILD_CLI=ON -DHNNSTEREO_BUILD_TESTS=OFF \
    -DHNNSTEREO_BUILD_PERF=OFF -DHNNSTEREO_INSTALL=OFF ${launcher[@]+"${launcher[@]}"} >/dev/null
fi
cmake --build "$BUILD_DIR" -j "${BUILD_JOBS:-2}" --target fuzzers
status=0
printf '%-19s %10s %8s %8s %s\n' fuzzer execs exec/s cov result
for source in fuzz/fuzz_*.cc; do
  what=$(basename "$source" .cc)
  what=${what#fuzz_}
  work="$BUILD_DIR/fuzz/work/$what"
  findings="$BUILD_DIR/fuzz/findings/$what"
  mkdir -p "$work" "$findings"
  cp -n fuzz/corpus/"$what"/* "$work"/ 2>/dev/null || true
  log="$BUILD_DIR/fuzz/$what.log"
  result=clean
  # -rss_limit_mb: a parser that allocates beyond 2 GB for a small input is a finding too;
  # -timeout: one input running 10 s is a hang (libFuzzer's default waits 1200 s).
  if ! "$BUILD_DIR/fuzz/fuzz_$what" "$work" -max_total_time="$SECONDS_EACH" -rss_limit_mb=2048 -timeout=10 \
      -max_len=65536 -print_final_stats=1 -artifact_prefix="$findings/" >"$log" 2>&1; then
    result="FOUND (see $log, $findings/)"
    status=1
  fi
  execs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' || echo 0)
  speed=$(grep -o 'stat::average_exec_per_sec: *[0-9]*' "$log" | grep -o '[0-9]*$' || echo 0)
  cov=$(grep -o 'cov: [0-9]*' "$log" | tail -1 | grep -o '[0-9]*' || echo 0)
  printf '%-19s %10s %8s %8s %s\n' "$what" "${execs:-0}" "${speed:-0}" "${cov:-0}" "$result"
done
exit $status
