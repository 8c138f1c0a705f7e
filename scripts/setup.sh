#!/usr/bin/env bash
# Installs the system dependencies (Debian 12 packages) and builds hnnstereo into build/.
# Idempotent: packages already present are not reinstalled; the build is incremental.
set -euo pipefail
cd "$(dirname "$0")/.."

PACKAGES=(cmake g++ ninja-build pkg-config
  pocl-opencl-icd ocl-icd-opencl-dev opencl-headers opencl-clhpp-headers clinfo
  libopencv-dev libeigen3-dev libgtest-dev libgmock-dev libbenchmark-dev
  libcli11-dev nlohmann-json3-dev libcpp-httplib-dev
  libmodbus-dev python3-pymodbus python3-serial python3-serial-asyncio mbpoll socat
  python3-dev python3-venv pybind11-dev python3-numpy python3-opencv python3-pytest python3-pil
  python3-distributed python3-dask  # python -m hnnstereo.batch and its test (pip .[batch] elsewhere)
  chromium)  # chromium: only the web page's browser test (tests/web/cell_page_cli_test.cc)

# scripts/fuzz.sh: clang (libFuzzer) only when asked for.
if [ -n "${HNNSTEREO_FUZZ:-}" ]; then PACKAGES+=(clang); fi

missing=()
for package in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$package" 2>/dev/null | grep -q "install ok installed" ||
    missing+=("$package")
done
if ((${#missing[@]})); then
  echo "setup: installing ${missing[*]}" >&2
  SUDO=""
  if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

# scripts/fuzz.sh configures and builds its own folder: packages only.
if [ -n "${HNNSTEREO_SETUP_PACKAGES_ONLY:-}" ]; then exit 0; fi

BUILD_DIR=${BUILD_DIR:-build}
if [ ! -f "$BUILD_DIR/CMakeCache.txt" ]; then
  cmake -S . -B "$BUILD_DIR" -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
fi
# scripts/test.sh --sanitize: the sanitizer build (its own BUILD_DIR), set on every run so that a
# folder configured before keeps the requested sanitizers.
if [ -n "${HNNSTEREO_SANITIZE:-}" ]; then
  cmake -S . -B "$BUILD_DIR" -DHNNSTEREO_SANITIZE="$HNNSTEREO_SANITIZE" >/dev/null
fi
# Two cores: keep the build within memory and time.
cmake --build "$BUILD_DIR" -j "${BUILD_JOBS:-2}"
