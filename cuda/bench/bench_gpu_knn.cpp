// Benchmark: K-nearest neighbours (K = 50) and the whole normal-vector filter, CUDA grid vs the
// nanoflann kd-tree on all CPU cores, on KITTI frames replicated with x/y offsets.
//
//   bench_gpu_knn [--data DIR] [--sizes 124000,1000000,5000000] [--reps N] [--variants]
//
// Times are wall-clock medians after one warm-up call, host<->device copies included. Prints one
// markdown table per part.

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
#include <string>
#include <vector>

#include "ground_filter/cuda_knn.h"
#include "ground_filter/gpu_neighbor_search.h"
#include "ground_filter/kdtree_neighbor_search.h"
#include "ground_filter/normal_ground_filter.h"

namespace gf = ground_filter;

namespace {

using Clock = std::chrono::steady_clock;

double msSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

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

std::vector<float> readKittiBin(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  std::vector<float> rec, xyz;
  if (!f) return xyz;
  f.seekg(0, std::ios::end);
  rec.resize(static_cast<std::size_t>(f.tellg()) / sizeof(float));
  f.seekg(0);
  f.read(reinterpret_cast<char*>(rec.data()), static_cast<std::streamsize>(rec.size() * 4));
  for (std::size_t i = 0; i + 3 < rec.size(); i += 4) {
    xyz.insert(xyz.end(), {rec[i], rec[i + 1], rec[i + 2]});
  }
  return xyz;
}

/// `n` points: frames 0, 1, 2, ... cycled, copy t shifted by 200 m steps on a 7-wide x/y grid.
std::vector<float> replicate(const std::vector<std::vector<float>>& frames, std::size_t n) {
  std::vector<float> xyz;
  xyz.reserve(3 * n);
  for (int t = 0; xyz.size() < 3 * n; ++t) {
    const auto& f = frames[t % frames.size()];
    const float ox = 200.f * static_cast<float>(t % 7), oy = 200.f * static_cast<float>(t / 7);
    for (std::size_t i = 0; i < f.size() / 3 && xyz.size() < 3 * n; ++i) {
      xyz.insert(xyz.end(), {f[3 * i] + ox, f[3 * i + 1] + oy, f[3 * i + 2]});
    }
  }
  return xyz;
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

}  // namespace

int main(int argc, char** argv) {
  std::string data = GF_DATA_DIR;
  std::vector<std::size_t> sizes = {0, 1000000, 5000000};  // 0 = one KITTI frame as is
  int reps = 5;
  bool variants = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--data" && i + 1 < argc) {
      data = argv[++i];
    } else if (a == "--reps" && i + 1 < argc) {
      reps = std::max(1, std::atoi(argv[++i]));
    } else if (a == "--variants") {
      variants = true;
    } else if (a == "--sizes" && i + 1 < argc) {
      sizes.clear();
      std::string s = argv[++i];
      for (std::size_t p = 0; p <= s.size();) {
        const std::size_t q = std::min(s.find(',', p), s.size());
        sizes.push_back(std::strtoull(s.substr(p, q - p).c_str(), nullptr, 10));
        p = q + 1;
      }
    } else {
      std::fprintf(stderr, "usage: %s [--data DIR] [--sizes N,N,..] [--reps N] [--variants]\n",
                   argv[0]);
      return 2;
    }
  }
  std::vector<std::vector<float>> frames;
  for (int f = 0; f < 6; ++f) {
    char name[32];
    std::snprintf(name, sizeof name, "/%06d.bin", f);
    auto xyz = readKittiBin(data + name);
    if (!xyz.empty()) frames.push_back(std::move(xyz));
  }
  if (frames.empty()) {
    std::fprintf(stderr, "no KITTI frames (000000.bin ...) in %s\n", data.c_str());
    return 1;
  }
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
      probe.deviceName().c_str(), cores, k, reps);

  struct Row {
    std::string size;
    double gpu_up, gpu_grid, gpu_query, gpu_total, gpu_device_only, cpu_total, cpu_build;
    std::size_t rows_differ;
  };
  struct FRow {
    std::string size;
    double gpu_total, gpu_knn, gpu_pca, gpu_rest, cpu_total, cpu_knn, cpu_pca, cpu_rest;
    std::size_t labels_differ;
    std::string note;
  };
  if (variants) {  // copy bandwidths on this machine, 64 MiB blocks
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
  std::vector<Row> knn_rows;
  std::vector<std::string> stage_lines;
  std::vector<FRow> filter_rows;
  std::vector<std::string> variant_lines;

  for (std::size_t want : sizes) {
    const std::vector<float> xyz = want == 0 ? frames[0] : replicate(frames, want);
    const std::size_t n = xyz.size() / 3;
    const int r = n > 2000000 ? std::max(1, reps / 2) : reps;
    std::fprintf(stderr, "size %zu ...\n", n);

    // ---- KNN
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
    knn_rows.push_back({sizeLabel(n), median(up), median(grid), median(query), median(total),
                        median(dev_only), cpu_ms, median(build), differ});

    if (variants) {
      for (bool sorted : {true, false}) {
        for (int mp : {0, 6, 25}) {
          gf::CudaKnnOptions o;
          o.sort_cells = sorted;
          o.level_min_points = mp;
          gf::CudaKnn v(o);
          std::vector<double> tq, tt;
          v.search(xyz.data(), n, k, gidx.data(), gd2.data());
          for (int i = 0; i < std::max(r, 3); ++i) {
            v.search(xyz.data(), n, k, gidx.data(), gd2.data());
            tq.push_back(v.lastTimings().query_ms);
            tt.push_back(v.lastTimings().total_ms);
          }
          o.collect_stats = true;
          gf::CudaKnn cs(o);
          cs.search(xyz.data(), n, k, nullptr, nullptr);
          const auto& t = cs.lastTimings();
          char line[400];
          std::snprintf(line, sizeof line,
                        "| %s | %s | %s | %.2f | %.2f | %.0f | %.0f | %.2f | %.2f | %.0f | %.0f |",
                        sizeLabel(n).c_str(), sorted ? "nearest first" : "raster",
                        mp == 0 ? "auto (K/4)" : std::to_string(mp).c_str(), median(tq), median(tt),
                        t.candidates_per_query, t.insertions_per_query, t.shells_per_query,
                        t.levels_per_query, t.mean_query_cycles, t.max_query_cycles);
          variant_lines.push_back(line);
          if (sorted && mp == 0) {
            variant_lines.push_back("|  | " + t.detail + " | | | | | | | | | |");
          }
        }
      }
      for (int chunks : {1, 4, 16}) {
        gf::CudaKnnOptions o;
        o.download_chunks = chunks;
        gf::CudaKnn v(o);
        std::vector<double> tq, tt;
        v.search(xyz.data(), n, k, gidx.data(), gd2.data());
        for (int i = 0; i < std::max(r, 3); ++i) {
          v.search(xyz.data(), n, k, gidx.data(), gd2.data());
          tq.push_back(v.lastTimings().query_ms);
          tt.push_back(v.lastTimings().total_ms);
        }
        char line[200];
        std::snprintf(line, sizeof line,
                      "| %s | %d download chunks | auto | %.2f | %.2f | | | | | | |",
                      sizeLabel(n).c_str(), chunks, median(tq), median(tt));
        variant_lines.push_back(line);
      }
    }
    {  // the filter's GPU calls: search with lists kept on the device, PCA, vote counts
      gf::GpuNeighborSearch gs;
      gs.keepListsOnDevice(true);
      gf::NeighborLists lists;
      std::vector<gf::PointPca> pca;
      std::vector<std::uint8_t> flags(n);
      for (std::size_t i = 0; i < n; ++i) flags[i] = (i * 2654435761u) % 3 == 0;
      std::vector<std::uint16_t> fl(n), sz(n);
      std::vector<double> ts, tp, tpk, tc;
      for (int i = 0; i <= std::max(r, 3); ++i) {
        auto t0 = Clock::now();
        gs.search(xyz.data(), n, k, &lists);
        const double a = msSince(t0);
        t0 = Clock::now();
        gs.neighborhoodPca(&pca);
        const double b = msSince(t0);
        const double bk = gs.cudaKnn().lastTimings().pca_ms;
        t0 = Clock::now();
        gs.countFlaggedNeighbors(flags.data(), fl.data(), sz.data());
        const double c = msSince(t0);
        if (i == 0) continue;  // warm-up
        ts.push_back(a);
        tp.push_back(b);
        tpk.push_back(bk);
        tc.push_back(c);
      }
      char line[300];
      std::snprintf(line, sizeof line, "| %s | %.2f | %.2f | %.2f | %.2f | %.2f |",
                    sizeLabel(n).c_str(), median(ts), median(tpk), median(tp), median(tc),
                    median(ts) + median(tp) + median(tc));
      stage_lines.push_back(line);
    }
    gidx.clear();
    gidx.shrink_to_fit();
    gd2.clear();
    gd2.shrink_to_fit();
    cl = gf::NeighborLists();

    // ---- whole normal-vector filter
    const auto cloud = gf::CloudView::packedXyz(xyz.data(), n);
    gf::NormalGroundFilterParams pg, pc;
    pg.knn_backend = "gpu";
    pc.knn_backend = "kdtree";
    gf::NormalGroundFilter fg(pg), fc(pc);
    std::vector<std::uint8_t> lg, lc;
    gf::FilterStats sg, sc;
    std::vector<double> g_knn, g_pca, c_knn, c_pca;
    const double g_ms = timeMedian(r, [&] {
      fg.filter(cloud, &lg, &sg);
      g_knn.push_back(stage(sg, "knn"));
      g_pca.push_back(stage(sg, "pca"));
    });
    const double c_ms = timeMedian(r, [&] {
      fc.filter(cloud, &lc, &sc);
      c_knn.push_back(stage(sc, "knn") + stage(sc, "kdtree_build"));
      c_pca.push_back(stage(sc, "pca"));
    });
    std::size_t ldiff = 0;
    for (std::size_t i = 0; i < n; ++i) ldiff += lg[i] != lc[i];
    const double gk = median(g_knn), gp = median(g_pca), ck = median(c_knn), cp = median(c_pca);
    filter_rows.push_back({sizeLabel(n), g_ms, gk, gp, g_ms - gk - gp, c_ms, ck, cp, c_ms - ck - cp,
                           ldiff, sg.backend + (sg.note.empty() ? "" : ": " + sg.note)});
    std::fprintf(stderr, "  gpu filter stages:");
    for (const auto& s : sg.stage_ms) std::fprintf(stderr, " %s %.2f", s.first.c_str(), s.second);
    std::fprintf(stderr, "\n  cpu filter stages:");
    for (const auto& s : sc.stage_ms) std::fprintf(stderr, " %s %.2f", s.first.c_str(), s.second);
    std::fprintf(stderr, "\n");
  }

  std::printf("K-nearest neighbours, K = %d (ms)\n\n", k);
  std::printf(
      "| points | GPU upload | GPU grid | GPU query + download | GPU total | GPU, lists "
      "kept on device | kd-tree (%d threads) | of which build | speed-up | rows differing "
      "|\n",
      cores);
  std::printf("|---|---|---|---|---|---|---|---|---|---|\n");
  for (const auto& r : knn_rows) {
    std::printf("| %s | %.2f | %.2f | %.2f | **%.2f** | %.2f | %.1f | %.1f | **%.0fx** | %zu |\n",
                r.size.c_str(), r.gpu_up, r.gpu_grid, r.gpu_query, r.gpu_total, r.gpu_device_only,
                r.cpu_total, r.cpu_build, r.cpu_total / r.gpu_total, r.rows_differ);
  }
  std::printf("\nWhole normal-vector filter (ms)\n\n");
  std::printf(
      "| points | GPU total | GPU knn | GPU pca | GPU rest | kd-tree total | kd-tree knn "
      "| kd-tree pca | kd-tree rest | speed-up | labels differing | backend |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  for (const auto& r : filter_rows) {
    std::printf(
        "| %s | **%.1f** | %.1f | %.1f | %.1f | %.1f | %.1f | %.1f | %.1f | %.1fx | %zu | %s |\n",
        r.size.c_str(), r.gpu_total, r.gpu_knn, r.gpu_pca, r.gpu_rest, r.cpu_total, r.cpu_knn,
        r.cpu_pca, r.cpu_rest, r.cpu_total / r.gpu_total, r.labels_differ, r.note.c_str());
  }
  std::printf(
      "\nGPU calls of the filter (ms): search with lists kept on the device, PCA (kernel + "
      "download; and with conversion to PointPca), vote counts (flags up, counts down)\n\n"
      "| points | search | PCA kernel + download | PCA call | vote counts | sum |\n"
      "|---|---|---|---|---|---|\n");
  for (const auto& l : stage_lines) std::printf("%s\n", l.c_str());
  if (!variant_lines.empty()) {
    std::printf(
        "\nGPU KNN variants (ms; work per query from a run with counters)\n\n| points | "
        "cell order | level_min_points | query + download | total | candidates | "
        "insertions | shells | levels | mean cycles | max cycles |\n"
        "|---|---|---|---|---|---|---|---|---|---|---|\n");
    for (const auto& l : variant_lines) std::printf("%s\n", l.c_str());
  }
  return 0;
}
