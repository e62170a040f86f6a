// Base fixture of the GPU tests (test_cuda_knn, test_gpu_neighbor_search, test_gpu_pipeline).
#ifndef GROUND_FILTER_CUDA_TEST_GPU_TEST_H
#define GROUND_FILTER_CUDA_TEST_GPU_TEST_H

#include <gtest/gtest.h>

#include <string>

#include "ground_filter/cuda_knn.h"

namespace gf_test {

/// \brief Fails each test (never skips it) when no CUDA device can run it: these tests run on
///        the GPU machine, where a missing device is an error.
class GpuTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string why;
    ASSERT_TRUE(ground_filter::CudaKnn::deviceAvailable(&why))
        << "these tests need a CUDA GPU: " << why;
  }
};

}  // namespace gf_test

#endif  // GROUND_FILTER_CUDA_TEST_GPU_TEST_H
