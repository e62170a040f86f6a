# Sources of the ROS/PCL-free core library (ground_filter_core), relative to the package root.
# Included by the top-level CMakeLists.txt and by cuda/CMakeLists.txt (standalone GPU build), so
# the list exists once. The CUDA adapter (src/core/gpu_neighbor_search.cpp) is added where CUDA is.
set(GF_CORE_SOURCES
  src/core/param_parse.cpp
  src/core/plane_fit.cpp
  src/core/voxel_ground_filter.cpp
  src/core/voxel_ground_filter_params.cpp
  src/core/voxel/voxelize.cpp
  src/core/voxel/segments.cpp
  src/core/voxel/ground_model.cpp
  src/core/voxel/classify.cpp
  src/core/voxel/vote.cpp
  src/core/voxel/worker_pool.cpp
  src/core/morph_ground.cpp
  src/core/filter_factory.cpp
  src/core/metrics.cpp
  src/core/scene_generator.cpp
  src/core/paper_normalisation.cpp
  src/core/normal_ground_filter.cpp
  src/core/normal_ground_filter_params.cpp
  src/core/normal/order.cpp
  src/core/normal/neighborhoods.cpp
  src/core/normal/neighborhood_pca.cpp
  src/core/normal/vote.cpp
  src/core/normal/plane.cpp
  src/core/normal/classify.cpp
  src/core/kdtree_neighbor_search.cpp
  src/core/neighbor_search_factory.cpp
  src/core/working_volume.cpp
)
