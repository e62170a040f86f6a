// ground_filter_scale_benchmark: how a method's time and memory grow with the size of a scan.
// Generates one TLS-like station scan per size (the scene generator's `tls` kind, the point
// budget set to the size), runs each method at each thread count on it and prints ms, ns per
// point, the peak memory the filter added and bytes per point, then the spread of the per-point
// figures over the sizes (linear cost: max / min close to 1).

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "cli_args.h"
#include "eval/metrics.h"
#include "eval/scene_generator.h"
#include "ground_filter/cloud_view.h"
#include "ground_filter/ground_filter.h"

namespace gf = ground_filter;
namespace cli = ground_filter::cli;

namespace {

const char kUsage[] =
    "usage: ground_filter_scale_benchmark [--sizes LIST] [--methods LIST] [--threads LIST]\n"
    "                                     [--repeat N] [--seed N] [--gpu] [--set NAME=VALUE]...\n"
    "\n"
    "Generates a TLS-like station scan (builtin:tls, a street seen from a tripod scanner,\n"
    "density falling with range) of each size and times GroundFilter::filter() on it: median\n"
    "ms of --repeat runs after one warm-up, ns per point, the peak resident memory the filter\n"
    "added on top of the scan (VmHWM after /proc/self/clear_refs) and bytes per point, and F1\n"
    "against the exact truth. Last, per method and thread count, the largest / smallest per-\n"
    "point time and memory over the sizes (1.00 = perfectly linear cost).\n"
    "\n"
    "--sizes LIST     scan sizes in million points (default 1,5,20,50; 0.05 .. 100)\n"
    "--methods LIST   methods (default voxel,normal; also voxel_paper)\n"
    "--threads LIST   values of the 'threads' parameter, a row each (default 1,2)\n"
    "--repeat N       timed runs per row (default 3)\n"
    "--seed N         scene seed (default 1)\n"
    "--gpu            also a row 'normal/gpu' (knn_backend=gpu: the whole normal filter on a\n"
    "                 CUDA GPU; where none is usable the filter falls back to the kd-tree and\n"
    "                 the row says so)\n"
    "--set NAME=VALUE a filter parameter for every method (repeatable), e.g.\n"
    "                 --set knn_backend=gpu for the normal method on a CUDA GPU\n"
    "--help           this text\n";

using cli::UsageError;

struct Options {
  std::vector<double> sizes_m = {1, 5, 20, 50};
  std::vector<std::string> methods = {"voxel", "normal"};
  std::vector<int> threads = {1, 2};
  int repeat = 3;
  int seed = 1;
  bool gpu = false;
  gf::ParamSettings settings;
};

std::vector<std::string> splitList(const std::string& opt, const std::string& v) {
  std::vector<std::string> out;
  std::stringstream in(v);
  std::string item;
  while (std::getline(in, item, ',')) {
    if (item.empty()) throw UsageError(opt + ": empty entry in '" + v + "'");
    out.push_back(item);
  }
  if (out.empty()) throw UsageError(opt + ": empty list");
  return out;
}

Options parseArgs(int argc, char** argv) {
  Options o;
  std::vector<std::string> paths;
  cli::parseCommandLine(
      argc, argv, kUsage, {{"--repeat", &o.repeat, 1, 1000}, {"--seed", &o.seed, 0, 1000000}},
      &o.settings, &paths, [&](cli::ArgCursor* args) {
        if (args->option() == "--sizes") {
          o.sizes_m.clear();
          for (const auto& s : splitList("--sizes", args->value())) {
            char* end = nullptr;
            const double m = std::strtod(s.c_str(), &end);
            if (end == s.c_str() || *end != '\0' || !(m >= 0.05 && m <= 100.0)) {
              throw UsageError("--sizes: '" + s +
                               "' is not a number of million points in 0.05..100");
            }
            o.sizes_m.push_back(m);
          }
        } else if (args->option() == "--methods") {
          o.methods = splitList("--methods", args->value());
        } else if (args->option() == "--gpu") {
          o.gpu = true;
        } else if (args->option() == "--threads") {
          o.threads = cli::parseIntList("--threads", args->value(), 1, 1024);
        } else {
          return false;
        }
        return true;
      });
  if (!paths.empty()) throw UsageError("no PATH operands: the scans are generated");
  return o;
}

/// A field of /proc/self/status in KiB (VmRSS, VmHWM); -1 where it cannot be read.
long statusKib(const char* field) {
  std::ifstream in("/proc/self/status");
  std::string line;
  const std::string key = std::string(field) + ":";
  while (std::getline(in, line)) {
    if (line.compare(0, key.size(), key) == 0) return std::atol(line.c_str() + key.size());
  }
  return -1;
}

/// Resets VmHWM to the current RSS (Linux 4.0+); false where the kernel refuses.
bool resetPeak() {
  std::ofstream out("/proc/self/clear_refs");
  out << "5";
  out.flush();
  return static_cast<bool>(out);
}

struct Row {
  double size_m = 0;
  std::string method;
  int threads = 0;
  std::size_t points = 0;
  double median_ms = 0;
  double peak_mib = -1;  // memory the filter added at its peak; < 0 unknown
  double f1 = 0;
  double nsPerPoint() const { return points ? median_ms * 1e6 / points : 0.0; }
  double bytesPerPoint() const { return peak_mib < 0 ? -1.0 : peak_mib * 1048576.0 / points; }
};

/// One method at one thread count on one scan: a fresh filter (its buffers count in the peak).
Row benchRow(const Options& opt, double size_m, const std::string& method, int threads,
             const gf::CloudView& view, const std::vector<std::int8_t>& truth, bool gpu) {
  gf::ParamSettings settings = opt.settings;
  settings.emplace_back("threads", std::to_string(threads));
  if (gpu) settings.emplace_back("knn_backend", "gpu");
  Row row;
  row.size_m = size_m;
  row.method = gpu ? method + "/gpu" : method;
  row.threads = threads;
  row.points = view.size();
  const bool peak_known = resetPeak();
  const long base_kib = statusKib("VmRSS");
  std::vector<double> times;
  {
    std::unique_ptr<gf::GroundFilter> filter;
    try {
      filter = gf::makeGroundFilter(method, settings);
    } catch (const std::invalid_argument& e) {
      throw UsageError(e.what());
    }
    std::vector<std::uint8_t> labels;
    gf::FilterStats stats;
    filter->filter(view, &labels, &stats);  // warm-up: buffers sized, pages touched
    if (gpu && stats.backend.find("gpu") == std::string::npos) row.method = method + "/gpu->cpu";
    for (int r = 0; r < opt.repeat; ++r) {
      const auto t0 = std::chrono::steady_clock::now();
      filter->filter(view, &labels, nullptr);
      times.push_back(cli::msSince(t0));
    }
    row.f1 = gf::computeMetrics(gf::countConfusion(labels, truth)).f1;
  }
  const long peak_kib = statusKib("VmHWM");
  if (peak_known && base_kib >= 0 && peak_kib >= base_kib)
    row.peak_mib = (peak_kib - base_kib) / 1024.0;
  row.median_ms = cli::median(times);
  return row;
}

/// The CUDA context (~100 MB of host memory, once per process) is created before any row, so
/// that it does not count in the first GPU row's peak.
void warmGpu(const Options& opt) {
  gf::SceneParams sp = gf::builtinSceneParams("tls");
  sp.tls_points = 20000;
  const gf::GeneratedScan g = gf::generateScene(sp);
  gf::ParamSettings settings = opt.settings;
  settings.emplace_back("knn_backend", "gpu");
  std::vector<std::uint8_t> labels;
  gf::makeGroundFilter("normal", settings)
      ->filter(gf::CloudView::packedXyz(g.xyz.data(), g.size()), &labels, nullptr);
}

void printRow(const Row& r) {
  std::printf("%7.2f %-11s %7d %10zu %11.1f %8.1f %9.1f %9.1f %6.4f\n", r.size_m, r.method.c_str(),
              r.threads, r.points, r.median_ms, r.nsPerPoint(), r.peak_mib, r.bytesPerPoint(),
              r.f1);
  std::fflush(stdout);
}

/// Per method and thread count: largest / smallest ns and bytes per point over the sizes.
void printSpread(const Options& opt, const std::vector<Row>& rows) {
  std::printf("\nspread over the sizes (largest / smallest per-point figure; 1.00 = linear)\n");
  std::printf("%-11s %7s %12s %14s %16s\n", "method", "threads", "ns/pt spread", "bytes/pt spread",
              "bytes/pt median");
  std::vector<std::string> names = opt.methods;
  if (opt.gpu) names.push_back("normal/gpu");
  for (const auto& m : names) {
    for (int t : opt.threads) {
      std::vector<double> ns, bytes;
      for (const auto& r : rows) {
        if (r.method != m || r.threads != t) continue;
        ns.push_back(r.nsPerPoint());
        if (r.bytesPerPoint() > 0) bytes.push_back(r.bytesPerPoint());
      }
      if (ns.empty()) continue;
      const auto ratio = [](const std::vector<double>& v) {
        if (v.empty()) return -1.0;
        const auto mm = std::minmax_element(v.begin(), v.end());
        return *mm.first > 0 ? *mm.second / *mm.first : -1.0;
      };
      std::printf("%-11s %7d %12.2f %14.2f %16.1f\n", m.c_str(), t, ratio(ns), ratio(bytes),
                  bytes.empty() ? -1.0 : cli::median(bytes));
    }
  }
}

int run(const Options& opt) {
  std::string settings;
  for (const auto& kv : opt.settings) settings += " " + kv.first + "=" + kv.second;
  std::printf("%s\n", cli::simdDescription().c_str());
  std::printf(
      "builtin:tls seed %d; %d timed runs per row after 1 warm-up; %u hardware threads%s%s\n",
      opt.seed, opt.repeat, std::thread::hardware_concurrency(),
      settings.empty() ? "" : "; settings", settings.c_str());
  std::printf(
      "peak_MiB: resident memory the filter added at its peak (its buffers and outputs), on\n"
      "top of the scan itself (12 bytes a point of x y z float32)\n\n");
  std::printf("%7s %-11s %7s %10s %11s %8s %9s %9s %6s\n", "size_M", "method", "threads", "points",
              "median_ms", "ns/pt", "peak_MiB", "bytes/pt", "F1");
  bool gpu_asked = opt.gpu;
  for (const auto& kv : opt.settings) gpu_asked |= kv.first == "knn_backend" && kv.second == "gpu";
  if (gpu_asked) warmGpu(opt);
  std::vector<Row> rows;
  for (double size_m : opt.sizes_m) {
    std::vector<float> xyz;
    std::vector<std::int8_t> truth;  // the eval kit's truth type (1 ground, 0 not)
    {
      gf::SceneParams sp = gf::builtinSceneParams("tls");
      sp.seed = static_cast<unsigned>(opt.seed);
      sp.tls_points = static_cast<std::size_t>(size_m * 1e6);
      gf::GeneratedScan g = gf::generateScene(sp);
      xyz.swap(g.xyz);
      truth.assign(g.truth.begin(), g.truth.end());
    }  // the generator's other arrays are freed before any filter runs
    const gf::CloudView view = gf::CloudView::packedXyz(xyz.data(), truth.size());
    for (const auto& m : opt.methods) {
      for (int t : opt.threads) {
        rows.push_back(benchRow(opt, size_m, m, t, view, truth, false));
        printRow(rows.back());
        if (opt.gpu && m == "normal") {
          rows.push_back(benchRow(opt, size_m, m, t, view, truth, true));
          printRow(rows.back());
        }
      }
    }
  }
  printSpread(opt, rows);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  return cli::runTool("ground_filter_scale_benchmark", [&] { return run(parseArgs(argc, argv)); });
}
