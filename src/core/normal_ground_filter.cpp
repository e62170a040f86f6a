#include "ground_filter/normal_ground_filter.h"

#include <omp.h>

#include <Eigen/Core>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>

#include "ground_filter/neighbor_search_factory.h"
#include "ground_filter/param_parse.h"

namespace ground_filter {

// ------------------------------------------------------------------------------------ params

void NormalGroundFilterParams::set(const std::string& name, const std::string& value) {
  if (name == "cell_size") {
    cell_size = parseDoubleParam(name, value);
  } else if (name == "k") {
    k = parseIntParam(name, value);
  } else if (name == "min_normal_angle") {
    min_normal_angle = parseDoubleParam(name, value);
  } else if (name == "max_normal_angle") {
    max_normal_angle = parseDoubleParam(name, value);
  } else if (name == "min_planarity") {
    min_planarity = parseDoubleParam(name, value);
  } else if (name == "bayes_vote") {
    bayes_vote = parseBoolParam(name, value);
  } else if (name == "plane_distance") {
    plane_distance = parseDoubleParam(name, value);
  } else if (name == "std_filter") {
    std_filter = parseBoolParam(name, value);
  } else if (name == "std_multiplier") {
    std_multiplier = parseDoubleParam(name, value);
  } else if (name == "ransac_iterations") {
    ransac_iterations = parseIntParam(name, value);
  } else if (name == "plane_all_points") {
    plane_all_points = parseBoolParam(name, value);
  } else if (name == "local_planes") {
    local_planes = parseBoolParam(name, value);
  } else if (name == "tile_size") {
    tile_size = parseDoubleParam(name, value);
  } else if (name == "use_segments") {
    use_segments = parseBoolParam(name, value);
  } else if (name == "segment_points") {
    segment_points = parseIntParam(name, value);
  } else if (name == "knn_backend") {
    knn_backend = value;
  } else if (name == "threads") {
    threads = parseIntParam(name, value);
  } else {
    throw std::invalid_argument(
        "unknown parameter '" + name +
        "' for method normal (known: cell_size, k, min_normal_angle, max_normal_angle, "
        "min_planarity, bayes_vote, plane_distance, std_filter, std_multiplier, "
        "ransac_iterations, plane_all_points, local_planes, tile_size, use_segments, "
        "segment_points, knn_backend, threads)");
  }
}

void NormalGroundFilterParams::validate() const {
  checkRange("cell_size", cell_size, 0.001, 1000.0, "m");
  checkRange("k", k, 3, 256, "points");
  // The window is an angle of the normal to the horizontal; it must contain the vertical (90 deg)
  // and reach at most 90 deg away from it on either side.
  checkRange("min_normal_angle", min_normal_angle, 0.0, 90.0, "deg");
  checkRange("max_normal_angle", max_normal_angle, 90.0, 180.0, "deg");
  checkRange("min_planarity", min_planarity, 0.0, 1.0, "");
  checkRange("plane_distance", plane_distance, 0.001, 10.0, "m");
  checkRange("std_multiplier", std_multiplier, 0.1, 10.0, "");
  checkRange("ransac_iterations", ransac_iterations, 1, 100000, "");
  checkRange("tile_size", tile_size, 0.5, 100000.0, "m");
  checkRange("segment_points", segment_points, 256, 1 << 26, "points");
  checkRange("threads", threads, 0, 256, "threads");
  const auto backends = neighborSearchBackends();
  if (std::find(backends.begin(), backends.end(), knn_backend) == backends.end()) {
    std::string known;
    for (const auto& b : backends) known += (known.empty() ? "" : ", ") + b;
    throw std::invalid_argument("parameter 'knn_backend' = '" + knn_backend +
                                "' is not one of: " + known);
  }
}

// ------------------------------------------------------------------------------------ helpers

namespace {

using Clock = std::chrono::steady_clock;

double msSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

int resolveThreads(int threads) { return threads > 0 ? threads : omp_get_num_procs(); }

/// Spreads the 32 bits of v over the even bits of a 64-bit word (Morton interleave).
std::uint64_t spreadBits(std::uint64_t v) {
  v &= 0xffffffffULL;
  v = (v | (v << 16)) & 0x0000ffff0000ffffULL;
  v = (v | (v << 8)) & 0x00ff00ff00ff00ffULL;
  v = (v | (v << 4)) & 0x0f0f0f0f0f0f0f0fULL;
  v = (v | (v << 2)) & 0x3333333333333333ULL;
  v = (v | (v << 1)) & 0x5555555555555555ULL;
  return v;
}

/// Integer cell coordinate of `v` on a grid starting at `lo`, clamped to 32 bits.
std::uint32_t cellIndex(double v, double lo, double inv_cell) {
  const double c = std::floor((v - lo) * inv_cell);
  if (!(c > 0.0)) return 0;
  if (c >= 4294967295.0) return 4294967295U;
  return static_cast<std::uint32_t>(c);
}

/// Stable LSD radix sort of `order` (values 0..n-1) by `keys[order[i]]`; 8-bit digits, passes
/// whose digit is the same for every key are skipped.
void radixSortByKey(const std::vector<std::uint64_t>& keys, std::vector<std::uint32_t>* order,
                    std::vector<std::uint32_t>* scratch) {
  const std::size_t n = keys.size();
  order->resize(n);
  for (std::size_t i = 0; i < n; ++i) (*order)[i] = static_cast<std::uint32_t>(i);
  if (n < 2) return;
  std::array<std::array<std::uint32_t, 256>, 8> hist{};
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint64_t key = keys[i];
    for (int d = 0; d < 8; ++d) ++hist[d][(key >> (8 * d)) & 0xff];
  }
  scratch->resize(n);
  for (int d = 0; d < 8; ++d) {
    auto& h = hist[d];
    if (h[(keys[0] >> (8 * d)) & 0xff] == n) continue;  // all keys share this digit
    std::uint32_t sum = 0;
    for (auto& c : h) {
      const std::uint32_t c0 = c;
      c = sum;
      sum += c0;
    }
    for (std::size_t i = 0; i < n; ++i) {
      const std::uint32_t v = (*order)[i];
      (*scratch)[h[(keys[v] >> (8 * d)) & 0xff]++] = v;
    }
    order->swap(*scratch);
  }
}

/// Small deterministic generator (splitmix64): same sequence on every platform and library.
struct SplitMix64 {
  std::uint64_t state;
  explicit SplitMix64(std::uint64_t seed) : state(seed) {}
  std::uint64_t next() {
    std::uint64_t z = (state += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
  }
  std::size_t below(std::size_t n) { return static_cast<std::size_t>(next() % n); }
};

/// Plane n . (p - origin) + d = 0 with unit normal n, in coordinates relative to `origin`.
struct Plane {
  Eigen::Vector3d n = Eigen::Vector3d::UnitZ();
  double d = 0.0;
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  bool valid = false;
  double distance(const float* p) const {
    return n.x() * (p[0] - origin.x()) + n.y() * (p[1] - origin.y()) + n.z() * (p[2] - origin.z()) +
           d;
  }
};

constexpr std::uint64_t kRansacSeed = 0x67f1a3c5d2b9e481ULL;  // fixed: reproducible output
constexpr std::size_t kRansacEvalPoints = 2048;  // hypotheses are scored on at most this many
constexpr std::size_t kMinTilePoints = 10;  // fewer voted points: the tile uses the global plane

/// RANSAC plane through the points `idx` of `xyz`, its normal within `max_tilt_cos` of vertical
/// (|n_z| >= max_tilt_cos), refined by least squares on its inliers.
Plane fitPlaneRansac(const float* xyz, const std::vector<std::uint32_t>& idx, int iterations,
                     double threshold, double max_tilt_cos, std::uint64_t seed,
                     std::vector<std::uint32_t>* eval_scratch) {
  Plane best;
  const std::size_t m = idx.size();
  if (m < 3) return best;
  const float* o = xyz + 3 * static_cast<std::size_t>(idx[0]);
  best.origin = Eigen::Vector3d(o[0], o[1], o[2]);
  auto point = [&](std::uint32_t i) {
    const float* p = xyz + 3 * static_cast<std::size_t>(i);
    return Eigen::Vector3d(p[0] - best.origin.x(), p[1] - best.origin.y(), p[2] - best.origin.z());
  };
  // Score on an evenly strided subset of large sets (deterministic, keeps big tiles cheap).
  std::vector<std::uint32_t>& eval = *eval_scratch;
  eval.clear();
  const std::size_t stride = (m + kRansacEvalPoints - 1) / kRansacEvalPoints;
  for (std::size_t i = 0; i < m; i += stride) eval.push_back(idx[i]);

  SplitMix64 rng(seed);
  std::size_t best_count = 0;
  Eigen::Vector3d best_n = Eigen::Vector3d::UnitZ();
  double best_d = 0.0;
  double needed = iterations;
  for (int it = 0; it < iterations && it < needed; ++it) {
    const std::size_t a = rng.below(m), b = rng.below(m), c = rng.below(m);
    if (a == b || a == c || b == c) continue;
    const Eigen::Vector3d pa = point(idx[a]);
    Eigen::Vector3d nrm = (point(idx[b]) - pa).cross(point(idx[c]) - pa);
    const double len = nrm.norm();
    if (!(len > 1e-9)) continue;  // collinear or duplicate sample
    nrm /= len;
    if (std::abs(nrm.z()) < max_tilt_cos) continue;
    const double d = -nrm.dot(pa);
    std::size_t count = 0;
    for (std::uint32_t i : eval) {
      if (std::abs(nrm.dot(point(i)) + d) <= threshold) ++count;
    }
    if (count > best_count) {
      best_count = count;
      best_n = nrm;
      best_d = d;
      // Adaptive stop: enough hypotheses for 99 % confidence at this inlier ratio.
      const double w = static_cast<double>(count) / static_cast<double>(eval.size());
      const double fail = 1.0 - w * w * w;
      needed = fail <= 0.0 ? 0.0 : std::ceil(std::log(0.01) / std::log(fail));
    }
  }
  if (best_count < 3) return best;

  // Least-squares refinement on all inliers (centred covariance, smallest eigenvector).
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  std::size_t inliers = 0;
  for (std::uint32_t i : idx) {
    const Eigen::Vector3d p = point(i);
    if (std::abs(best_n.dot(p) + best_d) <= threshold) {
      mean += p;
      ++inliers;
    }
  }
  best.n = best_n;
  best.d = best_d;
  best.valid = true;
  if (inliers < 3) return best;
  mean /= static_cast<double>(inliers);
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (std::uint32_t i : idx) {
    const Eigen::Vector3d p = point(i);
    if (std::abs(best_n.dot(p) + best_d) <= threshold) {
      const Eigen::Vector3d q = p - mean;
      cov.noalias() += q * q.transpose();
    }
  }
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es;
  es.computeDirect(cov);
  Eigen::Vector3d n = es.eigenvectors().col(0);
  if (n.dot(best_n) < 0.0) n = -n;
  if (std::isfinite(n.x()) && std::abs(n.z()) >= max_tilt_cos) {
    best.n = n;
    best.d = -n.dot(mean);
  }
  return best;
}

/// Dimensionality features of Demantke et al. from the normalised eigenvalues (sigma_i =
/// sqrt(lambda_i), sigma_1 >= sigma_2 >= sigma_3): linearity (s1 - s2)/s1, planarity
/// (s2 - s3)/s1, scattering s3/s1. Flat (paper): planarity is the largest of the three, and at
/// least `min_planarity`.
bool isFlat(const PointPca& r, double min_planarity) {
  const double s1 = std::sqrt(static_cast<double>(r.eigen[2]));
  const double s2 = std::sqrt(static_cast<double>(r.eigen[1]));
  const double s3 = std::sqrt(static_cast<double>(r.eigen[0]));
  if (!(s1 > 0.0)) return false;
  const double linear = (s1 - s2) / s1, planar = (s2 - s3) / s1, scatter = s3 / s1;
  return planar >= linear && planar >= scatter && planar >= min_planarity;
}

}  // namespace

// ------------------------------------------------------------------------------------ filter

struct NormalGroundFilter::Impl {
  std::unique_ptr<NeighborSearch> search;
  NeighborLists lists;
  std::vector<PointPca> pca;
  // Valid points, packed and in grid-column (Morton) order; `source` maps back to input indices.
  std::vector<float> raw_xyz, xyz;
  std::vector<std::uint32_t> raw_source, source;
  std::vector<std::uint64_t> keys;
  std::vector<std::uint32_t> order, sort_scratch;
  std::vector<std::uint8_t> candidate, voted, ground;
  std::vector<std::uint16_t> vote_flagged, vote_size;         // per-point counts from a GPU backend
  std::vector<std::pair<std::size_t, std::size_t>> segments;  // [begin, end) in sorted order
  std::vector<std::pair<std::size_t, std::size_t>> tiles;     // [begin, end) in tile_order
  std::vector<std::uint32_t> tile_order;
  std::vector<std::vector<std::uint32_t>> thread_idx, thread_eval;
};

NormalGroundFilter::NormalGroundFilter(const NormalGroundFilterParams& params)
    : params_(params), impl_(std::make_unique<Impl>()) {
  params_.validate();
  impl_->search = makeNeighborSearch(params_.knn_backend, params_.threads, &backend_note_);
  // A GPU backend keeps the lists in GPU memory; PCA and vote counts below then run there.
  impl_->search->keepListsOnDevice(true);
}

NormalGroundFilter::~NormalGroundFilter() = default;

std::string NormalGroundFilter::backend() const { return impl_->search->name(); }

void NormalGroundFilter::filter(const CloudView& cloud, std::vector<std::uint8_t>* labels,
                                FilterStats* stats) {
  const auto t_start = Clock::now();
  Impl& im = *impl_;
  const NormalGroundFilterParams& p = params_;
  const int threads = resolveThreads(p.threads);
  FilterStats local_stats;
  FilterStats& st = stats ? *stats : local_stats;
  st = FilterStats();
  st.input_points = cloud.size();
  st.backend = im.search->name();
  st.note = backend_note_;
  labels->assign(cloud.size(), kNonGround);

  // 1. Compact the finite points and order them by x/y grid column (Morton order of the cells):
  //    neighbouring points end up close in memory and segments are compact blocks of columns.
  auto t0 = Clock::now();
  im.raw_xyz.clear();
  im.raw_source.clear();
  double min_x = std::numeric_limits<double>::infinity(), min_y = min_x;
  double max_x = -min_x, max_y = -min_x;
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    float x, y, z;
    if (!cloud.get(i, &x, &y, &z)) continue;
    im.raw_xyz.push_back(x);
    im.raw_xyz.push_back(y);
    im.raw_xyz.push_back(z);
    im.raw_source.push_back(static_cast<std::uint32_t>(i));
    min_x = std::min<double>(min_x, x);
    min_y = std::min<double>(min_y, y);
    max_x = std::max<double>(max_x, x);
    max_y = std::max<double>(max_y, y);
  }
  const std::size_t n = im.raw_source.size();
  st.invalid_points = cloud.size() - n;
  if (n == 0) {
    st.stage_ms.emplace_back("sort", msSince(t0));
    st.total_ms = msSince(t_start);
    return;
  }
  // Coarsen the ordering grid for very wide clouds so cell indices fit in 32 bits.
  const double extent = std::max(max_x - min_x, max_y - min_y);
  const double cell = std::max(p.cell_size, extent / 4.0e9);
  im.keys.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint32_t cx = cellIndex(im.raw_xyz[3 * i], min_x, 1.0 / cell);
    const std::uint32_t cy = cellIndex(im.raw_xyz[3 * i + 1], min_y, 1.0 / cell);
    im.keys[i] = spreadBits(cx) | (spreadBits(cy) << 1);
  }
  radixSortByKey(im.keys, &im.order, &im.sort_scratch);
  im.xyz.resize(3 * n);
  im.source.resize(n);
  for (std::size_t j = 0; j < n; ++j) {
    const std::uint32_t s = im.order[j];
    std::copy_n(&im.raw_xyz[3 * static_cast<std::size_t>(s)], 3, &im.xyz[3 * j]);
    im.source[j] = im.raw_source[s];
  }
  // Segments of at most segment_points, cut at column borders (whole cloud when disabled).
  im.segments.clear();
  if (p.use_segments) {
    const std::size_t seg = static_cast<std::size_t>(p.segment_points);
    std::size_t begin = 0;
    while (begin < n) {
      std::size_t end = std::min(n, begin + seg);
      if (end < n) {
        std::size_t cut = end;
        while (cut > begin + 1 && im.keys[im.order[cut - 1]] == im.keys[im.order[cut]]) --cut;
        if (cut > begin + 1) end = cut;  // else one column is larger than a segment: split it
      }
      im.segments.emplace_back(begin, end);
      begin = end;
    }
  } else {
    im.segments.emplace_back(0, n);
  }
  st.stage_ms.emplace_back("sort", msSince(t0));

  // 2-4. Per segment: neighbours (computed once), PCA + candidates, naive-Bayes vote.
  const double max_tilt_deg = std::min(90.0 - p.min_normal_angle, p.max_normal_angle - 90.0);
  const double min_abs_nz = std::cos(max_tilt_deg * M_PI / 180.0);
  im.candidate.assign(n, 0);
  im.voted.assign(n, 0);
  // Stage times by name, summed over segments, in first-seen order.
  std::vector<std::pair<std::string, double>> search_ms;
  auto addMs = [&search_ms](const std::string& name, double ms) {
    for (auto& e : search_ms) {
      if (e.first == name) {
        e.second += ms;
        return;
      }
    }
    search_ms.emplace_back(name, ms);
  };
  double vote_ms = 0.0;
  for (const auto& sg : im.segments) {
    const std::size_t b = sg.first, len = sg.second - sg.first;
    const float* sxyz = im.xyz.data() + 3 * b;
    t0 = Clock::now();
    bool have_pca = im.search->searchWithPca(sxyz, len, p.k, &im.lists, &im.pca);
    if (!have_pca) im.search->search(sxyz, len, p.k, &im.lists);
    const double search_wall = msSince(t0);
    const auto parts = im.search->lastStageMs();
    for (const auto& e : parts) addMs(e.first, e.second);
    if (parts.empty()) addMs("knn", search_wall);

    t0 = Clock::now();
    if (!have_pca && !im.search->neighborhoodPca(&im.pca)) {
      computeNeighborhoodPca(sxyz, im.lists, threads, &im.pca);
    }
    std::size_t candidates = 0;
    for (std::size_t i = 0; i < len; ++i) {
      const PointPca& r = im.pca[i];
      const bool flat = r.valid && isFlat(r, p.min_planarity);
      const bool cand = flat && std::abs(r.normal[2]) >= min_abs_nz;
      im.candidate[b + i] = cand;
      candidates += cand;
    }
    addMs("pca", msSince(t0));

    // Naive-Bayes vote (paper): classes U (candidates) and V (the rest) of this neighbourhood
    // set, priors P(U) = U/N and P(V) = V/N; likelihood of a point's neighbourhood under U is the
    // share u/m of candidates among its m neighbours, under V it is (m - u)/m. Ground when
    // P(U) u/m > P(V) (m - u)/m, i.e. U u > V (m - u).
    t0 = Clock::now();
    if (p.bayes_vote) {
      const double U = static_cast<double>(candidates);
      const double V = static_cast<double>(len - candidates);
      const int k = im.lists.k;
      const std::uint8_t* cand = im.candidate.data() + b;
      std::uint8_t* voted = im.voted.data() + b;
      const int nt = static_cast<int>(std::min<std::size_t>(threads, len / 4096 + 1));
      im.vote_flagged.resize(len);
      im.vote_size.resize(len);
      if (im.search->countFlaggedNeighbors(cand, im.vote_flagged.data(), im.vote_size.data())) {
        // u and m counted where the lists are (GPU); same rule as below.
#pragma omp parallel for num_threads(nt) schedule(static, 4096)
        for (std::int64_t i = 0; i < static_cast<std::int64_t>(len); ++i) {
          const int u = im.vote_flagged[i], m = im.vote_size[i];
          voted[i] = U * u > V * (m - u);
        }
      } else {
#pragma omp parallel for num_threads(nt) schedule(static, 4096)
        for (std::int64_t i = 0; i < static_cast<std::int64_t>(len); ++i) {
          const std::int32_t* row = &im.lists.indices[static_cast<std::size_t>(i) * k];
          int m = 0, u = 0;
          for (; m < k && row[m] >= 0; ++m) u += cand[row[m]];
          voted[i] = U * u > V * (m - u);
        }
      }
    } else {
      std::copy_n(im.candidate.data() + b, len, im.voted.data() + b);
    }
    vote_ms += msSince(t0);
  }
  // The backend that really ran (a GPU search may fall back to the kd-tree for one scan).
  st.backend = im.search->lastBackend();
  const std::string last_note = im.search->lastNote();
  if (!last_note.empty()) st.note += (st.note.empty() ? "" : "; ") + last_note;
  for (const auto& e : search_ms) st.stage_ms.push_back(e);
  st.stage_ms.emplace_back("vote", vote_ms);

  // 5. Plane(s) through the voted points: RANSAC per x/y tile (or one for the cloud), then the
  //    distance test and the mean +- std band of the voted points' distances.
  t0 = Clock::now();
  im.ground.assign(n, 0);
  if (p.local_planes) {
    const double tile = std::max(p.tile_size, extent / 4.0e9);
    for (std::size_t i = 0; i < n; ++i) {
      const std::uint32_t tx = cellIndex(im.xyz[3 * i], min_x, 1.0 / tile);
      const std::uint32_t ty = cellIndex(im.xyz[3 * i + 1], min_y, 1.0 / tile);
      im.keys[i] = (static_cast<std::uint64_t>(tx) << 32) | ty;
    }
  } else {
    std::fill(im.keys.begin(), im.keys.end(), 0);
  }
  im.keys.resize(n);
  radixSortByKey(im.keys, &im.tile_order, &im.sort_scratch);
  im.tiles.clear();
  for (std::size_t b = 0; b < n;) {
    std::size_t e = b + 1;
    while (e < n && im.keys[im.tile_order[e]] == im.keys[im.tile_order[b]]) ++e;
    im.tiles.emplace_back(b, e);
    b = e;
  }

  // Cloud-wide plane: the only one without local planes, the fallback for sparse tiles.
  im.thread_idx.resize(threads);
  im.thread_eval.resize(threads);
  bool need_global = !p.local_planes;
  for (const auto& tl : im.tiles) {
    if (need_global) break;
    std::size_t voted = 0;
    for (std::size_t j = tl.first; j < tl.second && voted < kMinTilePoints; ++j) {
      voted += im.voted[im.tile_order[j]];
    }
    need_global = voted < kMinTilePoints;
  }
  Plane global;
  if (need_global) {
    std::vector<std::uint32_t>& all_voted = im.thread_idx[0];
    all_voted.clear();
    for (std::size_t i = 0; i < n; ++i) {
      if (im.voted[i]) all_voted.push_back(static_cast<std::uint32_t>(i));
    }
    global = fitPlaneRansac(im.xyz.data(), all_voted, p.ransac_iterations, p.plane_distance,
                            min_abs_nz, kRansacSeed, &im.thread_eval[0]);
  }

  const int nt = static_cast<int>(std::min<std::size_t>(threads, im.tiles.size()));
#pragma omp parallel for num_threads(nt) schedule(dynamic, 1)
  for (std::int64_t t = 0; t < static_cast<std::int64_t>(im.tiles.size()); ++t) {
    const int tid = omp_get_thread_num();
    std::vector<std::uint32_t>& tv = im.thread_idx[tid];
    const std::size_t tb = im.tiles[t].first, te = im.tiles[t].second;
    tv.clear();
    for (std::size_t j = tb; j < te; ++j) {
      if (im.voted[im.tile_order[j]]) tv.push_back(im.tile_order[j]);
    }
    Plane plane = global;
    if (p.local_planes && tv.size() >= kMinTilePoints) {
      const std::uint64_t seed = kRansacSeed ^ (im.keys[im.tile_order[tb]] * 0x9e3779b97f4a7c15ULL);
      const Plane fit = fitPlaneRansac(im.xyz.data(), tv, p.ransac_iterations, p.plane_distance,
                                       min_abs_nz, seed, &im.thread_eval[tid]);
      if (fit.valid) plane = fit;
    }
    if (!plane.valid) continue;
    // Band of the voted points' signed distances within the threshold.
    double lo = -p.plane_distance, hi = p.plane_distance;
    if (p.std_filter) {
      double s = 0.0, s2 = 0.0;
      std::size_t c = 0;
      for (std::uint32_t i : tv) {
        const double d = plane.distance(&im.xyz[3 * static_cast<std::size_t>(i)]);
        if (std::abs(d) <= p.plane_distance) {
          s += d;
          s2 += d * d;
          ++c;
        }
      }
      if (c > 0) {
        const double mean = s / c;
        const double sd = std::sqrt(std::max(0.0, s2 / c - mean * mean));
        lo = std::max(lo, mean - p.std_multiplier * sd);
        hi = std::min(hi, mean + p.std_multiplier * sd);
      }
    }
    for (std::size_t j = tb; j < te; ++j) {
      const std::uint32_t i = im.tile_order[j];
      if (!im.voted[i] && !p.plane_all_points) continue;
      const double d = plane.distance(&im.xyz[3 * static_cast<std::size_t>(i)]);
      im.ground[i] = d >= lo && d <= hi;
    }
  }
  st.stage_ms.emplace_back("plane", msSince(t0));

  std::size_t ground = 0;
  for (std::size_t j = 0; j < n; ++j) {
    if (im.ground[j]) {
      (*labels)[im.source[j]] = kGround;
      ++ground;
    }
  }
  st.ground_points = ground;
  st.total_ms = msSince(t_start);
}

}  // namespace ground_filter
