// ground_filter_benchmark: wall time of a ground filter's core per frame (median / min / max / mean
// over repeated runs), throughput, and per-stage medians from FilterStats::stage_ms.

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <iostream>
#include <map>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "cli_args.h"
#include "eval/scan_io.h"
#include "ground_filter/ground_filter.h"
#include "ground_filter/height_above_ground.h"

namespace gf = ground_filter;
namespace cli = ground_filter::cli;

namespace {

const char kUsage[] =
    "usage: ground_filter_benchmark [--method NAME] [--params FILE] [--set NAME=VALUE]...\n"
    "                               [--repeat N] [--warmup N] [--threads N[,N...]]\n"
    "                               [--hag-threads N[,N...]] [PATH...]\n"
    "\n"
    "Times GroundFilter::filter() on each scan (the core only: loading is not timed) and prints\n"
    "median / min / max / mean ms per frame, million points per second (from the median) and the\n"
    "median of every stage the filter reports.\n"
    "\n"
    "PATH                scan file, directory or builtin:KIND[:SEED] (lidar, tls, verge,\n"
    "                    offroad, trail);\n"
    "                    default: DATA/semantickitti/seq00/00000{0,1,2}.bin and\n"
    "                    DATA/unlabelled/os128_000000.pcd with DATA = $GF_DATA_DIR or the\n"
    "                    build-time default " GF_DEFAULT_DATA_DIR
    "\n"
    "--method NAME       filter method: voxel (default), normal, voxel_paper\n"
    "--params FILE       parameters from a flat YAML file (config/*.yaml, 'name: value')\n"
    "--set NAME=VALUE    override a filter parameter (repeatable; after --params)\n"
    "--repeat N          timed runs per file (default 20)\n"
    "--warmup N          untimed runs per file before timing (default 2)\n"
    "--threads LIST      set the filter's 'threads' parameter, one table row per value\n"
    "                    (e.g. 1,2); default: the method's default\n"
    "--hag-threads LIST  after each timed filter call, also time GroundSurface::build() and\n"
    "                    heights() on its labels (as a nodelet does for height_above_ground),\n"
    "                    with GroundSurfaceParams::threads taken from LIST in turn, call by call\n"
    "                    (0 = all cores); prints their medians per file and value\n"
    "--help              this text\n";

using cli::UsageError;

struct Options {
  std::string method = "voxel";
  gf::ParamSettings settings;
  int repeat = 20;
  int warmup = 2;
  std::vector<std::string> threads;  // empty: the method's default
  std::vector<int> hag_threads;      // --hag-threads; empty: no surface
  std::vector<std::string> paths;
};

Options parseArgs(int argc, char** argv) {
  Options o;
  cli::FilterArgs filter_args;
  cli::parseCommandLine(argc, argv, kUsage,
                        {{"--repeat", &o.repeat, 1, 1000000}, {"--warmup", &o.warmup, 0, 1000000}},
                        nullptr, &o.paths, [&](cli::ArgCursor* args) {
                          if (args->option() == "--hag-threads") {
                            o.hag_threads =
                                cli::parseIntList("--hag-threads", args->value(), 0, 256);
                            return true;
                          }
                          if (args->option() != "--threads") return filter_args.consume(args);
                          for (int t : cli::parseIntList("--threads", args->value(), 0, 1000000)) {
                            o.threads.push_back(std::to_string(t));
                          }
                          return true;
                        });
  o.method = filter_args.method;
  o.settings = filter_args.settings();
  if (o.paths.empty()) {
    const std::string data = cli::dataDir();
    for (const char* f : {"semantickitti/seq00/000000.bin", "semantickitti/seq00/000001.bin",
                          "semantickitti/seq00/000002.bin", "unlabelled/os128_000000.pcd"}) {
      o.paths.push_back(data + "/" + f);
    }
  }
  return o;
}

struct Row {
  std::string label;  // file stem (+ @threads)
  std::string file;
  std::string threads;
  std::size_t points = 0;
  double median_ms = 0.0, min_ms = 0.0, max_ms = 0.0;
  double mean_ms = 0.0;  // with the scans that pay a periodic cost (a stream's re-measurements)
  std::vector<std::pair<std::string, double>> stages;  // name, median ms (execution order)
  struct Hag {
    int threads;
    double build_ms, heights_ms, total_ms;  // medians
    std::size_t calls;
  };
  std::vector<Hag> hag;  // one per --hag-threads value
};

/// One filter per thread setting, built before any loading so bad parameters fail fast.
std::vector<std::unique_ptr<gf::GroundFilter>> makeFilters(
    const Options& opt, const std::vector<std::string>& thread_values) {
  std::vector<std::unique_ptr<gf::GroundFilter>> filters;
  for (const auto& t : thread_values) {
    gf::ParamSettings settings = opt.settings;
    if (!t.empty()) settings.emplace_back("threads", t);
    try {
      filters.push_back(gf::makeGroundFilter(opt.method, settings));
    } catch (const std::invalid_argument& e) {
      throw UsageError(e.what());
    }
  }
  return filters;
}

/// `filter` on one loaded file: warm-up calls, then the timed ones; medians per stage.
Row benchFile(const Options& opt, gf::GroundFilter& filter, const std::string& file,
              const std::string& threads, const gf::CloudView& view,
              std::vector<std::uint8_t>* labels) {
  gf::FilterStats stats;
  for (int w = 0; w < opt.warmup; ++w) filter.filter(view, labels, &stats);
  std::vector<double> times;
  std::vector<std::string> stage_order;
  std::map<std::string, std::vector<double>> stage_times;
  // One surface per --hag-threads value, each timed right after a filter call of its own.
  const std::size_t nh = opt.hag_threads.size();
  std::vector<gf::GroundSurface> surfaces(nh);
  std::vector<std::vector<double>> hag_build(nh), hag_heights(nh), hag_total(nh);
  std::vector<float> heights;
  for (int r = 0; r < opt.repeat; ++r) {
    stats = gf::FilterStats();
    const auto t0 = std::chrono::steady_clock::now();
    filter.filter(view, labels, &stats);
    times.push_back(cli::msSince(t0));
    if (nh > 0) {
      const std::size_t h = static_cast<std::size_t>(r) % nh;
      gf::GroundSurfaceParams params;
      params.setScanType(stats.scan_type);  // as the nodelets do
      params.threads = opt.hag_threads[h];
      const auto b0 = std::chrono::steady_clock::now();
      surfaces[h].build(view, *labels, params);
      const double build_ms = cli::msSince(b0);
      const auto h0 = std::chrono::steady_clock::now();
      surfaces[h].heights(view, &heights);
      const double heights_ms = cli::msSince(h0);
      hag_build[h].push_back(build_ms);
      hag_heights[h].push_back(heights_ms);
      hag_total[h].push_back(build_ms + heights_ms);
    }
    for (const auto& s : stats.stage_ms) {
      auto& v = stage_times[s.first];
      if (v.empty()) stage_order.push_back(s.first);
      v.push_back(s.second);
    }
  }
  Row row;
  row.file = file;
  row.threads = threads;
  row.label = gf::scanStem(file) + (row.threads.empty() ? "" : "@" + row.threads);
  row.points = view.size();
  row.median_ms = cli::median(times);
  row.min_ms = *std::min_element(times.begin(), times.end());
  row.max_ms = *std::max_element(times.begin(), times.end());
  for (const double t : times) row.mean_ms += t / static_cast<double>(times.size());
  for (const auto& name : stage_order)
    row.stages.emplace_back(name, cli::median(stage_times[name]));
  for (std::size_t h = 0; h < nh; ++h) {
    if (hag_total[h].empty()) continue;  // fewer timed runs than values
    row.hag.push_back(Row::Hag{opt.hag_threads[h], cli::median(hag_build[h]),
                               cli::median(hag_heights[h]), cli::median(hag_total[h]),
                               hag_total[h].size()});
  }
  return row;
}

/// --hag-threads: the surface's medians per file, filter setting and value.
void printHag(const std::vector<Row>& rows) {
  std::size_t name_w = 4;
  for (const auto& r : rows) name_w = std::max(name_w, r.file.size());
  std::printf("\nheight above ground after each filter call (build() + heights(), medians ms)\n");
  std::printf("%-*s %7s %11s %6s %9s %10s %9s %9s\n", static_cast<int>(name_w), "file", "threads",
              "hag_threads", "calls", "build_ms", "heights_ms", "total_ms", "%filter");
  for (const auto& r : rows) {
    for (const auto& h : r.hag) {
      std::printf("%-*s %7s %11d %6zu %9.3f %10.3f %9.3f %9.1f\n", static_cast<int>(name_w),
                  r.file.c_str(), r.threads.empty() ? "default" : r.threads.c_str(), h.threads,
                  h.calls, h.build_ms, h.heights_ms, h.total_ms,
                  r.median_ms > 0 ? 100.0 * h.total_ms / r.median_ms : 0.0);
    }
  }
}

/// The totals table: one row per file and thread setting, the sums of medians per setting.
void printTotals(const Options& opt, const std::vector<std::string>& thread_values,
                 const std::vector<Row>& rows) {
  std::string settings;
  for (const auto& kv : opt.settings) settings += " " + kv.first + "=" + kv.second;
  std::printf("%s\n", cli::simdDescription().c_str());
  std::printf("method %s%s%s; %d timed runs per file after %d warm-up; %u hardware threads\n",
              opt.method.c_str(), settings.empty() ? "" : ", settings", settings.c_str(),
              opt.repeat, opt.warmup, std::thread::hardware_concurrency());
  std::size_t name_w = 4;
  for (const auto& r : rows) name_w = std::max(name_w, r.file.size());
  std::printf("%-*s %7s %9s %9s %9s %9s %9s %9s\n", static_cast<int>(name_w), "file", "threads",
              "points", "median_ms", "min_ms", "max_ms", "mean_ms", "Mpts/s");
  for (const auto& r : rows) {
    const double mpts = r.median_ms > 0 ? r.points / (r.median_ms * 1e3) : 0.0;
    std::printf("%-*s %7s %9zu %9.3f %9.3f %9.3f %9.3f %9.2f\n", static_cast<int>(name_w),
                r.file.c_str(), r.threads.empty() ? "default" : r.threads.c_str(), r.points,
                r.median_ms, r.min_ms, r.max_ms, r.mean_ms, mpts);
  }
  for (const auto& t : thread_values) {
    std::size_t pts = 0;
    double ms = 0.0;
    for (const auto& r : rows) {
      if (r.threads != t) continue;
      pts += r.points;
      ms += r.median_ms;
    }
    std::printf("%-*s %7s %9zu %9.3f %9s %9s %9s %9.2f   (sum of medians)\n",
                static_cast<int>(name_w), "all files", t.empty() ? "default" : t.c_str(), pts, ms,
                "", "", "", ms > 0 ? pts / (ms * 1e3) : 0.0);
  }
}

/// Per-stage medians: one row per stage (union, first-seen order), one column per file.
void printStages(const std::vector<Row>& rows) {
  std::vector<std::string> stage_names;
  for (const auto& r : rows) {
    for (const auto& s : r.stages) {
      if (std::find(stage_names.begin(), stage_names.end(), s.first) == stage_names.end()) {
        stage_names.push_back(s.first);
      }
    }
  }
  if (stage_names.empty()) {
    std::printf("\n(the filter reports no stage timings)\n");
    return;
  }
  std::size_t stage_w = 5;
  for (const auto& s : stage_names) stage_w = std::max(stage_w, s.size());
  std::printf("\nper-stage median ms\n%-*s", static_cast<int>(stage_w), "stage");
  std::vector<int> col_w;
  for (const auto& r : rows) {
    col_w.push_back(static_cast<int>(std::max<std::size_t>(9, r.label.size())));
    std::printf(" %*s", col_w.back(), r.label.c_str());
  }
  std::printf("\n");
  for (const auto& name : stage_names) {
    std::printf("%-*s", static_cast<int>(stage_w), name.c_str());
    for (std::size_t i = 0; i < rows.size(); ++i) {
      const auto& st = rows[i].stages;
      const auto it =
          std::find_if(st.begin(), st.end(),
                       [&](const std::pair<std::string, double>& s) { return s.first == name; });
      if (it == st.end()) {
        std::printf(" %*s", col_w[i], "-");
      } else {
        std::printf(" %*.3f", col_w[i], it->second);
      }
    }
    std::printf("\n");
  }
}

int run(const Options& opt) {
  const std::vector<std::string> files = gf::listScanFiles(opt.paths);
  const std::vector<std::string> thread_values =
      opt.threads.empty() ? std::vector<std::string>{""} : opt.threads;
  std::vector<std::unique_ptr<gf::GroundFilter>> filters = makeFilters(opt, thread_values);
  std::vector<Row> rows;
  std::vector<std::uint8_t> labels;
  for (const auto& file : files) {
    const gf::Scan scan = gf::loadScan(file);
    const gf::CloudView view = gf::viewOf(scan.cloud);
    for (std::size_t ti = 0; ti < filters.size(); ++ti) {
      rows.push_back(benchFile(opt, *filters[ti], file, thread_values[ti], view, &labels));
    }
  }
  printTotals(opt, thread_values, rows);
  printStages(rows);
  if (!opt.hag_threads.empty()) printHag(rows);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  return cli::runTool("ground_filter_benchmark", [&] { return run(parseArgs(argc, argv)); });
}
