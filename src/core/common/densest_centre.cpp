// The centre of a cloud's densest area (densest_centre.h).

#include "common/densest_centre.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

namespace ground_filter {

constexpr std::size_t DensestCentre::kRead;
constexpr double DensestCentre::kCell;
constexpr double DensestCentre::kReach;
constexpr int DensestCentre::kShifts;
constexpr double DensestCentre::kMaxCellIndex;

bool DensestCentre::find(const CloudView& cloud, float c[3]) {
  // About kRead points, evenly spread: finite ones into x_, y_, z_.
  const std::size_t n = cloud.size(), step = n / kRead + 1;
  x_.clear();
  y_.clear();
  z_.clear();
  for (std::size_t i = 0; i < n; i += step) {
    const float x = cloud.x(i), y = cloud.y(i), z = cloud.z(i);
    if (!(std::isfinite(x) && std::isfinite(y) && std::isfinite(z))) continue;
    x_.push_back(x);
    y_.push_back(y);
    z_.push_back(z);
  }
  if (x_.size() < 1000) return false;
  // Start: the mean of the points in the densest kCell square; then move to the mean of
  // the points within kReach, a few times (a mean shift onto the density peak).
  std::vector<std::pair<std::int64_t, std::uint32_t>>& cells = cells_;
  cells.clear();
  for (std::size_t i = 0; i < x_.size(); ++i) {
    // Cells within 2^21 of the origin (16,000 km) only: the key packs two of them (ky in
    // (-2^21, 2^21), so a stride of 2^22 keeps keys apart), and a coordinate further out
    // would overflow the conversion; such a point joins no cell.
    const double fx = std::floor(x_[i] / kCell), fy = std::floor(y_[i] / kCell);
    if (!(std::fabs(fx) < kMaxCellIndex && std::fabs(fy) < kMaxCellIndex)) continue;
    const std::int64_t kx = static_cast<std::int64_t>(fx), ky = static_cast<std::int64_t>(fy);
    constexpr std::int64_t kRowStride = 2 * static_cast<std::int64_t>(kMaxCellIndex);
    cells.push_back({kx * kRowStride + ky, static_cast<std::uint32_t>(i)});
  }
  if (cells.empty()) return false;
  std::sort(cells.begin(), cells.end());
  std::size_t best = 0, best_n = 0;
  for (std::size_t a = 0; a < cells.size();) {
    std::size_t e = a;
    while (e < cells.size() && cells[e].first == cells[a].first) ++e;
    if (e - a > best_n) {
      best = a;
      best_n = e - a;
    }
    a = e;
  }
  double mx = 0.0, my = 0.0;
  for (std::size_t k = best; k < best + best_n; ++k) {
    mx += x_[cells[k].second];
    my += y_[cells[k].second];
  }
  mx /= static_cast<double>(best_n);
  my /= static_cast<double>(best_n);
  std::vector<double>& zs = zs_;
  for (int it = 0; it < kShifts; ++it) {
    double sx = 0.0, sy = 0.0;
    std::size_t m = 0;
    zs.clear();
    for (std::size_t i = 0; i < x_.size(); ++i) {
      const double dx = x_[i] - mx, dy = y_[i] - my;
      if (dx * dx + dy * dy > kReach * kReach) continue;
      sx += x_[i];
      sy += y_[i];
      zs.push_back(z_[i]);
      ++m;
    }
    if (m == 0) return false;
    mx = sx / static_cast<double>(m);
    my = sy / static_cast<double>(m);
  }
  const std::size_t k = zs.size() / 5;
  std::nth_element(zs.begin(), zs.begin() + static_cast<std::ptrdiff_t>(k), zs.end());
  c[0] = static_cast<float>(mx);
  c[1] = static_cast<float>(my);
  c[2] = static_cast<float>(zs[k]);
  return true;
}

}  // namespace ground_filter
