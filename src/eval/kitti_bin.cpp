#include "eval/kitti_bin.h"

#include <cstddef>
#include <fstream>
#include <stdexcept>

namespace ground_filter {

std::vector<float> readKittiRecords(const std::string& path) {
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  if (!in) throw std::runtime_error("cannot open " + path);
  const std::size_t bytes = static_cast<std::size_t>(in.tellg());
  if (bytes % 16 != 0) throw std::runtime_error(path + ": not 16-byte x y z intensity records");
  std::vector<float> rec(bytes / sizeof(float));
  in.seekg(0);
  if (!in.read(reinterpret_cast<char*>(rec.data()), static_cast<std::streamsize>(bytes))) {
    throw std::runtime_error("cannot read " + path);
  }
  return rec;
}

std::vector<float> readKittiXyz(const std::string& path) {
  const std::vector<float> rec = readKittiRecords(path);
  std::vector<float> xyz;
  xyz.reserve(rec.size() / 4 * 3);
  for (std::size_t i = 0; i + 3 < rec.size(); i += 4) {
    xyz.insert(xyz.end(), {rec[i], rec[i + 1], rec[i + 2]});
  }
  return xyz;
}

}  // namespace ground_filter
