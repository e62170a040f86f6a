#ifndef GROUND_FILTER_SRC_EVAL_SCAN_IO_H
#define GROUND_FILTER_SRC_EVAL_SCAN_IO_H

#include <pcl/PCLPointCloud2.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <string>
#include <utility>
#include <vector>

#include "eval/scene_generator.h"
#include "ground_filter/cloud_view.h"

namespace ground_filter {

/// \brief SemanticKITTI vegetation (class 70) counts as ground only below this sensor-frame z [m]
///        (-0.75 x the 1.73 m sensor height, as in the Ground-Segmentation-Benchmark protocol).
constexpr double kKittiVegetationGroundZ = -1.2975;

/// \brief One scan as read from disk (or generated): all its fields plus optional ground truth.
struct Scan {
  pcl::PCLPointCloud2 cloud;       ///< every field of the input, little-endian records
  std::vector<std::int8_t> truth;  ///< per point 1 ground, 0 non-ground, -1 ignored; empty = none
  /// Per point SemanticKITTI class (low 16 bits of a .label; the generator's classes for
  /// builtin: scenes); empty when the source has no classes.
  std::vector<std::uint16_t> semantic;
  std::string path;  ///< where it came from (file path or builtin:...)
  /// Subtracted from float64 x/y/z before they became float32 (a cloud in projected
  /// coordinates, beyond the working volume's hard box; 0 otherwise) [m]: the origin of the
  /// file lies at -shift in the cloud as loaded.
  double shift[3] = {0.0, 0.0, 0.0};

  /// \brief Number of point records (width x height).
  std::size_t size() const { return static_cast<std::size_t>(cloud.width) * cloud.height; }
  /// \brief True when ground truth was found for this scan.
  bool labelled() const { return !truth.empty(); }
};

/// \brief "" for a scan read as it is, else "; float64 x/y/z read as offsets from X Y Z"
///        (Scan::shift), for the reason line of the tools.
inline std::string shiftNote(const Scan& scan) {
  if (scan.shift[0] == 0.0 && scan.shift[1] == 0.0 && scan.shift[2] == 0.0) return "";
  char text[128];
  std::snprintf(text, sizeof(text), "; float64 x/y/z read as offsets from %.0f %.0f %.0f",
                scan.shift[0], scan.shift[1], scan.shift[2]);
  return text;
}

/// \brief Loads a scan.
///
/// - `*.bin`: KITTI float32 records `x y z intensity` (16 B a point). A sibling `<stem>.label`
///   (or `../labels/<stem>.label` for the SemanticKITTI `velodyne/` layout) is read as ground
///   truth with semanticKittiTruth().
/// - `*.pcd`, `*.ply`: read through PCL with all fields. A PCD field named `label` is ground truth
///   under the ISPRS protocol (isprsTruth()); PLY labels are not interpreted.
/// - `builtin:KIND[:SEED][:NAME=VALUE,...]` (parseSceneSpec()): a generated scene with exact
///   truth and classes (fields x y z intensity ring); KIND is one of builtinSceneKinds()
///   (scene_generator.h), e.g. `lidar` (street, HDL-64), `tls` (street, tripod scanner),
///   `verge`, `offroad`, `trail`; the fields set the sensor or world.
/// - float64 x/y/z (all three) become float32, moved first where they lie far from the origin
///   (Scan::shift), unless `keep_float64`: then they stay as they are (shift 0) and viewOf()
///   refuses the cloud; for a tool that passes the records on (scene_publisher: the nodelets
///   move such a cloud themselves, keeping its precision).
/// \throws std::runtime_error naming the file for a missing/unreadable/malformed file, an unknown
///         extension or a label count that does not match the points.
Scan loadScan(const std::string& path, bool keep_float64 = false);

/// \brief A generated scene as a Scan, as `builtin:` paths load it: packed fields x y z intensity
///        (float32) and ring (uint16), truth and classes; `path` is "builtin".
/// \throws std::runtime_error when the scene's arrays do not have one entry per point.
Scan scanOf(GeneratedScan scene);

/// \brief Short SemanticKITTI class name ("road", "vegetation", ...); "class N" when unknown.
std::string semanticKittiClassName(std::uint16_t cls);

/// \brief Scan files of `path_or_dir`: a file or `builtin:...` is returned as is; a directory
///        gives its `.bin`/`.pcd`/`.ply` files (not recursive), sorted by name.
/// \throws std::runtime_error when the path does not exist.
std::vector<std::string> listScanFiles(const std::string& path_or_dir);

/// \brief The scan files of every path in `paths` (listScanFiles of each), in order.
/// \throws std::runtime_error when a path does not exist or a directory holds no scan file.
std::vector<std::string> listScanFiles(const std::vector<std::string>& paths);

/// \brief Zero-copy view of the float32 x/y/z fields of `cloud`.
/// \throws std::runtime_error when x, y or z is missing or not float32, or the buffer is shorter
///         than its header says or has padded rows.
CloudView viewOf(const pcl::PCLPointCloud2& cloud);

/// \brief SemanticKITTI ground protocol for one point: raw .label value (class in the low 16 bits)
///        and the point's z. Returns 1 ground, 0 non-ground, -1 ignored (classes 0 and 1).
std::int8_t semanticKittiTruth(std::uint32_t raw_label, float z);

/// \brief ISPRS protocol of a PCD `label` value: 1 ground, 0 non-ground, anything else -1.
std::int8_t isprsTruth(double label_value);

/// \brief File stem used for outputs: `dir/000000.bin` -> `000000`, `builtin:lidar:7` ->
///        `builtin_lidar_7`.
std::string scanStem(const std::string& path);

/// \brief Splits `cloud` by `labels` (1 ground, else non-ground) into two unorganised clouds with
///        every field (padding removed), records in input order.
/// \throws std::runtime_error when labels.size() differs from the point count.
void splitCloud(const pcl::PCLPointCloud2& cloud, const std::vector<std::uint8_t>& labels,
                pcl::PCLPointCloud2* ground, pcl::PCLPointCloud2* nonground);

/// \brief Writes `dir/<stem>.gnd`: one uint8 per input point in input order (1 ground, 0 not).
///        Creates `dir` when missing. Returns the written path.
/// \throws std::runtime_error when the file cannot be written.
std::string writeLabels(const std::string& dir, const std::string& scan_path,
                        const std::vector<std::uint8_t>& labels);

/// \brief SemanticKITTI class ids written for ground / non-ground points by writeKittiLabels().
struct KittiLabelIds {
  std::uint16_t ground = 40;    ///< 40 "road" (the filter does not tell road from sidewalk)
  std::uint16_t nonground = 0;  ///< 0 "unlabeled" (ignored by SemanticKITTI training)
};

/// \brief Writes `dir/<stem>.label` as SemanticKITTI does: one little-endian uint32 per input
///        point in input order, the class id in the low 16 bits (ids.ground or ids.nonground),
///        instance 0 in the high 16 bits. Creates `dir` when missing; refuses to write where
///        the file would be the scan's own truth (`dir` = the scan's directory). Returns the
///        written path.
/// \throws std::runtime_error when the file cannot (or must not) be written.
std::string writeKittiLabels(const std::string& dir, const std::string& scan_path,
                             const std::vector<std::uint8_t>& labels,
                             const KittiLabelIds& ids = KittiLabelIds());

/// \brief Writes `scan` as a KITTI scan: `dir/<stem>.bin` (float32 x y z intensity a point, in
///        input order, non-finite points kept; intensity 0 without such a field) and, when the
///        scan is labelled, `dir/<stem>.label` that loadScan() reads back as the same truth: each
///        point's SemanticKITTI class where semanticKittiTruth() gives its truth, else 49
///        "other-ground" (ground), 99 "other-object" (non-ground) or 0 "unlabeled" (ignored).
///        For other tools (the peers' drivers) on generated scenes. Creates `dir` when missing;
///        refuses to overwrite the scan's own files. Returns the .bin path.
/// \throws std::runtime_error when a file cannot (or must not) be written.
std::string writeKittiScan(const std::string& dir, const Scan& scan);

/// \brief Writes `dir/<stem>_ground.pcd` and `dir/<stem>_nonground.pcd` (binary PCD, every input
///        field). Creates `dir` when missing. Returns the two written paths.
/// \throws std::runtime_error when a file cannot be written or the label count is wrong.
std::pair<std::string, std::string> writeSplitClouds(const std::string& dir,
                                                     const std::string& scan_path,
                                                     const pcl::PCLPointCloud2& cloud,
                                                     const std::vector<std::uint8_t>& labels);

}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_EVAL_SCAN_IO_H
