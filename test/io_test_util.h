// Helpers of the loader, writer, metric and ground_filter_eval CLI tests (test_io_metrics.cpp,
// test_eval_cli.cpp): temporary directories, file writers, a minimal JSON reader, runEval().
// Needs GF_DATA_DIR and GF_EVAL_BIN defined by the build.
#ifndef GROUND_FILTER_TEST_IO_TEST_UTIL_H
#define GROUND_FILTER_TEST_IO_TEST_UTIL_H

#include <pcl/io/pcd_io.h>
#include <stdlib.h>
#include <sys/wait.h>

#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <map>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "cli_args.h"
#include "eval/metrics.h"
#include "eval/scan_io.h"
#include "eval/scene_generator.h"
#include "gf_test_data.h"
#include "ground_filter/ground_filter.h"
#include "voxel/paper_voxel_filter.h"

namespace gf_io_test {

namespace gf = ground_filter;
namespace fs = std::filesystem;

// ------------------------------------------------------------------ helpers

class TempDir {
 public:
  TempDir() {
    std::string tmpl = (fs::temp_directory_path() / "gf_test_io_XXXXXX").string();
    if (!mkdtemp(tmpl.data())) throw std::runtime_error("mkdtemp failed");
    path_ = tmpl;
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  std::string operator/(const std::string& name) const { return (fs::path(path_) / name).string(); }
  const std::string& str() const { return path_; }

 private:
  std::string path_;
};

inline void writeBytes(const std::string& path, const void* data, std::size_t size) {
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  f.write(static_cast<const char*>(data), static_cast<std::streamsize>(size));
  ASSERT_TRUE(f.good()) << path;
}

/// Packed x y z of every point of `scan` (through its CloudView, so the field offsets count).
inline std::vector<float> xyzOf(const gf::Scan& scan) {
  const gf::CloudView v = gf::viewOf(scan.cloud);
  std::vector<float> xyz;
  for (std::size_t i = 0; i < v.size(); ++i) xyz.insert(xyz.end(), {v.x(i), v.y(i), v.z(i)});
  return xyz;
}

inline void writeText(const std::string& path, const std::string& text) {
  writeBytes(path, text.data(), text.size());
}

inline std::vector<char> readBytes(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return std::vector<char>((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
}

struct KittiPoint {
  float x, y, z, intensity;
  std::uint32_t label;
};

inline void writeKitti(const std::string& bin, const std::vector<KittiPoint>& pts,
                       bool with_labels) {
  std::vector<float> xyzi;
  std::vector<std::uint32_t> labels;
  for (const auto& p : pts) {
    xyzi.insert(xyzi.end(), {p.x, p.y, p.z, p.intensity});
    labels.push_back(p.label);
  }
  writeBytes(bin, xyzi.data(), xyzi.size() * sizeof(float));
  if (with_labels) {
    writeBytes(fs::path(bin).replace_extension(".label").string(), labels.data(),
               labels.size() * sizeof(std::uint32_t));
  }
}

template <typename T>
inline T fieldValue(const pcl::PCLPointCloud2& c, const std::string& name, std::size_t i) {
  for (const auto& f : c.fields) {
    if (f.name == name) {
      T v;
      std::memcpy(&v, c.data.data() + i * c.point_step + f.offset, sizeof(T));
      return v;
    }
  }
  throw std::runtime_error("no field " + name);
}

inline bool hasField(const pcl::PCLPointCloud2& c, const std::string& name) {
  for (const auto& f : c.fields) {
    if (f.name == name) return true;
  }
  return false;
}

inline double groundShare(const std::vector<std::int8_t>& truth) {
  std::size_t ground = 0, counted = 0;
  for (const auto t : truth) {
    if (t < 0) continue;
    ++counted;
    ground += t == 1;
  }
  return counted ? static_cast<double>(ground) / counted : std::nan("");
}

inline std::string dataDir() { return GF_DATA_DIR; }

// ------------------------------------------------------------------ a minimal JSON reader

struct Json {
  enum Type { kNull, kBool, kNumber, kString, kArray, kObject } type = kNull;
  bool b = false;
  double num = 0.0;
  std::string str;
  std::vector<Json> arr;
  std::map<std::string, Json> obj;
  const Json& at(const std::string& k) const {
    const auto it = obj.find(k);
    if (it == obj.end()) throw std::runtime_error("missing key " + k);
    return it->second;
  }
};

class JsonParser {
 public:
  explicit JsonParser(const std::string& s) : s_(s) {}
  Json parseDocument() {
    Json v = parseValue();
    skipWs();
    if (pos_ != s_.size()) throw std::runtime_error("trailing characters after JSON value");
    return v;
  }

 private:
  void skipWs() {
    while (pos_ < s_.size() && std::isspace(static_cast<unsigned char>(s_[pos_]))) ++pos_;
  }
  char peek() {
    skipWs();
    if (pos_ >= s_.size()) throw std::runtime_error("unexpected end of JSON");
    return s_[pos_];
  }
  void expect(char c) {
    if (peek() != c) throw std::runtime_error(std::string("expected '") + c + "'");
    ++pos_;
  }
  bool consume(const char* word) {
    const std::size_t n = std::strlen(word);
    if (s_.compare(pos_, n, word) != 0) return false;
    pos_ += n;
    return true;
  }
  std::string parseString() {
    expect('"');
    std::string out;
    while (pos_ < s_.size() && s_[pos_] != '"') {
      if (s_[pos_] == '\\') {
        ++pos_;
        if (pos_ >= s_.size()) break;
        const char e = s_[pos_];
        if (e == 'u') {
          out += static_cast<char>(std::stoi(s_.substr(pos_ + 1, 4), nullptr, 16));
          pos_ += 4;
        } else {
          out += e == 'n' ? '\n' : e == 't' ? '\t' : e;
        }
      } else {
        out += s_[pos_];
      }
      ++pos_;
    }
    expect('"');
    return out;
  }
  // The items of an object or array up to `close` (the opening bracket already read).
  template <typename Item>
  void parseList(char close, Item item) {
    if (peek() == close) {
      ++pos_;
      return;
    }
    do {
      item();
    } while (peek() == ',' && ++pos_);
    expect(close);
  }
  Json parseValue() {
    Json v;
    const char c = peek();
    if (c == '{') {
      v.type = Json::kObject;
      ++pos_;
      parseList('}', [&] {
        const std::string key = parseString();
        expect(':');
        if (v.obj.count(key)) throw std::runtime_error("duplicate key " + key);
        v.obj[key] = parseValue();
      });
    } else if (c == '[') {
      v.type = Json::kArray;
      ++pos_;
      parseList(']', [&] { v.arr.push_back(parseValue()); });
    } else if (c == '"') {
      v.type = Json::kString;
      v.str = parseString();
    } else if (consume("null")) {
      v.type = Json::kNull;
    } else if (consume("true")) {
      v.type = Json::kBool;
      v.b = true;
    } else if (consume("false")) {
      v.type = Json::kBool;
    } else {
      v.type = Json::kNumber;
      std::size_t used = 0;
      v.num = std::stod(s_.substr(pos_), &used);
      if (used == 0) throw std::runtime_error("bad JSON number");
      pos_ += used;
    }
    return v;
  }

  const std::string& s_;
  std::size_t pos_ = 0;
};

struct CommandResult {
  int status = -1;
  std::string out;
};

// Runs the program `bin` with `args`; stdout only, or stdout + stderr when merge_stderr.
inline CommandResult runCommand(const std::string& bin, const std::string& args,
                                bool merge_stderr = false) {
  const std::string cmd = "'" + bin + "' " + args + (merge_stderr ? " 2>&1" : " 2>/dev/null");
  CommandResult r;
  FILE* pipe = popen(cmd.c_str(), "r");
  if (!pipe) return r;
  char buf[4096];
  std::size_t n;
  while ((n = std::fread(buf, 1, sizeof(buf), pipe)) > 0) r.out.append(buf, n);
  const int st = pclose(pipe);
  r.status = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
  return r;
}

// Runs ground_filter_eval with `args` (runCommand()).
inline CommandResult runEval(const std::string& args, bool merge_stderr = false) {
  return runCommand(GF_EVAL_BIN, args, merge_stderr);
}

// A flat 20 x 20 road patch at z = -1.73 (label 40) plus a 1 m box (label 50 building) and two
// ignored points: 400 + 125 + 2 = 527 points, 2 ignored.
inline std::vector<KittiPoint> smallScene() {
  std::vector<KittiPoint> pts;
  for (int i = 0; i < 20; ++i) {
    for (int j = 0; j < 20; ++j) {
      pts.push_back({5.0f + 0.1f * i, -1.0f + 0.1f * j, -1.73f, 0.3f, 40});
    }
  }
  for (int i = 0; i < 5; ++i) {
    for (int j = 0; j < 5; ++j) {
      for (int k = 0; k < 5; ++k) {
        pts.push_back({5.5f + 0.2f * i, -0.5f + 0.2f * j, -1.5f + 0.2f * k, 0.8f, 50});
      }
    }
  }
  pts.push_back({9.0f, 9.0f, 0.0f, 0.0f, 0});
  pts.push_back({9.0f, 9.5f, 0.0f, 0.0f, 1});
  return pts;
}

}  // namespace gf_io_test

#endif  // GROUND_FILTER_TEST_IO_TEST_UTIL_H
