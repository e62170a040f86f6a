// A CUPTI activity tracer for measuring the GPU pipeline's host side (docs/gpu.md, "The host
// side, traced"): loaded into any CUDA program with CUDA_INJECTION64_PATH, it writes one line
// per kernel, copy, memset and runtime call with its start and end (ns, one clock for host and
// GPU) to $GF_TRACE_OUT. scripts/gpu_trace_gaps.py reads it. Built by cuda/run_gpu_checks.sh
// with GF_TRACE=1 (g++ against the toolkit's CUPTI); the record struct names change with the
// CUPTI version, so the script passes the newest ones its headers declare (KREC, MREC, SREC).
// Not part of the package's libraries.

#include <cupti.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <mutex>

namespace {

FILE* g_out = nullptr;
std::mutex g_mutex;

void CUPTIAPI bufferRequested(uint8_t** buffer, size_t* size, size_t* max_records) {
  *size = std::size_t{16} << 20;
  *buffer = static_cast<uint8_t*>(std::aligned_alloc(8, *size));
  *max_records = 0;
}

// Lines "<kind> <start> <end> <correlation id> <name>": K kernel, C copy (copyKind and bytes),
// S memset (bytes), R runtime call.
void CUPTIAPI bufferCompleted(CUcontext, uint32_t, uint8_t* buffer, size_t, size_t valid) {
  std::lock_guard<std::mutex> lock(g_mutex);
  CUpti_Activity* r = nullptr;
  while (g_out && cuptiActivityGetNextRecord(buffer, valid, &r) == CUPTI_SUCCESS) {
    switch (r->kind) {
      case CUPTI_ACTIVITY_KIND_KERNEL:
      case CUPTI_ACTIVITY_KIND_CONCURRENT_KERNEL: {
        const auto* k = reinterpret_cast<const KREC*>(r);
        std::fprintf(g_out, "K %llu %llu %u %s\n", static_cast<unsigned long long>(k->start),
                     static_cast<unsigned long long>(k->end), k->correlationId, k->name);
        break;
      }
      case CUPTI_ACTIVITY_KIND_MEMCPY: {
        const auto* m = reinterpret_cast<const MREC*>(r);
        std::fprintf(g_out, "C %llu %llu %u kind%u_%llu\n",
                     static_cast<unsigned long long>(m->start),
                     static_cast<unsigned long long>(m->end), m->correlationId,
                     static_cast<unsigned>(m->copyKind), static_cast<unsigned long long>(m->bytes));
        break;
      }
      case CUPTI_ACTIVITY_KIND_MEMSET: {
        const auto* m = reinterpret_cast<const SREC*>(r);
        std::fprintf(g_out, "S %llu %llu %u memset_%llu\n",
                     static_cast<unsigned long long>(m->start),
                     static_cast<unsigned long long>(m->end), m->correlationId,
                     static_cast<unsigned long long>(m->bytes));
        break;
      }
      case CUPTI_ACTIVITY_KIND_RUNTIME: {
        const auto* a = reinterpret_cast<const CUpti_ActivityAPI*>(r);
        const char* name = "?";
        cuptiGetCallbackName(CUPTI_CB_DOMAIN_RUNTIME_API, a->cbid, &name);
        std::fprintf(g_out, "R %llu %llu %u %s\n", static_cast<unsigned long long>(a->start),
                     static_cast<unsigned long long>(a->end), a->correlationId, name);
        break;
      }
      default:
        break;
    }
  }
  std::free(buffer);
}

void finish() {
  cuptiActivityFlushAll(1);
  std::lock_guard<std::mutex> lock(g_mutex);
  if (g_out) std::fclose(g_out);
  g_out = nullptr;
}

}  // namespace

/// \brief The entry point CUDA calls in a library named by CUDA_INJECTION64_PATH.
extern "C" int InitializeInjection() {
  const char* path = std::getenv("GF_TRACE_OUT");
  g_out = std::fopen(path ? path : "gpu_trace.txt", "w");
  if (!g_out) return 0;
  cuptiActivityRegisterCallbacks(bufferRequested, bufferCompleted);
  cuptiActivityEnable(CUPTI_ACTIVITY_KIND_CONCURRENT_KERNEL);
  cuptiActivityEnable(CUPTI_ACTIVITY_KIND_MEMCPY);
  cuptiActivityEnable(CUPTI_ACTIVITY_KIND_MEMSET);
  cuptiActivityEnable(CUPTI_ACTIVITY_KIND_RUNTIME);
  std::atexit(finish);
  return 1;
}
