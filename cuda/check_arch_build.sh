#!/bin/bash
# Builds the CUDA library (core-only configuration, no ROS, PCL or GPU needed) for the given
# architectures with a given nvcc, and prints what came out: the nvcc version, the kernel objects
# per architecture and the library's size. For a Jetson build checked on a desktop (Orin: 87 with
# CUDA 11.4 or later; Xavier: 72, which CUDA 13 no longer compiles: use a CUDA 11 or 12 nvcc).
#
#   bash cuda/check_arch_build.sh 87
#   NVCC=/path/to/cuda-11/bin/nvcc HOST_CXX=g++-11 bash cuda/check_arch_build.sh 72
#
# NVCC: the nvcc (default: the one CMake finds); HOST_CXX: its host compiler (CUDA 11.x
# accepts up to GCC 11); CUDA_ROOT: the toolkit's include/ and lib/ (a scattered install such
# as Debian's unpacked nvidia-cuda-toolkit: ROOT/usr/include, ROOT/usr/lib/x86_64-linux-gnu);
# CUOBJDUMP (default: beside nvcc, else on PATH); BUILD_DIR (default build-arch-ARCHS).
# docs/gpu.md "Build options" gives the figures.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
if [ $# -ne 1 ] || [ "$1" = "--help" ]; then
  sed -n '2,14p' "$0" | sed 's/^# \{0,1\}//'
  exit 2
fi
ARCHS="$1"
BUILD="${BUILD_DIR:-build-arch-${ARCHS//;/-}}"
args=(-DGF_CORE_ONLY=ON -DGF_CUDA=ON -DCMAKE_BUILD_TYPE=Release
      "-DCMAKE_CUDA_ARCHITECTURES=${ARCHS}")
[ -n "${NVCC:-}" ] && args+=("-DCMAKE_CUDA_COMPILER=${NVCC}")
[ -n "${HOST_CXX:-}" ] && args+=("-DCMAKE_CUDA_HOST_COMPILER=${HOST_CXX}")
if [ -n "${CUDA_ROOT:-}" ]; then
  lib="${CUDA_ROOT}/usr/lib/x86_64-linux-gnu"
  [ -d "${lib}" ] || lib="${CUDA_ROOT}/lib64"
  inc="${CUDA_ROOT}/usr/include"
  [ -f "${inc}/cuda_runtime.h" ] || inc="${CUDA_ROOT}/include"
  args+=("-DCUDAToolkit_INCLUDE_DIR=${inc}" "-DCUDA_CUDART=${lib}/libcudart.so"
         "-DCUDA_cudart_static_LIBRARY=${lib}/libcudart_static.a"
         "-DCUDAToolkit_LIBRARY_DIR=${lib}")
fi
cmake -S . -B "${BUILD}" "${args[@]}" > "${BUILD}.configure.log" 2>&1 ||
  { tail -20 "${BUILD}.configure.log"; echo "configure failed"; exit 1; }
cmake --build "${BUILD}" -j "$(nproc)" --target ground_filter_cuda > "${BUILD}.build.log" 2>&1 ||
  { tail -20 "${BUILD}.build.log"; echo "build failed"; exit 1; }
lib_a=$(find "${BUILD}" -name libground_filter_cuda.a | head -1)
# GF_CUDA=ON enables the CUDA language (configure fails without it): the cache names the nvcc.
nvcc_bin=$(sed -n 's/^CMAKE_CUDA_COMPILER:[A-Z]*=//p' "${BUILD}/CMakeCache.txt")
echo "nvcc: $("${nvcc_bin}" --version | tail -1)"
echo "architectures asked: ${ARCHS}"
objdump_bin="${CUOBJDUMP:-$(dirname "$(readlink -f "${nvcc_bin}")")/cuobjdump}"
command -v "${objdump_bin}" > /dev/null 2>&1 || objdump_bin=cuobjdump
if command -v "${objdump_bin}" > /dev/null 2>&1; then
  echo "kernel objects per architecture (cuobjdump -lelf):"
  "${objdump_bin}" -lelf "${lib_a}" | grep -o 'sm_[0-9a-z]*' | sort | uniq -c
else
  echo "no cuobjdump (set CUOBJDUMP): kernel objects not listed"
fi
echo "library: ${lib_a}: $(stat -c %s "${lib_a}") bytes"
size -t "${lib_a}" | tail -1 | awk '{printf "text %d bytes, data %d, bss %d\n", $1, $2, $3}'
