#include "eval/scan_io.h"

#include <pcl/common/io.h>
#include <pcl/io/pcd_io.h>
#include <pcl/io/ply_io.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <filesystem>
#include <fstream>
#include <stdexcept>

#include "eval/scene_generator.h"
#include "ground_filter/point_field.h"
#include "ground_filter/working_volume_params.h"

namespace ground_filter {

namespace fs = std::filesystem;

namespace {

const char kBuiltinPrefix[] = "builtin:";

bool isBuiltin(const std::string& path) { return path.rfind(kBuiltinPrefix, 0) == 0; }

std::string lowerExtension(const std::string& path) {
  std::string ext = fs::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext;
}

bool isScanExtension(const std::string& ext) {
  return ext == ".bin" || ext == ".pcd" || ext == ".ply";
}

[[noreturn]] void fail(const std::string& path, const std::string& what) {
  throw std::runtime_error(path + ": " + what);
}

std::vector<char> readFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  if (!in) fail(path, "cannot open file");
  const std::streamsize size = in.tellg();
  std::vector<char> bytes(static_cast<std::size_t>(std::max<std::streamsize>(size, 0)));
  in.seekg(0);
  if (size > 0 && !in.read(bytes.data(), size)) fail(path, "read error");
  return bytes;
}

void checkRegularFile(const std::string& path) {
  std::error_code ec;
  if (!fs::exists(path, ec)) fail(path, "no such file");
  if (!fs::is_regular_file(path, ec)) fail(path, "not a regular file");
}

pcl::PCLPointField makeField(const std::string& name, std::uint32_t offset, std::uint8_t type) {
  return singleValueField<pcl::PCLPointField>(name, offset, type);
}

// x y z intensity as float32 at 0, 4, 8, 12: a KITTI record, the generator's first 16 bytes.
std::vector<pcl::PCLPointField> xyziFields() {
  return {makeField("x", 0, pcl::PCLPointField::FLOAT32),
          makeField("y", 4, pcl::PCLPointField::FLOAT32),
          makeField("z", 8, pcl::PCLPointField::FLOAT32),
          makeField("intensity", 12, pcl::PCLPointField::FLOAT32)};
}

// One row of `n` packed little-endian records of `step` bytes with `fields`; data not set.
void setLayout(std::vector<pcl::PCLPointField> fields, std::size_t n, std::uint32_t step,
               pcl::PCLPointCloud2* c) {
  c->fields = std::move(fields);
  c->height = 1;
  c->width = static_cast<std::uint32_t>(n);
  c->point_step = step;
  c->row_step = static_cast<std::uint32_t>(n * step);
  c->is_bigendian = false;
}

bool allFinite(const pcl::PCLPointCloud2& cloud) {
  const CloudView view = viewOf(cloud);
  for (std::size_t i = 0; i < view.size(); ++i) {
    if (!view.isValid(i)) return false;
  }
  return true;
}

// The SemanticKITTI label file of a .bin: next to it, or in ../labels/ for the velodyne/ layout.
std::string findKittiLabelFile(const std::string& bin_path) {
  const fs::path p(bin_path);
  const fs::path sibling = fs::path(p).replace_extension(".label");
  std::error_code ec;
  if (fs::exists(sibling, ec)) return sibling.string();
  if (p.parent_path().filename() == "velodyne") {
    const fs::path alt =
        p.parent_path().parent_path() / "labels" / p.filename().replace_extension(".label");
    if (fs::exists(alt, ec)) return alt.string();
  }
  return {};
}

Scan loadKittiBin(const std::string& path) {
  Scan scan;
  scan.path = path;
  std::vector<char> bytes = readFile(path);
  constexpr std::size_t kRecord = 4 * sizeof(float);
  if (bytes.size() % kRecord != 0) {
    fail(path, "size " + std::to_string(bytes.size()) +
                   " B is not a multiple of 16 B (KITTI float32 x y z intensity records)");
  }
  const std::size_t n = bytes.size() / kRecord;
  pcl::PCLPointCloud2& c = scan.cloud;
  setLayout(xyziFields(), n, kRecord, &c);
  c.data.assign(bytes.begin(), bytes.end());
  c.is_dense = allFinite(c);

  const std::string label_path = findKittiLabelFile(path);
  if (label_path.empty()) return scan;
  const std::vector<char> label_bytes = readFile(label_path);
  if (label_bytes.size() != n * sizeof(std::uint32_t)) {
    fail(label_path, "label count mismatch: " + std::to_string(label_bytes.size() / 4) +
                         " labels (" + std::to_string(label_bytes.size()) + " B) for " +
                         std::to_string(n) + " points in " + path);
  }
  const CloudView view = viewOf(c);
  scan.truth.resize(n);
  scan.semantic.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    std::uint32_t raw;
    std::memcpy(&raw, label_bytes.data() + 4 * i, sizeof(raw));  // little-endian host
    scan.truth[i] = semanticKittiTruth(raw, view.z(i));
    scan.semantic[i] = static_cast<std::uint16_t>(raw & 0xFFFFu);
  }
  return scan;
}

template <typename T>
double readAs(const std::uint8_t* p) {
  T v;
  std::memcpy(&v, p, sizeof(T));
  return static_cast<double>(v);
}

double readNumber(const std::uint8_t* p, std::uint8_t datatype) {
  // Indexed by pcl::PCLPointField's datatype codes INT8 (1) ... FLOAT64 (8).
  using Reader = double (*)(const std::uint8_t*);
  static const Reader kReaders[] = {nullptr,
                                    readAs<std::int8_t>,
                                    readAs<std::uint8_t>,
                                    readAs<std::int16_t>,
                                    readAs<std::uint16_t>,
                                    readAs<std::int32_t>,
                                    readAs<std::uint32_t>,
                                    readAs<float>,
                                    readAs<double>};
  static_assert(pcl::PCLPointField::INT8 == 1 && pcl::PCLPointField::FLOAT64 == 8,
                "PCL datatype codes");
  if (datatype == 0 || datatype >= sizeof(kReaders) / sizeof(kReaders[0])) {
    return std::nan("");  // unknown type: isprsTruth() maps it to "ignored"
  }
  return kReaders[datatype](p);
}

const pcl::PCLPointField* findField(const pcl::PCLPointCloud2& cloud, const std::string& name) {
  for (const auto& f : cloud.fields) {
    if (f.name == name) return &f;
  }
  return nullptr;
}

std::string fieldList(const pcl::PCLPointCloud2& cloud) {
  std::string s;
  for (const auto& f : cloud.fields) s += (s.empty() ? "" : " ") + f.name;
  return s.empty() ? "none" : s;
}

// Byte offset of point i (row-major over an organised cloud, rows may be padded).
std::size_t recordOffset(const pcl::PCLPointCloud2& cloud, std::size_t i) {
  if (cloud.width == 0) return 0;
  return (i / cloud.width) * cloud.row_step + (i % cloud.width) * cloud.point_step;
}

void checkBuffer(const std::string& path, const pcl::PCLPointCloud2& cloud) {
  const std::size_t need = static_cast<std::size_t>(cloud.row_step) * cloud.height;
  if (cloud.data.size() < need) {
    fail(path, "data holds " + std::to_string(cloud.data.size()) + " B, header needs " +
                   std::to_string(need) + " B");
  }
}

// A cloud whose x, y and z are all float64 (survey exports): each becomes a float32 in the
// first half of its 8 bytes, the precision the filters compute in (the rest of the record,
// and so every other field, is kept). A cloud whose middle lies beyond the working volume's hard
// box (projected coordinates: UTM, a national grid) is first moved by whole metres onto its
// middle, in double, so the float32 keeps millimetres: `shift` says by how much (else 0).
void narrowDoubleXyz(pcl::PCLPointCloud2* cloud, double shift[3]) {
  std::fill_n(shift, 3, 0.0);
  pcl::PCLPointField* f[3] = {nullptr, nullptr, nullptr};
  const char* names[3] = {"x", "y", "z"};
  for (int k = 0; k < 3; ++k) {
    for (auto& field : cloud->fields) {
      if (field.name == names[k]) f[k] = &field;
    }
    if (!f[k] || f[k]->datatype != pcl::PCLPointField::FLOAT64 || f[k]->count != 1 ||
        f[k]->offset + sizeof(double) > cloud->point_step) {
      return;  // not all three float64: viewOf() names what is wrong
    }
  }
  const std::size_t n = static_cast<std::size_t>(cloud->width) * cloud->height;
  auto coordinate = [&](std::size_t i, int k) {
    double v;
    std::memcpy(&v, cloud->data.data() + recordOffset(*cloud, i) + f[k]->offset, sizeof v);
    return v;
  };
  const std::size_t step = std::max<std::size_t>(1, n / 8192);
  std::vector<double> axis;
  double middle[3] = {0.0, 0.0, 0.0};
  for (int k = 0; k < 3 && n > 0; ++k) {
    axis.clear();
    for (std::size_t i = 0; i < n; i += step) {
      const double v = coordinate(i, k);
      if (std::isfinite(v)) axis.push_back(v);
    }
    if (axis.empty()) break;
    middle[k] = trimmedMiddle(&axis);
  }
  if (moveOntoMiddle(middle, kWorkingVolumeHardLimit)) std::copy_n(middle, 3, shift);
  for (std::size_t i = 0; i < n; ++i) {
    std::uint8_t* rec = cloud->data.data() + recordOffset(*cloud, i);
    for (int k = 0; k < 3; ++k) {
      double v;
      std::memcpy(&v, rec + f[k]->offset, sizeof v);
      const float narrow = narrowCoordinate(v - shift[k]);
      std::memcpy(rec + f[k]->offset, &narrow, sizeof narrow);
    }
  }
  for (int k = 0; k < 3; ++k) f[k]->datatype = pcl::PCLPointField::FLOAT32;
}

Scan loadPclFile(const std::string& path, bool pcd, bool narrow) {
  Scan scan;
  scan.path = path;
  int rc = -1;
  try {
    if (pcd) {
      // PCL 1.13 accepts a header without FIELDS and then crashes in read(): check it first.
      pcl::PCDReader reader;
      pcl::PCLPointCloud2 header;
      Eigen::Vector4f origin;
      Eigen::Quaternionf orientation;
      int version = 0, data_type = 0;
      unsigned int data_idx = 0;
      const int header_rc =
          reader.readHeader(path, header, origin, orientation, version, data_type, data_idx);
      if (header.fields.empty() || header.point_step == 0) {
        fail(path, "cannot read PCD file: no valid PCD header (FIELDS/SIZE/TYPE missing)");
      }
      if (static_cast<std::size_t>(header.width) * header.height == 0) {
        // No points: PCL 1.11 (Debian 11) refuses such a file
        // ("No points to read"); PCL 1.13 reads it as an empty cloud. Same result everywhere.
        header.data.clear();
        header.row_step = 0;
        scan.cloud = std::move(header);
        return scan;
      }
      if (header_rc < 0) {
        fail(path, "cannot read PCD file: no valid PCD header (FIELDS/SIZE/TYPE missing)");
      }
    }
    rc = pcd ? pcl::io::loadPCDFile(path, scan.cloud) : pcl::io::loadPLYFile(path, scan.cloud);
  } catch (const std::runtime_error&) {
    throw;
  } catch (const std::exception& e) {
    fail(path, std::string("cannot read ") + (pcd ? "PCD" : "PLY") + " file: " + e.what());
  }
  if (rc < 0) fail(path, std::string("cannot read ") + (pcd ? "PCD" : "PLY") + " file");
  if (scan.cloud.is_bigendian) fail(path, "big-endian point data is not supported");
  checkBuffer(path, scan.cloud);
  if (narrow) narrowDoubleXyz(&scan.cloud, scan.shift);

  const pcl::PCLPointField* label = pcd ? findField(scan.cloud, "label") : nullptr;
  if (label) {
    const std::size_t n = scan.size();
    if (label->offset + pcl::getFieldSize(label->datatype) > scan.cloud.point_step) {
      fail(path, "field 'label' lies outside the point record");
    }
    scan.truth.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
      const std::uint8_t* rec = scan.cloud.data.data() + recordOffset(scan.cloud, i);
      scan.truth[i] = isprsTruth(readNumber(rec + label->offset, label->datatype));
    }
  }
  return scan;
}

std::size_t fieldBytes(const pcl::PCLPointField& f) {
  return static_cast<std::size_t>(pcl::getFieldSize(f.datatype)) *
         std::max<std::uint32_t>(f.count, 1);
}

void writeBinaryPcd(const std::string& path, const pcl::PCLPointCloud2& cloud) {
  if (cloud.data.empty()) {
    // PCL 1.11 (Debian 11) refuses to write a cloud without points
    // ("Input point cloud has no data!"); a split with no ground or no non-ground point is
    // valid, so write the header alone (POINTS 0), as PCL 1.13 does.
    std::ofstream f(path, std::ios::binary | std::ios::trunc);
    if (!f) fail(path, "cannot write PCD file");
    pcl::PCDWriter writer;
    f << writer.generateHeaderBinary(cloud, Eigen::Vector4f::Zero(), Eigen::Quaternionf::Identity())
      << "DATA binary\n";
    f.close();
    if (!f) fail(path, "cannot write PCD file");
    return;
  }
  pcl::PCDWriter writer;
  int rc = -1;
  try {
    rc = writer.writeBinary(path, cloud);
  } catch (const std::exception& e) {
    fail(path, std::string("cannot write PCD file: ") + e.what());
  }
  if (rc < 0) fail(path, "cannot write PCD file");
}

void makeDir(const std::string& dir) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec || !fs::is_directory(dir)) fail(dir, "cannot create output directory: " + ec.message());
}

// Writes `bytes` to `path` (truncating), or fails naming it.
void writeFile(const std::string& path, const std::vector<unsigned char>& bytes) {
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  if (!f) fail(path, "cannot open for writing");
  f.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  f.close();
  if (!f) fail(path, "write error");
}

// builtin:KIND[:SEED][:NAME=VALUE,...]: a generated scene with fields x y z intensity ring.
Scan loadBuiltinScan(const std::string& path) {
  SceneParams params;
  try {
    params = parseSceneSpec(path.substr(sizeof(kBuiltinPrefix) - 1));
  } catch (const std::invalid_argument& e) {
    fail(path, std::string(e.what()) + "; expected builtin:KIND[:SEED][:NAME=VALUE,...]");
  }
  GeneratedScan gen;
  try {
    gen = generateScene(params);
  } catch (const std::exception& e) {
    fail(path, std::string("scene generator failed: ") + e.what());
  }
  Scan scan = scanOf(std::move(gen));
  scan.path = path;
  return scan;
}

}  // namespace

Scan scanOf(GeneratedScan scene) {
  const std::size_t n = scene.size();
  if (scene.xyz.size() != 3 * n || scene.intensity.size() != n || scene.ring.size() != n ||
      scene.semantic.size() != n) {
    throw std::runtime_error("generated scene: inconsistent array sizes");
  }
  Scan scan;
  scan.path = "builtin";
  pcl::PCLPointCloud2& c = scan.cloud;
  constexpr std::uint32_t kStep = 4 * sizeof(float) + sizeof(std::uint16_t);  // packed, 18 B
  std::vector<pcl::PCLPointField> fields = xyziFields();
  fields.push_back(makeField("ring", 16, pcl::PCLPointField::UINT16));
  setLayout(std::move(fields), n, kStep, &c);
  c.data.resize(n * kStep);
  for (std::size_t i = 0; i < n; ++i) {
    std::uint8_t* rec = c.data.data() + i * kStep;
    std::memcpy(rec, &scene.xyz[3 * i], 3 * sizeof(float));
    std::memcpy(rec + 12, &scene.intensity[i], sizeof(float));
    std::memcpy(rec + 16, &scene.ring[i], sizeof(std::uint16_t));
  }
  c.is_dense = allFinite(c);
  scan.truth.assign(scene.truth.begin(), scene.truth.end());  // 1 ground, 0 non-ground
  scan.semantic = std::move(scene.semantic);
  return scan;
}

std::int8_t semanticKittiTruth(std::uint32_t raw_label, float z) {
  switch (raw_label & 0xFFFFu) {
    case 0:  // unlabeled
    case 1:  // outlier
      return -1;
    case 40:  // road
    case 44:  // parking
    case 48:  // sidewalk
    case 49:  // other-ground
    case 60:  // lane-marking
    case 72:  // terrain
      return 1;
    case 70:  // vegetation: ground only near the road surface
      return static_cast<double>(z) < kKittiVegetationGroundZ ? 1 : 0;
    default:
      return 0;
  }
}

std::string semanticKittiClassName(std::uint16_t cls) {
  switch (cls) {
    case 0:
      return "unlabeled";
    case 1:
      return "outlier";
    case 10:
      return "car";
    case 11:
      return "bicycle";
    case 13:
      return "bus";
    case 15:
      return "motorcycle";
    case 16:
      return "on-rails";
    case 18:
      return "truck";
    case 20:
      return "other-vehicle";
    case 30:
      return "person";
    case 31:
      return "bicyclist";
    case 32:
      return "motorcyclist";
    case 40:
      return "road";
    case 44:
      return "parking";
    case 48:
      return "sidewalk";
    case 49:
      return "other-ground";
    case 50:
      return "building";
    case 51:
      return "fence";
    case 52:
      return "other-structure";
    case 60:
      return "lane-marking";
    case 70:
      return "vegetation";
    case 71:
      return "trunk";
    case 72:
      return "terrain";
    case 80:
      return "pole";
    case 81:
      return "traffic-sign";
    case 99:
      return "other-object";
    default:
      return "class " + std::to_string(cls);
  }
}

std::int8_t isprsTruth(double label_value) {
  if (label_value == 1.0) return 1;
  if (label_value == 0.0) return 0;
  return -1;
}

std::string scanStem(const std::string& path) {
  if (isBuiltin(path)) {
    std::string s = path;  // builtin:lidar16:2:beams=32 -> builtin_lidar16_2_beams-32
    std::replace(s.begin(), s.end(), ':', '_');
    std::replace(s.begin(), s.end(), ',', '_');
    std::replace(s.begin(), s.end(), '=', '-');
    return s;
  }
  return fs::path(path).stem().string();
}

CloudView viewOf(const pcl::PCLPointCloud2& cloud) {
  std::size_t offsets[3];
  const char* names[3] = {"x", "y", "z"};
  for (int k = 0; k < 3; ++k) {
    const pcl::PCLPointField* f = findField(cloud, names[k]);
    if (!f || f->datatype != pcl::PCLPointField::FLOAT32) {
      throw std::runtime_error(std::string("point cloud has no float32 field '") + names[k] +
                               "' (fields: " + fieldList(cloud) + ")");
    }
    if (f->offset + sizeof(float) > cloud.point_step) {
      throw std::runtime_error(std::string("field '") + names[k] + "' at offset " +
                               std::to_string(f->offset) + " lies outside the " +
                               std::to_string(cloud.point_step) + " B point record");
    }
    offsets[k] = f->offset;
  }
  const std::size_t n = static_cast<std::size_t>(cloud.width) * cloud.height;
  if (cloud.height > 1 && cloud.row_step != cloud.width * cloud.point_step) {
    throw std::runtime_error("organised cloud with padded rows (row_step " +
                             std::to_string(cloud.row_step) +
                             " != width x point_step) is not "
                             "supported");
  }
  const std::size_t need = n * cloud.point_step;
  if (cloud.data.size() < need) {
    throw std::runtime_error("point cloud data holds " + std::to_string(cloud.data.size()) +
                             " B, but " + std::to_string(n) + " points of " +
                             std::to_string(cloud.point_step) + " B need " + std::to_string(need));
  }
  return CloudView(cloud.data.data(), n, cloud.point_step, offsets[0], offsets[1], offsets[2]);
}

std::vector<std::string> listScanFiles(const std::string& path_or_dir) {
  if (isBuiltin(path_or_dir)) return {path_or_dir};
  std::error_code ec;
  if (!fs::exists(path_or_dir, ec)) fail(path_or_dir, "no such file or directory");
  if (!fs::is_directory(path_or_dir, ec)) return {path_or_dir};
  std::vector<std::string> files;
  for (const auto& entry : fs::directory_iterator(path_or_dir, ec)) {
    if (!entry.is_regular_file()) continue;
    if (isScanExtension(lowerExtension(entry.path().string()))) {
      files.push_back(entry.path().string());
    }
  }
  if (ec) fail(path_or_dir, "cannot list directory: " + ec.message());
  std::sort(files.begin(), files.end());
  return files;
}

std::vector<std::string> listScanFiles(const std::vector<std::string>& paths) {
  std::vector<std::string> files;
  for (const auto& p : paths) {
    const std::vector<std::string> found = listScanFiles(p);
    if (found.empty()) throw std::runtime_error(p + ": no .bin, .pcd or .ply files in directory");
    files.insert(files.end(), found.begin(), found.end());
  }
  return files;
}

Scan loadScan(const std::string& path, bool keep_float64) {
  if (isBuiltin(path)) return loadBuiltinScan(path);
  checkRegularFile(path);
  const std::string ext = lowerExtension(path);
  if (ext == ".bin") return loadKittiBin(path);
  if (ext == ".pcd") return loadPclFile(path, true, !keep_float64);
  if (ext == ".ply") return loadPclFile(path, false, !keep_float64);
  fail(path, "unknown scan file type '" + ext + "' (expected .bin, .pcd or .ply)");
}

void splitCloud(const pcl::PCLPointCloud2& cloud, const std::vector<std::uint8_t>& labels,
                pcl::PCLPointCloud2* ground, pcl::PCLPointCloud2* nonground) {
  const std::size_t n = static_cast<std::size_t>(cloud.width) * cloud.height;
  if (labels.size() != n) {
    throw std::runtime_error("splitCloud: " + std::to_string(labels.size()) + " labels for " +
                             std::to_string(n) + " points");
  }
  checkBuffer("splitCloud input", cloud);
  // Packed layout: every real field in offset order, PCL "_" padding dropped.
  std::vector<pcl::PCLPointField> fields;
  for (const auto& f : cloud.fields) {
    if (f.name == "_" || pcl::getFieldSize(f.datatype) == 0) continue;
    if (f.offset + fieldBytes(f) > cloud.point_step) {
      throw std::runtime_error("splitCloud: field '" + f.name + "' lies outside the point record");
    }
    fields.push_back(f);
  }
  std::sort(
      fields.begin(), fields.end(),
      [](const pcl::PCLPointField& a, const pcl::PCLPointField& b) { return a.offset < b.offset; });
  std::vector<pcl::PCLPointField> out_fields = fields;
  std::uint32_t step = 0;
  for (auto& f : out_fields) {
    f.count = std::max<std::uint32_t>(f.count, 1);
    f.offset = step;
    step += static_cast<std::uint32_t>(fieldBytes(f));
  }
  const std::size_t n_ground =
      static_cast<std::size_t>(std::count(labels.begin(), labels.end(), std::uint8_t{1}));
  pcl::PCLPointCloud2* outs[2] = {nonground, ground};
  const std::size_t counts[2] = {n - n_ground, n_ground};
  for (int k = 0; k < 2; ++k) {
    pcl::PCLPointCloud2& o = *outs[k];
    o.header = cloud.header;
    o.fields = out_fields;
    o.height = 1;
    o.width = static_cast<std::uint32_t>(counts[k]);
    o.point_step = step;
    o.row_step = static_cast<std::uint32_t>(counts[k] * step);
    o.is_bigendian = cloud.is_bigendian;
    o.is_dense = cloud.is_dense;
    o.data.resize(counts[k] * step);
  }
  std::size_t next[2] = {0, 0};
  for (std::size_t i = 0; i < n; ++i) {
    const int k = labels[i] == 1 ? 1 : 0;
    const std::uint8_t* src = cloud.data.data() + recordOffset(cloud, i);
    std::uint8_t* dst = outs[k]->data.data() + next[k]++ * step;
    for (std::size_t j = 0; j < fields.size(); ++j) {
      std::memcpy(dst + out_fields[j].offset, src + fields[j].offset, fieldBytes(fields[j]));
    }
  }
}

std::string writeLabels(const std::string& dir, const std::string& scan_path,
                        const std::vector<std::uint8_t>& labels) {
  makeDir(dir);
  const std::string out = (fs::path(dir) / (scanStem(scan_path) + ".gnd")).string();
  writeFile(out, labels);
  return out;
}

std::string writeKittiLabels(const std::string& dir, const std::string& scan_path,
                             const std::vector<std::uint8_t>& labels, const KittiLabelIds& ids) {
  makeDir(dir);
  const fs::path out_path = fs::path(dir) / (scanStem(scan_path) + ".label");
  const std::string out = out_path.string();
  std::error_code ec;
  if (fs::exists(out_path, ec) &&
      fs::equivalent(fs::path(scan_path).parent_path().empty() ? fs::path(".")
                                                               : fs::path(scan_path).parent_path(),
                     fs::path(dir), ec)) {
    fail(out, "is the scan's own SemanticKITTI truth: write the labels to another directory");
  }
  std::vector<unsigned char> bytes(labels.size() * 4);
  for (std::size_t i = 0; i < labels.size(); ++i) {
    const std::uint32_t v = labels[i] == 1 ? ids.ground : ids.nonground;
    for (int b = 0; b < 4; ++b) bytes[4 * i + b] = static_cast<unsigned char>(v >> (8 * b));
  }
  writeFile(out, bytes);
  return out;
}

namespace {

// The class writeKittiScan() gives point i: one semanticKittiTruth() reads back as its truth.
std::uint32_t kittiClassOf(const Scan& scan, std::size_t i, float z) {
  const std::int8_t truth = scan.truth[i];
  if (!scan.semantic.empty() && semanticKittiTruth(scan.semantic[i], z) == truth) {
    return scan.semantic[i];
  }
  return truth == 1 ? 49u : truth == 0 ? 99u : 0u;  // other-ground, other-object, unlabeled
}

}  // namespace

std::string writeKittiScan(const std::string& dir, const Scan& scan) {
  makeDir(dir);
  const fs::path bin = fs::path(dir) / (scanStem(scan.path) + ".bin");
  std::error_code ec;
  if (fs::exists(bin, ec) && fs::exists(scan.path, ec) && fs::equivalent(bin, scan.path, ec)) {
    fail(bin.string(), "is the scan itself: write it to another directory");
  }
  const pcl::PCLPointCloud2& c = scan.cloud;
  const char* names[4] = {"x", "y", "z", "intensity"};
  const pcl::PCLPointField* fields[4];
  for (int k = 0; k < 4; ++k) fields[k] = findField(c, names[k]);
  const std::size_t n = scan.size();
  std::vector<unsigned char> points(n * 16), labels(scan.labelled() ? n * 4 : 0);
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint8_t* rec = c.data.data() + i * c.point_step;
    float v[4] = {0.f, 0.f, 0.f, 0.f};
    for (int k = 0; k < 4; ++k) {
      if (fields[k])
        v[k] = static_cast<float>(readNumber(rec + fields[k]->offset, fields[k]->datatype));
    }
    std::memcpy(&points[16 * i], v, sizeof(v));  // KITTI .bin: little-endian float32 records
    if (labels.empty()) continue;
    const std::uint32_t cls = kittiClassOf(scan, i, v[2]);
    for (int b = 0; b < 4; ++b) labels[4 * i + b] = static_cast<unsigned char>(cls >> (8 * b));
  }
  writeFile(bin.string(), points);
  if (!labels.empty()) writeFile(fs::path(bin).replace_extension(".label").string(), labels);
  return bin.string();
}

std::pair<std::string, std::string> writeSplitClouds(const std::string& dir,
                                                     const std::string& scan_path,
                                                     const pcl::PCLPointCloud2& cloud,
                                                     const std::vector<std::uint8_t>& labels) {
  pcl::PCLPointCloud2 ground, nonground;
  splitCloud(cloud, labels, &ground, &nonground);
  makeDir(dir);
  const std::string stem = scanStem(scan_path);
  const std::string g = (fs::path(dir) / (stem + "_ground.pcd")).string();
  const std::string ng = (fs::path(dir) / (stem + "_nonground.pcd")).string();
  writeBinaryPcd(g, ground);
  writeBinaryPcd(ng, nonground);
  return {g, ng};
}

}  // namespace ground_filter
