#include "airborne/scan_type.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <numeric>
#include <stdexcept>

#include "airborne/origin_view.h"
#include "ground_filter/param_parse.h"

namespace ground_filter {

namespace {

// tan(30 deg): a point 30 deg or more above the origin rises at least this much per metre.
constexpr double kTan30 = 0.57735026918962576;
// Points closer to the origin than this on every axis are no-return placeholders (an organised
// scan's empty cells at 0, 0, 0), not returns.
constexpr float kPlaceholder = 1e-3f;

// The q-quantile of v (reorders v).
float quantile(std::vector<float>* v, double q) {
  const std::size_t k = std::min(v->size() - 1, static_cast<std::size_t>(q * (v->size() - 1)));
  std::nth_element(v->begin(), v->begin() + static_cast<std::ptrdiff_t>(k), v->end());
  return (*v)[k];
}

}  // namespace

const char* scanTypeName(ScanType type) {
  switch (type) {
    case ScanType::kAirborne:
      return "airborne";
    case ScanType::kTls:
      return "tls";
    case ScanType::kGround:
      break;
  }
  return "ground";
}

const std::vector<std::string>& scanTypeSettings() {
  static const std::vector<std::string> values = {"auto", "ground", "airborne", "tls",
                                                  "registered"};
  return values;
}

void validateScanTypeSetting(const std::string& value) {
  checkChoice("scan_type", value, scanTypeSettings());
}

ScanMeasures ScanTypeClassifier::measure(const CloudView& cloud, const float origin[3]) {
  ScanMeasures m = measureSample(cloud, origin);
  if (m.cells > 0) measureColumns(cloud, &m, kMaxRead);
  m.hidden_share = OriginView().hiddenShare(cloud, origin);
  return m;
}

ScanMeasures ScanTypeClassifier::measureSample(const CloudView& cloud, const float origin[3]) {
  ScanMeasures m;
  const std::size_t n = cloud.size();
  const std::size_t step = std::max<std::size_t>(1, (n + kMaxSamples - 1) / kMaxSamples);
  xs_.clear();
  ys_.clear();
  zs_.clear();
  depth_.clear();
  std::size_t below = 0, high = 0;
  double nearest2 = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < n; i += step) {
    float x, y, z;
    if (!cloud.get(i, &x, &y, &z)) continue;
    const float dx = x - origin[0], dy = y - origin[1], dz = z - origin[2];
    if (std::fabs(dx) < kPlaceholder && std::fabs(dy) < kPlaceholder &&
        std::fabs(dz) < kPlaceholder) {
      continue;
    }
    xs_.push_back(x);
    ys_.push_back(y);
    // Squared horizontal distance against squared height: the angles without a square root.
    const double h2 = static_cast<double>(dx) * dx + static_cast<double>(dy) * dy;
    const double dz2 = static_cast<double>(dz) * dz;
    nearest2 = std::min(nearest2, h2 + dz2);
    if (dz < 0.f) ++below;
    if (dz < 0.f && h2 <= dz2) depth_.push_back(-dz);  // 45 deg or more below the origin
    if (dz > 0.f && dz2 >= kTan30 * kTan30 * h2) ++high;
  }
  m.sampled = xs_.size();
  if (m.sampled == 0) return m;
  m.nearest = std::sqrt(nearest2);
  const double ns = static_cast<double>(m.sampled);
  m.below_share = below / ns;
  m.high_share = high / ns;
  m.steep_share = depth_.size() / ns;
  if (!depth_.empty()) m.steep_depth = quantile(&depth_, 0.5);

  // xy box without the outermost percent on each side (a stray far return does not stretch it).
  tmp_ = xs_;
  const float x0 = quantile(&tmp_, 0.01), x1 = quantile(&tmp_, 0.99);
  tmp_ = ys_;
  const float y0 = quantile(&tmp_, 0.01), y1 = quantile(&tmp_, 0.99);
  m.extent = std::max(x1 - x0, y1 - y0);
  box_[0] = x0;
  box_[1] = x1;
  box_[2] = y0;
  box_[3] = y1;
  if (!(m.extent > 0.0)) return m;
  // About 16 points a cell on an evenly covered box, at most 64 cells a side.
  const int side = std::max(4, std::min(64, static_cast<int>(std::sqrt(ns / 16.0))));
  m.cell = m.extent / side;
  const int nx = std::max(1, std::min(side, static_cast<int>(std::ceil((x1 - x0) / m.cell))));
  const int ny = std::max(1, std::min(side, static_cast<int>(std::ceil((y1 - y0) / m.cell))));
  counts_.assign(static_cast<std::size_t>(nx) * ny, 0);
  for (std::size_t i = 0; i < xs_.size(); ++i) {
    if (xs_[i] < x0 || xs_[i] > x1 || ys_[i] < y0 || ys_[i] > y1) continue;
    const int cx = std::min(nx - 1, static_cast<int>((xs_[i] - x0) / m.cell));
    const int cy = std::min(ny - 1, static_cast<int>((ys_[i] - y0) / m.cell));
    ++counts_[static_cast<std::size_t>(cy) * nx + cx];
  }
  // The densest cell's centre (a spinning sensor's points are densest around it).
  const std::size_t densest =
      static_cast<std::size_t>(std::max_element(counts_.begin(), counts_.end()) - counts_.begin());
  const std::size_t row = static_cast<std::size_t>(nx);
  const double centre_x = x0 + (static_cast<double>(densest % row) + 0.5) * m.cell;
  const double centre_y = y0 + (static_cast<double>(densest / row) + 0.5) * m.cell;
  m.densest_offset = std::hypot(centre_x - origin[0], centre_y - origin[1]);
  counts_.erase(std::remove(counts_.begin(), counts_.end(), 0u), counts_.end());
  m.cells = counts_.size();
  if (counts_.empty()) return m;
  std::sort(counts_.begin(), counts_.end(), std::greater<std::uint32_t>());
  const std::size_t top = (counts_.size() + 9) / 10;
  const double all = std::accumulate(counts_.begin(), counts_.end(), 0.0);
  m.top_share = std::accumulate(counts_.begin(), counts_.begin() + top, 0.0) / all;
  return m;
}

void ScanTypeClassifier::measureColumns(const CloudView& cloud, ScanMeasures* m, std::size_t most) {
  const float x0 = box_[0], x1 = box_[1], y0 = box_[2], y1 = box_[3];
  const std::size_t n = cloud.size();
  const std::size_t want = std::min(n, most);
  if (want == 0) return;
  // In double: a float box can span more than float's range. Columns wider than kColumn only
  // where the box is over 2^31 of them a side, so the keys and the casts to them stay in range
  // whatever the coordinates.
  const double span = std::max(static_cast<double>(x1) - x0, static_cast<double>(y1) - y0);
  const double c = std::max(kColumn, span / 2147483648.0);
  const std::uint64_t nx =
      static_cast<std::uint64_t>(std::ceil((static_cast<double>(x1) - x0) / c)) + 1;
  keys_.clear();
  // Point k of the read sits at k n / want plus a jitter below the step: an even spread that a
  // scan pattern's period (rings, sweeps) cannot alias with.
  const std::size_t step = n / want;
  std::uint32_t lcg = 12345u;
  for (std::size_t k = 0; k < want; ++k) {
    std::size_t i = static_cast<std::size_t>(static_cast<double>(k) * n / want);
    if (step > 1) {
      lcg = lcg * 1664525u + 1013904223u;
      i = std::min(n - 1, i + (lcg >> 8) % step);
    }
    float x, y, z;
    if (!cloud.get(i, &x, &y, &z)) continue;
    if (!(x >= x0 && x <= x1 && y >= y0 && y <= y1)) continue;
    keys_.push_back(static_cast<std::uint64_t>((static_cast<double>(y) - y0) / c) * nx +
                    static_cast<std::uint64_t>((static_cast<double>(x) - x0) / c));
  }
  m->read = keys_.size();
  if (keys_.empty()) return;
  counts_.clear();
  const std::uint64_t ny =
      static_cast<std::uint64_t>(std::ceil((static_cast<double>(y1) - y0) / c)) + 1;
  if (nx * ny <= kDenseColumns) {  // a count per column of the box: no sort
    dense_.assign(static_cast<std::size_t>(nx * ny), 0u);
    for (const std::uint64_t key : keys_) ++dense_[static_cast<std::size_t>(key)];
    for (const std::uint32_t count : dense_) {
      if (count > 0) counts_.push_back(count);
    }
  } else {
    std::sort(keys_.begin(), keys_.end());
    for (std::size_t a = 0; a < keys_.size();) {
      std::size_t b = a + 1;
      while (b < keys_.size() && keys_[b] == keys_[a]) ++b;
      counts_.push_back(static_cast<std::uint32_t>(b - a));
      a = b;
    }
  }
  m->columns = counts_.size();
  m->column_mean = static_cast<double>(keys_.size()) / static_cast<double>(counts_.size());
  const std::size_t top = (counts_.size() + 9) / 10;
  std::nth_element(counts_.begin(), counts_.begin() + static_cast<std::ptrdiff_t>(top - 1),
                   counts_.end(), std::greater<std::uint32_t>());
  double in_top = 0.0;
  for (std::size_t j = 0; j < top; ++j) in_top += counts_[j];
  m->column_top_share = in_top / static_cast<double>(keys_.size());
}

void ScanTypeClassifier::classify(const CloudView& cloud, const float origin[3], ScanDecision* d) {
  ScanMeasures m = measureSample(cloud, origin);
  d->below_share = m.sampled > 0 ? m.below_share : 1.0;
  d->densest_offset = m.densest_offset;
  const bool judged = m.sampled >= kMinPoints && m.extent >= kMinExtent;
  const bool nadir_view = m.steep_share >= kSteepShare && m.steep_depth >= kNadirDepth;
  // Rule 4's columns where rule 3 finds an even sampling, and where rule 2 finds the points far
  // below the origin (a registered map tile below its frame's origin looks the same from
  // there), on a smaller read: a drone's stream of scans meets rule 2 on every scan.
  if (judged && nadir_view) {
    measureColumns(cloud, &m, kNadirRead);
  } else if (judged && m.top_share < kConcentrated) {
    measureColumns(cloud, &m, kMaxRead);
  }
  // False where the columns were not measured (their fields stay 0): rules 2 and 3 gate rule 4.
  const bool side_view =
      m.column_mean >= kMinColumnMean && m.column_top_share >= kColumnConcentrated;
  char buf[kReasonRoom];
  d->registered = false;
  d->side_view = false;
  const double cell = m.cell, top = 100.0 * m.top_share, below = 100.0 * m.below_share;
  const char* cell_fmt = cell < 10.0 ? "%.1f" : "%.0f";
  char cell_text[16];
  std::snprintf(cell_text, sizeof(cell_text), cell_fmt, cell);
  if (m.sampled < kMinPoints) {
    d->type = ScanType::kGround;
    std::snprintf(buf, sizeof(buf),
                  "auto: %zu valid points, too few to judge (fewer than %zu): ground-level mode",
                  m.sampled, kMinPoints);
  } else if (!(m.extent >= kMinExtent)) {
    d->type = ScanType::kGround;
    std::snprintf(buf, sizeof(buf),
                  "auto: the points cover %.2f m across, too little to judge (under %.0f m): "
                  "ground-level mode",
                  m.extent, kMinExtent);
  } else if (side_view) {
    // Rule 4. Where rule 2 holds too: a nadir sensor at the origin sees the surfaces below it
    // evenly at the 1 m scale, and these columns hold the side view of sensors near the ground
    // (walls, trunks, each position's near field): a map tile registered below its frame's
    // origin, or a sensor looking obliquely down from a mast (OriginView tells them apart).
    d->type = ScanType::kGround;
    d->registered = true;
    d->side_view = m.nearest <= kFarOrigin;
    const int n = std::snprintf(
        buf, sizeof(buf),
        "auto: side view: the densest tenth of the %.0f m xy columns holds %.0f %% of %zu points "
        "read (%.0f %% or more: density falls with range from each sensor position; a registered "
        "cloud), although ",
        kColumn, 100.0 * m.column_top_share, m.read, 100.0 * kColumnConcentrated);
    if (n > 0 && static_cast<std::size_t>(n) < sizeof(buf)) {
      if (nadir_view) {
        std::snprintf(buf + n, sizeof(buf) - n,
                      "%.0f %% of the points lie 45 deg or more below the origin, median %.0f m "
                      "down (not the even sampling of a nadir view)",
                      100.0 * m.steep_share, m.steep_depth);
      } else {
        std::snprintf(buf + n, sizeof(buf) - n,
                      "the densest tenth of the %s m cells holds only %.0f %%", cell_text, top);
      }
    }
  } else if (nadir_view) {
    d->type = ScanType::kAirborne;
    std::snprintf(buf, sizeof(buf),
                  "auto: %.0f %% of the points lie 45 deg or more below the origin, median %.0f m "
                  "down (a sensor looking down); the densest tenth of the %s m xy cells holds "
                  "%.0f %% of the points",
                  100.0 * m.steep_share, m.steep_depth, cell_text, top);
  } else if (m.top_share < kConcentrated) {
    d->type = ScanType::kAirborne;
    std::snprintf(buf, sizeof(buf),
                  "auto: the densest tenth of the %s m xy cells holds %.0f %% of the points (even "
                  "sampling: nadir; a ground-level scan holds %.0f %% or more); %.0f %% below the "
                  "origin; the densest tenth of the %.0f m columns holds %.0f %% of %zu points "
                  "read (%.1f a column; a side view: %.0f %% or more at %.0f or more a column)",
                  cell_text, top, 100.0 * kConcentrated, below, kColumn, 100.0 * m.column_top_share,
                  m.read, m.column_mean, 100.0 * kColumnConcentrated, kMinColumnMean);
  } else {
    // Rule 3 needs no sensor at the origin, so a scan exported in map coordinates is judged
    // too; one with no point near the origin has its sensor elsewhere: no range cut.
    d->registered = m.nearest > kFarOrigin;
    d->type = m.high_share >= kTlsHighShare && !d->registered ? ScanType::kTls : ScanType::kGround;
    const int n = std::snprintf(buf, sizeof(buf),
                                "auto: the densest tenth of the %s m xy cells holds %.0f %% of the "
                                "points (density falls with range from a ground-level sensor); "
                                "%.0f %% below the origin",
                                cell_text, top, below);
    if (d->type == ScanType::kTls && n > 0 && static_cast<std::size_t>(n) < sizeof(buf)) {
      std::snprintf(buf + n, sizeof(buf) - n, ", %.0f %% 30 deg or more above it (tripod scanner)",
                    100.0 * m.high_share);
    } else if (d->registered && n > 0 && static_cast<std::size_t>(n) < sizeof(buf)) {
      std::snprintf(buf + n, sizeof(buf) - n,
                    "; no point within %.0f m of the origin (map coordinates: no range cut)",
                    kFarOrigin);
    }
  }
  d->reason.reserve(kReasonRoom);
  d->reason.assign(buf);
}

ScanTypeSwitch::ScanTypeSwitch(const std::string& setting, bool morph_ground) {
  validateScanTypeSetting(setting);
  automatic_ = !morph_ground && setting == "auto";
  if (morph_ground) {
    fixed_ = {ScanType::kAirborne, false, false, "morph_ground: true"};
  } else if (setting == "airborne") {
    fixed_ = {ScanType::kAirborne, false, false, "scan_type: airborne"};
  } else if (setting == "tls") {
    fixed_ = {ScanType::kTls, false, false, "scan_type: tls"};
  } else if (setting == "registered") {  // merged stations or sweeps: no sensor at the origin
    fixed_ = {ScanType::kGround, true, false, "scan_type: registered"};
  } else {
    fixed_ = {ScanType::kGround, false, false, "scan_type: ground"};
  }
}

void ScanTypeSwitch::setOrigin(float x, float y, float z) {
  origin_[0] = x;
  origin_[1] = y;
  origin_[2] = z;
}

const ScanDecision& ScanTypeSwitch::pin(const CloudView& cloud) {
  if (!automatic_) return fixed_;
  if (!pinned_) classifier_.classify(cloud, origin_, &last_);  // else: kept for this scan
  pinned_ = true;
  return last_;
}

const ScanDecision& ScanTypeSwitch::decide(const CloudView& cloud) {
  if (!automatic_) return fixed_;
  if (pinned_) {
    pinned_ = false;
    return last_;
  }
  classifier_.classify(cloud, origin_, &last_);
  return last_;
}

}  // namespace ground_filter
