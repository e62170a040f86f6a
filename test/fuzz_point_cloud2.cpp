// libFuzzer target over the nodelets' byte path without any ROS graph: serialised bytes ->
// deserializePointCloud2 -> checkPointCloud2 -> processPointCloud2 (view, working volume,
// filter, split, labelled cloud; or its two halves with a float field written into the copies),
// as GroundFilterNodelet runs it. Every accepted cloud must come
// out with each record in exactly one output. Built by test/sanitize/CMakeLists.txt (ASan +
// UBSan); run by scripts/fuzz.sh. GF_FUZZ_METHOD selects the filter (voxel | normal).
#include <Eigen/Geometry>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "ground_filter/ground_filter.h"
#include "point_cloud2.h"

namespace gf = ground_filter;

namespace {

std::unique_ptr<gf::GroundFilter> g_filter;

// Aborts with a message: libFuzzer records the input as a crash.
void require(bool ok, const char* what) {
  if (!ok) {
    std::fprintf(stderr, "fuzz_point_cloud2: invariant violated: %s\n", what);
    std::abort();
  }
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int* /*argc*/, char*** /*argv*/) {
  const char* method = std::getenv("GF_FUZZ_METHOD");
  // As the nodelet runs it (max_range 1000 m); one thread: libFuzzer runs inputs back to back.
  g_filter =
      gf::makeGroundFilter(method ? method : "voxel", {{"threads", "1"}, {"max_range", "1000"}});
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size > 0xFFFFFFFFu) return 0;
  sensor_msgs::PointCloud2 msg;
  std::string why;
  if (!gf::deserializePointCloud2(data, static_cast<std::uint32_t>(size), &msg, &why)) return 0;
  gf::CloudLayout layout;
  if (gf::checkPointCloud2(msg, &layout, &why) != gf::CloudRejectReason::kNone) return 0;

  // An odd seq also runs the gravity-frame path (a rotated, translated view).
  Eigen::Isometry3d transform = Eigen::Isometry3d::Identity();
  transform.rotate(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitX()));
  transform.translation() = Eigen::Vector3d(1.0, -2.0, 0.5);
  const bool transformed = (msg.header.seq & 1u) != 0;

  gf::CloudProcessingBuffers buffers;
  gf::ProcessedCloud out;
  // Seq bit 1: the nodelets' height path, a float field written into every output as it is
  // copied (filterPointCloud2(), then writeOutputs() with the field).
  const bool with_field = (msg.header.seq & 2u) != 0;
  std::vector<float> values;
  gf::RecordFloatField field;
  field.name = "height_above_ground";
  field.values = &values;
  if (with_field) {
    gf::filterPointCloud2(msg, layout, g_filter.get(), transformed ? &transform : nullptr, &buffers,
                          &out);
    for (std::size_t i = 0; i < layout.points; ++i) values.push_back(static_cast<float>(i));
    gf::writeOutputs(msg, layout, /*want_labeled=*/true, &buffers, &out, nullptr, &field,
                     /*field_in_split=*/true);
  } else {
    gf::processPointCloud2(msg, layout, g_filter.get(), transformed ? &transform : nullptr,
                           /*want_labeled=*/true, &buffers, &out);
  }
  // The split's record size: the input's, or with the field (unless it was refused).
  std::size_t step = layout.point_step;
  if (with_field && out.field_error.empty()) {
    std::size_t offset = 0;
    bool append = false;
    require(gf::fieldSlot(msg.fields, layout.point_step, field.name,
                          sensor_msgs::PointField::FLOAT32, 4, &offset, &step, &append, &why),
            "field slot");
  }
  require(out.ground && out.nonground, "outputs missing");
  require(out.counts.ground + out.counts.nonground == layout.points, "points not conserved");
  require(out.ground->width == out.counts.ground, "ground width");
  require(out.nonground->width == out.counts.nonground, "nonground width");
  require(out.ground->point_step == step && out.nonground->point_step == step, "split step");
  require(out.ground->data.size() == out.counts.ground * step, "ground bytes");
  require(out.nonground->data.size() == out.counts.nonground * step, "nonground bytes");
  require(out.counts.invalid <= out.counts.nonground, "invalid points outside non-ground");
  if (out.labeled) {
    require(out.labeled->width == msg.width && out.labeled->height == msg.height, "labelled size");
    require(out.labeled->data.size() == std::size_t{out.labeled->point_step} * layout.points,
            "labelled bytes");
  }
  // The outputs must be valid clouds themselves (a consumer's checkPointCloud2 accepts them).
  gf::CloudLayout out_layout;
  require(gf::checkPointCloud2(*out.ground, &out_layout, &why) == gf::CloudRejectReason::kNone,
          "ground output invalid");
  require(gf::checkPointCloud2(*out.nonground, &out_layout, &why) == gf::CloudRejectReason::kNone,
          "nonground output invalid");
  return 0;
}
