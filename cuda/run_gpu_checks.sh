#!/usr/bin/env bash
# GPU machine (CUDA + CMake >= 3.18, no ROS/PCL/Eigen): the project's core-only build with the CUDA
# library (-DGF_CORE_ONLY=ON -DGF_CUDA=ON), its GPU tests and the benchmark, then the GPU tests
# (ctest) and the benchmark table. Needs the carry folder (default .carry):
#   .carry/googletest  (Debian's /usr/src/googletest)   .carry/eigen3/Eigen  (/usr/include/eigen3)
#   .carry/nanoflann/nanoflann.hpp                      .carry/data/00000[0-5].bin (KITTI seq 00)
#   .carry/data/os128_000000.bin (optional: the Ouster frame as KITTI-style x y z 0 records)
# Usage: [GF_CMAKE_ARGS="-DCMAKE_CUDA_ARCHITECTURES=90"] [GF_TRACE=1] bash cuda/run_gpu_checks.sh
#        [benchmark args]
# Logs go to $OUT (the device tool's output folder) or build-cuda/logs. GF_TRACE=1 also runs the
# benchmark once under the CUPTI tracer (cuda/bench/cupti_trace.cpp, built here with g++) into
# gpu_trace.txt.gz and prints scripts/gpu_trace_gaps.py's medians for the KITTI frame.
set -uo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
CARRY="${GF_CARRY:-${PWD}/.carry}"
LOG="${OUT:-${PWD}/build-cuda/logs}"
mkdir -p "${LOG}"
{ nvidia-smi --query-gpu=name,driver_version,memory.total,clocks.sm,clocks.max.sm --format=csv
  nvcc --version | tail -2; cmake --version | head -1; nproc; } > "${LOG}/env.txt" 2>&1
gen=(); command -v ninja > /dev/null && gen=(-G Ninja)
# The GPU's targets and tests only (the core's own gtests run in CI).
GPU_TARGETS="test_cuda_knn test_gpu_neighbor_search test_gpu_pipeline test_gpu_fallback bench_gpu_knn
  bench_graph_probe ground_filter_scale_benchmark"
GPU_TESTS="cuda_knn|gpu_neighbor_search|gpu_pipeline|test_gpu_fallback"
# shellcheck disable=SC2086  # GF_CMAKE_ARGS: several words on purpose
cmake -S . -B build-cuda "${gen[@]}" -DCMAKE_BUILD_TYPE=Release -DGF_CORE_ONLY=ON -DGF_CUDA=ON \
  -DGF_EIGEN_DIR="${CARRY}/eigen3" -DGF_GTEST_DIR="${CARRY}/googletest" \
  -DGF_DATA_DIR="${CARRY}/data" ${GF_CMAKE_ARGS:-} > "${LOG}/build.log" 2>&1 &&
  cmake --build build-cuda -j "$(nproc)" --target ${GPU_TARGETS} >> "${LOG}/build.log" 2>&1
build_rc=$?
if [ "${build_rc}" != "0" ]; then tail -40 "${LOG}/build.log"; echo "BUILD FAILED"; exit 1; fi
(cd build-cuda && ctest -V --timeout 300 -R "^(${GPU_TESTS})\$") > "${LOG}/ctest.log" 2>&1
test_rc=$?
grep -hE "^\[ +(KITTI|5M|FILTER) +\]|tests passed|FAILED|Failure|mismatch" \
  "${LOG}/ctest.log" | head -40
build-cuda/bench_gpu_knn "$@" > "${LOG}/bench.log" 2> "${LOG}/bench.err"
bench_rc=$?
cat "${LOG}/bench.log"; tail -5 "${LOG}/bench.err"
if [ "${GF_TRACE:-0}" = "1" ]; then
  # CUPTI's headers and library lie under the toolkit's targets/<arch>/; its record structs
  # carry a version in their names: the newest that the headers declare.
  cuda_root="$(dirname "$(dirname "$(command -v nvcc)")")"
  cupti_h="$(find -L "${cuda_root}" -name cupti.h -path "*include*" | head -1)"
  cupti_so="$(find -L "${cuda_root}" -name "libcupti.so" | head -1)"
  inc="$(dirname "${cupti_h}")"
  rec() { grep -ho "} CUpti_Activity$1[0-9]*;" "${inc}"/*.h | tr -d '}; ' | sort -V | tail -1; }
  g++ -O2 -shared -fPIC -DKREC="$(rec Kernel)" -DMREC="$(rec Memcpy)" -DSREC="$(rec Memset)" \
    -I"${inc}" cuda/bench/cupti_trace.cpp -L"$(dirname "${cupti_so}")" -lcupti \
    -Wl,-rpath,"$(dirname "${cupti_so}")" -o build-cuda/libgf_cupti_trace.so &&
    GF_TRACE_OUT="${LOG}/gpu_trace.txt" CUDA_INJECTION64_PATH="${PWD}/build-cuda/libgf_cupti_trace.so" \
      build-cuda/bench_gpu_knn "$@" > "${LOG}/bench_traced.log" 2>&1 &&
    gzip -f "${LOG}/gpu_trace.txt" &&
    python3 scripts/gpu_trace_gaps.py "${LOG}/gpu_trace.txt.gz" --show 0 \
      --points "$(($(stat -c %s "${CARRY}/data/000000.bin") / 16))" ||
    echo "GF_TRACE: the trace failed (${LOG}/bench_traced.log)"
fi
echo "ctest rc=${test_rc} bench rc=${bench_rc}"
[ "${test_rc}" = "0" ] && [ "${bench_rc}" = "0" ]
