#!/usr/bin/env bash
# Extra CI steps of scripts/run_tests.sh (sourced after scripts/common.sh). Each writes JUnit
# results into $1 (the catkin test results folder), so scripts/test_summary.py counts them.

GF_JUNIT="${GF_ROOT}/scripts/junit_result.py"

# The Noetic/focal path where it can be reproduced here: nanoflann hidden, the cuda/ guard forced
# to its "CMake too old" branch (focal has CMake 3.16; cuda/ needs 3.18), only the core and the
# kd-tree test built (separate workspace .ws_focal/), and the installed headers in C++14.
gf_check_focal_like() {
  local results="$1" ws="${GF_ROOT}/.ws_focal" log
  mkdir -p "${ws}/src"
  ln -sfn "${GF_ROOT}" "${ws}/src/ground_filter"
  log="${ws}/focal_like.log"
  echo "[ci] focal-like: configure without nanoflann, cuda/ guard forced; build core + kd-tree test"
  # --force-cmake: configure every time, so its status lines are in this log.
  if ! (cd "${ws}" && catkin_make --force-cmake -DCMAKE_BUILD_TYPE=Release \
          -DCMAKE_DISABLE_FIND_PACKAGE_nanoflann=ON -DGF_CUDA_MIN_CMAKE=99 \
          ground_filter_core test_kdtree_neighbor_search -j"$(nproc 2>/dev/null || echo 2)") \
        >"${log}" 2>&1; then
    python3 "${GF_JUNIT}" "${results}/ci-focal_like_build.xml" focal_like configure_build failed \
      "configure/build failed: $(tail -n 20 "${log}")"
    return 0
  fi
  local cuda_line nano_line
  cuda_line="$(grep -m1 "ground_filter: CUDA KNN backend:" "${log}")"
  nano_line="$(grep -m1 "ground_filter: nanoflann not found" "${log}")"
  if [[ "${cuda_line}" == *"OFF (CMake "*" is older than 99"* && -n "${nano_line}" ]]; then
    python3 "${GF_JUNIT}" "${results}/ci-focal_like_build.xml" focal_like configure_build passed \
      "${cuda_line#-- }; ${nano_line#-- }"
  else
    python3 "${GF_JUNIT}" "${results}/ci-focal_like_build.xml" focal_like configure_build failed \
      "expected the cuda/ guard's reason and 'nanoflann not found', got: '${cuda_line}' '${nano_line}'"
  fi
  # The kd-tree test: every test passes except the nanoflann comparison, which is skipped.
  local xml="${results}/gtest-focal_like_kdtree.xml"
  "${ws}/devel/lib/ground_filter/test_kdtree_neighbor_search" --gtest_output="xml:${xml}" \
    >"${ws}/focal_like_test.log" 2>&1
  local rc=$?
  if [ "${rc}" = "0" ] && grep -q "nanoflann not found at configure time" "${ws}/focal_like_test.log"; then
    python3 "${GF_JUNIT}" "${results}/ci-focal_like_skip.xml" focal_like nanoflann_test_skipped \
      passed "kd-tree tests pass, KittiFrameMatchesNanoflann skipped with its reason"
  else
    python3 "${GF_JUNIT}" "${results}/ci-focal_like_skip.xml" focal_like nanoflann_test_skipped \
      failed "exit ${rc}: $(tail -n 20 "${ws}/focal_like_test.log")"
  fi
  # Installed headers (install(DIRECTORY include/ground_filter/), subfolders included) in C++14
  # (focal's default GCC 9 and downstream packages that stay on C++14), each on its own with only
  # include/ on the path: a public header that includes a private one (src/) fails here.
  local bad=() rel pcl_inc headers
  pcl_inc="$(ls -d /usr/include/pcl-1.* 2>/dev/null | sort -V | tail -n 1)"
  headers="$(cd "${GF_ROOT}/include" && find ground_filter -name '*.h' | sort)"
  : >"${ws}/cxx14.log"
  for rel in ${headers}; do
    if ! echo "#include <${rel}>" | g++ -std=c++14 -fsyntax-only \
          -x c++ -I"${GF_ROOT}/include" -isystem /usr/include/eigen3 ${pcl_inc:+-isystem "${pcl_inc}"} - \
          >>"${ws}/cxx14.log" 2>&1; then
      bad+=("${rel}")
    fi
  done
  if [ ${#bad[@]} -eq 0 ]; then
    python3 "${GF_JUNIT}" "${results}/ci-cxx14_headers.xml" focal_like cxx14_headers passed \
      "$(echo "${headers}" | wc -l) headers compile alone with -std=c++14"
  else
    python3 "${GF_JUNIT}" "${results}/ci-cxx14_headers.xml" focal_like cxx14_headers failed \
      "not C++14: ${bad[*]} (see ${ws}/cxx14.log)"
  fi
}

# A container whose hostname does not resolve and an unresolvable ROS_HOSTNAME: demo.sh and the
# Python launch helpers must still run (ROS on loopback). Needs `unshare --uts` (root).
gf_check_container() {
  local results="$1" out name status detail
  if ! unshare --uts true 2>/dev/null; then
    python3 "${GF_JUNIT}" "${results}/ci-container.xml" container unresolvable_hostname skipped \
      "unshare --uts not permitted here (needs root or user namespaces)"
    return 0
  fi
  echo "[ci] container: unresolvable hostname and ROS_HOSTNAME (unshare --uts)"
  out="$(unshare --uts --fork bash -c \
    'hostname gf-unresolvable-host && exec bash "$0"' "${GF_ROOT}/scripts/ci_container_check.sh")"
  echo "${out}" | grep "^CHECK " || echo "${out}" | tail -n 20
  while read -r _ name status detail; do
    python3 "${GF_JUNIT}" "${results}/ci-container_${name}.xml" container "${name}" "${status}" \
      "${detail}" >/dev/null
  done < <(echo "${out}" | grep "^CHECK ")
  if ! echo "${out}" | grep -q "^CHECK "; then
    python3 "${GF_JUNIT}" "${results}/ci-container.xml" container unresolvable_hostname failed \
      "no result lines: $(echo "${out}" | tail -n 10)"
  fi
}

# The CUDA architecture default (cmake/gf_cuda.cmake) for toolkits and CMake versions this machine
# does not have: a fake JetPack 5 nvcc (CUDA 11.4, up to sm_87), an nvcc without
# --list-gpu-arch, CMake 3.20 (list) and 3.25 (all-major). Script mode, about a second.
gf_check_cuda_archs() {
  local results="$1" dir out expected
  dir="$(mktemp -d /tmp/gf_cuda_archs_XXXXXX)"
  cat >"${dir}/nvcc_jetpack5" <<'SH'
#!/bin/sh
case "$1" in
  --version) echo "Cuda compilation tools, release 11.4, V11.4.315" ;;
  --list-gpu-arch) printf 'compute_53\ncompute_62\ncompute_72\ncompute_75\ncompute_80\ncompute_86\ncompute_87\n' ;;
  *) exit 1 ;;
esac
SH
  printf '#!/bin/sh\n[ "$1" = --version ] && echo "Cuda compilation tools, release 10.2, V10.2.89" && exit 0\nexit 1\n' \
    >"${dir}/nvcc_old"
  chmod +x "${dir}/nvcc_jetpack5" "${dir}/nvcc_old"
  cat >"${dir}/t.cmake" <<EOF2
include("${GF_ROOT}/cmake/gf_cuda.cmake")
set(CMAKE_VERSION 3.20.0)
gf_cuda_default_architectures("${dir}/nvcc_jetpack5" a)
gf_cuda_default_architectures("${dir}/nvcc_old" b)
gf_nvcc_version("${dir}/nvcc_jetpack5" va)
gf_nvcc_version("${dir}/nvcc_old" vb)
set(CMAKE_VERSION 3.25.1)
gf_cuda_default_architectures("${dir}/nvcc_jetpack5" c)
message("RESULT|\${a}|\${b}|\${va}|\${vb}|\${c}")
EOF2
  out="$(cmake -P "${dir}/t.cmake" 2>&1 | grep '^RESULT|')"
  expected="RESULT|72-real;75-real;80-real;86-real;87|72-real;75-real;80-real;86-real;87-real;89-real;90|11.4|10.2|all-major"
  rm -rf "${dir}"
  if [ "${out}" = "${expected}" ]; then
    python3 "${GF_JUNIT}" "${results}/ci-cuda_archs.xml" cuda_guard default_architectures passed \
      "JetPack 5 nvcc + CMake 3.20: 72-real;75-real;80-real;86-real;87; no --list-gpu-arch: full list; CMake >= 3.23: all-major"
  else
    python3 "${GF_JUNIT}" "${results}/ci-cuda_archs.xml" cuda_guard default_architectures failed \
      "got '${out}', expected '${expected}'"
  fi
}
