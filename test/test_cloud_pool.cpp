// Unit tests of the nodelets' message pools (src/nodelets/cloud_pool.h) without a ROS graph:
// a pooled message goes out again only once nobody holds it, and pooled outputs are the same
// clouds as new ones.

#include <gtest/gtest.h>

#include <cstring>
#include <limits>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "cloud_pool.h"
#include "gf_test_clouds.h"
#include "ground_filter/working_volume.h"
#include "point_cloud2.h"

namespace gf = ground_filter;
using sensor_msgs::PointCloud2;

namespace {

using namespace gf_test;  // NOLINT(build/namespaces): the cloud builders (gf_test_clouds.h)

void setFloat(PointCloud2* c, std::size_t i, std::size_t offset, float v) {
  std::memcpy(
      c->data.data() + (i / c->width) * c->row_step + (i % c->width) * c->point_step + offset, &v,
      sizeof(v));
}

// Every other point ground: the split changes with every cloud's size.
class ParityFilter : public gf::GroundFilter {
 public:
  void filter(const gf::CloudView& cloud, std::vector<std::uint8_t>* labels,
              gf::FilterStats*) override {
    labels->resize(cloud.size());
    for (std::size_t i = 0; i < cloud.size(); ++i)
      (*labels)[i] = i % 2 ? gf::kGround : gf::kNonGround;
  }
  std::string name() const override { return "parity"; }
};

}  // namespace

TEST(CloudPool, HandsOutOnlyWhatNobodyHolds) {
  gf::CloudPool pool(2);
  auto a = pool.take(100);
  auto b = pool.take(100);  // a is held: a second message
  EXPECT_NE(a.get(), b.get());
  auto c = pool.take(100);  // both held, pool full: a new message, not pooled
  EXPECT_NE(c.get(), a.get());
  EXPECT_NE(c.get(), b.get());
  EXPECT_EQ(pool.size(), 2u);
  EXPECT_EQ(pool.made(), 3u);
  const PointCloud2* a_address = a.get();
  a->data.assign(5000, 7);
  a.reset();
  auto d = pool.take(4000);  // a again, its buffer kept (not larger than 2 x 4000 + 1 MiB)
  EXPECT_EQ(d.get(), a_address);
  EXPECT_EQ(d->data.size(), 5000u);
  EXPECT_EQ(pool.reused(), 1u);
  // After rare huge clouds, a small one leaves no huge buffer resident in any idle slot.
  d->data.assign(std::size_t{8} << 20, 1);
  b->data.assign(std::size_t{8} << 20, 1);
  const PointCloud2* b_address = b.get();
  d.reset();
  b.reset();
  auto e = pool.take(1000);
  EXPECT_EQ(e.get(), a_address);
  EXPECT_LT(e->data.capacity(), std::size_t{1} << 20);
  b = pool.take(1000);  // the other slot, whose buffer went with the take() before
  EXPECT_EQ(b.get(), b_address);
  EXPECT_EQ(b->data.capacity(), 0u);
  // clear() frees the idle slots and keeps the held ones.
  e.reset();
  pool.clear();
  EXPECT_EQ(pool.size(), 1u);  // b is still held
  b.reset();
  pool.clear();
  EXPECT_EQ(pool.size(), 0u);
}

// Pooled outputs give the same clouds as new ones, cloud after cloud of changing size and split,
// and an output still held by a subscriber is never written over.
TEST(ProcessPointCloud2, PooledOutputsEqualNewOnesAndHeldOnesStay) {
  gf::WorkingVolume volume;
  volume.max_range = 100.0;  // x = i, y = 2i, z = 3i: points beyond i = 26 are non-ground too
  gf::WorkingVolumeFilter filter(std::make_unique<ParityFilter>(), volume);
  gf::CloudProcessingBuffers buffers;
  gf::OutputPools pools;
  gf::ProcessedCloud held;
  std::vector<std::uint8_t> held_ground, held_nonground;
  for (std::uint32_t width : {40u, 12u, 60u, 5u, 33u}) {
    PointCloud2 c = makeCloud(width, 2, 8);
    setFloat(&c, 3, 8, std::numeric_limits<float>::quiet_NaN());
    gf::CloudLayout layout;
    ASSERT_EQ(gf::checkPointCloud2(c, &layout, nullptr), gf::CloudRejectReason::kNone);
    gf::ProcessedCloud pooled, fresh;
    gf::processPointCloud2(c, layout, &filter, nullptr, false, &buffers, &pooled, &pools);
    gf::processPointCloud2(c, layout, &filter, nullptr, false, &buffers, &fresh);
    for (const auto& pair : {std::make_pair(pooled.ground, fresh.ground),
                             std::make_pair(pooled.nonground, fresh.nonground)}) {
      const PointCloud2& p = *pair.first;
      const PointCloud2& f = *pair.second;
      EXPECT_EQ(p.header.frame_id, f.header.frame_id) << width;
      EXPECT_EQ(p.header.stamp, f.header.stamp) << width;
      EXPECT_EQ(p.fields.size(), f.fields.size()) << width;
      EXPECT_EQ(p.width, f.width) << width;
      EXPECT_EQ(p.height, f.height) << width;
      EXPECT_EQ(p.point_step, f.point_step) << width;
      EXPECT_EQ(p.row_step, f.row_step) << width;
      EXPECT_EQ(p.is_dense, f.is_dense) << width;
      EXPECT_EQ(p.data, f.data) << width;
    }
    EXPECT_EQ(pooled.counts.ground + pooled.counts.nonground, 2u * width);
    if (width == 40u) {  // a subscriber keeps the first cloud's outputs
      held = pooled;
      held_ground = held.ground->data;
      held_nonground = held.nonground->data;
    }
  }
  EXPECT_EQ(held.ground->data, held_ground);
  EXPECT_EQ(held.nonground->data, held_nonground);
  EXPECT_GE(pools.ground.reused(), 3u);  // every cloud after the second reused the released one
  EXPECT_GE(pools.nonground.reused(), 3u);
}
