# Part of -DGF_CORE_ONLY=ON -DGF_SANITIZE=ON (cmake/gf_core_only.cmake, clang): the libFuzzer
# target over the serialised-PointCloud2 path and the link options of the sanitized gtests.

# point_cloud2{,_check}.cpp and cloud_pool.cpp need only message headers and roscpp_serialization (no ROS graph).
find_library(ROSCPP_SERIALIZATION roscpp_serialization REQUIRED)
find_library(ROSTIME rostime REQUIRED)
find_library(CPP_COMMON cpp_common REQUIRED)
add_library(gf_pointcloud2_san STATIC "${GF_SOURCE_ROOT}/src/nodelets/point_cloud2.cpp"
  "${GF_SOURCE_ROOT}/src/nodelets/point_cloud2_check.cpp"
  "${GF_SOURCE_ROOT}/src/nodelets/cloud_pool.cpp")
target_compile_options(gf_pointcloud2_san PRIVATE -fsanitize=fuzzer-no-link)
target_link_libraries(gf_pointcloud2_san PUBLIC ground_filter_core ${ROSCPP_SERIALIZATION}
  ${ROSTIME} ${CPP_COMMON})
add_executable(fuzz_point_cloud2 "${GF_SOURCE_ROOT}/test/fuzz_point_cloud2.cpp")
target_include_directories(fuzz_point_cloud2 PRIVATE "${GF_SOURCE_ROOT}/src/nodelets")
target_compile_options(fuzz_point_cloud2 PRIVATE -fsanitize=fuzzer)
target_link_options(fuzz_point_cloud2 PRIVATE -fsanitize=fuzzer)
target_link_libraries(fuzz_point_cloud2 gf_pointcloud2_san)

# test/gf_test_alloc_counter.h replaces the global operator new/delete. clang's static ASan
# runtime defines them too: weak from LLVM 12 on (the test's win), strong in LLVM 11 (Debian 11):
# "multiple definition of operator new". There the tests link the shared runtime instead, whose
# operators the executable's own override (found on the runtime's folder by an rpath).
include(CheckCXXSourceCompiles)
set(CMAKE_REQUIRED_FLAGS -fsanitize=address)
set(CMAKE_REQUIRED_LINK_OPTIONS -fsanitize=address)
set(CMAKE_REQUIRED_QUIET ON)
check_cxx_source_compiles("#include <cstdlib>
  #include <new>
  void* operator new(std::size_t n) { return std::malloc(n ? n : 1); }
  void operator delete(void* p) noexcept { std::free(p); }
  int main() { delete new int(1); return 0; }" GF_ASAN_STATIC_NEW_REPLACEABLE)
unset(CMAKE_REQUIRED_FLAGS)
unset(CMAKE_REQUIRED_LINK_OPTIONS)
unset(CMAKE_REQUIRED_QUIET)
if(NOT GF_ASAN_STATIC_NEW_REPLACEABLE)
  execute_process(COMMAND ${CMAKE_CXX_COMPILER}
    -print-file-name=libclang_rt.asan-${CMAKE_SYSTEM_PROCESSOR}.so
    OUTPUT_VARIABLE gf_asan_so OUTPUT_STRIP_TRAILING_WHITESPACE)
  if(NOT IS_ABSOLUTE "${gf_asan_so}" OR NOT EXISTS "${gf_asan_so}")
    message(FATAL_ERROR "clang ${CMAKE_CXX_COMPILER_VERSION}: a replaced operator new does not "
      "link with the static ASan runtime, and the shared one was not found ('${gf_asan_so}')")
  endif()
  get_filename_component(gf_asan_dir "${gf_asan_so}" DIRECTORY)
  set(GF_TEST_LINK -shared-libsan "-Wl,-rpath,${gf_asan_dir}")
  message(STATUS "ground_filter: clang ${CMAKE_CXX_COMPILER_VERSION}: the gtests link the shared "
                 "ASan runtime (${gf_asan_so}): its static operator new is not replaceable")
endif()
