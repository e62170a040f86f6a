# -DGF_CORE_ONLY=ON: the ROS/PCL-free core, the evaluation kit without scan files and the core's
# gtests, without catkin, ROS or PCL (included by CMakeLists.txt, which stops after it):
#
#   cmake -S . -B build-core -DGF_CORE_ONLY=ON [-DCMAKE_TOOLCHAIN_FILE=cmake/aarch64_toolchain.cmake]
#   cmake --build build-core -j2 && (cd build-core && ctest)
#
# for another architecture (scripts/check_arm64.sh: aarch64 under qemu-user), the compiler floor
# (scripts/check_gcc9.sh) or any machine without ROS. With -DGF_SANITIZE=ON (clang only,
# scripts/sanitize.sh): everything under -fsanitize=address,undefined, the gtests as asan_<name>,
# and the libFuzzer target fuzz_point_cloud2 (scripts/fuzz.sh; needs roscpp_serialization).
#
# With -DGF_CUDA=ON (CMake >= 3.18 and nvcc; cuda/run_gpu_checks.sh on the GPU machine, which has
# no ROS, PCL or Eigen package: it passes the carry folder's Eigen, googletest and data): the
# CUDA library inside the core, as the catkin build has it, plus its GPU tests and benchmarks
# (cmake/gf_cuda_checks.cmake).
#
# GF_EIGEN_DIR: Eigen's headers (header-only: the host's serve any target), default
# /usr/include/eigen3; GF_GTEST_DIR: googletest sources (Debian's package googletest), default
# /usr/src/googletest; GF_DATA_DIR: the data folder (default: $GF_DATA_DIR, else data/, else
# ../shared/data; the data tests skip with the reason without it).
set(GF_EIGEN_DIR /usr/include/eigen3 CACHE PATH "Eigen 3 headers")
set(GF_GTEST_DIR /usr/src/googletest CACHE PATH "googletest sources")
include(${GF_SOURCE_ROOT}/cmake/ground_filter_data_dir.cmake)
if(NOT GF_DATA_DIR)
  gf_resolve_data_dir("${GF_SOURCE_ROOT}" GF_DATA_DIR)
endif()
message(STATUS "ground_filter core: test data folder ${GF_DATA_DIR}")
find_package(OpenMP REQUIRED)
find_package(Threads REQUIRED)

set(GF_TEST_PREFIX "")
if(GF_SANITIZE)
  if(NOT CMAKE_CXX_COMPILER_ID STREQUAL "Clang")
    message(FATAL_ERROR "GF_SANITIZE: configure with CXX=clang++ (libFuzzer needs clang)")
  endif()
  # -O1 keeps the sanitized tests fast enough; UB is fatal so a test or fuzz run cannot miss it.
  add_compile_options(-g -O1 -fno-omit-frame-pointer -fsanitize=address,undefined
                      -fno-sanitize-recover=undefined)
  add_link_options(-fsanitize=address,undefined)
  set(GF_TEST_PREFIX asan_)
endif()

if(GF_CUDA)
  if(CMAKE_VERSION VERSION_LESS 3.18)
    message(FATAL_ERROR "GF_CUDA needs CMake 3.18 (language CUDA), this is ${CMAKE_VERSION}")
  endif()
  set(gf_archs_given OFF)
  if(DEFINED CMAKE_CUDA_ARCHITECTURES)  # -DCMAKE_CUDA_ARCHITECTURES=... wins
    set(gf_archs_given ON)
  endif()
  enable_language(CUDA)
  if(NOT gf_archs_given)  # the catkin build's default (cmake/gf_cuda.cmake)
    include(${GF_SOURCE_ROOT}/cmake/gf_cuda.cmake)
    gf_cuda_default_architectures("${CMAKE_CUDA_COMPILER}" CMAKE_CUDA_ARCHITECTURES)
  endif()
  add_subdirectory(${GF_SOURCE_ROOT}/cuda ${CMAKE_BINARY_DIR}/cuda)
  find_package(CUDAToolkit REQUIRED)  # CUDA::cudart_static for the GPU tests, at this level too
endif()

# The same sources and code-generation flags as the catkin build's core, static here.
if(GF_CUDA)
  gf_add_core(ground_filter_core STATIC EIGEN ${GF_EIGEN_DIR})
  target_compile_definitions(ground_filter_core PUBLIC GROUND_FILTER_HAVE_CUDA)
  target_link_libraries(ground_filter_core PUBLIC ground_filter_cuda)
else()
  gf_add_core(ground_filter_core STATIC EIGEN ${GF_EIGEN_DIR} EXTRA ${GF_CORE_NO_CUDA_SOURCES})
endif()
gf_add_eval_kit(ground_filter_eval_kit ground_filter_core)

set(INSTALL_GTEST OFF CACHE BOOL "" FORCE)
set(BUILD_GMOCK OFF CACHE BOOL "" FORCE)
set(CMAKE_POLICY_VERSION_MINIMUM 3.5)  # googletest 1.12 asks for 3.5; CMake 4 needs >= 3.5
add_subdirectory(${GF_GTEST_DIR} ${CMAKE_BINARY_DIR}/googletest EXCLUDE_FROM_ALL)

set(GF_TEST_LINK "")
if(GF_SANITIZE)
  # Coverage for the fuzzer without pulling libFuzzer's main() into the gtests.
  target_compile_options(ground_filter_core PRIVATE -fsanitize=fuzzer-no-link)
  include(${GF_SOURCE_ROOT}/cmake/gf_sanitize.cmake)  # fuzz_point_cloud2, GF_TEST_LINK
endif()

enable_testing()
# gf_core_test(<name> <source> [gtest_main]): a gtest of the core (tests reach private headers).
function(gf_core_test name source)
  set(target ${GF_TEST_PREFIX}${name})
  add_executable(${target} ${GF_SOURCE_ROOT}/test/${source})
  target_include_directories(${target} PRIVATE ${GF_SOURCE_ROOT}/test)
  target_link_libraries(${target} ground_filter_eval_kit ground_filter_core_private gtest ${ARGN})
  target_link_options(${target} PRIVATE ${GF_TEST_LINK})
  target_compile_definitions(${target} PRIVATE GF_DATA_DIR="${GF_DATA_DIR}")
  # The tests' reference arithmetic (brute-force distances) rounds like the core's: aarch64's
  # compilers fuse a * b + c by default.
  target_compile_options(${target} PRIVATE -ffp-contract=off)
  add_test(NAME ${target} COMMAND ${target})
endfunction()
gf_core_test(test_core test_voxel_ground_filter.cpp gtest_main)
gf_core_test(test_voxel_scale test_voxel_scale.cpp gtest_main)
gf_core_test(test_working_volume test_working_volume.cpp gtest_main)
gf_core_test(test_gpu_fallback test_gpu_fallback.cpp gtest_main)
if(GF_CUDA)  # there it checks the GPU
  target_link_libraries(${GF_TEST_PREFIX}test_gpu_fallback ground_filter_cuda_headers)
  include(${GF_SOURCE_ROOT}/cmake/gf_cuda_checks.cmake)
endif()
gf_core_test(test_scene_generator test_scene_generator.cpp)
gf_core_test(test_height_above_ground test_height_above_ground.cpp gtest_main)
if(NOT GF_SANITIZE)  # long under the sanitizers; the SIMD levels and exact lists run natively
  gf_core_test(test_simd_levels test_simd_levels.cpp gtest_main)
  # Exact neighbour lists of every query code path (here without PCL: KITTI .bin scans only).
  gf_core_test(test_kdtree_neighbor_search test_kdtree_neighbor_search.cpp gtest_main)
  target_compile_definitions(test_kdtree_neighbor_search PRIVATE GF_TEST_NO_SCAN_IO)
  # Labels of KITTI .bin scans with both methods (scripts/check_arm64.sh compares architectures).
  add_executable(label_scans ${GF_SOURCE_ROOT}/test/label_scans.cpp)
  target_link_libraries(label_scans ground_filter_eval_kit ground_filter_core_private)
endif()
