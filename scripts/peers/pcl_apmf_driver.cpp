// pcl_apmf_driver (and pcl_apmf_native_driver, the same built for this CPU): the morphological
// peer of docs/evaluation.md's held-out table, PCL's ApproximateProgressiveMorphologicalFilter
// (Debian's libpcl-dev) with the parameters of PCL's tutorial (progressive_morphological_filtering:
// max_window_size 20, slope 1.0, initial_distance 0.5, max_distance 3.0) and PCL's defaults for
// the rest (cell_size 1.0, base 2.0, exponential); one thread. Its ground indices are ground.
// Driver interface of scripts/peers/README.md:
//   pcl_apmf_driver --out DIR [--repeats N] [--set NAME=VALUE]... FILE...
// NAME: cell_size, max_window_size, slope, initial_distance, max_distance, base, exponential.
#include <pcl/point_types.h>
#include <pcl/segmentation/approximate_progressive_morphological_filter.h>

#include <map>
#include <stdexcept>
#include <string>
#include <vector>

#include "driver_common.h"

#ifndef PEER_NAME
#define PEER_NAME "pcl_apmf"
#endif

namespace {

int run(int argc, char** argv) {
  const peers::Args args = peers::parseArgs(
      argc, argv, "usage: pcl_apmf_driver --out DIR [--repeats N] [--set NAME=VALUE] FILE...");
  std::map<std::string, double> p = {{"cell_size", 1.0},    {"max_window_size", 20.0},
                                     {"slope", 1.0},        {"initial_distance", 0.5},
                                     {"max_distance", 3.0}, {"base", 2.0},
                                     {"exponential", 1.0}};
  for (const auto& kv : args.sets) {
    if (p.count(kv.first) == 0) {
      throw std::invalid_argument("unknown --set " + kv.first +
                                  " (cell_size, max_window_size, slope, initial_distance, "
                                  "max_distance, base, exponential)");
    }
    p[kv.first] = peers::number(kv.first, kv.second);
  }
  std::printf("PARAMS %s", PEER_NAME);
  for (const auto& kv : p) std::printf(" %s=%g", kv.first.c_str(), kv.second);
  std::printf(" threads=1\n");
  for (const std::string& file : args.files) {
    const peers::Scan scan = peers::readScan(file);
    std::vector<std::size_t> index;  // given point -> input point
    const pcl::PointCloud<pcl::PointXYZ>::Ptr given = peers::givenXyz(scan, &index);
    std::vector<int> ground;  // pcl::Indices from PCL 1.11; Noetic has 1.10
    std::vector<double> ms;
    // Call 0 is the warm-up, whose labels are written; a fresh instance per call.
    for (int r = 0; r <= args.repeats; ++r) {
      pcl::ApproximateProgressiveMorphologicalFilter<pcl::PointXYZ> pmf;
      pmf.setCellSize(static_cast<float>(p["cell_size"]));
      pmf.setMaxWindowSize(static_cast<int>(p["max_window_size"]));
      pmf.setSlope(static_cast<float>(p["slope"]));
      pmf.setInitialDistance(static_cast<float>(p["initial_distance"]));
      pmf.setMaxDistance(static_cast<float>(p["max_distance"]));
      pmf.setBase(static_cast<float>(p["base"]));
      pmf.setExponential(p["exponential"] != 0.0);
      pmf.setNumberOfThreads(1);
      pmf.setInputCloud(given);
      std::vector<int> got;
      const double t = peers::timeMs([&] { pmf.extract(got); });
      if (r == 0) {
        ground = got;
      } else {
        ms.push_back(t);
      }
    }
    std::vector<unsigned char> labels(scan.size(), 0);
    for (const auto k : ground) labels.at(index.at(static_cast<std::size_t>(k))) = 1;
    peers::writeGnd(args.out, file, labels);
    peers::printResult(PEER_NAME, file, scan.size(), ground.size(), ms, args.repeats);
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) { return peers::runDriver("pcl_apmf_driver", run, argc, argv); }
