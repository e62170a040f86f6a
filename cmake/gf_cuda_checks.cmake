# Part of -DGF_CORE_ONLY=ON -DGF_CUDA=ON (cmake/gf_core_only.cmake), the GPU machine's build
# (cuda/run_gpu_checks.sh): the CUDA library's GPU tests, the GPU benchmark and the scale
# benchmark, on the core and evaluation kit that gf_core_only.cmake defines.
set(GF_CUDA_DIR ${GF_SOURCE_ROOT}/cuda)

add_executable(test_cuda_knn ${GF_CUDA_DIR}/test/test_cuda_knn.cpp
  ${GF_CUDA_DIR}/test/brute_force_knn.cpp)
target_link_libraries(test_cuda_knn ground_filter_cuda gtest_main OpenMP::OpenMP_CXX)
target_include_directories(test_cuda_knn PRIVATE ${GF_CUDA_DIR}/src)  # knn_tuning.h: the knobs
target_compile_definitions(test_cuda_knn PRIVATE GF_DATA_DIR="${GF_DATA_DIR}")
add_test(NAME cuda_knn COMMAND test_cuda_knn)

# gf_gpu_check(<name> <source> <links>...): a GPU test or benchmark on the core's private headers
# (kd-tree) and the CUDA library's headers (its interface and adapters).
function(gf_gpu_check name source)
  add_executable(${name} ${source} ${GF_CUDA_DIR}/test/brute_force_knn.cpp)
  target_include_directories(${name} PRIVATE ${GF_CUDA_DIR}/test ${GF_CUDA_DIR}/src)
  target_link_libraries(${name} ground_filter_core_private ground_filter_cuda_headers ${ARGN})
  target_compile_definitions(${name} PRIVATE GF_DATA_DIR="${GF_DATA_DIR}")
endfunction()
gf_gpu_check(test_gpu_neighbor_search ${GF_CUDA_DIR}/test/test_gpu_neighbor_search.cpp gtest_main)
add_test(NAME gpu_neighbor_search COMMAND test_gpu_neighbor_search)
gf_gpu_check(test_gpu_pipeline ${GF_CUDA_DIR}/test/test_gpu_pipeline.cpp gtest_main
  ground_filter_eval_kit CUDA::cudart_static)
add_test(NAME gpu_pipeline COMMAND test_gpu_pipeline)
gf_gpu_check(bench_gpu_knn ${GF_CUDA_DIR}/bench/bench_gpu_knn.cpp OpenMP::OpenMP_CXX)
# Whether capturing a scan's launches into a CUDA graph pays when sizes change every scan
# (docs/gpu.md, "The host side, traced"): cub and the runtime only.
add_executable(bench_graph_probe ${GF_CUDA_DIR}/bench/graph_probe.cu)
target_link_libraries(bench_graph_probe CUDA::cudart_static)

# Cost over scan size (docs/evaluation.md#ground_filter_scale_benchmark-cost-over-scan-size):
# generated TLS scans of 1-50 M points, CPU rows and, with --gpu, GPU rows.
add_executable(ground_filter_scale_benchmark ${GF_SOURCE_ROOT}/src/tools/scale_benchmark.cpp
  ${GF_SOURCE_ROOT}/src/tools/cli_args.cpp)
target_include_directories(ground_filter_scale_benchmark PRIVATE ${GF_SOURCE_ROOT}/src/tools)
target_link_libraries(ground_filter_scale_benchmark ground_filter_eval_kit
  ground_filter_core_private CUDA::cudart_static)
