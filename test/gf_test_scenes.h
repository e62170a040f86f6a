// Test-only synthetic scenes with exact truth shared by the core filter tests (ROS-free): a cloud
// with a ground flag per point, surfaces, boxes, porous bushes, and the ground share of a subset.
#ifndef GROUND_FILTER_TEST_GF_TEST_SCENES_H
#define GROUND_FILTER_TEST_GF_TEST_SCENES_H

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <random>
#include <vector>

#include "ground_filter/cloud_view.h"
#include "ground_filter/ground_filter.h"

namespace gf_test {

/// \brief Packed x y z with a truth flag per point (1 ground, 0 not).
struct TruthCloud {
  std::vector<float> xyz;
  std::vector<std::uint8_t> truth;
  void add(float x, float y, float z, bool ground) {
    xyz.insert(xyz.end(), {x, y, z});
    truth.push_back(ground ? 1 : 0);
  }
  std::size_t size() const { return truth.size(); }
  ground_filter::CloudView view() const {
    return ground_filter::CloudView::packedXyz(xyz.data(), size());
  }
};

/// \brief Ground surface z = height(x, y) sampled every `step` metres with Gaussian noise.
template <typename HeightFn>
void addSurface(TruthCloud* c, float x0, float x1, float y0, float y1, float step, HeightFn height,
                float noise, std::mt19937* rng) {
  std::normal_distribution<float> n(0.f, noise);
  for (float x = x0; x < x1; x += step) {
    for (float y = y0; y < y1; y += step) c->add(x, y, height(x, y) + n(*rng), true);
  }
}

/// \brief Outer faces of an axis-aligned box standing on z0 (no bottom face), all non-ground.
inline void addBox(TruthCloud* c, float cx, float cy, float sx, float sy, float z0, float h,
                   float step) {
  for (float z = z0 + step; z <= z0 + h; z += step) {
    for (float t = -sx / 2; t <= sx / 2; t += step) {
      c->add(cx + t, cy - sy / 2, z, false);
      c->add(cx + t, cy + sy / 2, z, false);
    }
    for (float t = -sy / 2; t <= sy / 2; t += step) {
      c->add(cx - sx / 2, cy + t, z, false);
      c->add(cx + sx / 2, cy + t, z, false);
    }
  }
  for (float u = -sx / 2; u <= sx / 2; u += step) {
    for (float v = -sy / 2; v <= sy / 2; v += step) c->add(cx + u, cy + v, z0 + h, false);
  }
}

/// \brief A porous bush at (x0, y0) on the ground at z0: scattered non-ground returns through
///        its volume (radius r, height h, about one per litre) above 0.2 m and a base layer
///        0.06-0.14 m above the ground; the indices of the base points go to `base` when given.
inline void addPorousBush(TruthCloud* c, float x0, float y0, float z0, float r, float h,
                          std::mt19937* rng, std::vector<std::size_t>* base = nullptr) {
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  const int volume = static_cast<int>(4000.f * r * r * h);
  for (int i = 0; i < volume; ++i) {
    const float x = r * u(*rng), y = r * u(*rng), z = 0.5f * h * (1.f + u(*rng));
    if (x * x + y * y > r * r || z < 0.2f) continue;
    c->add(x0 + x, y0 + y, z0 + z, false);
  }
  const int twigs = static_cast<int>(1100.f * r * r);
  for (int i = 0; i < twigs; ++i) {
    const float x = r * u(*rng), y = r * u(*rng);
    if (x * x + y * y > r * r) continue;
    if (base) base->push_back(c->size());
    c->add(x0 + x, y0 + y, z0 + 0.1f + 0.04f * u(*rng), false);
  }
}

/// \brief Indices of the ground points of `c` within `margin` of the footprint of a box centred
///        at (cx, cy) with sides sx x sy (the ground beside a car).
inline std::vector<std::size_t> groundNearFootprint(const TruthCloud& c, float cx, float cy,
                                                    float sx, float sy, float margin) {
  std::vector<std::size_t> idx;
  for (std::size_t i = 0; i < c.size(); ++i) {
    const float dx = std::abs(c.xyz[3 * i] - cx) - sx / 2,
                dy = std::abs(c.xyz[3 * i + 1] - cy) - sy / 2;
    if (c.truth[i] && dx < margin && dy < margin) idx.push_back(i);
  }
  return idx;
}

/// \brief A bush beside a car (the vegetation rule's scene of both methods).
struct BushAndCar {
  TruthCloud c;
  std::vector<std::size_t> bush_base;  ///< the bush's base points
  std::vector<std::size_t> by_car;     ///< the ground within 0.3 m of the car's footprint
};

/// \brief Flat noisy ground (z = 0, 5 cm grid, 5 mm noise, x and y from -half to half m) with a
///        porous bush at (2, 0) (radius 0.6 m, 0.9 m high, addPorousBush) and a car-like box
///        (4 x 1.8 m, faces on a 5 cm grid, from z0 to z0 + h) at (car_x, car_y).
inline BushAndCar bushAndCar(unsigned seed, float half, float car_x, float car_y, float z0,
                             float h) {
  std::mt19937 rng(seed);
  BushAndCar s;
  addSurface(
      &s.c, -half, half, -half, half, 0.05f, [](float, float) { return 0.f; }, 0.005f, &rng);
  addPorousBush(&s.c, 2.f, 0.f, 0.f, 0.6f, 0.9f, &rng, &s.bush_base);
  addBox(&s.c, car_x, car_y, 4.f, 1.8f, z0, h, 0.05f);
  s.by_car = groundNearFootprint(s.c, car_x, car_y, 4.f, 1.8f, 0.3f);
  return s;
}

/// \brief Share of the points `idx` labelled ground (0 for none).
inline double groundShare(const std::vector<std::uint8_t>& labels,
                          const std::vector<std::size_t>& idx) {
  std::size_t g = 0;
  for (std::size_t i : idx) g += labels[i] == ground_filter::kGround;
  return idx.empty() ? 0.0 : static_cast<double>(g) / static_cast<double>(idx.size());
}

}  // namespace gf_test

#endif  // GROUND_FILTER_TEST_GF_TEST_SCENES_H
