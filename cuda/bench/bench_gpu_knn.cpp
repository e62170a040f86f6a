// Benchmark: K-nearest neighbours (K = 50), CUDA grid vs the kd-tree on all CPU cores, and the
// whole normal-vector filter side by side: kd-tree backend on 2 threads, on all cores, and the
// GPU pipeline (knn_backend gpu), per stage, on a KITTI frame, an Ouster OS-128 frame and KITTI
// frames replicated with x/y offsets.
//
//   bench_gpu_knn [--data DIR] [--sizes 0,1000000,5000000] [--reps N] [--filter-reps N]
//                 [--variants] [--no-filter]
//
// KNN times are wall-clock medians after one warm-up call, host<->device copies included. Filter
// times: the three configurations run in turn (A, B, C, A, B, C, ...) and each column is the
// median of its calls (>= 15 per size up to 1 M points, --filter-reps); the GPU's total is wall
// time from host xyz in to host labels out. Prints one markdown table per part.

#include <cuda_runtime.h>
#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "brute_force_knn.h"  // readKittiBin (cuda/test/)
#include "common/threads_timing.h"
#include "gpu_neighbor_search.h"
#include "ground_filter/cuda_knn.h"
#include "ground_filter/normal_ground_filter.h"
#include "knn/kdtree_neighbor_search.h"
#include "knn_tuning.h"  // cuda/src: the query kernel's experiment knobs and work counters
#include "replicate_frames.h"

namespace gf = ground_filter;

namespace {

using gf::Clock;
using gf::msSince;

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t m = v.size() / 2;
  return v.size() % 2 ? v[m] : 0.5 * (v[m - 1] + v[m]);
}

/// Median wall time of `reps` calls of f after one warm-up call.
double timeMedian(int reps, const std::function<void()>& f) {
  f();
  std::vector<double> t;
  for (int r = 0; r < reps; ++r) {
    const auto t0 = Clock::now();
    f();
    t.push_back(msSince(t0));
  }
  return median(t);
}

std::string sizeLabel(std::size_t n) {
  char b[32];
  if (n >= 1000000)
    std::snprintf(b, sizeof b, "%.1f M", n / 1e6);
  else
    std::snprintf(b, sizeof b, "%.0f k", n / 1e3);
  return b;
}

double stage(const gf::FilterStats& s, const std::string& name) {
  for (const auto& st : s.stage_ms) {
    if (st.first == name) return st.second;
  }
  return 0.0;
}

struct FilterCol {
  std::string name;
  int runs = 0;
  double total = 0, sort = 0, knn = 0, pca = 0, vote = 0, plane = 0, pack = 0, up = 0, down = 0;
};

struct FilterRow {
  std::string size;
  FilterCol col[3];  // CPU 2 threads, CPU all cores, GPU
  std::size_t differ = 0;
  std::string note;
};

std::string fmt(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.2f", v);
  return b;
}

/// The whole filter on `xyz`: kd-tree backend on 2 threads, on all cores, and the GPU, `reps`
/// rounds in turn after one warm-up call each; medians per column and stage.
FilterRow benchFilter(const std::string& label, const std::vector<float>& xyz, int reps) {
  const std::size_t n = xyz.size() / 3;
  std::fprintf(stderr, "filter %s ...\n", label.c_str());
  const auto cloud = gf::CloudView::packedXyz(xyz.data(), n);
  gf::NormalGroundFilterParams p2, pa, pg;
  // Replicated KITTI frames are many sensors' scans side by side: scan_type auto may take the
  // airborne mode (CPU only) for them; the benchmark times the ground-level pipeline.
  p2.scan_type = pa.scan_type = pg.scan_type = "ground";
  p2.threads = 2;
  pg.knn_backend = "gpu";
  std::unique_ptr<gf::NormalGroundFilter> f[3] = {std::make_unique<gf::NormalGroundFilter>(p2),
                                                  std::make_unique<gf::NormalGroundFilter>(pa),
                                                  std::make_unique<gf::NormalGroundFilter>(pg)};
  const char* names[3] = {"CPU kd-tree, 2 threads", "CPU kd-tree, all cores", "GPU"};
  std::vector<std::uint8_t> labels[3];
  gf::FilterStats st;
  std::vector<double> t[3][9];
  FilterRow row;
  row.size = label;
  for (int c = 0; c < 3; ++c) f[c]->filter(cloud, &labels[c], &st);  // warm-up
  for (int r = 0; r < reps; ++r) {
    for (int c = 0; c < 3; ++c) {
      f[c]->filter(cloud, &labels[c], &st);
      t[c][0].push_back(st.total_ms);
      t[c][1].push_back(stage(st, "sort"));
      t[c][2].push_back(stage(st, "knn") + stage(st, "kdtree_build"));
      t[c][3].push_back(stage(st, "pca"));
      t[c][4].push_back(stage(st, "vote"));
      t[c][5].push_back(stage(st, "plane"));
      t[c][6].push_back(stage(st, "pack"));
      t[c][7].push_back(stage(st, "upload"));
      t[c][8].push_back(stage(st, "download"));
      if (c == 2 && st.backend != "gpu") row.note = st.backend + ": " + st.note;
    }
  }
  for (int c = 0; c < 3; ++c) {
    FilterCol& col = row.col[c];
    col.name = names[c];
    col.runs = reps;
    col.total = median(t[c][0]);
    col.sort = median(t[c][1]);
    col.knn = median(t[c][2]);
    col.pca = median(t[c][3]);
    col.vote = median(t[c][4]);
    col.plane = median(t[c][5]);
    col.pack = median(t[c][6]);
    col.up = median(t[c][7]);
    col.down = median(t[c][8]);
  }
  for (std::size_t i = 0; i < n; ++i) row.differ += labels[2][i] != labels[1][i];
  return row;
}

struct BenchOptions {
  std::string data = GF_DATA_DIR;
  std::vector<std::size_t> sizes = {0, 1000000, 5000000};  // 0 = one KITTI frame as is
  int reps = 5;
  int freps = 15;
  bool variants = false;
  bool filter = true;
};

/// Parses the command line; false (usage printed) on an unknown argument.
bool parseArgs(int argc, char** argv, BenchOptions* o) {
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--data" && i + 1 < argc) {
      o->data = argv[++i];
    } else if (a == "--reps" && i + 1 < argc) {
      o->reps = std::max(1, std::atoi(argv[++i]));
    } else if (a == "--filter-reps" && i + 1 < argc) {
      o->freps = std::max(1, std::atoi(argv[++i]));
    } else if (a == "--variants") {
      o->variants = true;
    } else if (a == "--no-filter") {
      o->filter = false;
    } else if (a == "--sizes" && i + 1 < argc) {
      o->sizes.clear();
      std::string s = argv[++i];
      for (std::size_t p = 0; p <= s.size();) {
        const std::size_t q = std::min(s.find(',', p), s.size());
        o->sizes.push_back(std::strtoull(s.substr(p, q - p).c_str(), nullptr, 10));
        p = q + 1;
      }
    } else {
      std::fprintf(stderr,
                   "usage: %s [--data DIR] [--sizes N,N,..] [--reps N] [--filter-reps N] "
                   "[--variants] [--no-filter]\n",
                   argv[0]);
      return false;
    }
  }
  return true;
}

/// KITTI frames 000000.bin .. 000005.bin of `data` (those present).
std::vector<std::vector<float>> loadFrames(const std::string& data) {
  std::vector<std::vector<float>> frames;
  for (int f = 0; f < 6; ++f) {
    char name[32];
    std::snprintf(name, sizeof name, "/%06d.bin", f);
    auto xyz = gf_test::readKittiBin(data + name);
    if (!xyz.empty()) frames.push_back(std::move(xyz));
  }
  return frames;
}

/// Copy bandwidths on this machine, 64 MiB blocks.
void printCopyBandwidth(int cores) {
  const std::size_t bytes = 64u << 20;
  void* d = nullptr;
  void* h = nullptr;
  if (cudaMalloc(&d, bytes) == cudaSuccess && cudaMallocHost(&h, bytes) == cudaSuccess) {
    std::vector<char> user(bytes, 1);
    cudaMemset(d, 7, bytes);
    const double d2h_pinned =
        timeMedian(5, [&] { cudaMemcpy(h, d, bytes, cudaMemcpyDeviceToHost); });
    const double h2d_pinned =
        timeMedian(5, [&] { cudaMemcpy(d, h, bytes, cudaMemcpyHostToDevice); });
    const double d2h_pageable =
        timeMedian(5, [&] { cudaMemcpy(user.data(), d, bytes, cudaMemcpyDeviceToHost); });
    const double host_copy = timeMedian(5, [&] {
#pragma omp parallel for schedule(static)
      for (int s = 0; s < 64; ++s) {
        std::memcpy(user.data() + (std::size_t(s) << 20),
                    static_cast<char*>(h) + (std::size_t(s) << 20), std::size_t(1) << 20);
      }
    });
    const double host_copy1 = timeMedian(5, [&] { std::memcpy(user.data(), h, bytes); });
    auto gbs = [&](double ms) { return bytes / ms / 1e6; };
    std::printf(
        "copy bandwidth (GB/s, 64 MiB): D2H pinned %.1f, H2D pinned %.1f, D2H pageable "
        "%.1f, host memcpy pinned->pageable %.1f (%d threads), %.1f (1 thread)\n\n",
        gbs(d2h_pinned), gbs(h2d_pinned), gbs(d2h_pageable), gbs(host_copy), cores,
        gbs(host_copy1));
  }
  cudaFree(d);
  cudaFreeHost(h);
}

struct KnnRow {
  std::string size;
  double gpu_up, gpu_grid, gpu_query, gpu_total, gpu_device_only, cpu_total, cpu_build;
  std::size_t rows_differ;
};

/// The GPU search (lists downloaded, and kept on the device) against the kd-tree on all cores;
/// `r` timed calls each after a warm-up.
KnnRow benchKnn(const std::string& label, const std::vector<float>& xyz, int k, int r) {
  const std::size_t n = xyz.size() / 3;
  gf::CudaKnn gpu;
  std::vector<std::int32_t> gidx(n * k);
  std::vector<float> gd2(n * k);
  std::vector<double> up, grid, query, total, dev_only;
  gpu.search(xyz.data(), n, k, gidx.data(), gd2.data());  // warm-up
  for (int i = 0; i < std::max(r, 3); ++i) {
    gpu.search(xyz.data(), n, k, gidx.data(), gd2.data());
    const auto& t = gpu.lastTimings();
    up.push_back(t.upload_ms);
    grid.push_back(t.grid_ms);
    query.push_back(t.query_ms);
    total.push_back(t.total_ms);
  }
  {  // lists left on the device (what the filter does)
    gf::CudaKnn dev;
    dev.search(xyz.data(), n, k, nullptr, nullptr);
    for (int i = 0; i < std::max(r, 3); ++i) {
      dev.search(xyz.data(), n, k, nullptr, nullptr);
      dev_only.push_back(dev.lastTimings().total_ms);
    }
  }
  gf::KdTreeNeighborSearch cpu(0);
  gf::NeighborLists cl;
  std::vector<double> build;
  const double cpu_ms = timeMedian(r, [&] {
    cpu.search(xyz.data(), n, k, &cl);
    build.push_back(cpu.lastBuildMs());
  });
  std::size_t differ = 0;
  for (std::size_t i = 0; i < n; ++i) {
    for (int j = 0; j < k; ++j) {
      if (gidx[i * k + j] != cl.indices[i * k + j] || gd2[i * k + j] != cl.sq_dists[i * k + j]) {
        ++differ;
        break;
      }
    }
  }
  return {label,  median(up),    median(grid), median(query), median(total), median(dev_only),
          cpu_ms, median(build), differ};
}

/// List merging and the identical-point skip (on/off), lists kept on the device; K 50 and the
/// filter's K 64: one table line per variant (times, then work counters from a counting run).
void benchVariants(const std::string& label, const std::vector<float>& xyz, int k, int r,
                   std::vector<std::string>* lines) {
  const std::size_t n = xyz.size() / 3;
  struct V {
    int k, merge_min;
    bool skip;
    int heavy;
  };
  for (const V& vv :
       {V{k, 0, false, 0}, V{k, 6, true, 0}, V{k, 6, true, 2048}, V{k, 6, true, 8192},
        V{k, 6, true, 32768}, V{64, 0, false, 0}, V{64, 6, true, 0}, V{64, 6, true, 8192}}) {
    gf::CudaKnnTuning o;
    o.merge_min = vv.merge_min;
    o.skip_duplicates = vv.skip;
    o.heavy_candidates = vv.heavy;
    gf::CudaKnn v;
    gf::CudaKnnTuningAccess::set(v, o);
    std::vector<double> tq, tt;
    v.search(xyz.data(), n, vv.k, nullptr, nullptr);
    for (int i = 0; i < std::max(r, 5); ++i) {
      v.search(xyz.data(), n, vv.k, nullptr, nullptr);
      tq.push_back(v.lastTimings().query_ms);
      tt.push_back(v.lastTimings().total_ms);
    }
    o.collect_stats = true;
    gf::CudaKnn cs;
    gf::CudaKnnTuningAccess::set(cs, o);
    cs.search(xyz.data(), n, vv.k, nullptr, nullptr);
    const gf::CudaKnnQueryStats& t = gf::CudaKnnTuningAccess::stats(cs);
    char line[400];
    std::snprintf(line, sizeof line,
                  "| %s | K %d, merge from %d, skip identical %s, heavy from %d | %.2f | %.2f | "
                  "%.0f | %.0f | %.2f | %.2f | %.0f | %.0f |",
                  label.c_str(), vv.k, vv.merge_min, vv.skip ? "on" : "off", vv.heavy, median(tq),
                  median(tt), t.candidates_per_query, t.insertions_per_query, t.shells_per_query,
                  t.levels_per_query, t.mean_query_cycles, t.max_query_cycles);
    lines->push_back(line);
    if (vv.k == 64 && vv.merge_min == 6) {  // the slowest query without / with heavy
      lines->push_back("|  | " + t.detail + " | | | | | | | | |");
    }
  }
}

void printKnnTable(int k, int cores, const std::vector<KnnRow>& rows) {
  std::printf("K-nearest neighbours, K = %d (ms)\n\n", k);
  std::printf(
      "| points | GPU upload | GPU grid | GPU query + download | GPU total | GPU, lists "
      "kept on device | kd-tree (%d threads) | of which build | speed-up | rows differing "
      "|\n",
      cores);
  std::printf("|---|---|---|---|---|---|---|---|---|---|\n");
  for (const auto& r : rows) {
    std::printf("| %s | %.2f | %.2f | %.2f | **%.2f** | %.2f | %.1f | %.1f | **%.0fx** | %zu |\n",
                r.size.c_str(), r.gpu_up, r.gpu_grid, r.gpu_query, r.gpu_total, r.gpu_device_only,
                r.cpu_total, r.cpu_build, r.cpu_total / r.gpu_total, r.rows_differ);
  }
}

void printFilterTable(const std::vector<FilterRow>& rows) {
  std::printf(
      "\nWhole normal-vector filter (ms, medians; the three configurations run in turn in one "
      "run). Stages: sort = NaN compaction + grid-column order; knn = kd-tree build + queries "
      "(CPU) or grid + queries (GPU); GPU io = host packing / upload / labels download\n\n");
  std::printf(
      "| points | backend | runs | total | sort | knn | pca | vote | plane | GPU io | labels "
      "differing from CPU (all cores) | speed-up vs CPU all cores |\n"
      "|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  for (const auto& r : rows) {
    for (int c = 0; c < 3; ++c) {
      const FilterCol& f = r.col[c];
      std::printf(
          "| %s | %s | %d | **%.2f** | %.2f | %.2f | %.2f | %.2f | %.2f | %s | %s | %.1fx |\n",
          r.size.c_str(), f.name.c_str(), f.runs, f.total, f.sort, f.knn, f.pca, f.vote, f.plane,
          c == 2 ? (fmt(f.pack) + " / " + fmt(f.up) + " / " + fmt(f.down)).c_str() : "",
          c == 2 ? std::to_string(r.differ).c_str() : "", r.col[1].total / f.total);
    }
    if (!r.note.empty()) std::printf("|  | note: %s | | | | | | | | | | |\n", r.note.c_str());
  }
}

void printVariantTable(const std::vector<std::string>& lines) {
  if (lines.empty()) return;
  std::printf(
      "\nGPU KNN variants, lists kept on the device (ms; work per query from a run with "
      "counters)\n\n| points | variant | query | total | candidates | "
      "insertions | shells | levels | mean cycles | max cycles |\n"
      "|---|---|---|---|---|---|---|---|---|---|\n");
  for (const auto& l : lines) std::printf("%s\n", l.c_str());
}

}  // namespace

int main(int argc, char** argv) {
  BenchOptions opt;
  if (!parseArgs(argc, argv, &opt)) return 2;
  const std::vector<std::vector<float>> frames = loadFrames(opt.data);
  if (frames.empty()) {
    std::fprintf(stderr, "no KITTI frames (000000.bin ...) in %s\n", opt.data.c_str());
    return 1;
  }
  const std::vector<float> os128 =
      gf_test::readKittiBin(opt.data + "/os128_000000.bin");  // converted PCD
  std::string why;
  if (!gf::CudaKnn::deviceAvailable(&why)) {
    std::fprintf(stderr, "no usable CUDA device: %s\n", why.c_str());
    return 1;
  }
  const int k = 50;
  const int cores = omp_get_num_procs();
  gf::CudaKnn probe;
  std::printf(
      "device: %s; CPU: %d cores (kd-tree and filter use all); K = %d; median of %d runs "
      "after a warm-up\n\n",
      probe.deviceName().c_str(), cores, k, opt.reps);
  if (opt.variants) printCopyBandwidth(cores);
  std::vector<KnnRow> knn_rows;
  std::vector<FilterRow> filter_rows;
  std::vector<std::string> variant_lines;

  std::vector<std::size_t> todo = opt.sizes;
  if (!os128.empty()) todo.push_back(static_cast<std::size_t>(-1));  // the Ouster frame last
  for (std::size_t want : todo) {
    const bool is_os = want == static_cast<std::size_t>(-1);
    const std::vector<float> xyz =
        is_os ? os128 : (want == 0 ? frames[0] : gf_test::replicateFrames(frames, want));
    const std::size_t n = xyz.size() / 3;
    const std::string label = is_os ? "OS-128 (240 k)" : sizeLabel(n);
    const int r = n > 2000000 ? std::max(1, opt.reps / 2) : opt.reps;
    std::fprintf(stderr, "size %zu ...\n", n);
    knn_rows.push_back(benchKnn(label, xyz, k, r));
    if (opt.variants) benchVariants(label, xyz, k, r, &variant_lines);
    // ---- whole normal-vector filter: CPU 2 threads, CPU all cores, GPU, in turn
    if (opt.filter) {
      const int freps = n > 2000000 ? std::max(3, opt.freps / 3) : opt.freps;
      filter_rows.push_back(benchFilter(label, xyz, freps));
    }
  }
  printKnnTable(k, cores, knn_rows);
  printFilterTable(filter_rows);
  printVariantTable(variant_lines);
  return 0;
}
