# Sources of the ROS/PCL-free core library (ground_filter_core), relative to the package root, one
# line per room of src/core/ (docs/architecture.md). Included by cmake/ground_filter_core.cmake
# for every build of the core, so the list exists once.
#
# gf_core_room(<folder under src/core, or . for its top> <file name without .cpp> ...)
macro(gf_core_room dir)
  foreach(gf_name ${ARGN})
    if("${dir}" STREQUAL ".")
      list(APPEND GF_CORE_SOURCES src/core/${gf_name}.cpp)
    else()
      list(APPEND GF_CORE_SOURCES src/core/${dir}/${gf_name}.cpp)
    endif()
  endforeach()
endmacro()

set(GF_CORE_SOURCES)
# shared: makeGroundFilter, parameter parsing, plane fit, working volume, morphological ground
# surface (airborne mode of both methods), scan_type (which mode a scan runs in)
gf_core_room(simd simd)
gf_core_room(common plane_fit param_parse densest_centre ground_tilt scan_lines side_task)
gf_core_room(. build_info filter_factory working_volume)
gf_core_room(airborne morph_ground walled_roofs scan_type origin_view airborne_mode)
# voxel method: the filter and its parameter table, one file per stage, the paper mode
gf_core_room(voxel voxel_ground_filter voxel_ground_filter_params paper_voxel_filter)
gf_core_room(voxel voxelize voxelize_build avx2_passes segments ground_model classify vote vegetation
             line_walls worker_pool)
# normal method: the filter and its parameter table (and the settings derived from it), one file
# per stage
gf_core_room(normal normal_ground_filter normal_ground_filter_params normal_settings)
gf_core_room(normal order cell_keys lattice sample neighborhoods vote plane local_ground
             vegetation scatter_labels line_walls)
# K nearest neighbours, a room below the normal method that uses it (knn/): the
# kd-tree (build, portable / AVX-512 / AVX2 / NEON queries), the PCA of the lists, the backend
# factory
gf_core_room(knn kdtree_neighbor_search kdtree_build kdtree_query_avx512 kdtree_query_avx2
             kdtree_query_neon)
gf_core_room(knn neighborhood_pca neighbor_search_factory)
# height above ground: the ground surface from a filter's labels
gf_core_room(hag height_above_ground surface_points_avx2)

# The CUDA library's entry points (makeGpuKnnBackend(), makeGpuNormalExecutor(), ...) where CUDA is
# not built: added to the core instead of linking ground_filter_cuda (cuda/src/gpu_*.cpp define
# them there).
set(GF_CORE_NO_CUDA_SOURCES src/core/no_cuda.cpp)

# The evaluation kit (src/eval/: ground_filter_eval_kit, a static library of the tools and tests,
# never linked into the core or the nodelets): metrics and the generated scenes (Eigen only), and
# the scan files (KITTI .bin, PCD, PLY, labels) where PCL is built.
set(GF_EVAL_KIT_SOURCES src/eval/kitti_bin.cpp src/eval/metrics.cpp src/eval/scene_generator.cpp
    src/eval/scene_spec.cpp src/eval/scene_terrain.cpp)
set(GF_EVAL_KIT_PCL_SOURCES src/eval/scan_io.cpp)
