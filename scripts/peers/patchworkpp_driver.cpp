// patchworkpp_driver: Patchwork++ (url-kaist/patchwork-plusplus, its C++ core, fetched and built
// by `bash scripts/peers/build.sh --patchworkpp`, never part of this package) with its default
// patchwork::Params (KITTI: sensor_height 1.723, RNR / RVPF / TGR on). Driver interface of
// scripts/peers/README.md:
//   patchworkpp_driver --out DIR [--repeats N] [--set sensor_height=H] FILE...
// The intensity goes to it as a 4th column where the file has one (its reflected-noise removal
// needs it; without, Patchwork++ skips that step). A fresh instance per file; call 0 is the
// warm-up whose labels are written, then N timed estimateGround() calls (one thread).
#include <patchwork/patchworkpp.h>

#include <Eigen/Core>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "driver_common.h"

namespace {

int run(int argc, char** argv) {
  const peers::Args args = peers::parseArgs(
      argc, argv,
      "usage: patchworkpp_driver --out DIR [--repeats N] [--set sensor_height=H] FILE...");
  patchwork::Params params;
  params.verbose = false;
  for (const auto& kv : args.sets) {
    if (kv.first == "sensor_height") {
      params.sensor_height = peers::number(kv.first, kv.second);
    } else {
      throw std::invalid_argument("unknown --set " + kv.first + " (sensor_height)");
    }
  }
  std::printf(
      "PARAMS patchworkpp sensor_height=%.3f th_seeds=%.3f th_dist=%.3f RNR=%d RVPF=%d "
      "TGR=%d\n",
      params.sensor_height, params.th_seeds, params.th_dist, params.enable_RNR, params.enable_RVPF,
      params.enable_TGR);
  for (const std::string& file : args.files) {
    const peers::Scan scan = peers::readScan(file);
    std::vector<std::size_t> index;  // given point -> input point
    for (std::size_t i = 0; i < scan.size(); ++i) {
      if (scan.given(i)) index.push_back(i);
    }
    Eigen::MatrixXf cloud(static_cast<Eigen::Index>(index.size()), scan.has_intensity ? 4 : 3);
    for (std::size_t k = 0; k < index.size(); ++k) {
      const std::size_t i = index[k];
      const auto r = static_cast<Eigen::Index>(k);
      cloud(r, 0) = scan.x[i];
      cloud(r, 1) = scan.y[i];
      cloud(r, 2) = scan.z[i];
      if (scan.has_intensity) cloud(r, 3) = scan.intensity[i];
    }
    auto peer = std::make_unique<patchwork::PatchWorkpp>(params);
    std::vector<unsigned char> labels(scan.size(), 0);
    std::vector<double> ms;
    for (int r = 0; r <= args.repeats; ++r) {
      const double t = peers::timeMs([&] { peer->estimateGround(cloud); });
      if (r > 0) {
        ms.push_back(t);
        continue;
      }
      const Eigen::VectorXi ground = peer->getGroundIndices();  // indices into `cloud`
      for (Eigen::Index g = 0; g < ground.size(); ++g) {
        labels.at(index.at(static_cast<std::size_t>(ground[g]))) = 1;
      }
    }
    std::size_t n_ground = 0;
    for (unsigned char l : labels) n_ground += l;
    peers::writeGnd(args.out, file, labels);
    peers::printResult("patchworkpp", file, scan.size(), n_ground, ms, args.repeats);
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) { return peers::runDriver("patchworkpp_driver", run, argc, argv); }
