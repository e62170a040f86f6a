#include "voxel/paper_normalisation.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>

namespace ground_filter {

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

PaperNormalisedVoxelFilter::PaperNormalisedVoxelFilter(const VoxelGroundFilterParams& params,
                                                       int segment_points, bool normalise)
    : voxel_(params),
      segment_points_(static_cast<std::size_t>(std::max(segment_points, 0))),
      normalise_(normalise) {
  if (segment_points < 3) {
    throw std::invalid_argument("segment_points = " + std::to_string(segment_points) +
                                " is out of range [3, 2147483647] points");
  }
}

void PaperNormalisedVoxelFilter::filter(const CloudView& cloud, std::vector<std::uint8_t>* labels,
                                        FilterStats* stats) {
  const auto t0 = std::chrono::steady_clock::now();
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
  st.total_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  if (stats) *stats = st;
}

}  // namespace ground_filter
