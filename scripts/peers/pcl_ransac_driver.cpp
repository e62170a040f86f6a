// pcl_ransac_driver: the "one plane" peer of the results table, PCL's SACSegmentation (Debian's
// libpcl-dev): SACMODEL_PLANE, RANSAC, distance 0.2 m, at most 1000 iterations, optimized
// coefficients; the plane's inliers are ground. Driver interface of scripts/peers/README.md:
//   pcl_ransac_driver --out DIR [--repeats N] [--set distance=M] [--set iterations=N] FILE...
// FILE: KITTI .bin (float32 x y z intensity) or PCD. Writes DIR/<stem>.gnd (one uint8 per input
// point, 1 ground) and prints "RESULT pcl_ransac <stem> points=N ground=S median_ms=T repeats=N".
#include <pcl/ModelCoefficients.h>
#include <pcl/PointIndices.h>
#include <pcl/io/pcd_io.h>
#include <pcl/point_types.h>
#include <pcl/segmentation/sac_segmentation.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <stdexcept>
#include <string>
#include <vector>

namespace {

// x y z of every record, in file order.
std::vector<pcl::PointXYZ> readScan(const std::string& path) {
  std::vector<pcl::PointXYZ> pts;
  if (path.size() > 4 && path.compare(path.size() - 4, 4, ".bin") == 0) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw std::runtime_error(path + ": cannot open");
    float rec[4];
    while (in.read(reinterpret_cast<char*>(rec), sizeof(rec))) {
      pts.emplace_back(rec[0], rec[1], rec[2]);
    }
    return pts;
  }
  pcl::PointCloud<pcl::PointXYZ> cloud;
  if (pcl::io::loadPCDFile(path, cloud) != 0) throw std::runtime_error(path + ": cannot read");
  pts.assign(cloud.points.begin(), cloud.points.end());
  return pts;
}

std::string stemOf(const std::string& path) {
  const std::size_t slash = path.find_last_of('/');
  std::string name = slash == std::string::npos ? path : path.substr(slash + 1);
  const std::size_t dot = name.find_last_of('.');
  return dot == std::string::npos ? name : name.substr(0, dot);
}

int run(int argc, char** argv) {
  std::string out;
  int repeats = 7, iterations = 1000;
  double distance = 0.2;
  std::vector<std::string> files;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const bool has_value = i + 1 < argc;
    if (a == "--out" && has_value) {
      out = argv[++i];
    } else if (a == "--repeats" && has_value) {
      repeats = std::stoi(argv[++i]);
    } else if (a == "--set" && has_value) {
      const std::string kv = argv[++i];
      if (kv.rfind("distance=", 0) == 0) {
        distance = std::stod(kv.substr(9));
      } else if (kv.rfind("iterations=", 0) == 0) {
        iterations = std::stoi(kv.substr(11));
      } else {
        throw std::invalid_argument("unknown --set " + kv + " (distance, iterations)");
      }
    } else if (a.rfind("--", 0) == 0) {
      throw std::invalid_argument("unknown option " + a);
    } else {
      files.push_back(a);
    }
  }
  if (out.empty() || files.empty() || repeats < 1) {
    throw std::invalid_argument("usage: pcl_ransac_driver --out DIR [--repeats N] FILE...");
  }
  std::printf("PARAMS pcl_ransac distance=%g iterations=%d\n", distance, iterations);
  for (const std::string& file : files) {
    const std::vector<pcl::PointXYZ> pts = readScan(file);
    // Non-finite points and no-return placeholders at (0,0,0) are not given to the peer.
    pcl::PointCloud<pcl::PointXYZ>::Ptr given(new pcl::PointCloud<pcl::PointXYZ>);
    std::vector<std::size_t> index;  // given point -> input point
    for (std::size_t i = 0; i < pts.size(); ++i) {
      const auto& p = pts[i];
      if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) continue;
      if (p.x == 0.f && p.y == 0.f && p.z == 0.f) continue;
      given->push_back(p);
      index.push_back(i);
    }
    pcl::PointIndices inliers;
    std::vector<double> ms;
    // Call 0 is the warm-up, whose labels are written; a fresh instance per call.
    for (int r = 0; r <= repeats; ++r) {
      pcl::SACSegmentation<pcl::PointXYZ> seg;
      seg.setOptimizeCoefficients(true);
      seg.setModelType(pcl::SACMODEL_PLANE);
      seg.setMethodType(pcl::SAC_RANSAC);
      seg.setDistanceThreshold(distance);
      seg.setMaxIterations(iterations);
      seg.setInputCloud(given);
      pcl::PointIndices got;
      pcl::ModelCoefficients coefficients;
      const auto t0 = std::chrono::steady_clock::now();
      seg.segment(got, coefficients);
      const double t =
          std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
      if (r == 0) {
        inliers = got;
      } else {
        ms.push_back(t);
      }
    }
    std::vector<unsigned char> labels(pts.size(), 0);
    for (int k : inliers.indices) labels[index[static_cast<std::size_t>(k)]] = 1;
    const std::string path = out + "/" + stemOf(file) + ".gnd";
    std::ofstream f(path, std::ios::binary);
    f.write(reinterpret_cast<const char*>(labels.data()),
            static_cast<std::streamsize>(labels.size()));
    if (!f) throw std::runtime_error(path + ": cannot write");
    std::sort(ms.begin(), ms.end());
    std::printf("RESULT pcl_ransac %s points=%zu ground=%.4f median_ms=%.3f repeats=%d\n",
                stemOf(file).c_str(), pts.size(),
                pts.empty() ? 0.0 : static_cast<double>(inliers.indices.size()) / pts.size(),
                ms[ms.size() / 2], repeats);
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return run(argc, argv);
  } catch (const std::exception& e) {
    std::cerr << "pcl_ransac_driver: " << e.what() << std::endl;
    return 1;
  }
}
