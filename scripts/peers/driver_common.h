// What the peer drivers of scripts/peers share (scripts/peers/README.md: the interface): reading a
// scan, the command line, the points given to a peer, the .gnd output.
#ifndef GROUND_FILTER_SCRIPTS_PEERS_DRIVER_COMMON_H
#define GROUND_FILTER_SCRIPTS_PEERS_DRIVER_COMMON_H

#include <pcl/PCLPointCloud2.h>
#include <pcl/conversions.h>
#include <pcl/io/pcd_io.h>
#include <pcl/point_types.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstddef>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace peers {

/// \brief One scan in file order: x y z, and intensity where the file has it.
struct Scan {
  std::vector<float> x, y, z, intensity;
  bool has_intensity = false;
  std::size_t size() const { return x.size(); }
  /// \brief Whether point i goes to the peer: finite, and not a no-return placeholder at the
  ///        origin (53 k of RELLIS-3D's 131 k points).
  bool given(std::size_t i) const {
    return std::isfinite(x[i]) && std::isfinite(y[i]) && std::isfinite(z[i]) &&
           !(x[i] == 0.f && y[i] == 0.f && z[i] == 0.f);
  }
};

/// \brief Appends the x y z of `c` to `s`.
template <typename PointT>
void appendPoints(const pcl::PointCloud<PointT>& c, Scan* s) {
  for (const PointT& p : c.points) {
    s->x.push_back(p.x);
    s->y.push_back(p.y);
    s->z.push_back(p.z);
  }
}

/// \brief The points of `s` given to a peer (Scan::given), and in `index` each one's input index.
inline pcl::PointCloud<pcl::PointXYZ>::Ptr givenXyz(const Scan& s,
                                                    std::vector<std::size_t>* index) {
  pcl::PointCloud<pcl::PointXYZ>::Ptr given(new pcl::PointCloud<pcl::PointXYZ>);
  index->clear();
  for (std::size_t i = 0; i < s.size(); ++i) {
    if (!s.given(i)) continue;
    given->push_back(pcl::PointXYZ(s.x[i], s.y[i], s.z[i]));
    index->push_back(i);
  }
  return given;
}

/// \brief Reads a KITTI .bin (float32 x y z intensity) or a PCD (x y z [intensity], any type
///        and encoding PCL reads).
inline Scan readScan(const std::string& path) {
  Scan s;
  if (path.size() > 4 && path.compare(path.size() - 4, 4, ".bin") == 0) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw std::runtime_error(path + ": cannot open");
    float rec[4];
    while (in.read(reinterpret_cast<char*>(rec), sizeof(rec))) {
      s.x.push_back(rec[0]);
      s.y.push_back(rec[1]);
      s.z.push_back(rec[2]);
      s.intensity.push_back(rec[3]);
    }
    s.has_intensity = true;
    return s;
  }
  pcl::PCLPointCloud2 blob;
  if (pcl::io::loadPCDFile(path, blob) != 0) throw std::runtime_error(path + ": cannot read");
  s.has_intensity = std::any_of(blob.fields.begin(), blob.fields.end(),
                                [](const pcl::PCLPointField& f) { return f.name == "intensity"; });
  if (s.has_intensity) {
    pcl::PointCloud<pcl::PointXYZI> c;
    pcl::fromPCLPointCloud2(blob, c);
    appendPoints(c, &s);
    for (const auto& p : c.points) s.intensity.push_back(p.intensity);
  } else {
    pcl::PointCloud<pcl::PointXYZ> c;
    pcl::fromPCLPointCloud2(blob, c);
    appendPoints(c, &s);
    s.intensity.assign(s.x.size(), 0.f);
  }
  return s;
}

/// \brief The file name without folder and extension.
inline std::string stemOf(const std::string& path) {
  const std::size_t slash = path.find_last_of('/');
  std::string name = slash == std::string::npos ? path : path.substr(slash + 1);
  const std::size_t dot = name.find_last_of('.');
  return dot == std::string::npos ? name : name.substr(0, dot);
}

/// \brief `s` without the `chars` at either end.
inline std::string trimmed(const std::string& s, const char* chars = " \t\r") {
  const std::size_t a = s.find_first_not_of(chars);
  if (a == std::string::npos) return "";
  return s.substr(a, s.find_last_not_of(chars) - a + 1);
}

/// \brief `value` as a number, the whole of it.
/// \throws std::invalid_argument naming `name` when it is not one.
inline double number(const std::string& name, const std::string& value) {
  std::size_t used = 0;
  double v = 0.0;
  try {
    v = std::stod(value, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used == 0 || used != value.size()) {
    throw std::invalid_argument(name + "=" + value + ": not a number");
  }
  return v;
}

/// \brief `--out DIR [--repeats N] [--set NAME=VALUE]... FILE...`
struct Args {
  std::string out;
  int repeats = 7;
  std::vector<std::pair<std::string, std::string>> sets;
  std::vector<std::string> files;
};

/// \throws std::invalid_argument with `usage` on a bad command line.
inline Args parseArgs(int argc, char** argv, const std::string& usage) {
  Args a;
  for (int i = 1; i < argc; ++i) {
    const std::string s = argv[i];
    const bool has_value = i + 1 < argc;
    if (s == "--out" && has_value) {
      a.out = argv[++i];
    } else if (s == "--repeats" && has_value) {
      a.repeats = static_cast<int>(number("--repeats", argv[++i]));
    } else if (s == "--set" && has_value) {
      const std::string kv = argv[++i];
      const std::size_t eq = kv.find('=');
      if (eq == std::string::npos) throw std::invalid_argument("--set " + kv + ": NAME=VALUE");
      a.sets.emplace_back(kv.substr(0, eq), kv.substr(eq + 1));
    } else if (s.rfind("--", 0) == 0) {
      throw std::invalid_argument("unknown option " + s + "\n" + usage);
    } else {
      a.files.push_back(s);
    }
  }
  if (a.out.empty() || a.files.empty() || a.repeats < 1) throw std::invalid_argument(usage);
  return a;
}

/// \brief Writes DIR/<stem>.gnd: one uint8 per input point, 1 ground.
inline void writeGnd(const std::string& dir, const std::string& file,
                     const std::vector<unsigned char>& labels) {
  const std::string path = dir + "/" + stemOf(file) + ".gnd";
  std::ofstream f(path, std::ios::binary);
  f.write(reinterpret_cast<const char*>(labels.data()),
          static_cast<std::streamsize>(labels.size()));
  if (!f) throw std::runtime_error(path + ": cannot write");
}

/// \brief Runs `call()` once; returns its wall time [ms].
template <typename Call>
double timeMs(Call&& call) {
  const auto t0 = std::chrono::steady_clock::now();
  call();
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

/// \brief The median of `ms` (not empty).
inline double median(std::vector<double> ms) {
  std::sort(ms.begin(), ms.end());
  return ms[ms.size() / 2];
}

/// \brief Prints a file's RESULT line (the driver interface).
inline void printResult(const char* peer, const std::string& file, std::size_t points,
                        std::size_t ground, const std::vector<double>& ms, int repeats) {
  std::printf("RESULT %s %s points=%zu ground=%.4f median_ms=%.3f repeats=%d\n", peer,
              stemOf(file).c_str(), points,
              points ? static_cast<double>(ground) / static_cast<double>(points) : 0.0, median(ms),
              repeats);
}

/// \brief main() of a driver: `run`, any exception reported as "<name>: what" with status 1.
inline int runDriver(const char* name, int (*run)(int, char**), int argc, char** argv) {
  try {
    return run(argc, argv);
  } catch (const std::exception& e) {
    std::cerr << name << ": " << e.what() << std::endl;
    return 1;
  }
}

}  // namespace peers

#endif  // GROUND_FILTER_SCRIPTS_PEERS_DRIVER_COMMON_H
