// Working volume (issue 12): far points (300 km, 1e7 m, 1e30 m) are labelled non-ground one by
// one and counted, and every other point of a real KITTI frame keeps its label, for both filters
// and both KNN backends.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "eval/kitti_bin.h"
#include "eval/scene_generator.h"
#include "gf_test_data.h"
#include "ground_filter/ground_filter.h"
#include "ground_filter/voxel_ground_filter.h"
#include "ground_filter/working_volume.h"

namespace gf = ground_filter;

namespace {

const std::string kKittiFrame = std::string(GF_DATA_DIR) + "/semantickitti/seq00/000000.bin";

// The frame's x y z; the tests that call it start with GF_SKIP_WITHOUT_DATA(kKittiFrame).
const std::vector<float>& kittiFrame() {
  static const std::vector<float> xyz = gf::readKittiXyz(kKittiFrame);
  return xyz;
}

// The far coordinates the issue names, each on a different axis and sign.
const float kFar[][3] = {{300e3f, 0.f, 0.f},   {0.f, -1e7f, 0.f},  {0.f, 0.f, 1e30f},
                         {-1e30f, 1e30f, 5.f}, {5001.f, 0.f, 0.f}, {0.f, 0.f, -2e5f}};

struct Case {
  std::string method;
  gf::ParamSettings settings;
};

std::vector<Case> cases() {
  return {{"voxel", {}},
          {"normal", {{"knn_backend", "kdtree"}}},
          // Without a GPU this runs on the kd-tree fallback: the wrapper must not care.
          {"normal", {{"knn_backend", "gpu"}}}};
}

std::string caseName(const Case& c) {
  return c.method + (c.settings.empty() ? std::string() : "/" + c.settings[0].second);
}

}  // namespace

TEST(WorkingVolume, ContainsBallAndHardLimit) {
  gf::WorkingVolume v;
  v.max_range = 100.0;
  EXPECT_TRUE(v.contains(0.f, 0.f, 0.f));
  EXPECT_TRUE(v.contains(99.9f, 0.f, 0.f));
  EXPECT_FALSE(v.contains(100.1f, 0.f, 0.f));
  EXPECT_FALSE(v.contains(60.f, 60.f, 60.f));  // 103.9 m away
  v.origin[0] = 1000.f;                        // a sensor away from the frame origin
  EXPECT_TRUE(v.contains(1099.f, 0.f, 0.f));
  EXPECT_FALSE(v.contains(0.f, 0.f, 0.f));
  v = gf::WorkingVolume();
  v.max_range = 0.0;  // off: only the hard limit per axis
  EXPECT_TRUE(v.contains(4999.f, -4999.f, 4999.f));
  EXPECT_FALSE(v.contains(5001.f, 0.f, 0.f));
  EXPECT_FALSE(v.contains(0.f, 0.f, -1e30f));
  EXPECT_FALSE(v.contains(std::numeric_limits<float>::max(), 0.f, 0.f));
}

TEST(WorkingVolume, ValidateRanges) {
  gf::WorkingVolume v;
  for (double ok : {0.0, 0.001, 1000.0, gf::kWorkingVolumeHardLimit}) {
    v.max_range = ok;
    EXPECT_NO_THROW(v.validate()) << ok;
  }
  for (double bad : {-1.0, gf::kWorkingVolumeHardLimit + 1.0, std::nan(""), 1e300}) {
    v.max_range = bad;
    EXPECT_THROW(v.validate(), std::invalid_argument) << bad;
  }
  v.max_range = 10.0;
  v.origin[1] = std::numeric_limits<float>::infinity();
  EXPECT_THROW(v.validate(), std::invalid_argument);
  EXPECT_THROW(gf::makeGroundFilter("voxel", {{"max_range", "-5"}}), std::invalid_argument);
  EXPECT_THROW(gf::makeGroundFilter("voxel", {{"max_range", "abc"}}), std::invalid_argument);
  EXPECT_THROW(gf::WorkingVolumeFilter(nullptr, gf::WorkingVolume()), std::invalid_argument);
}

// The failure: without the working volume one far point fails the whole scan.
TEST(WorkingVolume, BareVoxelFilterFailsOnOneFarPoint) {
  GF_SKIP_WITHOUT_DATA(kKittiFrame);
  std::vector<float> xyz = kittiFrame();
  xyz.insert(xyz.end(), {300e3f, 0.f, 0.f});
  gf::VoxelGroundFilter bare;
  std::vector<std::uint8_t> labels;
  EXPECT_THROW(bare.filter(gf::CloudView::packedXyz(xyz.data(), xyz.size() / 3), &labels),
               std::runtime_error);
}

// 1, 10 and 1000 far points at random places in a KITTI frame: they are non-ground and
// counted; every other point keeps the label it gets without them.
TEST(WorkingVolume, FarPointsInKittiFrameLeaveOtherLabelsUnchanged) {
  GF_SKIP_WITHOUT_DATA(kKittiFrame);
  const std::vector<float>& frame = kittiFrame();
  const std::size_t n = frame.size() / 3;
  ASSERT_GT(n, 100000u);
  for (const Case& c : cases()) {
    SCOPED_TRACE(caseName(c));
    auto filter = gf::makeGroundFilter(c.method, c.settings);
    std::vector<std::uint8_t> reference;
    gf::FilterStats ref_stats;
    filter->filter(gf::CloudView::packedXyz(frame.data(), n), &reference, &ref_stats);
    ASSERT_EQ(reference.size(), n);
    EXPECT_EQ(ref_stats.out_of_range_points, 0u);
    ASSERT_GT(ref_stats.ground_points, n / 3);  // a real result to compare against
    std::printf("[ %s ] backend '%s', %zu of %zu points ground\n", caseName(c).c_str(),
                ref_stats.backend.c_str(), ref_stats.ground_points, n);
    std::mt19937 rng(12);
    for (std::size_t far_count : {1u, 10u, 1000u}) {
      SCOPED_TRACE(far_count);
      // Mark positions for the far points, then interleave them with the frame in order.
      std::vector<bool> is_far(n + far_count, false);
      for (std::size_t placed = 0; placed < far_count;) {
        const std::size_t at = rng() % is_far.size();
        if (!is_far[at]) is_far[at] = true, ++placed;
      }
      std::vector<float> xyz;
      xyz.reserve(3 * is_far.size());
      std::size_t next = 0, k = 0;
      for (std::size_t i = 0; i < is_far.size(); ++i) {
        if (is_far[i]) {
          const float* p = kFar[k++ % (sizeof(kFar) / sizeof(kFar[0]))];
          xyz.insert(xyz.end(), {p[0], p[1], p[2]});
        } else {
          xyz.insert(xyz.end(), {frame[3 * next], frame[3 * next + 1], frame[3 * next + 2]});
          ++next;
        }
      }
      std::vector<std::uint8_t> labels;
      gf::FilterStats stats;
      ASSERT_NO_THROW(
          filter->filter(gf::CloudView::packedXyz(xyz.data(), is_far.size()), &labels, &stats));
      ASSERT_EQ(labels.size(), is_far.size());
      EXPECT_EQ(stats.input_points, is_far.size());
      EXPECT_EQ(stats.out_of_range_points, far_count);
      EXPECT_EQ(stats.invalid_points, 0u);
      EXPECT_EQ(stats.ground_points, ref_stats.ground_points);
      std::size_t changed = 0, far_ground = 0;
      for (std::size_t i = 0, j = 0; i < is_far.size(); ++i) {
        if (is_far[i]) {
          far_ground += labels[i] != gf::kNonGround;
        } else {
          changed += labels[i] != reference[j++];
        }
      }
      EXPECT_EQ(far_ground, 0u);
      EXPECT_EQ(changed, 0u);
    }
  }
}

// max_range cuts a real frame: points beyond it are non-ground and counted; NaN points are
// counted as invalid, not as out of range; each point is counted once.
TEST(WorkingVolume, MaxRangeAndNaNCounts) {
  GF_SKIP_WITHOUT_DATA(kKittiFrame);
  std::vector<float> xyz = kittiFrame();
  const std::size_t n = xyz.size() / 3;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (std::size_t i = 0; i < n; i += 1000) xyz[3 * i + 1] = nan;
  std::size_t expect_nan = 0, expect_far = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const float x = xyz[3 * i], y = xyz[3 * i + 1], z = xyz[3 * i + 2];
    if (!std::isfinite(y)) {
      ++expect_nan;
    } else if (std::sqrt(double{x} * x + double{y} * y + double{z} * z) > 20.0) {
      ++expect_far;
    }
  }
  ASSERT_GT(expect_far, 1000u);
  auto filter = gf::makeGroundFilter("voxel", {{"max_range", "20"}});
  std::vector<std::uint8_t> labels;
  gf::FilterStats stats;
  filter->filter(gf::CloudView::packedXyz(xyz.data(), n), &labels, &stats);
  ASSERT_EQ(labels.size(), n);
  EXPECT_EQ(stats.invalid_points, expect_nan);
  EXPECT_EQ(stats.out_of_range_points, expect_far);
  EXPECT_EQ(stats.input_points, n);
  std::size_t ground = 0, bad = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const float x = xyz[3 * i], y = xyz[3 * i + 1], z = xyz[3 * i + 2];
    ground += labels[i] == gf::kGround;
    const bool out = !std::isfinite(y) || x * x + y * y + z * z > 400.f;
    bad += out && labels[i] != gf::kNonGround;
  }
  EXPECT_EQ(bad, 0u);
  EXPECT_EQ(ground, stats.ground_points);
  EXPECT_GT(ground, 0u);
  ASSERT_FALSE(stats.stage_ms.empty());
  EXPECT_EQ(stats.stage_ms.front().first, "working volume");
}

// All points out of range, or none at all: labels of the right size, no throw.
TEST(WorkingVolume, AllOutOfRangeAndEmpty) {
  for (const Case& c : cases()) {
    SCOPED_TRACE(caseName(c));
    auto filter = gf::makeGroundFilter(c.method, c.settings);
    std::vector<float> xyz = {1e30f, 0.f, 0.f, -1e7f, 3.f, 3.f, 0.f, 0.f, 9e9f};
    std::vector<std::uint8_t> labels = {7};
    gf::FilterStats stats;
    ASSERT_NO_THROW(filter->filter(gf::CloudView::packedXyz(xyz.data(), 3), &labels, &stats));
    EXPECT_EQ(labels, std::vector<std::uint8_t>(3, gf::kNonGround));
    EXPECT_EQ(stats.out_of_range_points, 3u);
    EXPECT_EQ(stats.ground_points, 0u);
    ASSERT_NO_THROW(filter->filter(gf::CloudView(), &labels, &stats));
    EXPECT_TRUE(labels.empty());
    EXPECT_EQ(stats.out_of_range_points, 0u);
  }
}

// The origin moves the volume (the nodelet centres it on the sensor in the gravity frame).
TEST(WorkingVolume, OriginMovesTheVolume) {
  GF_SKIP_WITHOUT_DATA(kKittiFrame);
  std::vector<float> xyz = kittiFrame();
  const std::size_t n = xyz.size() / 3;
  for (std::size_t i = 0; i < n; ++i) xyz[3 * i] += 3000.f;  // sensor at x = 3 km
  gf::WorkingVolume volume;
  volume.max_range = 200.0;
  gf::WorkingVolumeFilter filter(std::make_unique<gf::VoxelGroundFilter>(), volume);
  std::vector<std::uint8_t> labels;
  gf::FilterStats stats;
  filter.filter(gf::CloudView::packedXyz(xyz.data(), n), &labels, &stats);
  // Centred on 0, every point is 3 km away: no sensor can see nothing within 100 m of itself, so
  // scan_type reads the cloud as given in map coordinates and max_range does not cut it.
  EXPECT_EQ(stats.out_of_range_points, 0u) << stats.scan_reason;
  EXPECT_NE(stats.scan_reason.find("map coordinates"), std::string::npos) << stats.scan_reason;
  const std::vector<std::uint8_t> unmoved = labels;
  filter.setOrigin(3000.f, 0.f, 0.f);
  filter.filter(gf::CloudView::packedXyz(xyz.data(), n), &labels, &stats);
  EXPECT_EQ(stats.out_of_range_points, 0u);
  EXPECT_GT(stats.ground_points, n / 3);
  EXPECT_EQ(labels, unmoved);
  EXPECT_THROW(filter.setOrigin(std::nanf(""), 0.f, 0.f), std::invalid_argument);
  EXPECT_EQ(filter.name(), "voxel");
}

// A survey tile or map in projected coordinates (UTM, a national grid) lies kilometres beyond the
// hard box of its origin: the box moves onto the cloud's middle and every point is filtered
// (before, all of them were out of range: no ground at all).
namespace {

// How many labels `filter` gives `xyz` moved by `shift` (in float32) as it gives them unmoved
// (`at_origin`); the moved call's stats in `stats`.
std::size_t sameLabelsMoved(gf::GroundFilter* filter, const std::vector<float>& xyz,
                            const double shift[3], const std::vector<std::uint8_t>& at_origin,
                            gf::FilterStats* stats) {
  std::vector<float> moved(xyz);
  for (std::size_t i = 0; i < moved.size(); ++i) {
    moved[i] = static_cast<float>(moved[i] + shift[i % 3]);
  }
  std::vector<std::uint8_t> labels;
  filter->filter(gf::CloudView::packedXyz(moved.data(), moved.size() / 3), &labels, stats);
  std::size_t same = 0;
  for (std::size_t i = 0; i < labels.size(); ++i) same += labels[i] == at_origin[i];
  return same;
}

}  // namespace

TEST(WorkingVolume, CloudInProjectedCoordinatesIsFilteredOnItsMiddle) {
  const gf::GeneratedScan scan = gf::generateScene(gf::builtinSceneParams("airborne"));
  const std::size_t n = scan.size();
  for (const char* method : {"voxel", "normal"}) {
    SCOPED_TRACE(method);
    auto filter = gf::makeGroundFilter(method);
    std::vector<std::uint8_t> at_origin;
    gf::FilterStats stats;
    filter->filter(gf::CloudView::packedXyz(scan.xyz.data(), n), &at_origin, &stats);
    ASSERT_GT(stats.ground_points, n / 4);
    // 6 and 7 km off (float32 ulp 0.5 mm), and where ISPRS' Vaihingen lies in UTM 32N (0.5 m).
    for (const auto& shift : {std::vector<double>{6000.0, -7000.0, 300.0},
                              std::vector<double>{497000.0, 5419000.0, 0.0}}) {
      const std::size_t same =
          sameLabelsMoved(filter.get(), scan.xyz, shift.data(), at_origin, &stats);
      EXPECT_EQ(stats.out_of_range_points, 0u) << stats.scan_reason;
      EXPECT_NE(stats.scan_reason.find("box moved onto the cloud's middle"), std::string::npos)
          << stats.scan_reason;
      // Only the float32 rounding of the moved coordinates differs.
      EXPECT_GT(static_cast<double>(same), (shift[1] > 1e6 ? 0.99 : 0.999) * n)
          << same << " of " << n;
    }
  }
  // One stray echo beyond the box of a cloud near its origin: the box stays, the echo is cut.
  std::vector<float> stray(scan.xyz);
  stray.insert(stray.end(), {9.0e6f, 0.f, 0.f});
  auto filter = gf::makeGroundFilter("voxel");
  std::vector<std::uint8_t> labels;
  gf::FilterStats stats;
  filter->filter(gf::CloudView::packedXyz(stray.data(), n + 1), &labels, &stats);
  EXPECT_EQ(stats.out_of_range_points, 1u);
  EXPECT_EQ(stats.scan_reason.find("box moved"), std::string::npos) << stats.scan_reason;
}

// scan_type ground or tls set for such a cloud (a thinned map, as the docs advise): most of it
// beyond the box says no sensor sits at the origin all the same; it used to be cut whole.
TEST(WorkingVolume, MostOfTheCloudBeyondTheBoxMovesItWhateverTheScanType) {
  const gf::GeneratedScan street = gf::generateScene(gf::builtinSceneParams("lidar"));
  const std::size_t m = street.size();
  for (const char* type : {"ground", "tls"}) {
    for (const char* method : {"voxel", "normal"}) {
      SCOPED_TRACE(std::string(method) + " " + type);
      auto filter = gf::makeGroundFilter(method, {{"scan_type", type}});
      std::vector<std::uint8_t> at_origin;
      gf::FilterStats stats;
      filter->filter(gf::CloudView::packedXyz(street.xyz.data(), m), &at_origin, &stats);
      ASSERT_GT(stats.ground_points, m / 4);
      const double shift[3] = {6000.0, -7000.0, 300.0};
      const std::size_t same = sameLabelsMoved(filter.get(), street.xyz, shift, at_origin, &stats);
      EXPECT_EQ(stats.out_of_range_points, 0u) << stats.scan_reason;
      EXPECT_NE(stats.scan_reason.find("box moved onto the cloud's middle"), std::string::npos)
          << stats.scan_reason;
      EXPECT_GT(static_cast<double>(same), 0.97 * m) << same << " of " << m;
    }
  }
}

// The voxel filter tests the volume on the bounds it takes anyway (filterInside()); when the
// box of the points reaches outside the ball although every point is inside (a KITTI frame with
// max_range just above its farthest point: the box corners are farther), the wrapper checks the
// points itself. Labels equal the bare filter's in both cases.
TEST(WorkingVolume, VolumeTestedOnTheBounds) {
  GF_SKIP_WITHOUT_DATA(kKittiFrame);
  const std::vector<float>& xyz = kittiFrame();
  const std::size_t n = xyz.size() / 3;
  const gf::CloudView view = gf::CloudView::packedXyz(xyz.data(), n);
  double farthest = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const double x = xyz[3 * i], y = xyz[3 * i + 1], z = xyz[3 * i + 2];
    farthest = std::max(farthest, std::sqrt(x * x + y * y + z * z));
  }
  gf::VoxelGroundFilter bare;
  std::vector<std::uint8_t> reference, labels;
  bare.filter(view, &reference);
  gf::WorkingVolume whole;
  whole.max_range = 0.0;
  EXPECT_TRUE(bare.filterInside(view, whole, &labels));
  EXPECT_EQ(labels, reference);
  gf::WorkingVolume ball;
  ball.max_range = std::ceil(farthest) + 1.0;
  ASSERT_GT(farthest, 50.0);                             // a real frame
  EXPECT_FALSE(bare.filterInside(view, ball, &labels));  // the box's corners lie outside
  gf::WorkingVolumeFilter wrapped(std::make_unique<gf::VoxelGroundFilter>(), ball);
  gf::FilterStats stats;
  wrapped.filter(view, &labels, &stats);
  EXPECT_EQ(stats.out_of_range_points, 0u);
  EXPECT_EQ(labels, reference);
  // Reused: the wrapper asks the inner filter again, or not, after a scan with a far point; the
  // labels never depend on it.
  std::vector<float> far = xyz;
  far.insert(far.end(), {300e3f, 0.f, 0.f});
  for (int round = 0; round < 3; ++round) {
    SCOPED_TRACE(round);
    wrapped.filter(gf::CloudView::packedXyz(far.data(), n + 1), &labels, &stats);
    EXPECT_EQ(stats.out_of_range_points, 1u);
    EXPECT_EQ(std::vector<std::uint8_t>(labels.begin(), labels.end() - 1), reference);
    for (int again = 0; again < 2; ++again) {
      wrapped.filter(view, &labels, &stats);
      EXPECT_EQ(stats.out_of_range_points, 0u);
      EXPECT_EQ(labels, reference);
    }
  }
  // The box test agrees with contains() at the corners, float rounding included.
  gf::WorkingVolume v;
  v.max_range = 100.0;
  const float a[3] = {-70.f, -70.f, -10.f}, b[3] = {100.f, 0.f, 0.f};
  const float c[3] = {70.f, 70.f, 10.f}, d[3] = {71.f, 50.f, 10.f};
  EXPECT_EQ(v.containsBox(a, b), v.contains(100.f, -70.f, -10.f));
  EXPECT_FALSE(v.containsBox(a, b));
  EXPECT_TRUE(v.containsBox(a, c));   // corner 99.5 m away
  EXPECT_FALSE(v.containsBox(a, d));  // corner (71, -70, -10): 100.2 m
}

// ------------------------------------------------------------ min_range and body_box

namespace {

// A generated street scan (HDL-64, 1.73 m up) plus returns from the vehicle's own body: a flat
// step plate 0.18 m above the road in front of the sensor and the roof rails beside it,
// interleaved with the scan's points. The plate is flat and level: left in, it reads as ground.
struct BodyScene {
  std::vector<float> xyz;
  std::vector<bool> body;
  std::size_t size() const { return body.size(); }
};

BodyScene bodyScene() {
  const gf::GeneratedScan scan = gf::generateScene(gf::builtinSceneParams("lidar"));
  std::vector<float> body;
  for (float x = 0.8f; x <= 2.0f; x += 0.05f) {
    for (float y = -0.8f; y <= 0.8f; y += 0.05f) body.insert(body.end(), {x, y, -1.55f});
  }
  for (float x = -1.5f; x <= 0.5f; x += 0.05f) {
    for (float y : {-0.7f, 0.7f}) body.insert(body.end(), {x, y, -0.2f});
  }
  BodyScene s;
  const std::size_t nb = body.size() / 3, n = scan.size() + nb;
  // Body returns spread over the scan order (a spinning sensor sees them every revolution).
  for (std::size_t i = 0, b = 0, p = 0; i < n; ++i) {
    const bool is_body = b < nb && (p >= scan.size() || (i * nb) / n >= b);
    const float* src = is_body ? &body[3 * b++] : &scan.xyz[3 * p++];
    s.xyz.insert(s.xyz.end(), {src[0], src[1], src[2]});
    s.body.push_back(is_body);
  }
  return s;
}

// Labels of `filter` on the points of `s` that `drop` leaves, scattered back (others kNonGround).
std::vector<std::uint8_t> labelsWithout(gf::GroundFilter* filter, const BodyScene& s,
                                        const std::vector<bool>& drop) {
  std::vector<float> xyz;
  std::vector<std::size_t> idx;
  for (std::size_t i = 0; i < s.size(); ++i) {
    if (drop[i]) continue;
    xyz.insert(xyz.end(), {s.xyz[3 * i], s.xyz[3 * i + 1], s.xyz[3 * i + 2]});
    idx.push_back(i);
  }
  std::vector<std::uint8_t> inner;
  filter->filter(gf::CloudView::packedXyz(xyz.data(), idx.size()), &inner);
  std::vector<std::uint8_t> out(s.size(), gf::kNonGround);
  for (std::size_t j = 0; j < idx.size(); ++j) out[idx[j]] = inner[j];
  return out;
}

}  // namespace

// The vehicle's own returns: left in, the flat bonnet becomes ground; with min_range or a
// body box they are non-ground, counted as near points, and take no part in the ground model
// (every other label equals a run without them), for both methods and both KNN backends.
TEST(WorkingVolume, MinRangeAndBodyBoxExcludeTheVehicle) {
  const BodyScene s = bodyScene();
  const gf::CloudView view = gf::CloudView::packedXyz(s.xyz.data(), s.size());
  std::size_t body_count = 0;
  for (bool b : s.body) body_count += b;
  ASSERT_GT(body_count, 500u);
  struct Exclusion {
    std::string key, value;
  };
  const Exclusion exclusions[] = {{"min_range", "2.8"},
                                  {"body_box", "[-1.6, 2.1, -0.9, 0.9, -1.6, -0.1]"}};
  for (const Case& c : cases()) {
    SCOPED_TRACE(caseName(c));
    auto plain = gf::makeGroundFilter(c.method, c.settings);
    std::vector<std::uint8_t> plain_labels;
    plain->filter(view, &plain_labels);
    std::size_t body_ground = 0;
    for (std::size_t i = 0; i < s.size(); ++i) body_ground += s.body[i] && plain_labels[i];
    std::printf("[ %s ] body returns left in: %zu of %zu ground\n", caseName(c).c_str(),
                body_ground, body_count);
    EXPECT_GT(body_ground, body_count / 2) << "the plate should read as ground when left in";
    for (const Exclusion& e : exclusions) {
      SCOPED_TRACE(e.key);
      gf::ParamSettings settings = c.settings;
      settings.push_back({e.key, e.value});
      auto filter = gf::makeGroundFilter(c.method, settings);
      auto* wrapped = dynamic_cast<gf::WorkingVolumeFilter*>(filter.get());
      ASSERT_NE(wrapped, nullptr);
      std::vector<bool> drop(s.size());
      std::size_t dropped = 0;
      for (std::size_t i = 0; i < s.size(); ++i) {
        drop[i] = wrapped->volume().excluded(s.xyz[3 * i], s.xyz[3 * i + 1], s.xyz[3 * i + 2]);
        dropped += drop[i];
        if (s.body[i]) ASSERT_TRUE(drop[i]) << i;  // the whole body is inside
      }
      EXPECT_LT(dropped, body_count + 50);  // hardly any of the street
      std::vector<std::uint8_t> labels;
      gf::FilterStats stats;
      for (int again = 0; again < 2; ++again) {  // scratch buffers reused
        filter->filter(view, &labels, &stats);
        EXPECT_EQ(stats.near_points, dropped);
        EXPECT_EQ(stats.out_of_range_points, 0u);
        EXPECT_EQ(labels, labelsWithout(plain.get(), s, drop));
      }
      std::size_t ground = 0;
      for (std::size_t i = 0; i < s.size(); ++i) {
        if (drop[i]) EXPECT_EQ(labels[i], gf::kNonGround) << i;
        ground += labels[i];
      }
      EXPECT_EQ(stats.ground_points, ground);
      EXPECT_GT(ground, s.size() / 4);
    }
  }
}

// min_range 0 and no body box: the same labels as the plain filter, byte for byte.
TEST(WorkingVolume, ExclusionsOffChangeNothing) {
  const BodyScene s = bodyScene();
  const gf::CloudView view = gf::CloudView::packedXyz(s.xyz.data(), s.size());
  for (const Case& c : cases()) {
    SCOPED_TRACE(caseName(c));
    gf::ParamSettings off = c.settings;
    off.push_back({"min_range", "0"});
    off.push_back({"body_box", "[]"});
    std::vector<std::uint8_t> a, b;
    gf::FilterStats stats;
    gf::makeGroundFilter(c.method, c.settings)->filter(view, &a);
    gf::makeGroundFilter(c.method, off)->filter(view, &b, &stats);
    EXPECT_EQ(a, b);
    EXPECT_EQ(stats.near_points, 0u);
  }
}

// The body box is given in the sensor frame: with the sensor turned (a gravity frame), the box
// turns with it, and min_range does not care.
TEST(WorkingVolume, BodyBoxFollowsTheSensorPose) {
  gf::WorkingVolume v;
  v.body_box = {0.5, 1.5, -0.5, 0.5, -1.0, 1.0};
  EXPECT_TRUE(v.excluded(1.f, 0.f, 0.f));
  EXPECT_FALSE(v.excluded(0.f, 1.f, 0.f));
  // Sensor yawed 90 deg and 2 m up in the view's frame: sensor x -> view y.
  const float yaw90[9] = {0.f, -1.f, 0.f, 1.f, 0.f, 0.f, 0.f, 0.f, 1.f};
  const float origin[3] = {0.f, 0.f, 2.f};
  gf::WorkingVolumeFilter f(gf::makeGroundFilter("voxel"), v);
  f.setPose(origin, yaw90);
  EXPECT_TRUE(f.volume().excluded(0.f, 1.f, 2.f));
  EXPECT_FALSE(f.volume().excluded(1.f, 0.f, 2.f));
  EXPECT_FALSE(f.volume().excluded(0.f, 1.f, 0.f));  // 2 m below the box
  gf::WorkingVolume m;
  m.min_range = 3.0;
  gf::WorkingVolumeFilter g(gf::makeGroundFilter("voxel"), m);
  g.setPose(origin, yaw90);
  EXPECT_TRUE(g.volume().excluded(0.f, 2.9f, 2.f));
  EXPECT_FALSE(g.volume().excluded(0.f, 3.1f, 2.f));
}

// Bad values are refused naming the key; the filter is not built.
TEST(WorkingVolume, MinRangeAndBodyBoxValidation) {
  auto refused = [](const gf::ParamSettings& s, const std::string& key) {
    try {
      gf::makeGroundFilter("voxel", s);
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(key), std::string::npos) << e.what();
      return true;
    }
    return false;
  };
  EXPECT_TRUE(refused({{"min_range", "-1"}}, "min_range"));
  EXPECT_TRUE(refused({{"min_range", "abc"}}, "min_range"));
  EXPECT_TRUE(refused({{"max_range", "50"}, {"min_range", "60"}}, "min_range"));
  EXPECT_TRUE(refused({{"max_range", "50"}, {"min_range", "50"}}, "min_range"));
  EXPECT_TRUE(refused({{"body_box", "[1, 0, -1, 1, -1, 1]"}}, "body_box x"));
  EXPECT_TRUE(refused({{"body_box", "[-1, 1, -1, 1, 2, 1]"}}, "body_box z"));
  EXPECT_TRUE(refused({{"body_box", "[-1, 1, -1, 1, 0]"}}, "body_box"));
  EXPECT_TRUE(refused({{"body_box", "[-1, 1, -1, 1, 0, x]"}}, "body_box"));
  EXPECT_FALSE(refused({{"max_range", "0"}, {"min_range", "60"}}, "min_range"));  // off: any
  EXPECT_FALSE(refused({{"max_range", "50"}, {"min_range", "2"}}, "min_range"));
  EXPECT_FALSE(refused({{"body_box", "-1 1 -1 1 -1 1"}}, "body_box"));
  // setPose() validates too: the filter keeps its pose.
  gf::WorkingVolumeFilter f(gf::makeGroundFilter("voxel"), gf::WorkingVolume());
  const float nan_rot[9] = {NAN, 0, 0, 0, 1, 0, 0, 0, 1}, o[3] = {1, 2, 3};
  EXPECT_THROW(f.setPose(o, nan_rot), std::invalid_argument);
  EXPECT_EQ(f.volume().rotation[0], 1.f);
  EXPECT_EQ(f.volume().origin[0], 0.f);
}
