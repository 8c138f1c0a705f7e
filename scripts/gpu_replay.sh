#!/usr/bin/env bash
# The engine on another OpenCL device (a GPU) without the image libraries: capture the networks
# of the benchmark cases here, carry them with hnnstereo_replay and the OpenCL engine test to
# the machine with the device, replay them there (docs/benchmark.md, "On a GPU").
#
#   scripts/gpu_replay.sh pack [BUILD_DIR] [PACK_DIR]   # here: build/ -> .gpu/ (git-ignored)
#   scripts/gpu_replay.sh run [PACK_DIR] [OUT_DIR]      # there: replay, engine tests -> OUT_DIR
#
# pack: `hnnstereo match --save-network` on the vendored Teddy pair for sparse-2000,
# sparse-5000, all features (the default match) and the dense 60 x 60 network; the binaries
# hnnstereo_replay and host_opencl_engine_test (they link only libOpenCL, which is copied).
# run: finds the NVIDIA OpenCL driver (libnvidia-opencl.so.1) when no ICD names one, then
# replays every network with every weight storage and the cpu reference (winners compared),
# profiles the two large cases, and runs the OpenCL engine tests against the GPU.
set -euo pipefail
cd "$(dirname "$0")/.."
mode=${1:?pack or run}
case "$mode" in
  pack)
    build=${2:-build}
    pack=${3:-.gpu}
    rm -rf "$pack" && mkdir -p "$pack/bin" "$pack/lib" "$pack/net"
    teddy=tests/data/middlebury2003_teddy
    export POCL_CACHE_DIR=${POCL_CACHE_DIR:-$PWD/$build/pocl-cache}
    match() {
      "$build/hnnstereo" match --left $teddy/im2.png --right $teddy/im6.png --rectified \
        --max-disparity 64 --out "$pack/net/$1.csv" --save-network "$pack/net/$1.hnnet" --quiet \
        "${@:2}"
      rm -f "$pack/net/$1.csv"
    }
    match sparse-2000 --max-features 2000
    match sparse-5000 --max-features 5000
    match teddy-all
    match dense-60x60 --dense --network feature --max-features 60
    cp "$build/perf/hnnstereo_replay" "$build/tests/host/host_opencl_engine_test" "$pack/bin/"
    cp -L "$(ldconfig -p | awk '/libOpenCL.so.1 .*x86-64/ {print $NF; exit}')" "$pack/lib/libOpenCL.so.1"
    du -sh "$pack"
    ;;
  run)
    pack=${2:-.gpu}
    out=${3:-gpu-out}
    mkdir -p "$out"
    export LD_LIBRARY_PATH="$PWD/$pack/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
    export HNNSTEREO_KERNEL_CACHE=/tmp/hnnstereo-kernels
    # The NVIDIA driver's OpenCL library is often mounted without an ICD file naming it (and a
    # CPU ICD such as PoCL may be installed): list it beside the installed ICDs.
    if [ -z "${OCL_ICD_VENDORS:-}" ]; then
      driver=$(ldconfig -p | awk '/libnvidia-opencl.so.1/ {print $NF; exit}')
      [ -n "$driver" ] || driver=$(find /usr /lib /lib64 /opt -maxdepth 5 -name 'libnvidia-opencl.so*' 2>/dev/null | head -1)
      mkdir -p /tmp/icd
      cp /etc/OpenCL/vendors/*.icd /tmp/icd/ 2>/dev/null || true
      if [ -n "$driver" ]; then
        echo "$driver" >/tmp/icd/nvidia.icd
        echo "gpu_replay: NVIDIA OpenCL driver $driver"
      else
        echo "gpu_replay: no NVIDIA OpenCL driver (libnvidia-opencl.so*) found"
      fi
      export OCL_ICD_VENDORS=/tmp/icd
    fi
    nvidia-smi -L 2>/dev/null || true
    bin="$pack/bin"
    "$bin/hnnstereo_replay" "$pack"/net/*.hnnet --cpu --repeats 5 \
      --storages auto,csr,blocked-float,blocked-half,on-the-fly --out "$out/replay.json" \
      2>&1 | tee "$out/replay.txt"
    # The row blocks' step as before this kernel existed (one row per work-item), same run.
    "$bin/hnnstereo_replay" "$pack"/net/*.hnnet --storages blocked-float,blocked-half,on-the-fly \
      --block-step item --repeats 5 --out "$out/replay_item.json" 2>&1 | tee "$out/replay_item.txt"
    "$bin/hnnstereo_replay" "$pack/net/sparse-5000.hnnet" "$pack/net/teddy-all.hnnet" \
      --storages blocked-half,blocked-float,on-the-fly --repeats 3 --profile \
      --out "$out/profile.json" >"$out/profile.txt" 2>&1 || true
    "$bin/host_opencl_engine_test" --gtest_output="json:$out/engine_test.json" \
      >"$out/engine_test.txt" 2>&1 || echo "gpu_replay: engine tests FAILED (see engine_test.txt)"
    tail -3 "$out/engine_test.txt"
    ;;
  *) echo "gpu_replay.sh: pack or run" >&2; exit 2 ;;
esac
