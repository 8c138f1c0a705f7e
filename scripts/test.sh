#!/usr/bin/env bash
# The test suite: set-up and build, then the tests through CTest (OpenCL kernel tests run under
# both POCL_WORK_GROUP_METHOD=loopvec and =cbs).
#
#   bash scripts/test.sh [--extended | --all] [--sanitize address,undefined|thread] [CTEST ARGS...]
#
# Without --extended or --all: the default suite, every test but those labelled `extended` (the
# long sweeps, the soak and the tests that assert on wall time; docs/testing.md). --extended runs
# those only, --all both (.ci/run and the README run --all).
#
# --sanitize builds into a folder of its own (build-asan for address/undefined, build-tsan for
# thread; BUILD_DIR overrides) with HNNSTEREO_SANITIZE and runs the suite with the suppression
# files of tests/sanitizers/ (third-party code only, each entry explained there). Without it,
# nothing changes: build/ and the plain suite (what .ci/run calls).
set -euo pipefail
cd "$(dirname "$0")/.."
SANITIZE=""
SUITE=default
ctest_args=()
while (($#)); do
  case "$1" in
    --extended) SUITE=extended; shift ;;
    --all) SUITE=all; shift ;;
    --sanitize) SANITIZE=${2:?--sanitize needs address,undefined or thread}; shift 2 ;;
    --sanitize=*) SANITIZE=${1#--sanitize=}; shift ;;
    *) ctest_args+=("$1"); shift ;;
  esac
done
if [ -n "$SANITIZE" ]; then
  case "$SANITIZE" in
    thread) default_dir=build-tsan ;;
    address | undefined | address,undefined | undefined,address) default_dir=build-asan ;;
    *) echo "test.sh: --sanitize takes address,undefined or thread (got '$SANITIZE')" >&2; exit 2 ;;
  esac
  export BUILD_DIR=${BUILD_DIR:-$default_dir}
  export HNNSTEREO_SANITIZE=$SANITIZE
  supp="$PWD/tests/sanitizers"
  # halt_on_error: the first report fails the test that caused it; the reports name the test.
  export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:halt_on_error=1:detect_stack_use_after_return=1:strict_string_checks=1}
  export LSAN_OPTIONS=${LSAN_OPTIONS:-suppressions=$supp/lsan.supp:print_suppressions=0}
  export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1:suppressions=$supp/ubsan.supp}
  export TSAN_OPTIONS=${TSAN_OPTIONS:-halt_on_error=1:second_deadlock_stack=1:suppressions=$supp/tsan.supp}
  if ((${#ctest_args[@]} == 0)); then
    # python_hnnstereo: pip builds the module a second time, without the sanitizers, and runs it
    # in an uninstrumented python; it would test nothing the sanitizers see (and cost a full
    # build). Under ThreadSanitizer: the threaded code, the robot link and the serve loop (with
    # its web page), not the single-threaded numerics.
    if [ "$SANITIZE" = thread ]; then
      ctest_args=(-L "robot|web" -E "python_hnnstereo")
    else
      ctest_args=(-E "python_hnnstereo")
    fi
  fi
fi
bash scripts/setup.sh
BUILD_DIR=${BUILD_DIR:-build}
# The Python module is built here with the rest (pip install . into BUILD_DIR/python-venv), so
# that its test runs pytest only; skipped (exit 77) there when PyPI was never reachable.
if [ -z "$SANITIZE" ]; then
  set +e
  tests/python/run_python_tests.sh --install-only "$PWD" "$PWD/$BUILD_DIR" "$PWD/$BUILD_DIR/hnnstereo"
  python_built=$?
  set -e
  case "$python_built" in
    0) export HNNSTEREO_PYTHON_INSTALLED=1 ;;
    77) ;;
    *) echo "test.sh: building the Python module failed" >&2; exit "$python_built" ;;
  esac
fi
export POCL_CACHE_DIR="$PWD/$BUILD_DIR/pocl-cache"
mkdir -p "$POCL_CACHE_DIR"
case "$SUITE" in
  default) ctest_args+=(-LE extended) ;;
  extended) ctest_args+=(-L extended) ;;
esac
ctest --test-dir "$BUILD_DIR" --output-on-failure -j "${TEST_JOBS:-2}" ${ctest_args[@]+"${ctest_args[@]}"}
