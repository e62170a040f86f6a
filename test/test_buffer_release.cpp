// BufferReleasePolicy: the nodelets drop their filter's buffers after a rare huge cloud.
#include <gtest/gtest.h>

#include "buffer_release.h"

namespace ground_filter {
namespace {

TEST(BufferReleasePolicy, ReleasesAfterCalmCloudsFollowingAHugeOne) {
  BufferReleasePolicy policy(1000000, 4.0, 10);
  for (int i = 0; i < 50; ++i) EXPECT_FALSE(policy.afterCloud(240000));  // steady stream
  EXPECT_FALSE(policy.afterCloud(20000000));                             // the huge cloud
  for (int i = 0; i < 9; ++i) EXPECT_FALSE(policy.afterCloud(240000)) << i;
  EXPECT_TRUE(policy.afterCloud(240000));  // the 10th calm cloud in a row
  for (int i = 0; i < 50; ++i) EXPECT_FALSE(policy.afterCloud(240000));  // starts afresh
}

TEST(BufferReleasePolicy, SmallPeaksAndSimilarSizesNeverRelease) {
  BufferReleasePolicy policy(1000000, 4.0, 10);
  EXPECT_FALSE(policy.afterCloud(900000));  // below min_points: buffers are cheap
  for (int i = 0; i < 100; ++i) EXPECT_FALSE(policy.afterCloud(1000));
  BufferReleasePolicy steady(1000000, 4.0, 10);
  for (int i = 0; i < 100; ++i) EXPECT_FALSE(steady.afterCloud(i % 2 ? 2000000 : 600000));
}

TEST(BufferReleasePolicy, ALargeCloudAmongTheCalmOnesRestartsTheCount) {
  BufferReleasePolicy policy(1000000, 4.0, 10);
  policy.afterCloud(8000000);
  for (int i = 0; i < 9; ++i) EXPECT_FALSE(policy.afterCloud(100000));
  EXPECT_FALSE(policy.afterCloud(4000000));  // not calm: more than peak / 4
  for (int i = 0; i < 9; ++i) EXPECT_FALSE(policy.afterCloud(100000)) << i;
  EXPECT_TRUE(policy.afterCloud(100000));
  policy.afterCloud(8000000);
  policy.reset();
  for (int i = 0; i < 20; ++i) EXPECT_FALSE(policy.afterCloud(100000));  // peak forgotten
}

}  // namespace
}  // namespace ground_filter
