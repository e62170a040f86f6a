// Labels of KITTI .bin scans (float32 x y z intensity per point) with one method of the core, one
// byte per point (0 non-ground, 1 ground) in OUT_DIR/<scan>.labels: scripts/check_arm64.sh runs
// it on x86-64 and under qemu-aarch64 and compares the files. Needs no PCL (the core only).
//
//   label_scans OUT_DIR METHOD [NAME=VALUE ...] -- SCAN.bin ...
#include <chrono>
#include <cstdio>
#include <exception>
#include <fstream>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "eval/kitti_bin.h"
#include "ground_filter/ground_filter.h"
#include "simd/simd.h"

namespace gf = ground_filter;

namespace {

std::string stem(const std::string& path) {
  const std::size_t slash = path.find_last_of('/');
  std::string name = slash == std::string::npos ? path : path.substr(slash + 1);
  const std::size_t dot = name.rfind('.');
  return dot == std::string::npos ? name : name.substr(0, dot);
}

}  // namespace

int main(int argc, char** argv) {
  try {
    if (argc < 5) {
      std::fprintf(stderr, "usage: %s OUT_DIR METHOD [NAME=VALUE ...] -- SCAN.bin ...\n", argv[0]);
      return 2;
    }
    const std::string out_dir = argv[1], method = argv[2];
    gf::ParamSettings settings;
    int i = 3;
    for (; i < argc && std::string(argv[i]) != "--"; ++i) {
      const std::string kv = argv[i];
      const std::size_t eq = kv.find('=');
      if (eq == std::string::npos) throw std::invalid_argument("not NAME=VALUE: " + kv);
      settings.emplace_back(kv.substr(0, eq), kv.substr(eq + 1));
    }
    if (i == argc) throw std::invalid_argument("missing -- before the scans");
    std::unique_ptr<gf::GroundFilter> filter = gf::makeGroundFilter(method, settings);
    std::printf("%s; method %s\n", gf::simd::describe().c_str(), method.c_str());
    std::vector<std::uint8_t> labels;
    for (++i; i < argc; ++i) {
      const std::vector<float> rec = gf::readKittiRecords(argv[i]);
      const gf::CloudView view(rec.data(), rec.size() / 4, 16, 0, 4, 8);
      const auto t0 = std::chrono::steady_clock::now();
      filter->filter(view, &labels);
      const double ms =
          std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
      std::size_t ground = 0;
      for (std::uint8_t l : labels) ground += l == gf::kGround;
      const std::string out = out_dir + "/" + stem(argv[i]) + ".labels";
      std::ofstream f(out, std::ios::binary);
      f.write(reinterpret_cast<const char*>(labels.data()),
              static_cast<std::streamsize>(labels.size()));
      if (!f) throw std::runtime_error("cannot write " + out);
      std::printf("%s: %zu points, %zu ground, %.1f ms\n", stem(argv[i]).c_str(), labels.size(),
                  ground, ms);
    }
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "label_scans: %s\n", e.what());
    return 1;
  }
}
