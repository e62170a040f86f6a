// linefit_driver: linefit_ground_segmentation (lorenwel/linefit_ground_segmentation, its core
// library, fetched and built by `bash scripts/peers/build.sh --linefit`, never part of this
// package) with the parameters of its own launch file (segmentation_params.yaml: sensor height
// 1.8 m, r 0.5-50 m, 120 bins x 360 segments, ...), mapped as its ROS node maps them (r_min,
// r_max and max_fit_error squared), on one thread. Driver interface of scripts/peers/README.md:
//   linefit_driver --out DIR [--repeats N] [--set NAME=VALUE]... FILE...
// NAME: any key of that YAML (e.g. sensor_height=1.28 for RELLIS-3D's mount). A fresh instance
// per file; call 0 is the warm-up whose labels are written.
#include <ground_segmentation/ground_segmentation.h>

#include <cmath>
#include <fstream>
#include <map>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include "driver_common.h"

#ifndef LINEFIT_PARAMS
#error "LINEFIT_PARAMS: the path of its segmentation_params.yaml (scripts/peers/CMakeLists.txt)"
#endif

namespace {

// "key: value  # comment" lines of a flat YAML.
std::map<std::string, std::string> readFlatYaml(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path + ": cannot open");
  std::map<std::string, std::string> kv;
  for (std::string line; std::getline(in, line);) {
    line = line.substr(0, line.find('#'));
    const std::size_t colon = line.find(':');
    if (colon == std::string::npos) continue;
    auto trim = [](std::string s) {
      const std::size_t b = s.find_first_not_of(" \t\"'"), e = s.find_last_not_of(" \t\"'\r");
      return b == std::string::npos ? std::string() : s.substr(b, e - b + 1);
    };
    kv[trim(line.substr(0, colon))] = trim(line.substr(colon + 1));
  }
  return kv;
}

GroundSegmentationParams paramsOf(const std::map<std::string, std::string>& kv) {
  GroundSegmentationParams p;
  for (const auto& e : kv) {
    const std::string& k = e.first;
    if (k == "gravity_aligned_frame" || k == "latch" || k == "visualize" || k == "n_threads") {
      continue;  // ROS-only, or fixed below
    }
    static const std::set<std::string> kKnown = {"r_min",
                                                 "r_max",
                                                 "max_fit_error",
                                                 "n_bins",
                                                 "n_segments",
                                                 "max_dist_to_line",
                                                 "sensor_height",
                                                 "min_slope",
                                                 "max_slope",
                                                 "long_threshold",
                                                 "max_long_height",
                                                 "max_start_height",
                                                 "line_search_angle"};
    if (!kKnown.count(k)) throw std::invalid_argument("unknown linefit parameter " + k);
    const double v = peers::number(k, e.second);
    if (k == "r_min") {
      p.r_min_square = v * v;
    } else if (k == "r_max") {
      p.r_max_square = v * v;
    } else if (k == "max_fit_error") {
      p.max_error_square = v * v;
    } else if (k == "n_bins") {
      p.n_bins = static_cast<int>(v);
    } else if (k == "n_segments") {
      p.n_segments = static_cast<int>(v);
    } else if (k == "max_dist_to_line") {
      p.max_dist_to_line = v;
    } else if (k == "sensor_height") {
      p.sensor_height = v;
    } else if (k == "min_slope") {
      p.min_slope = v;
    } else if (k == "max_slope") {
      p.max_slope = v;
    } else if (k == "long_threshold") {
      p.long_threshold = v;
    } else if (k == "max_long_height") {
      p.max_long_height = v;
    } else if (k == "max_start_height") {
      p.max_start_height = v;
    } else if (k == "line_search_angle") {
      p.line_search_angle = v;
    } else {
      throw std::invalid_argument("unknown linefit parameter " + k);
    }
  }
  p.visualize = false;
  p.n_threads = 1;
  return p;
}

int run(int argc, char** argv) {
  const peers::Args args = peers::parseArgs(
      argc, argv, "usage: linefit_driver --out DIR [--repeats N] [--set NAME=VALUE]... FILE...");
  std::map<std::string, std::string> kv = readFlatYaml(LINEFIT_PARAMS);
  for (const auto& s : args.sets) kv[s.first] = s.second;
  const GroundSegmentationParams params = paramsOf(kv);
  std::printf(
      "PARAMS linefit sensor_height=%.3f r_min=%.2f r_max=%.1f n_bins=%d n_segments=%d "
      "max_dist_to_line=%.3f n_threads=%d\n",
      params.sensor_height, std::sqrt(params.r_min_square), std::sqrt(params.r_max_square),
      params.n_bins, params.n_segments, params.max_dist_to_line, params.n_threads);
  for (const std::string& file : args.files) {
    const peers::Scan scan = peers::readScan(file);
    PointCloud cloud;
    std::vector<std::size_t> index;  // given point -> input point
    for (std::size_t i = 0; i < scan.size(); ++i) {
      if (!scan.given(i)) continue;
      cloud.push_back(pcl::PointXYZ(scan.x[i], scan.y[i], scan.z[i]));
      index.push_back(i);
    }
    GroundSegmentation peer(params);
    std::vector<unsigned char> labels(scan.size(), 0);
    std::size_t n_ground = 0;
    std::vector<double> ms;
    for (int r = 0; r <= args.repeats; ++r) {
      std::vector<int> segmentation;
      const double t = peers::timeMs([&] { peer.segment(cloud, &segmentation); });
      if (r > 0) {
        ms.push_back(t);
        continue;
      }
      for (std::size_t k = 0; k < segmentation.size(); ++k) {
        if (segmentation[k] == 1) {
          labels.at(index.at(k)) = 1;
          ++n_ground;
        }
      }
    }
    peers::writeGnd(args.out, file, labels);
    peers::printResult("linefit", file, scan.size(), n_ground, ms, args.repeats);
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) { return peers::runDriver("linefit_driver", run, argc, argv); }
