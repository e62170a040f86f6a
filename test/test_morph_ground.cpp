// The airborne mode's morphological ground surface (src/core/airborne/morph_ground), called
// directly: rules of its own that the filters' tests do not isolate.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <utility>
#include <vector>

#include "airborne/morph_ground.h"
#include "ground_filter/cloud_view.h"

namespace gf = ground_filter;

namespace {

/// The airborne mode's labels of packed x y z points with the default settings (every point
/// labelled).
std::vector<std::uint8_t> morphLabels(const std::vector<float>& xyz) {
  gf::MorphGround morph;
  std::vector<std::uint8_t> labels;
  const std::size_t n = xyz.size() / 3;
  EXPECT_EQ(morph.run(gf::CloudView::packedXyz(xyz.data(), n), gf::MorphGroundSettings(), &labels),
            n);
  return labels;
}

// Multipath and other low-noise returns lie metres below the terrain with nothing near them. As a
// cell's lowest return such a point would pit the surface (an opening removes bumps, not pits),
// and the bilinear surface would drag the ground around it below the height test. Terrain: a 4 %
// slope sampled every 0.5 m with 3 cm noise (4 returns per m², as a dense ALS tile); five single
// returns 2.5-8 m below it. All of them must come out non-ground and the ground within 2 m of
// them ground (without the rule 25 of the 251 ground returns within 2 m of them fail).
TEST(MorphGround, LowOutliersDoNotPitTheSurface) {
  std::mt19937 rng(5);
  std::normal_distribution<float> noise(0.f, 0.03f);
  auto height = [](float x, float y) { return 100.f + 0.04f * x - 0.02f * y; };
  std::vector<float> xyz;
  std::vector<std::uint8_t> truth;
  for (float x = -30.f; x < 30.f; x += 0.5f) {
    for (float y = -30.f; y < 30.f; y += 0.5f) {
      xyz.insert(xyz.end(), {x, y, height(x, y) + noise(rng)});
      truth.push_back(1);
    }
  }
  const float outliers[5][3] = {{0.3f, 0.2f, 8.f},
                                {-15.2f, 10.1f, 5.f},
                                {12.7f, -14.6f, 3.f},
                                {20.4f, 20.3f, 2.5f},
                                {-20.1f, -20.4f, 6.f}};
  for (const auto& o : outliers) {
    xyz.insert(xyz.end(), {o[0], o[1], height(o[0], o[1]) - o[2]});
    truth.push_back(0);
  }
  const std::size_t n = truth.size();
  const std::vector<std::uint8_t> labels = morphLabels(xyz);
  ASSERT_EQ(labels.size(), n);
  std::size_t near = 0, near_kept = 0, ground = 0, ground_kept = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (!truth[i]) {
      EXPECT_EQ(labels[i], 0) << "outlier at " << xyz[3 * i] << ", " << xyz[3 * i + 1];
      continue;
    }
    ++ground;
    ground_kept += labels[i];
    for (const auto& o : outliers) {
      if (std::hypot(xyz[3 * i] - o[0], xyz[3 * i + 1] - o[1]) < 2.f) {
        ++near;
        near_kept += labels[i];
      }
    }
  }
  ASSERT_GT(near, 200u);
  EXPECT_EQ(near_kept, near);
  EXPECT_EQ(ground_kept, ground);
}

// A 150 x 150 m tile sampled about once per m2 (jittered 1 m grid, 3 cm noise; random numbers
// from `seed`) with the surface `z(x, y, &roof)`: xyz, and per point whether z set roof.
template <class Z>
std::vector<float> tileOf(unsigned seed, Z z, std::vector<std::uint8_t>* on_roof) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> jitter(0.f, 1.f);
  std::normal_distribution<float> noise(0.f, 0.03f);
  std::vector<float> xyz;
  on_roof->clear();
  for (float gx = -75.f; gx < 75.f; gx += 1.f) {
    for (float gy = -75.f; gy < 75.f; gy += 1.f) {
      const float x = gx + jitter(rng), y = gy + jitter(rng);
      bool roof = false;
      xyz.insert(xyz.end(), {x, y, z(x, y, &roof) + noise(rng)});
      on_roof->push_back(roof);
    }
  }
  return xyz;
}

// A flat-topped block in tileOf()'s tile on a 2 % slope: `walls` says which of its four sides
// (bits 0-3: -x, +x, -y, +y) drop `height` m to the ground; a side without a wall is a 30 % ramp
// down to the ground. `rough` adds hills of that amplitude [m] to its top. Returns xyz; truth 1
// where the point is on the block's top (inside the footprint, 5 m in from its edges).
std::vector<float> blockTile(float half, float height, int walls, float rough,
                             std::vector<std::uint8_t>* on_top) {
  auto z = [&](float x, float y, bool* top_point) {
    const float ground = 50.f + 0.02f * x;
    // Distance outside the footprint along each side that has no wall (the ramp's run).
    const float ox = std::fabs(x) - half, oy = std::fabs(y) - half;
    const bool wall_x = (walls >> (x < 0 ? 0 : 1)) & 1, wall_y = (walls >> (y < 0 ? 2 : 3)) & 1;
    const float top = ground + height + rough * std::sin(x / 7.f) * std::cos(y / 9.f);
    *top_point = ox < -5.f && oy < -5.f;
    if (ox <= 0.f && oy <= 0.f) return top;
    if ((ox <= 0.f || !wall_x) && (oy <= 0.f || !wall_y)) {
      const float run = std::max(ox, oy);
      return std::max(ground, top - 0.3f * run);  // the ramp of a side without a wall
    }
    return ground;
  };
  return tileOf(11, z, on_top);
}

// A roof wider than the opening (2 x morph_window = 36 m) is not ground: a hall 60 m across,
// 8 m high, walls all round. Every return on its roof is an object, the ground around it ground
// (without the walled-roof rule every return on the roof came out ground).
TEST(MorphGround, AHallWiderThanTheOpeningIsNotGround) {
  std::vector<std::uint8_t> on_top;
  const std::vector<float> xyz = blockTile(30.f, 8.f, 0xf, 0.f, &on_top);
  const std::vector<std::uint8_t> labels = morphLabels(xyz);
  std::size_t roof = 0, roof_ground = 0, ground = 0, ground_kept = 0;
  for (std::size_t i = 0; i < on_top.size(); ++i) {
    const float x = xyz[3 * i], y = xyz[3 * i + 1];
    if (on_top[i]) {
      ++roof;
      roof_ground += labels[i];
    } else if (std::fabs(x) > 32.f || std::fabs(y) > 32.f) {
      ++ground;
      ground_kept += labels[i];
    }
  }
  ASSERT_GT(roof, 2000u);
  EXPECT_EQ(roof_ground, 0u);
  EXPECT_GT(ground_kept, ground * 99 / 100);
}

// Terrain that is as wide and as high stays ground when it is not walled all round (a terrace
// reached by a ramp on one side) or not one plane (a rough mesa with cliffs all round).
TEST(MorphGround, AWideTerraceOrARoughMesaIsTerrain) {
  for (const auto& c : {std::make_pair(0x7, 0.f), std::make_pair(0xf, 1.5f)}) {
    std::vector<std::uint8_t> on_top;
    const std::vector<float> xyz = blockTile(30.f, 8.f, c.first, c.second, &on_top);
    const std::vector<std::uint8_t> labels = morphLabels(xyz);
    std::size_t top = 0, top_kept = 0;
    for (std::size_t i = 0; i < on_top.size(); ++i) {
      top += on_top[i];
      top_kept += on_top[i] && labels[i];
    }
    ASSERT_GT(top, 2000u);
    EXPECT_GT(top_kept, top * 95 / 100) << "walls " << c.first << " rough " << c.second;
  }
}

// Of tileOf()'s points and their airborne labels: the roof returns and those labelled ground,
// and the other returns where `ground(x, y)` and those labelled ground.
struct Tally {
  std::size_t roof = 0, roof_ground = 0, ground = 0, ground_kept = 0;
};
template <class Where>
Tally tally(const std::vector<float>& xyz, const std::vector<std::uint8_t>& on_roof, Where ground) {
  const std::vector<std::uint8_t> labels = morphLabels(xyz);
  Tally t;
  for (std::size_t i = 0; i < on_roof.size(); ++i) {
    if (on_roof[i]) {
      ++t.roof;
      t.roof_ground += labels[i];
    } else if (ground(xyz[3 * i], xyz[3 * i + 1])) {
      ++t.ground;
      t.ground_kept += labels[i];
    }
  }
  return t;
}

// A hall 120 x 80 m whose roof has parts at several heights: thirds 40 m wide along x, the west
// one 3 m (or 1 m) lower, the centre as much higher. With 3 m the parts are regions of their
// own, and the wings stand on walls only once the raised bay has gone; with 1 m they are one
// region that lies on no one plane, but on three. Every roof return is an object either way, the
// ground around the hall ground.
TEST(MorphGround, AHallWithARoofAtSeveralHeightsIsNotGround) {
  for (const float step : {3.f, 1.f}) {
    std::vector<std::uint8_t> on_roof;
    const std::vector<float> xyz = tileOf(
        13,
        [step](float x, float y, bool* roof) {
          const float ground = 50.f + 0.02f * x;
          if (std::fabs(x) > 60.f || std::fabs(y) > 40.f) return ground;
          const float t = x < -20.f ? -step : (x < 20.f ? step : 0.f);
          const float edge = std::min(60.f - std::fabs(x), 40.f - std::fabs(y));
          const float seam = std::fabs(std::fabs(x) - 20.f);  // where two parts meet
          *roof = edge > 5.f && seam > 2.f;
          return 51.2f + 8.f + t;  // a pad level with the hall's highest ground
        },
        &on_roof);
    const Tally t = tally(
        xyz, on_roof, [](float x, float y) { return std::fabs(x) > 62.f || std::fabs(y) > 42.f; });
    ASSERT_GT(t.roof, 3000u);
    EXPECT_EQ(t.roof_ground, 0u) << "step " << step;
    EXPECT_GT(t.ground_kept, t.ground * 99 / 100) << "step " << step;
  }
}

// A hall 80 m across whose roof is in thirds at several heights (the centre 3 m higher, the west
// third 3 m lower), crossed by a strip 4 m wide without returns that runs through the raised bay
// to the hall's edges (a dark membrane, a gap between flight lines; the held-out PDAL tile
// sample_c has one). The fill ramps from the ground up into the strip, so the opening erodes the
// bay beside it step by step, as terrain, and only the steep-terrain pass keeps it: the bay's
// ends stay terrain, narrower than the opening, and the wings' borders rise to them instead of
// standing on walls. Every roof return is an object, the ground around the hall ground (before
// the rule for regions narrower than the opening, 7,564 of 9,109 returns on the generated hall
// `builtin:airborne:1:airborne_hall=80,airborne_hall_step=3,airborne_hall_gap=4` were ground).
TEST(MorphGround, AHallInPartsCrossedByAStripWithoutReturnsIsNotGround) {
  std::vector<std::uint8_t> on_roof;
  std::vector<float> xyz = tileOf(
      13,
      [](float x, float y, bool* roof) {
        const float ground = 50.f + 0.02f * x;
        if (std::fabs(x) > 40.f || std::fabs(y) > 40.f) return ground;
        const float third = 80.f / 6.f;
        const float t = x < -third ? -3.f : (x < third ? 3.f : 0.f);
        const float edge = std::min(40.f - std::fabs(x), 40.f - std::fabs(y));
        const float seam = std::fabs(std::fabs(x) - third);
        *roof = edge > 3.f && seam > 2.f;
        return 50.8f + 8.f + t;
      },
      &on_roof);
  // The strip: no return on the roof where |x| < 2 m.
  std::size_t kept = 0;
  for (std::size_t i = 0; i < on_roof.size(); ++i) {
    const float x = xyz[3 * i], y = xyz[3 * i + 1];
    if (std::fabs(x) < 2.f && std::fabs(y) <= 40.f) continue;
    std::copy(&xyz[3 * i], &xyz[3 * i] + 3, &xyz[3 * kept]);
    on_roof[kept++] = on_roof[i];
  }
  xyz.resize(3 * kept);
  on_roof.resize(kept);
  const Tally t = tally(
      xyz, on_roof, [](float x, float y) { return std::fabs(x) > 42.f || std::fabs(y) > 42.f; });
  ASSERT_GT(t.roof, 4000u);
  EXPECT_EQ(t.roof_ground, 0u);
  EXPECT_GT(t.ground_kept, t.ground * 99 / 100);
}

// Ground at a hall's foot stays ground once the hall has gone: a terrace 3 m above the tile's
// lower half (a retaining wall along y = 0, the whole tile wide), with a hall 60 m across on it.
// With the hall's edges left out the terrace stands on walls only, and it is one plane; but it
// reaches the tile's edge, where the ground goes on.
TEST(MorphGround, ATerraceUnderAHallStaysGround) {
  std::vector<std::uint8_t> on_roof;
  const std::vector<float> xyz = tileOf(
      13,
      [](float x, float y, bool* roof) {
        const float ground = 50.f + 0.02f * x + (y > 0.f ? 3.f : 0.f);
        if (std::fabs(x) > 30.f || std::fabs(y - 40.f) > 30.f) return ground;
        *roof = std::fabs(x) < 25.f && std::fabs(y - 40.f) < 25.f;
        return 53.6f + 8.f;
      },
      &on_roof);
  const Tally t = tally(xyz, on_roof, [](float x, float y) {
    return y > 2.f && (std::fabs(x) > 32.f || y < 8.f);  // the terrace beside the hall
  });
  ASSERT_GT(t.roof, 2000u);
  ASSERT_GT(t.ground, 3000u);
  EXPECT_EQ(t.roof_ground, 0u);
  EXPECT_GT(t.ground_kept, t.ground * 99 / 100);
}

// A courtyard stays ground: a ring of building 25 m deep (8 m high) round a yard 40 m across,
// with a ramp pit 10 m across and 3 m deep in the yard. The opening takes the ring, and the pit's
// walls are the yard's only steps; but the pit is a hole in the yard, not round it.
TEST(MorphGround, ACourtyardStaysGround) {
  std::vector<std::uint8_t> on_roof;
  const std::vector<float> xyz = tileOf(
      13,
      [](float x, float y, bool* roof) {
        const float r = std::max(std::fabs(x), std::fabs(y));
        if (r < 5.f) return 47.f;
        if (r < 20.f || r > 45.f) return 50.f;
        *roof = r > 25.f && r < 40.f;
        return 58.f;
      },
      &on_roof);
  const Tally t = tally(xyz, on_roof, [](float x, float y) {
    const float r = std::max(std::fabs(x), std::fabs(y));
    return r > 7.f && r < 18.f;  // the yard round the pit
  });
  ASSERT_GT(t.roof, 2000u);
  ASSERT_GT(t.ground, 1000u);
  EXPECT_EQ(t.roof_ground, 0u);
  EXPECT_GT(t.ground_kept, t.ground * 99 / 100);
}

// A narrow pit that is terrain keeps its floor: the rule asks for no return near the lowest one,
// not for the lowest to lie far below the mean or median of its surroundings (here 2-3 m).
TEST(MorphGround, APitWithWallsIsNotAnOutlier) {
  std::vector<float> xyz;
  std::vector<std::uint8_t> truth;
  for (float x = -20.f; x < 20.f; x += 0.5f) {
    for (float y = -20.f; y < 20.f; y += 0.5f) {
      // 3 m deep, 3 m wide at the bottom, walls 45 degrees: the floor's neighbours rise gradually.
      const float r = std::max(std::fabs(x), std::fabs(y));
      const float z = r < 1.5f ? -3.f : std::min(0.f, -3.f + (r - 1.5f));
      xyz.insert(xyz.end(), {x, y, z});
      truth.push_back(1);
    }
  }
  const std::vector<std::uint8_t> labels = morphLabels(xyz);
  ASSERT_EQ(labels.size(), truth.size());
  std::size_t floor = 0, floor_kept = 0;
  for (std::size_t i = 0; i < truth.size(); ++i) {
    if (xyz[3 * i + 2] < -2.9f) {
      ++floor;
      floor_kept += labels[i];
    }
  }
  ASSERT_GT(floor, 30u);
  EXPECT_EQ(floor_kept, floor);
}

// Under a dense canopy few pulses reach the ground: its returns can lie metres apart with only
// canopy above them (here one every 5 m on a 1 % slope, canopy 12-25 m up at 4 returns per m²,
// nothing in between). Each such return has canopy, and no return near its height, within 3 m,
// as a low outlier has; it is not one: the ground continues within a few metres. Every ground
// return must stay ground and the canopy non-ground (with the 3 m test alone all 144 ground
// returns left the surface and 1,165 canopy returns came out ground).
TEST(MorphGround, SparseGroundUnderACanopyIsNotAnOutlier) {
  std::mt19937 rng(9);
  std::uniform_real_distribution<float> crown(12.f, 25.f), jitter(-0.2f, 0.2f);
  auto height = [](float x, float y) { return 50.f + 0.01f * x + 0.005f * y; };
  std::vector<float> xyz;
  std::vector<std::uint8_t> truth;
  for (float x = -30.f; x < 30.f; x += 5.f) {
    for (float y = -30.f; y < 30.f; y += 5.f) {
      const float gx = x + jitter(rng), gy = y + jitter(rng);
      xyz.insert(xyz.end(), {gx, gy, height(gx, gy)});
      truth.push_back(1);
    }
  }
  for (float x = -32.f; x < 32.f; x += 0.5f) {
    for (float y = -32.f; y < 32.f; y += 0.5f) {
      xyz.insert(xyz.end(), {x, y, height(x, y) + crown(rng)});
      truth.push_back(0);
    }
  }
  const std::size_t n = truth.size();
  const std::vector<std::uint8_t> labels = morphLabels(xyz);
  ASSERT_EQ(labels.size(), n);
  std::size_t ground = 0, ground_kept = 0, canopy_ground = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (truth[i]) {
      ++ground;
      ground_kept += labels[i];
    } else {
      canopy_ground += labels[i];
    }
  }
  ASSERT_EQ(ground, 144u);
  EXPECT_EQ(ground_kept, ground);
  EXPECT_EQ(canopy_ground, 0u);
}

}  // namespace
