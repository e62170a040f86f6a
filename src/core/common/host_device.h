#ifndef GROUND_FILTER_SRC_CORE_COMMON_HOST_DEVICE_H
#define GROUND_FILTER_SRC_CORE_COMMON_HOST_DEVICE_H

// GF_HOST_DEVICE marks a function of the headers compiled by the host compiler and by nvcc
// (*cpu_gpu_common.h): __host__ __device__ under nvcc, nothing otherwise.

#ifdef __CUDACC__
#define GF_HOST_DEVICE __host__ __device__
#else
#define GF_HOST_DEVICE
#endif

#endif  // GROUND_FILTER_SRC_CORE_COMMON_HOST_DEVICE_H
