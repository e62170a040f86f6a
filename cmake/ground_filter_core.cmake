# The core library and the evaluation kit, defined once for every build of them: the catkin
# package (CMakeLists.txt), its -DGF_CORE_ONLY=ON build without ROS/PCL (cmake/gf_core_only.cmake:
# cross builds, GCC 9, sanitizers, and with -DGF_CUDA=ON the GPU machine's build).
include(${CMAKE_CURRENT_LIST_DIR}/ground_filter_core_sources.cmake)  # GF_CORE_SOURCES, ...
get_filename_component(GF_SOURCE_ROOT "${CMAKE_CURRENT_LIST_DIR}/.." ABSOLUTE)
include(CheckCXXCompilerFlag)

# Optimised unless told otherwise (tools and benchmarks are only meaningful so), C++17, PIC.
macro(gf_project_defaults)
  if(NOT CMAKE_BUILD_TYPE AND NOT CMAKE_CONFIGURATION_TYPES)
    set(CMAKE_BUILD_TYPE Release CACHE STRING "Build type" FORCE)
  endif()
  set(CMAKE_CXX_STANDARD 17)
  set(CMAKE_CXX_STANDARD_REQUIRED ON)
  set(CMAKE_POSITION_INDEPENDENT_CODE ON)
endmacro()

# gf_add_core(<target> [STATIC|SHARED] EIGEN <dir>... [EXTRA <sources>...]): the ROS/PCL-free
# core (Eigen's headers from <dir>, OpenMP, threads). Private headers (src/core/<room>/*.h, included as
# "voxel/vote.h") are on its own path only; in-tree code that reaches them links the INTERFACE
# target <target>_private.
function(gf_add_core target)
  cmake_parse_arguments(arg "" "" "EIGEN;EXTRA" ${ARGN})
  set(srcs ${GF_CORE_SOURCES} ${arg_EXTRA})
  list(TRANSFORM srcs PREPEND ${GF_SOURCE_ROOT}/)
  add_library(${target} ${arg_UNPARSED_ARGUMENTS} ${srcs})
  target_include_directories(${target} PUBLIC
    $<BUILD_INTERFACE:${GF_SOURCE_ROOT}/include> $<INSTALL_INTERFACE:include>)
  target_include_directories(${target} SYSTEM PUBLIC ${arg_EIGEN})
  target_include_directories(${target} PRIVATE ${GF_SOURCE_ROOT}/src/core)
  target_link_libraries(${target} PUBLIC OpenMP::OpenMP_CXX Threads::Threads)
  target_compile_options(${target} PRIVATE -Wall -Wextra)
  # No a * b + c fused into one FMA: every SIMD level and every architecture rounds alike. On
  # x86-64 nothing is fused anyway (no FMA in the baseline or in the AVX2/AVX-512 target
  # attributes); GCC for aarch64 fuses by default (docs/cpu_support.md).
  target_compile_options(${target} PRIVATE -ffp-contract=off)
  # std::sqrt as the one instruction it is: otherwise GCC tests every argument for a negative
  # value and calls libm to set errno, which nothing here reads. The same values; the kd-tree's
  # query bounds (two square roots a query) and the candidate test use it most
  # (docs/normal_speed.md#the-other-stages).
  target_compile_options(${target} PRIVATE -fno-math-errno)
  # A shared library's own functions are interposable by default under GCC: calls between them
  # go through the PLT and are never inlined (fitHeightPlane() in the ground model's cell loop).
  check_cxx_compiler_flag(-fno-semantic-interposition GF_HAVE_NO_SEMANTIC_INTERPOSITION)
  if(GF_HAVE_NO_SEMANTIC_INTERPOSITION)
    target_compile_options(${target} PRIVATE -fno-semantic-interposition)
  endif()
  # Loop heads on 32-byte boundaries: with GCC's default (16), unchanged code ran 5-9 % slower
  # after edits elsewhere moved it by 224 bytes (the airborne mode's row-minimum loop then
  # crossed a 64-byte line; docs/voxel_method.md, Results 2026-11-26 evening).
  # The airborne surface's opening (morph_ground.cpp) needs 64: its row loops at 32 left the
  # mode 15-20 % slower on the ISPRS tiles after the walled-roof step moved out of that file
  # (docs/evaluation.md, 2026-12-01).
  check_cxx_compiler_flag(-falign-loops=32 GF_HAVE_ALIGN_LOOPS)
  if(GF_HAVE_ALIGN_LOOPS)
    target_compile_options(${target} PRIVATE -falign-loops=32)
    set_source_files_properties(${GF_SOURCE_ROOT}/src/core/airborne/morph_ground.cpp
                                PROPERTIES COMPILE_OPTIONS -falign-loops=64)
  endif()
  add_library(${target}_private INTERFACE)
  target_include_directories(${target}_private INTERFACE ${GF_SOURCE_ROOT}/src/core)
  target_link_libraries(${target}_private INTERFACE ${target})
endfunction()

# gf_add_eval_kit(<target> <core target> [PCL]): the evaluation kit (src/eval/, included as
# "eval/metrics.h"), static: the tools and tests link it, the core and the nodelets never do.
# Scan files (scan_io: KITTI .bin, PCD, PLY) only with PCL (the caller links PCL).
function(gf_add_eval_kit target core)
  set(srcs ${GF_EVAL_KIT_SOURCES})
  if("PCL" IN_LIST ARGN)
    list(APPEND srcs ${GF_EVAL_KIT_PCL_SOURCES})
  endif()
  list(TRANSFORM srcs PREPEND ${GF_SOURCE_ROOT}/)
  add_library(${target} STATIC ${srcs})
  target_include_directories(${target} PUBLIC ${GF_SOURCE_ROOT}/src)
  target_link_libraries(${target} PUBLIC ${core})
  target_compile_options(${target} PRIVATE -Wall -Wextra)
endfunction()
