// ground_filter_knn_benchmark: K-nearest neighbours of every point of a scan with the core's
// kd-tree backend (KdTreeNeighborSearch) and with PCL's KdTreeFLANN, same points, same K; and the
// whole normal-vector filter on a large cloud made of KITTI frames shifted in x/y.

#include <omp.h>
#include <pcl/kdtree/kdtree_flann.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <iostream>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

#include "cli_args.h"
#include "eval/scan_io.h"
#include "ground_filter/ground_filter.h"
#include "knn/kdtree_neighbor_search.h"

namespace gf = ground_filter;
namespace cli = ground_filter::cli;

namespace {

const char kUsage[] =
    "usage: ground_filter_knn_benchmark [--k K] [--repeat N] [--threads N[,N...]] [SCAN]\n"
    "       ground_filter_knn_benchmark --large POINTS [--repeat N] [--set NAME=VALUE]... "
    "[SCAN...]\n"
    "\n"
    "Default mode: K nearest neighbours (itself included) of every point of SCAN with the core "
    "kd-tree\n"
    "(KdTreeNeighborSearch) and PCL KdTreeFLANN (nearestKSearch per point, OpenMP); prints the\n"
    "median build / query / total ms and checks both give the same distances.\n"
    "--large: a cloud of POINTS points from the SCANs (KITTI frames) repeated with x/y offsets of\n"
    "200 m, filtered by the normal-vector method; prints the median of every stage.\n"
    "\n"
    "SCAN      default DATA/semantickitti/seq00/000000.bin (--large: 00000{0..5}.bin),\n"
    "          DATA = $GF_DATA_DIR or " GF_DEFAULT_DATA_DIR
    "\n"
    "--k K            neighbours per point (default 50)\n"
    "--repeat N       timed runs (default 5; --large: 3)\n"
    "--threads LIST   query threads, one row per value (default 1,all cores)\n"
    "--set NAME=VALUE normal filter parameter for --large (repeatable)\n";

using Clock = std::chrono::steady_clock;

using cli::median;
using cli::msSince;

/// Finite points of a scan as packed xyz.
std::vector<float> packedXyz(const std::string& path) {
  const gf::Scan scan = gf::loadScan(path);
  const gf::CloudView view = gf::viewOf(scan.cloud);
  std::vector<float> xyz;
  xyz.reserve(3 * view.size());
  for (std::size_t i = 0; i < view.size(); ++i) {
    float x, y, z;
    if (view.get(i, &x, &y, &z)) xyz.insert(xyz.end(), {x, y, z});
  }
  return xyz;
}

int knnMode(const std::string& path, int k, int repeat, const std::vector<int>& thread_list) {
  const std::vector<float> xyz = packedXyz(path);
  const std::size_t n = xyz.size() / 3;
  std::printf("%s: %zu points, K = %d, median of %d runs\n", path.c_str(), n, k, repeat);
  std::printf("%-22s %7s %10s %10s %10s %14s\n", "backend", "threads", "build_ms", "query_ms",
              "total_ms", "sum_sq_dist");

  pcl::PointCloud<pcl::PointXYZ>::Ptr cloud(new pcl::PointCloud<pcl::PointXYZ>);
  cloud->resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    (*cloud)[i].x = xyz[3 * i];
    (*cloud)[i].y = xyz[3 * i + 1];
    (*cloud)[i].z = xyz[3 * i + 2];
  }

  for (int threads : thread_list) {
    // the core kd-tree backend (KdTreeNeighborSearch).
    gf::KdTreeNeighborSearch nano(threads);
    gf::NeighborLists lists;
    std::vector<double> build, query, total;
    for (int r = 0; r < repeat; ++r) {
      const auto t0 = Clock::now();
      nano.search(xyz.data(), n, k, &lists);
      total.push_back(msSince(t0));
      build.push_back(nano.lastBuildMs());
      query.push_back(nano.lastQueryMs());
    }
    double nano_sum = 0.0;
    for (float d : lists.sq_dists) nano_sum += std::isfinite(d) ? d : 0.0;
    std::printf("%-22s %7d %10.1f %10.1f %10.1f %14.3f\n", "kdtree (own, exact)", threads,
                median(build), median(query), median(total), nano_sum);

    // PCL KdTreeFLANN: build = setInputCloud, queries in parallel like the core does.
    std::vector<int> idx(n * static_cast<std::size_t>(k));
    std::vector<float> dist(n * static_cast<std::size_t>(k));
    build.clear();
    query.clear();
    total.clear();
    for (int r = 0; r < repeat; ++r) {
      const auto t0 = Clock::now();
      pcl::KdTreeFLANN<pcl::PointXYZ> tree;
      tree.setInputCloud(cloud);
      build.push_back(msSince(t0));
      const auto t1 = Clock::now();
#pragma omp parallel num_threads(threads)
      {
        std::vector<int> ki(k);
        std::vector<float> kd(k);
#pragma omp for schedule(dynamic, 512)
        for (std::int64_t i = 0; i < static_cast<std::int64_t>(n); ++i) {
          const int found = tree.nearestKSearch((*cloud)[i], k, ki, kd);
          for (int j = 0; j < found; ++j) {
            idx[i * k + j] = ki[j];
            dist[i * k + j] = kd[j];
          }
        }
      }
      query.push_back(msSince(t1));
      total.push_back(msSince(t0));
    }
    double pcl_sum = 0.0;
    for (float d : dist) pcl_sum += d;
    std::printf("%-22s %7d %10.1f %10.1f %10.1f %14.3f\n", "PCL KdTreeFLANN", threads,
                median(build), median(query), median(total), pcl_sum);
    if (std::abs(pcl_sum - nano_sum) > 1e-4 * std::max(1.0, nano_sum)) {
      std::fprintf(stderr, "distance sums differ: kdtree %.6f, PCL %.6f\n", nano_sum, pcl_sum);
      return 1;
    }
  }
  return 0;
}

int largeMode(const std::vector<std::string>& paths, std::size_t points, int repeat,
              const gf::ParamSettings& settings) {
  std::vector<std::vector<float>> frames;
  for (const auto& p : paths) frames.push_back(packedXyz(p));
  // Frames placed on a grid of 200 m offsets: KITTI frames reach about 80 m, so copies do not mix.
  std::vector<float> xyz;
  xyz.reserve(3 * points);
  for (std::size_t copy = 0; xyz.size() / 3 < points; ++copy) {
    const std::vector<float>& f = frames[copy % frames.size()];
    const float ox = 200.f * static_cast<float>(copy % 8),
                oy = 200.f * static_cast<float>(copy / 8);
    for (std::size_t i = 0; i + 2 < f.size() && xyz.size() / 3 < points; i += 3) {
      xyz.insert(xyz.end(), {f[i] + ox, f[i + 1] + oy, f[i + 2]});
    }
  }
  const std::size_t n = xyz.size() / 3;
  auto filter = gf::makeGroundFilter("normal", settings);
  std::map<std::string, std::vector<double>> stages;
  std::vector<std::string> order;
  std::vector<double> total;
  std::size_t ground = 0;
  for (int r = 0; r < repeat; ++r) {
    std::vector<std::uint8_t> labels;
    gf::FilterStats st;
    filter->filter(gf::CloudView::packedXyz(xyz.data(), n), &labels, &st);
    total.push_back(st.total_ms);
    for (const auto& s : st.stage_ms) {
      if (!stages.count(s.first)) order.push_back(s.first);
      stages[s.first].push_back(s.second);
    }
    ground = st.ground_points;
  }
  std::printf("normal filter on %zu points (%zu frames shifted by 200 m), median of %d runs\n", n,
              (n + frames[0].size() / 3 - 1) / (frames[0].size() / 3), repeat);
  for (const auto& s : order) std::printf("  %-14s %10.1f ms\n", s.c_str(), median(stages[s]));
  std::printf("  %-14s %10.1f ms  (%.2f M points/s, %zu ground)\n", "total", median(total),
              n / (median(total) * 1e3), ground);
  return 0;
}

struct Options : cli::SetsAndPaths {
  int k = 50;
  int repeat = 0;  // 0: the mode's default
  int large = 0;
  std::vector<int> threads;
};

Options parseArgs(int argc, char** argv) {
  Options o;
  cli::parseCommandLine(argc, argv, kUsage,
                        {{"--k", &o.k, 1, 256},
                         {"--repeat", &o.repeat, 1, 100000},
                         {"--large", &o.large, 1, 1000000000}},
                        &o, [&](cli::ArgCursor* args) {
                          if (args->option() != "--threads") return false;
                          o.threads = cli::parseIntList("--threads", args->value(), 1, 1024);
                          return true;
                        });
  return o;
}

int run(Options o) {
  // The data folder only when a default input is needed (cli::dataDir() fails without one).
  const std::string data = o.paths.empty() ? cli::dataDir() : std::string();
  std::printf("%s\n", cli::simdDescription().c_str());
  if (o.large > 0) {
    if (o.paths.empty()) {
      for (int f = 0; f < 6; ++f) {
        o.paths.push_back(data + "/semantickitti/seq00/00000" + std::to_string(f) + ".bin");
      }
    }
    return largeMode(o.paths, static_cast<std::size_t>(o.large), o.repeat > 0 ? o.repeat : 3,
                     o.settings);
  }
  if (o.paths.empty()) o.paths.push_back(data + "/semantickitti/seq00/000000.bin");
  if (o.threads.empty()) o.threads = {1, omp_get_num_procs()};
  int rc = 0;
  for (const auto& p : o.paths) rc |= knnMode(p, o.k, o.repeat > 0 ? o.repeat : 5, o.threads);
  return rc;
}

}  // namespace

int main(int argc, char** argv) {
  return cli::runTool("ground_filter_knn_benchmark", [&] { return run(parseArgs(argc, argv)); });
}
