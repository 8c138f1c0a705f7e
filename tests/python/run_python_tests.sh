#!/usr/bin/env bash
# The Python module's tests: a venv in the build directory (Debian's python3 with
# --system-site-packages, so numpy, cv2 and pytest come from Debian), scikit-build-core from PyPI
# once, `pip install .` of the source tree (build kept in BUILD_DIR/python-build, so later runs
# are incremental), then pytest. Exit 77 (skipped) only when PyPI cannot be reached and
# scikit-build-core is not installed yet, or when a MODULE the test file needs is missing.
# Usage: run_python_tests.sh [--install-only] SOURCE_DIR BUILD_DIR HNNSTEREO_BINARY
#            [TEST_FILE [MODULE...]]
# --install-only: the venv and the module, no tests (scripts/test.sh builds the module with the
# rest, before CTest, and then sets HNNSTEREO_PYTHON_INSTALLED=1: the test runs pytest only).
# TEST_FILE: the file under tests/python that pytest runs (default test_hnnstereo.py); MODULEs:
# what it needs beyond numpy, cv2 and pytest - exit 77 (skipped) when one cannot be imported.
set -euo pipefail
install_only=0
if [ "${1:-}" = --install-only ]; then install_only=1; shift; fi
source_dir=$1
build_dir=$2
export HNNSTEREO_BINARY=$3
test_file=$source_dir/tests/python/${4:-test_hnnstereo.py}
needed_modules=("${@:5}")
export HNNSTEREO_SOURCE_DIR=$source_dir
venv=$build_dir/python-venv
python=/usr/bin/python3  # Debian's: numpy and cv2 are its packages (not a pyenv python on PATH)
[ -x "$python" ] || python=python3

if [ ! -x "$venv/bin/python" ]; then
  "$python" -m venv --system-site-packages "$venv"
fi
if ! "$venv/bin/python" -c "import scikit_build_core" 2>/dev/null; then
  if ! "$venv/bin/pip" install --quiet --disable-pip-version-check --timeout 30 \
      "scikit-build-core>=0.8" 2>"$build_dir/python-venv-pip.log"; then
    echo "SKIPPED: PyPI is unreachable, scikit-build-core cannot be installed" \
         "($(tail -n 1 "$build_dir/python-venv-pip.log"))"
    exit 77
  fi
fi
for module in numpy cv2 pytest; do
  "$venv/bin/python" -c "import $module" ||
    { echo "the venv lacks $module: run scripts/setup.sh (python3-numpy python3-opencv python3-pytest)"; exit 1; }
done
for module in "${needed_modules[@]}"; do
  "$venv/bin/python" -c "import $module" 2>/dev/null ||
    { echo "SKIPPED: the venv lacks $module (scripts/setup.sh installs it)"; exit 77; }
done

if [ "${HNNSTEREO_PYTHON_INSTALLED:-}" = 1 ] && ((!install_only)); then
  cd "$build_dir"
  exec "$venv/bin/python" -m pytest -q -p no:cacheprovider "$test_file"
fi

launcher=()
if command -v ccache >/dev/null; then
  launcher=(--config-settings=cmake.define.CMAKE_CXX_COMPILER_LAUNCHER=ccache)
  # Paths relative to the source tree in ccache's keys: a fresh clone (another folder) finds the
  # objects of an earlier clone's module build instead of compiling every library again.
  export CCACHE_BASEDIR=${CCACHE_BASEDIR:-$source_dir} CCACHE_NOHASHDIR=${CCACHE_NOHASHDIR:-1}
fi
start=$SECONDS
# No build isolation: the build requirement (scikit-build-core) is in the venv, so no network is
# needed after the first run; the build directory is kept for incremental rebuilds.
CMAKE_BUILD_PARALLEL_LEVEL=${CMAKE_BUILD_PARALLEL_LEVEL:-2} \
  "$venv/bin/pip" install --quiet --disable-pip-version-check --no-build-isolation --no-deps \
  --config-settings=build-dir="$build_dir/python-build" "${launcher[@]}" "$source_dir"
echo "pip install: $((SECONDS - start)) s"
if ((install_only)); then exit 0; fi
cd "$build_dir"
exec "$venv/bin/python" -m pytest -q -p no:cacheprovider "$test_file"
