// Does capturing a scan's launches into a CUDA graph per scan pay, when the sizes change every
// scan (so the graph is captured anew and the executable graph updated each time)?
// Mimics the normal pipeline's grid section: a cub radix sort of 64-bit keys (48 bits), a cub
// inclusive scan, two memsets and 12 small kernels over n points, n varying +-1 % call to call.
// Modes, alternated call by call, wall time from the first call to the stream's end:
//   direct: launch everything, then sync
//   graph:  capture the same calls, cudaGraphExecUpdate (instantiate on failure), launch, sync
//   replay: launch an executable graph captured once (fixed n): the floor
// Built by cuda/run_gpu_checks.sh (build-cuda/bench_graph_probe [points [calls]]), or alone:
//   nvcc -O3 -arch=sm_90 -std=c++17 cuda/bench/graph_probe.cu -o graph_probe
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cub/cub.cuh>
#include <vector>

#define CK(x)                                                                                 \
  do {                                                                                        \
    cudaError_t e_ = (x);                                                                     \
    if (e_ != cudaSuccess) {                                                                  \
      std::fprintf(stderr, "%s:%d %s: %s\n", __FILE__, __LINE__, #x, cudaGetErrorString(e_)); \
      std::exit(1);                                                                           \
    }                                                                                         \
  } while (0)

__global__ void keysKernel(const float4* p, int n, unsigned long long* k, unsigned* v) {
  int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= n) return;
  float4 q = p[i];
  unsigned long long x = static_cast<unsigned long long>(fabsf(q.x) * 1000.f) & 0xffff;
  unsigned long long y = static_cast<unsigned long long>(fabsf(q.y) * 1000.f) & 0xffff;
  unsigned long long z = static_cast<unsigned long long>(fabsf(q.z) * 1000.f) & 0xffff;
  k[i] = (x << 32) | (y << 16) | z;
  v[i] = i;
}

__global__ void smallKernel(unsigned* a, const unsigned* b, int n, int salt) {
  int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= n) return;
  a[i] = b[i] * 2654435761u + salt;
}

__global__ void headsKernel(const unsigned long long* k, int n, unsigned* h) {
  int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= n) return;
  h[i] = (i == 0 || (k[i] >> 16) != (k[i - 1] >> 16)) ? 1u : 0u;
}

struct Bufs {
  float4* pts;
  unsigned long long *ka, *kb;
  unsigned *va, *vb, *h, *s, *t;
  void* temp;
  size_t temp_bytes;
};

void enqueue(const Bufs& b, int n, cudaStream_t st) {
  const int bs = 256, gs = (n + bs - 1) / bs;
  keysKernel<<<gs, bs, 0, st>>>(b.pts, n, b.ka, b.va);
  cub::DoubleBuffer<unsigned long long> kb(b.ka, b.kb);
  cub::DoubleBuffer<unsigned> vb(b.va, b.vb);
  size_t tb = b.temp_bytes;
  CK(cub::DeviceRadixSort::SortPairs(b.temp, tb, kb, vb, n, 0, 48, st));
  CK(cudaMemsetAsync(b.t, 0, 64 * sizeof(unsigned), st));
  CK(cudaMemsetAsync(b.s, 0, 1024 * sizeof(unsigned), st));
  headsKernel<<<gs, bs, 0, st>>>(kb.Current(), n, b.h);
  tb = b.temp_bytes;
  CK(cub::DeviceScan::InclusiveSum(b.temp, tb, b.h, b.s, n, st));
  for (int j = 0; j < 10; ++j) smallKernel<<<gs, bs, 0, st>>>(b.t, b.s, n, j);
  CK(cudaGetLastError());
}

double msSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

int main(int argc, char** argv) {
  const int n0 = argc > 1 ? std::atoi(argv[1]) : 62000;
  const int calls = argc > 2 ? std::atoi(argv[2]) : 201;
  const int nmax = n0 + n0 / 50 + 1;
  Bufs b{};
  CK(cudaMalloc(&b.pts, nmax * sizeof(float4)));
  CK(cudaMalloc(&b.ka, nmax * 8));
  CK(cudaMalloc(&b.kb, nmax * 8));
  CK(cudaMalloc(&b.va, nmax * 4));
  CK(cudaMalloc(&b.vb, nmax * 4));
  CK(cudaMalloc(&b.h, nmax * 4));
  CK(cudaMalloc(&b.s, std::max(nmax, 1024) * 4));
  CK(cudaMalloc(&b.t, std::max(nmax, 64) * 4));
  {
    std::vector<float4> hp(nmax);
    for (int i = 0; i < nmax; ++i) {
      hp[i] = make_float4((i * 7919 % 10007) * 0.01f, (i * 104729 % 10009) * 0.01f,
                          (i % 97) * 0.01f, 0.f);
    }
    CK(cudaMemcpy(b.pts, hp.data(), nmax * sizeof(float4), cudaMemcpyHostToDevice));
  }
  size_t t1 = 0, t2 = 0;
  {
    cub::DoubleBuffer<unsigned long long> kb(b.ka, b.kb);
    cub::DoubleBuffer<unsigned> vb(b.va, b.vb);
    CK(cub::DeviceRadixSort::SortPairs(nullptr, t1, kb, vb, nmax, 0, 48));
    CK(cub::DeviceScan::InclusiveSum(nullptr, t2, b.h, b.s, nmax));
  }
  b.temp_bytes = std::max(t1, t2);
  CK(cudaMalloc(&b.temp, b.temp_bytes));
  cudaStream_t st;
  CK(cudaStreamCreateWithFlags(&st, cudaStreamNonBlocking));

  cudaGraphExec_t exec = nullptr, fixed = nullptr;
  {
    cudaGraph_t g;
    CK(cudaStreamBeginCapture(st, cudaStreamCaptureModeThreadLocal));
    enqueue(b, n0, st);
    CK(cudaStreamEndCapture(st, &g));
    CK(cudaGraphInstantiate(&fixed, g, 0));
    CK(cudaGraphDestroy(g));
  }
  std::vector<double> direct, graph, replay, capture_only;
  int reinst = 0;
  for (int c = 0; c < calls; ++c) {
    const int n = n0 - n0 / 100 + (c * 7919) % (n0 / 50 + 1);  // +-1 %, new every call
    for (int mode = 0; mode < 3; ++mode) {
      CK(cudaStreamSynchronize(st));
      const auto t0 = std::chrono::steady_clock::now();
      if (mode == 0) {
        enqueue(b, n, st);
      } else if (mode == 1) {
        cudaGraph_t g;
        CK(cudaStreamBeginCapture(st, cudaStreamCaptureModeThreadLocal));
        enqueue(b, n, st);
        CK(cudaStreamEndCapture(st, &g));
        const double cap = msSince(t0);
        bool ok = false;
        if (exec) {
          cudaGraphExecUpdateResultInfo info;
          ok = cudaGraphExecUpdate(exec, g, &info) == cudaSuccess;
          if (!ok) {
            cudaGetLastError();
            CK(cudaGraphExecDestroy(exec));
          }
        }
        if (!ok) {
          ++reinst;
          CK(cudaGraphInstantiate(&exec, g, 0));
        }
        CK(cudaGraphDestroy(g));
        CK(cudaGraphLaunch(exec, st));
        if (c > 0) capture_only.push_back(cap);
      } else {
        CK(cudaGraphLaunch(fixed, st));
      }
      CK(cudaStreamSynchronize(st));
      const double ms = msSince(t0);
      if (c > 0) (mode == 0 ? direct : mode == 1 ? graph : replay).push_back(ms);
    }
  }
  std::printf("n %d, %d calls each (alternated), medians [us]:\n", n0, calls - 1);
  std::printf("  direct launches + sync            %8.1f\n", 1e3 * median(direct));
  std::printf(
      "  capture + update + launch + sync  %8.1f  (capture alone %.1f; %d instantiations)\n",
      1e3 * median(graph), 1e3 * median(capture_only), reinst);
  std::printf("  replay of a fixed graph + sync    %8.1f\n", 1e3 * median(replay));
  return 0;
}
