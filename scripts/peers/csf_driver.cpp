// csf_driver: the Cloth Simulation Filter (jianboqi/CSF, its C++ core src/, fetched and built by
// `bash scripts/peers/build.sh --csf`, never part of this package; Zhang et al., Remote Sensing
// 8(6):501, 2016) with its own defaults (CSF::CSF(), the same as PDAL's filters.csf: cloth
// resolution 1.0 m, rigidness 3, slope smoothing on, class threshold 0.5, time step 0.65, 500
// iterations). Driver interface of scripts/peers/README.md:
//   csf_driver --out DIR [--repeats N] [--set NAME=VALUE]... FILE...
// NAME: cloth_resolution, rigidness, smooth (0/1), class_threshold, time_step, iterations.
// One thread (its OpenMP loops). Per call a fresh CSF given the points (untimed); timed:
// do_filtering() without writing a cloth file. CSF assumes no sensor: every point given is
// labelled.
#include <CSF.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#include <cstdio>
#include <stdexcept>
#include <string>
#include <vector>

#include "driver_common.h"

namespace {

int run(int argc, char** argv) {
  const peers::Args args = peers::parseArgs(
      argc, argv, "usage: csf_driver --out DIR [--repeats N] [--set NAME=VALUE]... FILE...");
  Params params = CSF().params;  // its defaults
  for (const auto& kv : args.sets) {
    const std::string& k = kv.first;
    const bool known = k == "cloth_resolution" || k == "rigidness" || k == "smooth" ||
                       k == "class_threshold" || k == "time_step" || k == "iterations";
    const double v = known ? peers::number(k, kv.second) : 0.0;
    if (k == "cloth_resolution") {
      params.cloth_resolution = v;
    } else if (k == "rigidness") {
      params.rigidness = static_cast<int>(v);
    } else if (k == "smooth") {
      params.bSloopSmooth = v != 0.0;
    } else if (k == "class_threshold") {
      params.class_threshold = v;
    } else if (k == "time_step") {
      params.time_step = v;
    } else if (k == "iterations") {
      params.interations = static_cast<int>(v);
    } else {
      throw std::invalid_argument("unknown --set " + k +
                                  " (cloth_resolution, rigidness, smooth, class_threshold, "
                                  "time_step, iterations)");
    }
  }
#ifdef _OPENMP
  omp_set_num_threads(1);
#endif
  std::printf(
      "PARAMS csf cloth_resolution=%.3f rigidness=%d smooth=%d class_threshold=%.3f "
      "time_step=%.3f iterations=%d\n",
      params.cloth_resolution, params.rigidness, params.bSloopSmooth ? 1 : 0,
      params.class_threshold, params.time_step, params.interations);
  for (const std::string& file : args.files) {
    const peers::Scan scan = peers::readScan(file);
    std::vector<std::size_t> index;  // given point -> input point
    csf::PointCloud points;
    for (std::size_t i = 0; i < scan.size(); ++i) {
      if (!scan.given(i)) continue;
      points.push_back(csf::Point(scan.x[i], scan.y[i], scan.z[i]));
      index.push_back(i);
    }
    std::vector<unsigned char> labels(scan.size(), 0);
    std::size_t n_ground = 0;
    std::vector<double> ms;
    for (int r = 0; r <= args.repeats; ++r) {
      CSF csf;
      csf.params = params;
      csf.setPointCloud(points);  // its own axis swap (z up -> y up)
      std::vector<int> ground, off_ground;
      const double t = peers::timeMs([&] { csf.do_filtering(ground, off_ground, false); });
      if (r > 0) {
        ms.push_back(t);
        continue;
      }
      if (ground.size() + off_ground.size() != index.size()) {
        throw std::runtime_error(file + ": CSF labelled " +
                                 std::to_string(ground.size() + off_ground.size()) + " of " +
                                 std::to_string(index.size()) + " points");
      }
      for (int g : ground) labels.at(index.at(static_cast<std::size_t>(g))) = 1;
      n_ground = ground.size();
    }
    peers::writeGnd(args.out, file, labels);
    peers::printResult("csf", file, scan.size(), n_ground, ms, args.repeats);
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) { return peers::runDriver("csf_driver", run, argc, argv); }
