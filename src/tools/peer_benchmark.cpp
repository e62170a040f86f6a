// ground_filter_peer_benchmark: the voxel filter against PCL's SACSegmentation plane (RANSAC),
// alternated call by call on the same frames; medians, their ratio and, where the scan has ground
// truth, F1 of both. Benchmark only: this target alone is built with -march=native and
// PCL_NO_PRECOMPILE (PCL's templates compiled here, for this CPU); the voxel filter comes from
// the shipped core library (portable flags).

#include <pcl/ModelCoefficients.h>
#include <pcl/PointIndices.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/sample_consensus/method_types.h>
#include <pcl/sample_consensus/model_types.h>
#include <pcl/segmentation/sac_segmentation.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <iostream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "cli_args.h"
#include "eval/metrics.h"
#include "eval/scan_io.h"
#include "eval/scene_generator.h"
#include "ground_filter/voxel_ground_filter.h"

namespace gf = ground_filter;
namespace cli = ground_filter::cli;

namespace {

const char kUsage[] =
    "usage: ground_filter_peer_benchmark [--repeat N] [--warmup N] [--threads N]\n"
    "                                    [--replicate K] [--replicate-row] [--tls-points N]\n"
    "                                    [--no-peer] [--stages]\n"
    "                                    [--set NAME=VALUE]... [PATH...]\n"
    "\n"
    "Times the voxel filter (shipped build) and PCL's SACSegmentation plane (RANSAC, distance\n"
    "threshold 0.2 m, 1000 iterations, optimized coefficients; compiled here with -march=native\n"
    "and PCL_NO_PRECOMPILE), alternating the two call by call on the same points. Prints the\n"
    "median and min ms of both, the ratio voxel / RANSAC of the medians and, for labelled scans,\n"
    "F1 (ground positive) of both (RANSAC: plane inliers are ground).\n"
    "\n"
    "PATH            scan file, directory or builtin:lidar[:SEED] / builtin:tls[:SEED]; default:\n"
    "                DATA/semantickitti/seq00/00000{0,1,2}.bin (DATA = $GF_DATA_DIR or\n"
    "                " GF_DEFAULT_DATA_DIR
    ")\n"
    "--repeat N      timed calls of each method per input (default 15)\n"
    "--warmup N      untimed calls of each before timing (default 1)\n"
    "--threads N     the voxel filter's threads parameter (default 1)\n"
    "--replicate K   each input as K copies on a grid of ceil(sqrt(K)) copies along x by as many\n"
    "                rows along y as needed (shifted by the input's x / y extent + 10 m), as a\n"
    "                survey of adjacent scans would be; e.g. K = 40 makes 5 M points of a KITTI\n"
    "                frame, 7 x 6 frames, about 1.2 x 0.7 km (default 1)\n"
    "--replicate-row the K copies in one row along x instead (the layout before the grid: 40\n"
    "                KITTI copies reach 6.8 km, so the ones beyond x = 5000 m lie outside the\n"
    "                working volume and are non-ground without being filtered)\n"
    "--tls-points N  add a generated TLS scan of N points (builtin:tls with tls_points = N)\n"
    "--no-peer       time the voxel filter only\n"
    "--stages        also print the voxel filter's median stage times (its FilterStats; the\n"
    "                working-volume wrapper's pass and packing, when it runs, as\n"
    "                \"working volume\")\n"
    "--set N=V       voxel filter parameter (repeatable)\n"
    "--help          this text\n";

struct Options : cli::SetsAndPaths {
  int repeat = 15;
  int warmup = 1;
  int threads = 1;
  int replicate = 1;
  bool replicate_row = false;
  int tls_points = 0;
  bool peer = true;
  bool stages = false;
};

Options parseArgs(int argc, char** argv) {
  Options o;
  cli::parseCommandLine(argc, argv, kUsage,
                        {{"--repeat", &o.repeat, 1, 100000},
                         {"--warmup", &o.warmup, 0, 1000},
                         {"--threads", &o.threads, 0, 256},
                         {"--replicate", &o.replicate, 1, 1000},
                         {"--tls-points", &o.tls_points, 1000, 5000000}},
                        &o, [&](cli::ArgCursor* args) {
                          if (args->option() == "--no-peer") {
                            o.peer = false;
                          } else if (args->option() == "--stages") {
                            o.stages = true;
                          } else if (args->option() == "--replicate-row") {
                            o.replicate_row = true;
                          } else {
                            return false;
                          }
                          return true;
                        });
  return o;
}

// One input: packed x y z of its points (NaN/Inf kept: the voxel filter sees every point) and
// truth per point (-1 ignored) or empty.
struct Input {
  std::string name;
  std::vector<float> xyz;
  std::vector<std::int8_t> truth;
  std::size_t size() const { return xyz.size() / 3; }
};

// Extent [lo, hi] of the finite values of coordinate `axis` (0 = x, 1 = y).
std::pair<float, float> extentOf(const Input& in, int axis) {
  float lo = 1e30f, hi = -1e30f;
  for (std::size_t i = 0; i < in.size(); ++i) {
    const float v = in.xyz[3 * i + axis];
    if (std::isfinite(v)) {
      lo = std::min(lo, v);
      hi = std::max(hi, v);
    }
  }
  return {lo, hi};
}

// `copies` copies of `in`, each shifted by the input's extent + 10 m: on a grid of
// ceil(sqrt(copies)) along x (rows along y), or all along x when `row`.
Input replicate(Input in, int copies, bool row) {
  if (copies <= 1) return in;
  const auto ex = extentOf(in, 0), ey = extentOf(in, 1);
  const float step_x = ex.second > ex.first ? ex.second - ex.first + 10.f : 10.f;
  const float step_y = ey.second > ey.first ? ey.second - ey.first + 10.f : 10.f;
  int per_row = copies;
  if (!row) {
    per_row = static_cast<int>(std::ceil(std::sqrt(static_cast<double>(copies))));
  }
  const std::size_t n = in.size();
  Input out;
  out.name = in.name + " x" + std::to_string(copies) + (row ? " row" : " grid");
  out.xyz.reserve(in.xyz.size() * copies);
  for (int k = 0; k < copies; ++k) {
    const float dx = step_x * static_cast<float>(k % per_row);
    const float dy = step_y * static_cast<float>(k / per_row);
    for (std::size_t i = 0; i < n; ++i) {
      out.xyz.push_back(in.xyz[3 * i] + dx);
      out.xyz.push_back(in.xyz[3 * i + 1] + dy);
      out.xyz.push_back(in.xyz[3 * i + 2]);
    }
    out.truth.insert(out.truth.end(), in.truth.begin(), in.truth.end());
  }
  return out;
}

using cli::median;
using cli::msSince;

struct Row {
  std::string name;
  std::size_t points = 0;
  double voxel_med = 0, voxel_min = 0, peer_med = 0, peer_min = 0;
  double voxel_f1 = -1, peer_f1 = -1;
  std::vector<std::pair<std::string, double>> stage_med;  // --stages: median ms per stage
};

/// The inputs: every PATH's scan files (default: three KITTI frames of the dev data) and the
/// generated TLS scene (--tls-points), each replicated as asked.
std::vector<Input> loadInputs(const Options& opt) {
  std::vector<Input> inputs;
  std::vector<std::string> paths = opt.paths;
  if (paths.empty() && opt.tls_points == 0) {
    const std::string data = cli::dataDir();
    for (const char* f : {"000000", "000001", "000002"}) {
      paths.push_back(data + "/semantickitti/seq00/" + f + ".bin");
    }
  }
  for (const std::string& p : paths) {
    for (const std::string& file : gf::listScanFiles(p)) {
      const gf::Scan scan = gf::loadScan(file);
      const gf::CloudView view = gf::viewOf(scan.cloud);
      Input in;
      in.name = gf::scanStem(file);
      in.xyz.resize(3 * view.size());
      for (std::size_t i = 0; i < view.size(); ++i) {
        in.xyz[3 * i] = view.x(i);
        in.xyz[3 * i + 1] = view.y(i);
        in.xyz[3 * i + 2] = view.z(i);
      }
      in.truth = scan.truth;
      inputs.push_back(replicate(std::move(in), opt.replicate, opt.replicate_row));
    }
  }
  if (opt.tls_points > 0) {
    gf::SceneParams sp;
    sp.mode = gf::SceneParams::Mode::kTls;
    sp.tls_points = static_cast<std::size_t>(opt.tls_points);
    gf::GeneratedScan g = gf::generateScene(sp);
    Input in;
    in.name = "builtin:tls(" + std::to_string(opt.tls_points) + ")";
    in.xyz = std::move(g.xyz);
    in.truth.assign(g.truth.begin(), g.truth.end());
    inputs.push_back(replicate(std::move(in), opt.replicate, opt.replicate_row));
  }
  return inputs;
}

/// One input: the voxel filter and (--peer) PCL's RANSAC plane alternated call by call, medians,
/// minima, stage medians (--stages) and F1 where the input has truth.
Row benchInput(const Options& opt, const gf::ParamSettings& settings, const Input& in) {
  const std::size_t n = in.size();
  const gf::CloudView view = gf::CloudView::packedXyz(in.xyz.data(), n);
  auto voxel = gf::makeGroundFilter("voxel", settings);
  std::vector<std::uint8_t> labels, peer_labels(n, 0);
  // RANSAC input: the finite points (SACSegmentation itself drops nothing).
  pcl::PointCloud<pcl::PointXYZ>::Ptr cloud(new pcl::PointCloud<pcl::PointXYZ>);
  std::vector<std::size_t> index;
  if (opt.peer) cloud->reserve(n);
  for (std::size_t i = 0; i < n && opt.peer; ++i) {
    const float x = in.xyz[3 * i], y = in.xyz[3 * i + 1], z = in.xyz[3 * i + 2];
    if (!std::isfinite(x) || !std::isfinite(y) || !std::isfinite(z)) continue;
    cloud->push_back(pcl::PointXYZ(x, y, z));
    index.push_back(i);
  }
  pcl::SACSegmentation<pcl::PointXYZ> seg;
  seg.setOptimizeCoefficients(true);
  seg.setModelType(pcl::SACMODEL_PLANE);
  seg.setMethodType(pcl::SAC_RANSAC);
  seg.setDistanceThreshold(0.2);
  seg.setMaxIterations(1000);
  seg.setInputCloud(cloud);
  pcl::PointIndices inliers;
  pcl::ModelCoefficients coefficients;

  std::vector<double> tv, tp;
  gf::FilterStats stats;
  std::vector<std::pair<std::string, std::vector<double>>> stage_ms;
  for (int r = 0; r < opt.warmup + opt.repeat; ++r) {
    auto t0 = std::chrono::steady_clock::now();
    voxel->filter(view, &labels, opt.stages ? &stats : nullptr);
    const double v_ms = msSince(t0);
    double p_ms = 0.0;
    if (opt.peer) {
      t0 = std::chrono::steady_clock::now();
      seg.segment(inliers, coefficients);
      p_ms = msSince(t0);
    }
    if (r < opt.warmup) continue;
    for (const auto& st : opt.stages ? stats.stage_ms : decltype(stats.stage_ms)()) {
      auto it = std::find_if(stage_ms.begin(), stage_ms.end(),
                             [&](const auto& e) { return e.first == st.first; });
      if (it == stage_ms.end()) it = stage_ms.insert(stage_ms.end(), {st.first, {}});
      it->second.push_back(st.second);
    }
    tv.push_back(v_ms);
    tp.push_back(p_ms);
  }
  Row row;
  row.name = in.name;
  row.points = n;
  row.voxel_med = median(tv);
  row.voxel_min = *std::min_element(tv.begin(), tv.end());
  row.peer_med = median(tp);
  row.peer_min = *std::min_element(tp.begin(), tp.end());
  for (auto& st : stage_ms) row.stage_med.emplace_back(st.first, median(st.second));
  if (!in.truth.empty()) {
    row.voxel_f1 = gf::computeMetrics(gf::countConfusion(labels, in.truth)).f1;
    if (opt.peer) {
      for (int k : inliers.indices) peer_labels[index[static_cast<std::size_t>(k)]] = 1;
      row.peer_f1 = gf::computeMetrics(gf::countConfusion(peer_labels, in.truth)).f1;
    }
  }
  return row;
}

/// The table: one row per input, the sums of medians, the stage medians.
void printRows(const Options& opt, const std::vector<Row>& rows) {
  std::printf("%s\n", cli::simdDescription().c_str());
  std::printf(
      "voxel (threads=%d, shipped flags) vs PCL SACSegmentation plane (RANSAC 0.2 m, 1000 "
      "iterations, optimized; -march=native); %d alternated calls each after %d warm-up\n",
      opt.threads, opt.repeat, opt.warmup);
  std::printf("%-28s %9s %10s %9s %10s %9s %7s %8s %8s\n", "input", "points", "voxel_med",
              "voxel_min", "ransac_med", "ransac_min", "ratio", "voxel_F1", "ransac_F1");
  double sv = 0, sp = 0;
  std::size_t np = 0;
  for (const Row& r : rows) {
    auto fixed = [](double v, bool ok) {
      char buf[32];
      std::snprintf(buf, sizeof(buf), "%.2f", v);
      return ok ? std::string(buf) : std::string("-");
    };
    std::printf("%-28s %9zu %10.3f %9.3f %10.3f %9.3f %7s %8s %8s\n", r.name.c_str(), r.points,
                r.voxel_med, r.voxel_min, r.peer_med, r.peer_min,
                fixed(r.voxel_med / r.peer_med, opt.peer).c_str(),
                fixed(100.0 * r.voxel_f1, r.voxel_f1 >= 0).c_str(),
                fixed(100.0 * r.peer_f1, r.peer_f1 >= 0).c_str());
    sv += r.voxel_med;
    sp += r.peer_med;
    np += r.points;
  }
  if (rows.size() > 1) {
    char ratio[32] = "-";
    if (opt.peer) std::snprintf(ratio, sizeof(ratio), "%.2f", sv / sp);
    std::printf("%-28s %9zu %10.3f %9s %10.3f %9s %7s   (sums of medians)\n", "all", np, sv, "", sp,
                "", ratio);
  }
  for (const Row& r : rows) {
    if (r.stage_med.empty()) continue;
    std::printf("stages %s (median ms):", r.name.c_str());
    for (const auto& st : r.stage_med) std::printf(" %s %.3f", st.first.c_str(), st.second);
    std::printf("\n");
  }
}

int run(const Options& opt) {
  const std::vector<Input> inputs = loadInputs(opt);
  gf::ParamSettings settings = opt.settings;
  settings.emplace_back("threads", std::to_string(opt.threads));
  std::vector<Row> rows;
  for (const Input& in : inputs) rows.push_back(benchInput(opt, settings, in));
  printRows(opt, rows);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  return cli::runTool("ground_filter_peer_benchmark", [&] { return run(parseArgs(argc, argv)); });
}
