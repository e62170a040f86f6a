// ground_filter_eval: runs a ground filter over scan files and scores it against their ground
// truth. Contract (other tools parse it): see usage() and the README's "Evaluation tool" section.

#include <algorithm>
#include <chrono>
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <fstream>
#include <iostream>
#include <iterator>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "airborne/scan_type.h"
#include "cli_args.h"
#include "eval/metrics.h"
#include "eval/scan_io.h"
#include "eval_hag.h"
#include "ground_filter/ground_filter.h"

namespace gf = ground_filter;
namespace cli = ground_filter::cli;

namespace {

const char kUsage[] =
    "usage: ground_filter_eval [--method NAME] [--params FILE] [--set NAME=VALUE]... [--json]\n"
    "                          [--classes] [--write-labels DIR] [--label-format F]\n"
    "                          [--kitti-ids GROUND,NONGROUND] [--write-clouds DIR]\n"
    "                          [--write-scans DIR]\n"
    "                          [--repeat N] [--drop-one N] [--score-labels DIR]\n"
    "                          [--scan-measures] [--hag] [--hag-threads N] PATH...\n"
    "\n"
    "Runs a ground filter on every scan and prints per-file and pooled results: points, points\n"
    "labelled ground, filter time in ms, and where ground truth exists the confusion counts\n"
    "tp fp tn fn (ground = positive) with accuracy, precision, recall, F1 and IoU.\n"
    "\n"
    "PATH                a .bin (KITTI, sibling .label = SemanticKITTI truth), .pcd (a 'label'\n"
    "                    field = ISPRS truth: 1 ground, 0 not, other = ignored) or .ply file; a\n"
    "                    directory (all such files in it, sorted); or a generated scene\n"
    "                    builtin:KIND[:SEED][:NAME=VALUE,...], KIND one of lidar, lidar16,\n"
    "                    rosette, tls, verge, offroad, trail, garage, airborne, the registered\n"
    "                    mls, mls_air, stations, slam, tls_far, profiler, or uav, corridor\n"
    "                    (exact truth; src/eval/scene_generator.h); NAME=VALUE sets a field, e.g.\n"
    "                    builtin:lidar16:2:layout=trail,beams=32,sensor_height=1.2 (the\n"
    "                    fields: docs/evaluation.md; an unknown one is refused)\n"
    "--method NAME       filter method: voxel (default), normal, voxel_paper\n"
    "--params FILE       parameters from a flat YAML file (config/*.yaml, 'name: value')\n"
    "--set NAME=VALUE    override a filter parameter (repeatable; after --params)\n"
    "--classes           also print, pooled over the files, each semantic class (SemanticKITTI\n"
    "                    labels, generated scenes) split by truth: points and % labelled\n"
    "                    ground (= recall of a ground class); JSON key \"classes\"\n"
    "--json              print exactly one JSON object instead of the table:\n"
    "                    {\"files\":[{\"file\",\"points\",\"ground\",\"ms\",\n"
    "                    \"tp\",\"fp\",\"tn\",\"fn\",\"accuracy\",\"precision\",\n"
    "                    \"recall\",\"f1\",\"iou\",\"scan_type\",\"scan_reason\",\"note\"}...],\n"
    "                    \"pooled\":{...}}\n"
    "                    metrics are fractions in [0,1]; null where a file has no labels or a\n"
    "                    ratio is 0/0\n"
    "--write-labels DIR  write the labels of every scan into DIR, as --label-format says\n"
    "--label-format F    gnd (default): DIR/<stem>.gnd, one uint8 per input point (1 ground,\n"
    "                    0 not); kitti: DIR/<stem>.label, SemanticKITTI's format, one uint32\n"
    "                    per point (class id in the low 16 bits, instance 0), see --kitti-ids\n"
    "--kitti-ids G,N     SemanticKITTI class ids of ground and non-ground points (default\n"
    "                    40,0: 40 \"road\", 0 \"unlabeled\"; e.g. 49,99 for \"other-ground\",\n"
    "                    \"other-object\")\n"
    "--write-clouds DIR  write DIR/<stem>_ground.pcd and DIR/<stem>_nonground.pcd (binary, all\n"
    "                    input fields)\n"
    "--write-scans DIR   write every input scan as DIR/<stem>.bin (KITTI float32 x y z\n"
    "                    intensity) and, when labelled, DIR/<stem>.label (SemanticKITTI classes\n"
    "                    that read back as the same truth): generated scenes for other tools;\n"
    "                    with --json each file's \"scan_file\" names its .bin\n"
    "--repeat N          run the filter N times per file and report the median ms (default 1)\n"
    "--drop-one N        stability check (table only): per file, N times, filter the scan without\n"
    "                    one finite point (evenly spread over the file) and count the labels of\n"
    "                    the other points that differ from the whole scan's\n"
    "--scan-measures     with --json: each file's scan_type auto measures (JSON key\n"
    "                    \"scan_measures\": top_share, column_top_share, column_mean, read,\n"
    "                    steep_share, steep_depth, high_share, extent, hidden_share;\n"
    "                    docs/scan_types.md, docs/normal_method.md),\n"
    "                    computed whatever the decision (scripts/crossval.py reads them)\n"
    "--hag               also build the ground surface from each scan's labels (those of\n"
    "                    --score-labels where given) and compute every point's height above\n"
    "                    ground (include/ground_filter/height_above_ground.h, default\n"
    "                    GroundSurfaceParams; the shadow test for scans the filter did not\n"
    "                    take for airborne, as the nodelets do; with --score-labels for\n"
    "                    every scan) and print, per file and pooled: ms of\n"
    "                    build + heights (min and median of --repeat runs) and their shares of\n"
    "                    the filter's min and median ms on the same scan, the share of finite\n"
    "                    points with a NaN height; for builtin: scenes the median and p95 of\n"
    "                    |height - (z - true terrain)|; for labelled scans the median, p5, p95 of\n"
    "                    the heights of truly-ground points and their share within +-0.1 m, and\n"
    "                    the median, p5, p95 of truly-non-ground points' heights [m]. JSON: key\n"
    "                    \"hag\" in each file and at the top (pooled): ms_min, ms_median,\n"
    "                    share_min, share_median (of the filter's ms; null with --score-labels),\n"
    "                    nan_share, error_median, error_p95, ground_median, ground_p5,\n"
    "                    ground_p95, ground_within_0_1, nonground_median, nonground_p5,\n"
    "                    nonground_p95 (null where undefined)\n"
    "--hag-threads N     threads of the heights (GroundSurfaceParams::threads; 0 = all cores);\n"
    "                    default: the filter's own `threads`, as in the nodelets\n"
    "--score-labels DIR  run no filter: score DIR/<stem>.gnd (as --write-labels writes them,\n"
    "                    e.g. another ground filter's) against each scan's truth, same protocol\n"
    "                    and output; ms is 0; not with --drop-one or --repeat\n"
    "--help              this text\n"
    "\n"
    "Exit status: 0 ok, 1 a file could not be read/written or its labels do not match, 2 bad\n"
    "command line, unknown method or invalid parameter.\n";

using cli::UsageError;

struct Options {
  std::string method = "voxel";
  gf::ParamSettings settings;
  bool json = false;
  bool classes = false;
  bool scan_measures = false;
  bool hag = false;      // --hag
  int hag_threads = -1;  // --hag-threads; -1: the filter's
  std::string labels_dir;
  bool kitti_labels = false;  // --label-format kitti
  gf::KittiLabelIds kitti_ids;
  std::string clouds_dir;
  std::string scans_dir;  // --write-scans
  std::string score_dir;  // --score-labels: labels read from DIR/<stem>.gnd, no filter run
  int repeat = 1;
  int drop_one = 0;
  std::vector<std::string> paths;
};

// --drop-one: labels of the other points that changed when one point was left out.
struct DropResult {
  std::size_t drops = 0;      // points left out, one at a time
  std::size_t unchanged = 0;  // of those, how many changed no other label
  std::size_t median = 0;     // changed labels, median and largest over the drops
  std::size_t max = 0;
};

/// Filters `view` without one finite point, `count` times, against the whole scan's `labels`.
DropResult dropOne(gf::GroundFilter* filter, const gf::CloudView& view,
                   const std::vector<std::uint8_t>& labels, int count) {
  const std::size_t n = view.size(), stride = view.stride();
  std::vector<std::size_t> finite;
  for (std::size_t i = 0; i < n; ++i) {
    if (view.isValid(i)) finite.push_back(i);
  }
  DropResult out;
  if (finite.size() < 2 || count <= 0) return out;
  const std::uint8_t* bytes = view.data();
  std::vector<std::uint8_t> copy((n - 1) * stride);
  std::vector<std::uint8_t> other;
  std::vector<std::size_t> changed;
  const std::size_t drops = std::min<std::size_t>(static_cast<std::size_t>(count), finite.size());
  for (std::size_t j = 0; j < drops; ++j) {
    const std::size_t r = finite[(2 * j + 1) * finite.size() / (2 * drops)];
    std::copy(bytes, bytes + r * stride, copy.begin());
    std::copy(bytes + (r + 1) * stride, bytes + n * stride, copy.begin() + r * stride);
    const gf::CloudView less(copy.data(), n - 1, stride, view.xOffset(), view.yOffset(),
                             view.zOffset());
    filter->filter(less, &other);
    std::size_t c = 0;
    for (std::size_t i = 0; i + 1 < n; ++i) c += other[i] != labels[i < r ? i : i + 1];
    changed.push_back(c);
  }
  std::sort(changed.begin(), changed.end());
  out.drops = drops;
  out.unchanged = static_cast<std::size_t>(std::count(changed.begin(), changed.end(), 0));
  out.median = changed[changed.size() / 2];
  out.max = changed.back();
  return out;
}

struct FileResult {
  std::string file;
  std::size_t points = 0;
  std::size_t ground = 0;  // points labelled ground by the filter
  double ms = 0.0;
  bool labelled = false;
  gf::Confusion confusion;
  DropResult drop;
  std::string scan_type, scan_reason;  // FilterStats of the last run (parameter scan_type)
  std::string note;                    // FilterStats::note of the last run (e.g. a wider stride)
  std::string scan_file;               // --write-scans: the .bin written
  gf::ScanMeasures measures;           // --scan-measures
  cli::HagResult hag;                  // --hag
};

Options parseArgs(int argc, char** argv) {
  Options o;
  cli::FilterArgs filter_args;
  cli::parseCommandLine(
      argc, argv, kUsage,
      {{"--repeat", &o.repeat, 1, 1000000},
       {"--drop-one", &o.drop_one, 0, 1000000},
       {"--hag-threads", &o.hag_threads, 0, 256}},
      nullptr, &o.paths, [&](cli::ArgCursor* args) {
        const std::string& arg = args->option();
        if (arg == "--json") {
          o.json = true;
        } else if (arg == "--classes") {
          o.classes = true;
        } else if (arg == "--scan-measures") {
          o.scan_measures = true;
        } else if (arg == "--hag") {
          o.hag = true;
        } else if (arg == "--write-labels") {
          o.labels_dir = args->value();
        } else if (arg == "--label-format") {
          const std::string f = args->value();
          if (f != "gnd" && f != "kitti") {
            throw UsageError("--label-format must be gnd or kitti, not '" + f + "'");
          }
          o.kitti_labels = f == "kitti";
        } else if (arg == "--kitti-ids") {
          const std::string v = args->value();
          const std::size_t comma = v.find(',');
          int ids[2] = {-1, -1};
          try {
            if (comma == std::string::npos) throw std::invalid_argument(v);
            std::size_t used = 0;
            ids[0] = std::stoi(v.substr(0, comma), &used);
            if (used != comma) throw std::invalid_argument(v);
            ids[1] = std::stoi(v.substr(comma + 1), &used);
            if (used != v.size() - comma - 1) throw std::invalid_argument(v);
          } catch (const std::exception&) {
            ids[0] = -1;
          }
          if (ids[0] < 0 || ids[0] > 65535 || ids[1] < 0 || ids[1] > 65535) {
            throw UsageError("--kitti-ids needs two class ids 0..65535 as GROUND,NONGROUND, not '" +
                             v + "'");
          }
          o.kitti_ids.ground = static_cast<std::uint16_t>(ids[0]);
          o.kitti_ids.nonground = static_cast<std::uint16_t>(ids[1]);
        } else if (arg == "--write-clouds") {
          o.clouds_dir = args->value();
        } else if (arg == "--write-scans") {
          o.scans_dir = args->value();
        } else if (arg == "--score-labels") {
          o.score_dir = args->value();
        } else {
          return filter_args.consume(args);
        }
        return true;
      });
  if (o.paths.empty()) throw UsageError("no PATH given");
  if (o.json && o.drop_one > 0) throw UsageError("--drop-one prints a table: not with --json");
  if (!o.score_dir.empty() && (o.drop_one > 0 || o.repeat != 1)) {
    throw UsageError("--score-labels runs no filter: not with --drop-one or --repeat");
  }
  o.method = filter_args.method;
  o.settings = filter_args.settings();
  if (!o.score_dir.empty()) o.method = "labels:" + o.score_dir;  // the JSON's "method"
  return o;
}

std::string jsonString(const std::string& s) {
  std::string out = "\"";
  for (const char ch : s) {
    const unsigned char c = static_cast<unsigned char>(ch);
    if (c == '"' || c == '\\') {
      out += '\\';
      out += ch;
    } else if (c < 0x20) {
      char buf[8];
      std::snprintf(buf, sizeof(buf), "\\u%04x", c);
      out += buf;
    } else {
      out += ch;
    }
  }
  return out + "\"";
}

std::string jsonNumber(double v, int decimals) {
  if (!std::isfinite(v)) return "null";
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.*f", decimals, v);
  return buf;
}

// The keys shared by a file entry and the pooled entry.
std::string jsonRecord(const std::string& file, std::size_t points, std::size_t ground, double ms,
                       bool labelled, const gf::Confusion& c) {
  std::ostringstream os;
  os << "{\"file\":" << jsonString(file) << ",\"points\":" << points << ",\"ground\":" << ground
     << ",\"ms\":" << jsonNumber(ms, 4);
  if (labelled) {
    const gf::Metrics m = gf::computeMetrics(c);
    os << ",\"tp\":" << c.tp << ",\"fp\":" << c.fp << ",\"tn\":" << c.tn << ",\"fn\":" << c.fn
       << ",\"accuracy\":" << jsonNumber(m.accuracy, 6)
       << ",\"precision\":" << jsonNumber(m.precision, 6)
       << ",\"recall\":" << jsonNumber(m.recall, 6) << ",\"f1\":" << jsonNumber(m.f1, 6)
       << ",\"iou\":" << jsonNumber(m.iou, 6);
  } else {
    os << ",\"tp\":null,\"fp\":null,\"tn\":null,\"fn\":null,\"accuracy\":null,"
          "\"precision\":null,\"recall\":null,\"f1\":null,\"iou\":null";
  }
  return os.str();
}

std::string pct(double v) {
  if (!std::isfinite(v)) return "-";
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.2f", 100.0 * v);
  return buf;
}

void printRow(std::size_t name_w, const std::string& name, std::size_t points, std::size_t ground,
              double ms, bool labelled, const gf::Confusion& c) {
  std::printf("%-*s %9zu %9zu %9.2f", static_cast<int>(name_w), name.c_str(), points, ground, ms);
  if (labelled) {
    const gf::Metrics m = gf::computeMetrics(c);
    std::printf(" %9" PRIu64 " %8" PRIu64 " %9" PRIu64 " %8" PRIu64 " %7s %7s %7s %7s %7s\n", c.tp,
                c.fp, c.tn, c.fn, pct(m.accuracy).c_str(), pct(m.precision).c_str(),
                pct(m.recall).c_str(), pct(m.f1).c_str(), pct(m.iou).c_str());
  } else {
    std::printf(" %9s %8s %9s %8s %7s %7s %7s %7s %7s\n", "-", "-", "-", "-", "-", "-", "-", "-",
                "-");
  }
}

std::unique_ptr<gf::GroundFilter> makeFilter(const Options& opt) {
  try {
    return gf::makeGroundFilter(opt.method, opt.settings);
  } catch (const std::invalid_argument& e) {
    throw UsageError(e.what());
  }
}

/// --score-labels: `dir`/<stem>.gnd of `file`, one 0/1 byte per point of the scan.
std::vector<std::uint8_t> readGndLabels(const std::string& dir, const std::string& file,
                                        std::size_t points) {
  const std::string path = dir + "/" + gf::scanStem(file) + ".gnd";
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error(path + ": cannot open (labels of " + file + ")");
  std::vector<std::uint8_t> labels((std::istreambuf_iterator<char>(in)),
                                   std::istreambuf_iterator<char>());
  if (labels.size() != points) {
    throw std::runtime_error(path + ": " + std::to_string(labels.size()) + " labels for the " +
                             std::to_string(points) + " points of " + file);
  }
  const auto bad = std::find_if(labels.begin(), labels.end(), [](std::uint8_t v) { return v > 1; });
  if (bad != labels.end()) {
    throw std::runtime_error(path + ": label " + std::to_string(*bad) + " at point " +
                             std::to_string(bad - labels.begin()) + " (0 or 1 expected)");
  }
  return labels;
}

/// Filters one file (opt.repeat times), scores it, and writes its labels / clouds as asked;
/// `labels` is scratch, `classes` gathers the per-class counts.
FileResult evalFile(gf::GroundFilter* filter, const std::string& file, const Options& opt,
                    std::vector<std::uint8_t>* labels_out, std::vector<gf::ClassCount>* classes) {
  std::vector<std::uint8_t>& labels = *labels_out;
  const gf::Scan scan = gf::loadScan(file);
  const std::string scan_file =
      opt.scans_dir.empty() ? std::string() : gf::writeKittiScan(opt.scans_dir, scan);
  const gf::CloudView view = gf::viewOf(scan.cloud);
  if (filter) filter->setSensorOrigin(-scan.shift[0], -scan.shift[1], -scan.shift[2]);  // moved
  std::vector<double> times;
  gf::FilterStats stats;
  if (!opt.score_dir.empty()) {
    labels = readGndLabels(opt.score_dir, file, view.size());
    times.push_back(0.0);
  }
  for (int r = 0; filter && r < opt.repeat; ++r) {
    const auto t0 = std::chrono::steady_clock::now();
    filter->filter(view, &labels, &stats);
    times.push_back(cli::msSince(t0));
  }
  if (labels.size() != view.size()) {
    throw std::runtime_error(file + ": filter returned " + std::to_string(labels.size()) +
                             " labels for " + std::to_string(view.size()) + " points");
  }
  FileResult res;
  res.file = file;
  res.points = view.size();
  res.ground = static_cast<std::size_t>(std::count(labels.begin(), labels.end(), 1));
  res.ms = cli::median(times);
  res.labelled = scan.labelled();
  res.scan_type = stats.scan_type;
  res.scan_reason = stats.scan_reason + gf::shiftNote(scan);
  res.note = stats.note;
  res.scan_file = scan_file;
  if (res.labelled) res.confusion = gf::countConfusion(labels, scan.truth);
  if (opt.classes && res.labelled && !scan.semantic.empty()) {
    gf::addClassCounts(labels, scan.truth, scan.semantic, classes);
  }
  if (opt.hag) {
    res.hag = cli::hagOf(scan, view, labels, stats.scan_type,
                         opt.hag_threads >= 0 ? opt.hag_threads : stats.threads, opt.repeat);
    if (filter) {  // shares of the filter's time (none with --score-labels)
      res.hag.filter_min = *std::min_element(times.begin(), times.end());
      res.hag.filter_med = res.ms;
    }
  }
  if (opt.drop_one > 0) res.drop = dropOne(filter, view, labels, opt.drop_one);
  if (opt.scan_measures) {
    const float origin[3] = {0.f, 0.f, 0.f};
    res.measures = gf::ScanTypeClassifier().measure(view, origin);
  }
  if (!opt.labels_dir.empty()) {
    if (opt.kitti_labels) {
      gf::writeKittiLabels(opt.labels_dir, file, labels, opt.kitti_ids);
    } else {
      gf::writeLabels(opt.labels_dir, file, labels);
    }
  }
  if (!opt.clouds_dir.empty()) gf::writeSplitClouds(opt.clouds_dir, file, scan.cloud, labels);
  return res;
}

/// The sums over all files (confusion over the labelled ones; ms = sum of the files' ms).
struct Pooled {
  gf::Confusion confusion;
  std::size_t points = 0, ground = 0, labelled_files = 0;
  double ms = 0.0;
};

Pooled pool(const std::vector<FileResult>& results) {
  Pooled p;
  for (const auto& r : results) {
    p.points += r.points;
    p.ground += r.ground;
    p.ms += r.ms;
    if (r.labelled) {
      p.confusion.add(r.confusion);
      ++p.labelled_files;
    }
  }
  return p;
}

/// --hag numbers of each file, then of all files pooled (ms: sums of the files' min / median).
std::vector<std::vector<std::pair<std::string, double>>> hagTable(
    const std::vector<FileResult>& results) {
  std::vector<std::vector<std::pair<std::string, double>>> rows;
  cli::HagResult all;
  double ms_min = 0.0, ms_med = 0.0;
  for (const auto& r : results) {
    const double mn = *std::min_element(r.hag.ms.begin(), r.hag.ms.end());
    const double md = cli::median(r.hag.ms);
    rows.push_back(cli::hagNumbers(r.hag, mn, md));
    all.add(r.hag);
    ms_min += mn;
    ms_med += md;
  }
  rows.push_back(cli::hagNumbers(std::move(all), ms_min, ms_med));
  return rows;
}

std::string hagJson(const std::vector<std::pair<std::string, double>>& numbers) {
  std::string out = "{";
  for (const auto& kv : numbers) {
    out += (out.size() > 1 ? "," : "") + jsonString(kv.first) + ":" + jsonNumber(kv.second, 6);
  }
  return out + "}";
}

/// --json: exactly one JSON object (see usage()).
void printJson(const Options& opt, const std::vector<FileResult>& results, const Pooled& pooled,
               const std::vector<gf::ClassCount>& classes) {
  std::ostringstream os;
  const auto hag = opt.hag ? hagTable(results) : decltype(hagTable(results))();
  os << "{\"files\":[";
  for (std::size_t i = 0; i < results.size(); ++i) {
    const auto& r = results[i];
    os << (i ? "," : "") << jsonRecord(r.file, r.points, r.ground, r.ms, r.labelled, r.confusion)
       << ",\"labelled\":" << (r.labelled ? "true" : "false")
       << ",\"scan_type\":" << jsonString(r.scan_type)
       << ",\"scan_reason\":" << jsonString(r.scan_reason) << ",\"note\":" << jsonString(r.note);
    if (!opt.scans_dir.empty()) os << ",\"scan_file\":" << jsonString(r.scan_file);
    if (opt.hag) os << ",\"hag\":" << hagJson(hag[i]);
    if (opt.scan_measures) {
      const gf::ScanMeasures& m = r.measures;
      os << ",\"scan_measures\":{\"top_share\":" << m.top_share
         << ",\"column_top_share\":" << m.column_top_share << ",\"column_mean\":" << m.column_mean
         << ",\"read\":" << m.read << ",\"steep_share\":" << m.steep_share
         << ",\"steep_depth\":" << m.steep_depth << ",\"high_share\":" << m.high_share
         << ",\"extent\":" << m.extent << ",\"hidden_share\":" << m.hidden_share << "}";
    }
    os << "}";
  }
  os << "],\"pooled\":"
     << jsonRecord("pooled", pooled.points, pooled.ground, pooled.ms, pooled.labelled_files > 0,
                   pooled.confusion)
     << ",\"file_count\":" << results.size() << ",\"labelled_files\":" << pooled.labelled_files
     << "},\"method\":" << jsonString(opt.method) << ",\"repeat\":" << opt.repeat;
  if (opt.hag) os << ",\"hag\":" << hagJson(hag.back());
  if (opt.classes) {
    os << ",\"classes\":[";
    for (std::size_t i = 0; i < classes.size(); ++i) {
      const auto& c = classes[i];
      os << (i ? "," : "") << "{\"class\":" << c.cls
         << ",\"name\":" << jsonString(gf::semanticKittiClassName(c.cls))
         << ",\"truth\":" << static_cast<int>(c.truth) << ",\"points\":" << c.points
         << ",\"labelled_ground\":" << c.labelled_ground << "}";
    }
    os << "]";
  }
  os << "}";
  std::cout << os.str() << std::endl;
}

/// The table's extra sections: leave-one-out changes (--drop-one), per-class counts (--classes).
void printExtras(const Options& opt, std::size_t name_w, const std::vector<FileResult>& results,
                 const std::vector<gf::ClassCount>& classes) {
  if (opt.drop_one > 0) {
    std::printf(
        "\none point left out at a time (evenly spread finite points): labels of the other "
        "points\nthat changed\n");
    std::printf("%-*s %9s %9s %9s %9s %9s\n", static_cast<int>(name_w), "file", "points", "drops",
                "unchanged", "median", "max");
    for (const auto& r : results) {
      std::printf("%-*s %9zu %9zu %9zu %9zu %9zu\n", static_cast<int>(name_w), r.file.c_str(),
                  r.points, r.drop.drops, r.drop.unchanged, r.drop.median, r.drop.max);
    }
  }
  if (opt.hag) {
    std::printf(
        "\nheight above ground (--hag), m; ms = surface build + heights (min, median of %d "
        "run(s));\n%%fmin, %%fmed = ms_min / the filter's min, ms_med / the filter's median;\nnan "
        "= finite points without a height; err = |height - (z - true terrain)| "
        "(builtin: scenes);\ngnd / ngnd = heights of truly-ground / non-ground points, "
        "gnd_0.1 = %% of gnd within +-0.1 m\n",
        opt.repeat);
    std::printf("%-*s %7s %7s %6s %6s %6s %7s %7s %7s %7s %7s %7s %8s %8s %8s\n",
                static_cast<int>(name_w), "file", "ms_min", "ms_med", "%fmin", "%fmed", "nan%",
                "err_med", "err_p95", "gnd_med", "gnd_p5", "gnd_p95", "gnd_0.1", "ngnd_med",
                "ngnd_p5", "ngnd_p95");
    const auto rows = hagTable(results);
    for (std::size_t i = 0; i < rows.size(); ++i) {
      std::printf("%-*s", static_cast<int>(name_w),
                  i < results.size() ? results[i].file.c_str() : "pooled");
      for (const auto& kv : rows[i]) {
        const bool share = kv.first == "nan_share" || kv.first == "ground_within_0_1" ||
                           kv.first.compare(0, 6, "share_") == 0;
        char buf[32];
        std::snprintf(buf, sizeof(buf), "%.3f", kv.second);
        const int w = kv.first.compare(0, 9, "nonground") == 0                           ? 8
                      : kv.first == "nan_share" || kv.first.compare(0, 6, "share_") == 0 ? 6
                                                                                         : 7;
        std::printf(" %*s", w,
                    share                      ? pct(kv.second).c_str()
                    : std::isfinite(kv.second) ? buf
                                               : "-");
      }
      std::printf("\n");
    }
  }
  if (opt.classes) {
    std::printf(
        "\nper class, pooled (truth under the scan's protocol; %% labelled ground = recall\n"
        "of a ground row, false-positive share of a non-ground row)\n");
    std::printf("%5s %-16s %-10s %10s %10s %9s\n", "class", "name", "truth", "points", "as_ground",
                "%ground");
    for (const auto& c : classes) {
      std::printf(
          "%5u %-16s %-10s %10" PRIu64 " %10" PRIu64 " %9s\n", c.cls,
          gf::semanticKittiClassName(c.cls).c_str(), c.truth ? "ground" : "non-ground", c.points,
          c.labelled_ground,
          pct(static_cast<double>(c.labelled_ground) / static_cast<double>(c.points)).c_str());
    }
    if (classes.empty()) std::printf("(no file with semantic classes)\n");
  }
}

/// The default output: one table row per file and the pooled row, the scan types, the extras.
void printTable(const Options& opt, const std::vector<FileResult>& results, const Pooled& pooled,
                const std::vector<gf::ClassCount>& classes) {
  std::size_t name_w = 6;
  for (const auto& r : results) name_w = std::max(name_w, r.file.size());
  std::string settings;
  for (const auto& kv : opt.settings) settings += " " + kv.first + "=" + kv.second;
  std::printf("%s\n", cli::simdDescription().c_str());
  std::printf(
      "method %s%s%s; ms = filter time per file%s; metrics in %%, ground = positive\n",
      opt.method.c_str(), settings.empty() ? "" : ", settings", settings.c_str(),
      opt.repeat > 1 ? (" (median of " + std::to_string(opt.repeat) + " runs)").c_str() : "");
  std::printf("%-*s %9s %9s %9s %9s %8s %9s %8s %7s %7s %7s %7s %7s\n", static_cast<int>(name_w),
              "file", "points", "ground", "ms", "tp", "fp", "tn", "fn", "acc", "prec", "recall",
              "f1", "iou");
  for (const auto& r : results) {
    printRow(name_w, r.file, r.points, r.ground, r.ms, r.labelled, r.confusion);
  }
  printRow(name_w, "pooled", pooled.points, pooled.ground, pooled.ms, pooled.labelled_files > 0,
           pooled.confusion);
  std::printf("%zu file(s), %zu labelled; pooled ms = sum over files\n", results.size(),
              pooled.labelled_files);
  std::printf("\nscan type per file (parameter scan_type)\n");
  for (const auto& r : results) {
    std::printf("%-*s %-8s %s\n", static_cast<int>(name_w), r.file.c_str(), r.scan_type.c_str(),
                r.scan_reason.c_str());
  }
  printExtras(opt, name_w, results, classes);
}

int run(const Options& opt) {
  std::unique_ptr<gf::GroundFilter> filter;
  const std::vector<std::string> files = gf::listScanFiles(opt.paths);
  std::vector<FileResult> results;
  std::vector<gf::ClassCount> classes;
  std::vector<std::uint8_t> labels;
  for (const auto& file : files) {
    // A filter per file: what one keeps from a stream's scans (its view of the origin, its
    // scan lines) must not carry over to another file of about as many points.
    if (opt.score_dir.empty()) filter = makeFilter(opt);
    results.push_back(evalFile(filter.get(), file, opt, &labels, &classes));
  }
  const Pooled pooled = pool(results);
  if (opt.json) {
    printJson(opt, results, pooled, classes);
  } else {
    printTable(opt, results, pooled, classes);
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  return cli::runTool("ground_filter_eval", [&] { return run(parseArgs(argc, argv)); });
}
