// pcl_ransac_driver (and pcl_ransac_native_driver, the same built for this CPU): the "one plane"
// peer of the results table, PCL's SACSegmentation (Debian's libpcl-dev): SACMODEL_PLANE, RANSAC,
// distance 0.2 m, at most 1000 iterations, optimized coefficients; the plane's inliers are ground.
// Driver interface of scripts/peers/README.md:
//   pcl_ransac_driver --out DIR [--repeats N] [--set distance=M] [--set iterations=N] FILE...
// FILE: KITTI .bin (float32 x y z intensity) or PCD. Writes DIR/<stem>.gnd (one uint8 per input
// point, 1 ground) and prints "RESULT pcl_ransac <stem> points=N ground=S median_ms=T repeats=N".
#include <pcl/ModelCoefficients.h>
#include <pcl/PointIndices.h>
#include <pcl/point_types.h>
#include <pcl/segmentation/sac_segmentation.h>

#include <stdexcept>
#include <string>
#include <vector>

#include "driver_common.h"

#ifndef PEER_NAME
#define PEER_NAME "pcl_ransac"
#endif

namespace {

int run(int argc, char** argv) {
  const peers::Args args = peers::parseArgs(
      argc, argv, "usage: pcl_ransac_driver --out DIR [--repeats N] [--set distance=M] FILE...");
  int iterations = 1000;
  double distance = 0.2;
  for (const auto& kv : args.sets) {
    if (kv.first == "distance") {
      distance = peers::number(kv.first, kv.second);
    } else if (kv.first == "iterations") {
      iterations = static_cast<int>(peers::number(kv.first, kv.second));
    } else {
      throw std::invalid_argument("unknown --set " + kv.first + " (distance, iterations)");
    }
  }
  std::printf("PARAMS %s distance=%g iterations=%d\n", PEER_NAME, distance, iterations);
  for (const std::string& file : args.files) {
    const peers::Scan scan = peers::readScan(file);
    std::vector<std::size_t> index;  // given point -> input point
    const pcl::PointCloud<pcl::PointXYZ>::Ptr given = peers::givenXyz(scan, &index);
    pcl::PointIndices inliers;
    std::vector<double> ms;
    // Call 0 is the warm-up, whose labels are written; a fresh instance per call.
    for (int r = 0; r <= args.repeats; ++r) {
      pcl::SACSegmentation<pcl::PointXYZ> seg;
      seg.setOptimizeCoefficients(true);
      seg.setModelType(pcl::SACMODEL_PLANE);
      seg.setMethodType(pcl::SAC_RANSAC);
      seg.setDistanceThreshold(distance);
      seg.setMaxIterations(iterations);
      seg.setInputCloud(given);
      pcl::PointIndices got;
      pcl::ModelCoefficients coefficients;
      const double t = peers::timeMs([&] { seg.segment(got, coefficients); });
      if (r == 0) {
        inliers = got;
      } else {
        ms.push_back(t);
      }
    }
    std::vector<unsigned char> labels(scan.size(), 0);
    for (int k : inliers.indices) labels[index[static_cast<std::size_t>(k)]] = 1;
    peers::writeGnd(args.out, file, labels);
    peers::printResult(PEER_NAME, file, scan.size(), inliers.indices.size(), ms, args.repeats);
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) { return peers::runDriver("pcl_ransac_driver", run, argc, argv); }
