#include "voxel/paper_voxel_filter.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "common/threads_timing.h"

namespace ground_filter {

namespace {

// The voxel filter's parameters, after the whole set passed validate().
const VoxelGroundFilterParams& validated(const PaperVoxelParams& p) {
  p.validate();
  return p.voxel;
}

}  // namespace

VoxelGroundFilterParams paperVoxelParams() {
  VoxelGroundFilterParams p;
  p.voxel_size = 0.1;
  p.flatness_threshold = 0.04;
  p.height_margin = 1.0;
  p.local_planes = false;
  p.plane_distance = 0.10;
  p.std_filter = true;
  p.std_multiplier = 1.0;
  p.scan_type = "ground";  // the paper's steps only (its segments are not whole scans)
  p.level_tilt = 0.0;      // nor levelled: a segment has no sensor at its origin
  return p;
}

void paperNormaliseSegment(const CloudView& cloud, std::size_t begin, std::size_t end,
                           std::vector<float>* xyz, std::vector<std::size_t>* index,
                           bool normalise) {
  end = std::min(end, cloud.size());
  const std::size_t first = index->size();
  double sum[3] = {0, 0, 0};
  for (std::size_t i = begin; i < end; ++i) {
    float p[3];
    if (!cloud.get(i, &p[0], &p[1], &p[2])) continue;
    index->push_back(i);
    for (int k = 0; k < 3; ++k) sum[k] += p[k];
  }
  const std::size_t n = index->size() - first;
  if (n == 0) return;
  double mean[3], sq[3] = {0, 0, 0};
  for (int k = 0; k < 3; ++k) mean[k] = sum[k] / static_cast<double>(n);
  for (std::size_t j = first; j < index->size(); ++j) {
    float p[3];
    cloud.get((*index)[j], &p[0], &p[1], &p[2]);
    for (int k = 0; k < 3; ++k) sq[k] += (p[k] - mean[k]) * (p[k] - mean[k]);
  }
  double sd[3];
  for (int k = 0; k < 3; ++k) sd[k] = n > 1 ? std::sqrt(sq[k] / static_cast<double>(n - 1)) : 0.0;
  xyz->reserve(xyz->size() + 3 * n);
  for (std::size_t j = first; j < index->size(); ++j) {
    float p[3];
    cloud.get((*index)[j], &p[0], &p[1], &p[2]);
    for (int k = 0; k < 3; ++k) {
      if (!normalise) {
        xyz->push_back(p[k]);
        continue;
      }
      const double v = sd[k] > 0.0 ? 1.0 / (1.0 + std::exp(-(p[k] - mean[k]) / sd[k])) : 0.5;
      xyz->push_back(static_cast<float>(v));
    }
  }
}

const ParamTable<PaperVoxelParams>& PaperVoxelParams::table() {
  using P = PaperVoxelParams;
  static const ParamTable<P> rows = {
      {"segment_points", &P::segment_points, 3, 2147483647, "points", "points per segment"},
      {"paper_normalisation", &P::paper_normalisation, 0, 0, "bool",
       "logistic z-score mapping (false: metric)"},
  };
  return rows;
}

void PaperVoxelParams::set(const std::string& name, const std::string& value) {
  for (const auto& spec : table()) {
    if (name == spec.name) {
      setParam(table(), method(), name, value, this);
      return;
    }
  }
  voxel.set(name, value);
}

void PaperVoxelParams::validate() const {
  voxel.validate();
  checkParamRanges(table(), *this);
}

std::string PaperVoxelParams::describe() const {
  return describeParams(table(), *this) + " " + voxel.describe();
}

PaperNormalisedVoxelFilter::PaperNormalisedVoxelFilter(const PaperVoxelParams& params)
    : voxel_(validated(params)),
      segment_points_(static_cast<std::size_t>(params.segment_points)),
      normalise_(params.paper_normalisation) {
  // The paper's steps only: segments of a scan, normalised, have no sensor to lie below.
  voxel_.setSensorOrigin(NAN, NAN, NAN);
}

void PaperNormalisedVoxelFilter::filter(const CloudView& cloud, std::vector<std::uint8_t>* labels,
                                        FilterStats* stats) {
  const auto t0 = Clock::now();
  const std::size_t n = cloud.size();
  labels->assign(n, kNonGround);
  FilterStats st;
  st.input_points = n;
  for (std::size_t begin = 0; begin < n; begin += segment_points_) {
    xyz_.clear();
    index_.clear();
    paperNormaliseSegment(cloud, begin, begin + segment_points_, &xyz_, &index_, normalise_);
    st.invalid_points += std::min(segment_points_, n - begin) - index_.size();
    if (index_.empty()) continue;
    voxel_.filter(CloudView::packedXyz(xyz_.data(), index_.size()), &segment_labels_);
    for (std::size_t j = 0; j < index_.size(); ++j) (*labels)[index_[j]] = segment_labels_[j];
  }
  st.ground_points = static_cast<std::size_t>(std::count(labels->begin(), labels->end(), kGround));
  st.total_ms = msSince(t0);
  if (stats) *stats = st;
}

}  // namespace ground_filter
