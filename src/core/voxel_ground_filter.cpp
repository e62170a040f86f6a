#include "ground_filter/voxel_ground_filter.h"

#include <omp.h>

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "ground_filter/param_parse.h"
#include "ground_filter/plane_fit.h"

namespace ground_filter {

// ------------------------------------------------------------------------------------ params

void VoxelGroundFilterParams::set(const std::string& name, const std::string& value) {
  if (name == "voxel_size") {
    voxel_size = parseDoubleParam(name, value);
  } else if (name == "flatness_threshold") {
    flatness_threshold = parseDoubleParam(name, value);
  } else if (name == "min_points_per_voxel") {
    min_points_per_voxel = parseIntParam(name, value);
  } else if (name == "height_margin") {
    height_margin = parseDoubleParam(name, value);
  } else if (name == "seed_window") {
    seed_window = parseDoubleParam(name, value);
  } else if (name == "plane_distance") {
    plane_distance = parseDoubleParam(name, value);
  } else if (name == "std_filter") {
    std_filter = parseBoolParam(name, value);
  } else if (name == "std_multiplier") {
    std_multiplier = parseDoubleParam(name, value);
  } else if (name == "local_planes") {
    local_planes = parseBoolParam(name, value);
  } else if (name == "tile_size") {
    tile_size = parseDoubleParam(name, value);
  } else if (name == "max_slope_deg") {
    max_slope_deg = parseDoubleParam(name, value);
  } else if (name == "majority_vote") {
    majority_vote = parseBoolParam(name, value);
  } else if (name == "threads") {
    threads = parseIntParam(name, value);
  } else {
    throw std::invalid_argument(
        "unknown voxel parameter '" + name +
        "' (known: voxel_size, flatness_threshold, min_points_per_voxel, height_margin, seed_window, "
        "plane_distance, std_filter, std_multiplier, local_planes, tile_size, max_slope_deg, "
        "majority_vote, threads)");
  }
}

void VoxelGroundFilterParams::validate() const {
  checkRange("voxel_size", voxel_size, 0.005, 10.0, "m");
  checkRange("flatness_threshold", flatness_threshold, 0.0001, 10.0, "m");
  checkRange("min_points_per_voxel", min_points_per_voxel, 1, 1000, "points");
  checkRange("height_margin", height_margin, 0.01, 100.0, "m");
  checkRange("seed_window", seed_window, 0.01, 100.0, "m");
  checkRange("plane_distance", plane_distance, 0.001, 10.0, "m");
  checkRange("std_multiplier", std_multiplier, 0.1, 10.0, "");
  checkRange("tile_size", tile_size, 0.5, 1000.0, "m");
  checkRange("max_slope_deg", max_slope_deg, 0.0, 89.0, "deg");
  checkRange("threads", threads, 0, 256, "threads");
  if (tile_size < 2.0 * voxel_size) {
    throw std::invalid_argument("parameter 'tile_size' must be at least 2 * voxel_size");
  }
}

// ------------------------------------------------------------------------------------ impl

namespace {

using Clock = std::chrono::steady_clock;

double msSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

int bitsFor(std::uint64_t max_value) {
  int bits = 1;
  while ((max_value >> bits) != 0) ++bits;
  return bits;
}

constexpr int kMaxAxisBits = 21;  // 3 * 21 bits fit one 64-bit key

}  // namespace

struct VoxelGroundFilter::Impl {
  // Per valid point (compacted order).
  std::vector<std::uint32_t> point_index;  // valid slot -> input index
  std::vector<float> px, py, pz;           // coordinates relative to the cloud's min corner
  std::vector<std::uint64_t> keys, keys_tmp;
  std::vector<std::uint32_t> order, order_tmp;  // valid slots sorted by voxel key
  std::vector<std::uint32_t> voxel_of;          // valid slot -> voxel id
  std::vector<std::uint8_t> ground;             // valid slot -> label

  // Per voxel (sorted by key).
  std::vector<std::uint64_t> vkey;
  std::vector<std::uint32_t> vstart;  // CSR into `order`, size V + 1
  std::vector<float> vzmin, vzmax, vxmean, vymean, vzmean;
  std::vector<std::uint8_t> vkept;  // flat and below the height cut
  std::vector<std::int32_t> vsegment;
  std::vector<std::uint32_t> adj_start, adj;  // 26-adjacency CSR
  std::vector<std::uint32_t> vground;         // ground points per voxel
  std::vector<std::uint32_t> queue;

  // Tiles.
  std::vector<std::int32_t> tile_of_voxel;
  std::vector<std::uint32_t> tile_start, tile_voxels;
  std::vector<Plane> tile_plane;
  std::vector<std::uint8_t> tile_state;
  std::vector<double> tile_mu, tile_sigma;

  std::array<std::uint32_t, 2048> hist;
};

VoxelGroundFilter::VoxelGroundFilter(const VoxelGroundFilterParams& params)
    : params_(params), impl_(std::make_unique<Impl>()) {
  params_.validate();
}

VoxelGroundFilter::~VoxelGroundFilter() = default;

namespace {

// LSD radix sort of (key, value) pairs on the low `bits` bits of the key, 11 bits a pass.
void radixSort(std::vector<std::uint64_t>* keys, std::vector<std::uint32_t>* vals,
               std::vector<std::uint64_t>* keys_tmp, std::vector<std::uint32_t>* vals_tmp,
               int bits, std::array<std::uint32_t, 2048>* hist) {
  const std::size_t n = keys->size();
  keys_tmp->resize(n);
  vals_tmp->resize(n);
  for (int shift = 0; shift < bits; shift += 11) {
    hist->fill(0);
    const std::uint64_t* k = keys->data();
    for (std::size_t i = 0; i < n; ++i) ++(*hist)[(k[i] >> shift) & 2047u];
    std::uint32_t sum = 0;
    for (auto& h : *hist) {
      const std::uint32_t c = h;
      h = sum;
      sum += c;
    }
    const std::uint32_t* v = vals->data();
    std::uint64_t* kt = keys_tmp->data();
    std::uint32_t* vt = vals_tmp->data();
    for (std::size_t i = 0; i < n; ++i) {
      const std::uint32_t dst = (*hist)[(k[i] >> shift) & 2047u]++;
      kt[dst] = k[i];
      vt[dst] = v[i];
    }
    keys->swap(*keys_tmp);
    vals->swap(*vals_tmp);
  }
}

}  // namespace

void VoxelGroundFilter::filter(const CloudView& cloud, std::vector<std::uint8_t>* labels,
                               FilterStats* stats) {
  const auto t_start = Clock::now();
  const VoxelGroundFilterParams& p = params_;
  Impl& m = *impl_;
  FilterStats local_stats;
  FilterStats& st = stats ? *stats : local_stats;
  st = FilterStats();
  st.input_points = cloud.size();
  labels->assign(cloud.size(), kNonGround);
  const int threads = p.threads > 0 ? p.threads : omp_get_max_threads();

  // ---- 1. valid points and bounds
  auto t0 = Clock::now();
  const std::size_t n_in = cloud.size();
  m.point_index.clear();
  m.px.clear();
  m.py.clear();
  m.pz.clear();
  float minx = std::numeric_limits<float>::max(), miny = minx, minz = minx;
  float maxx = -minx, maxy = -minx, maxz = -minx;
  for (std::size_t i = 0; i < n_in; ++i) {
    float x, y, z;
    if (!cloud.get(i, &x, &y, &z)) continue;
    m.point_index.push_back(static_cast<std::uint32_t>(i));
    m.px.push_back(x);
    m.py.push_back(y);
    m.pz.push_back(z);
    minx = std::min(minx, x);
    miny = std::min(miny, y);
    minz = std::min(minz, z);
    maxx = std::max(maxx, x);
    maxy = std::max(maxy, y);
    maxz = std::max(maxz, z);
  }
  const std::size_t n = m.point_index.size();
  st.invalid_points = n_in - n;
  if (n == 0) {
    st.total_ms = msSince(t_start);
    return;
  }
  const double vs = p.voxel_size;
  const std::uint64_t nx = static_cast<std::uint64_t>((maxx - minx) / vs) + 1;
  const std::uint64_t ny = static_cast<std::uint64_t>((maxy - miny) / vs) + 1;
  const std::uint64_t nz = static_cast<std::uint64_t>((maxz - minz) / vs) + 1;
  const int bx = bitsFor(nx), by = bitsFor(ny), bz = bitsFor(nz);
  if (bx > kMaxAxisBits || by > kMaxAxisBits || bz > kMaxAxisBits) {
    std::ostringstream os;
    os << "cloud extent " << (maxx - minx) << " x " << (maxy - miny) << " x " << (maxz - minz)
       << " m is too large for voxel_size " << vs << " m (at most " << (1u << kMaxAxisBits)
       << " voxels per axis)";
    throw std::runtime_error(os.str());
  }
  const int shift_y = bz, shift_x = by + bz;
  const std::uint64_t mask_z = (std::uint64_t{1} << bz) - 1;
  const std::uint64_t mask_y = (std::uint64_t{1} << by) - 1;

  // Relative coordinates keep float precision for far-away clouds (UTM, TLS).
  m.keys.resize(n);
  m.order.resize(n);
  const double inv_vs = 1.0 / vs;
#pragma omp parallel for num_threads(threads) schedule(static) if (threads > 1)
  for (std::size_t s = 0; s < n; ++s) {
    m.px[s] -= minx;
    m.py[s] -= miny;
    m.pz[s] -= minz;
    const std::uint64_t ix = std::min<std::uint64_t>(static_cast<std::uint64_t>(m.px[s] * inv_vs), nx - 1);
    const std::uint64_t iy = std::min<std::uint64_t>(static_cast<std::uint64_t>(m.py[s] * inv_vs), ny - 1);
    const std::uint64_t iz = std::min<std::uint64_t>(static_cast<std::uint64_t>(m.pz[s] * inv_vs), nz - 1);
    m.keys[s] = (ix << shift_x) | (iy << shift_y) | iz;
    m.order[s] = static_cast<std::uint32_t>(s);
  }
  st.stage_ms.emplace_back("prepare", msSince(t0));

  // ---- 2. voxels: sort by key, runs become voxels
  t0 = Clock::now();
  radixSort(&m.keys, &m.order, &m.keys_tmp, &m.order_tmp, bx + by + bz, &m.hist);
  m.vkey.clear();
  m.vstart.clear();
  for (std::size_t i = 0; i < n; ++i) {
    if (i == 0 || m.keys[i] != m.keys[i - 1]) {
      m.vkey.push_back(m.keys[i]);
      m.vstart.push_back(static_cast<std::uint32_t>(i));
    }
  }
  const std::size_t nv = m.vkey.size();
  m.vstart.push_back(static_cast<std::uint32_t>(n));
  m.voxel_of.resize(n);
  m.vzmin.resize(nv);
  m.vzmax.resize(nv);
  m.vxmean.resize(nv);
  m.vymean.resize(nv);
  m.vzmean.resize(nv);
  m.vkept.assign(nv, 0);
  std::size_t flat_count = 0;
  double flat_z_sum = 0.0;
  for (std::size_t v = 0; v < nv; ++v) {
    float zmin = std::numeric_limits<float>::max(), zmax = -zmin;
    double xsum = 0.0, ysum = 0.0, zsum = 0.0;
    for (std::uint32_t i = m.vstart[v]; i < m.vstart[v + 1]; ++i) {
      const std::uint32_t s = m.order[i];
      m.voxel_of[s] = static_cast<std::uint32_t>(v);
      zmin = std::min(zmin, m.pz[s]);
      zmax = std::max(zmax, m.pz[s]);
      xsum += m.px[s];
      ysum += m.py[s];
      zsum += m.pz[s];
    }
    const std::uint32_t count = m.vstart[v + 1] - m.vstart[v];
    m.vzmin[v] = zmin;
    m.vzmax[v] = zmax;
    m.vxmean[v] = static_cast<float>(xsum / count);
    m.vymean[v] = static_cast<float>(ysum / count);
    m.vzmean[v] = static_cast<float>(zsum / count);
    // ---- 3. flat voxels (enough points, small height range)
    if (static_cast<int>(count) >= p.min_points_per_voxel && zmax - zmin < p.flatness_threshold) {
      m.vkept[v] = 1;
      ++flat_count;
      flat_z_sum += m.vzmean[v];
    }
  }
  st.stage_ms.emplace_back("voxelize", msSince(t0));

  // ---- 4. 26-adjacency by a monotone sweep over the sorted keys: for each of the 9 (dx, dy)
  // columns a cursor only moves forward, so the whole adjacency costs O(9 V).
  t0 = Clock::now();
  m.adj_start.resize(nv + 1);
  m.adj.clear();
  {
    std::array<std::size_t, 9> cursor;
    cursor.fill(0);
    for (std::size_t v = 0; v < nv; ++v) {
      m.adj_start[v] = static_cast<std::uint32_t>(m.adj.size());
      const std::uint64_t key = m.vkey[v];
      const std::int64_t ix = static_cast<std::int64_t>(key >> shift_x);
      const std::int64_t iy = static_cast<std::int64_t>((key >> shift_y) & mask_y);
      const std::int64_t iz = static_cast<std::int64_t>(key & mask_z);
      int c = 0;
      for (int dx = -1; dx <= 1; ++dx) {
        for (int dy = -1; dy <= 1; ++dy, ++c) {
          const std::int64_t jx = ix + dx, jy = iy + dy;
          if (jx < 0 || jy < 0 || jx >= static_cast<std::int64_t>(nx) ||
              jy >= static_cast<std::int64_t>(ny)) {
            continue;
          }
          const std::uint64_t base = (static_cast<std::uint64_t>(jx) << shift_x) |
                                     (static_cast<std::uint64_t>(jy) << shift_y);
          const std::uint64_t lo = base | static_cast<std::uint64_t>(std::max<std::int64_t>(iz - 1, 0));
          const std::uint64_t hi =
              base | static_cast<std::uint64_t>(std::min<std::int64_t>(iz + 1, nz - 1));
          std::size_t& q = cursor[c];
          while (q < nv && m.vkey[q] < lo) ++q;
          for (std::size_t w = q; w < nv && m.vkey[w] <= hi; ++w) {
            if (w != v) m.adj.push_back(static_cast<std::uint32_t>(w));
          }
        }
      }
    }
    m.adj_start[nv] = static_cast<std::uint32_t>(m.adj.size());
  }
  st.stage_ms.emplace_back("adjacency", msSince(t0));

  // ---- 5. height filter: flat voxels above (mean flat height + margin) are not ground seeds.
  t0 = Clock::now();
  if (flat_count > 0 && !p.local_planes) {
    const double cut = flat_z_sum / flat_count + p.height_margin;
    for (std::size_t v = 0; v < nv; ++v) {
      if (m.vkept[v] && m.vzmean[v] >= cut) m.vkept[v] = 0;
    }
  }

  // ---- 6. region growing over kept flat voxels (26-adjacency); largest segment by points.
  m.vsegment.assign(nv, -1);
  std::int32_t n_segments = 0;
  std::int32_t best_segment = -1;
  std::uint64_t best_points = 0;
  for (std::size_t v0 = 0; v0 < nv; ++v0) {
    if (!m.vkept[v0] || m.vsegment[v0] >= 0) continue;
    const std::int32_t seg = n_segments++;
    std::uint64_t seg_points = 0;
    m.queue.clear();
    m.queue.push_back(static_cast<std::uint32_t>(v0));
    m.vsegment[v0] = seg;
    for (std::size_t qi = 0; qi < m.queue.size(); ++qi) {
      const std::uint32_t v = m.queue[qi];
      seg_points += m.vstart[v + 1] - m.vstart[v];
      for (std::uint32_t a = m.adj_start[v]; a < m.adj_start[v + 1]; ++a) {
        const std::uint32_t w = m.adj[a];
        if (m.vkept[w] && m.vsegment[w] < 0) {
          m.vsegment[w] = seg;
          m.queue.push_back(w);
        }
      }
    }
    if (seg_points > best_points) {
      best_points = seg_points;
      best_segment = seg;
    }
  }
  st.stage_ms.emplace_back("segments", msSince(t0));

  // Mean and standard deviation of the signed plane distances of the points of the voxels
  // [begin, end) for which `take(v)` holds.
  auto residualStats = [&](const Plane& plane, auto take, std::size_t begin, std::size_t end,
                           double* mu, double* sigma) {
    double sum = 0.0, sum2 = 0.0;
    std::size_t cnt = 0;
    for (std::size_t v = begin; v < end; ++v) {
      if (!take(v)) continue;
      for (std::uint32_t i = m.vstart[v]; i < m.vstart[v + 1]; ++i) {
        const std::uint32_t s = m.order[i];
        const double dist = plane.distance(m.px[s], m.py[s], m.pz[s]);
        sum += dist;
        sum2 += dist * dist;
        ++cnt;
      }
    }
    *mu = cnt ? sum / cnt : 0.0;
    *sigma = cnt > 1 ? std::sqrt(std::max(0.0, sum2 / cnt - (*mu) * (*mu))) : 0.0;
  };

  // Local planes: tiles of tile_size are visited breadth-first from the tile holding most of the
  // largest segment. Each tile predicts its plane from the tile that reached it; its seeds are the
  // flat voxels within seed_window of that prediction (the paper's "mean flat height + 1 m"
  // cut, made local so hills are not cut off); the least-squares plane of the seeds is refined
  // once on seeds near it and kept when it is not steeper than max_slope_deg and the seeds span
  // an area, else the prediction is inherited.
  auto fitTilePlanes = [&](const Plane& start_plane, std::int32_t start_segment, std::uint64_t nx,
                           std::uint64_t ny, int shift_x, int shift_y, std::uint64_t mask_y) {
    const std::size_t nv = m.vkey.size();
    std::uint64_t tile_vox = std::max<std::uint64_t>(2, std::llround(p.tile_size / p.voxel_size));
    std::uint64_t ntx = (nx + tile_vox - 1) / tile_vox, nty = (ny + tile_vox - 1) / tile_vox;
    constexpr std::uint64_t kMaxTiles = 1u << 20;  // caps memory for kilometre-wide clouds
    while (ntx * nty > kMaxTiles) {
      tile_vox *= 2;
      ntx = (nx + tile_vox - 1) / tile_vox;
      nty = (ny + tile_vox - 1) / tile_vox;
    }
    const std::size_t nt = ntx * nty;
    m.tile_of_voxel.resize(nv);
    m.tile_start.assign(nt + 1, 0);
    for (std::size_t v = 0; v < nv; ++v) {
      const std::uint64_t ix = m.vkey[v] >> shift_x, iy = (m.vkey[v] >> shift_y) & mask_y;
      const std::int32_t t = static_cast<std::int32_t>((ix / tile_vox) * nty + iy / tile_vox);
      m.tile_of_voxel[v] = t;
      if (m.vkept[v]) ++m.tile_start[t + 1];
    }
    for (std::size_t t = 0; t < nt; ++t) m.tile_start[t + 1] += m.tile_start[t];
    m.tile_voxels.resize(m.tile_start[nt]);
    {
      std::vector<std::uint32_t>& fill = m.queue;  // reused as per-tile write cursors
      fill.assign(m.tile_start.begin(), m.tile_start.end() - 1);
      for (std::size_t v = 0; v < nv; ++v) {
        if (m.vkept[v]) m.tile_voxels[fill[m.tile_of_voxel[v]]++] = static_cast<std::uint32_t>(v);
      }
    }
    // Start tile: most points of the largest segment.
    std::vector<std::uint32_t>& seg_points = m.vground;  // reused scratch
    seg_points.assign(nt, 0);
    for (std::size_t v = 0; v < nv; ++v) {
      if (m.vsegment[v] == start_segment) {
        seg_points[m.tile_of_voxel[v]] += m.vstart[v + 1] - m.vstart[v];
      }
    }
    const std::size_t start =
        std::max_element(seg_points.begin(), seg_points.end()) - seg_points.begin();

    m.tile_plane.assign(nt, start_plane);
    m.tile_mu.assign(nt, 0.0);
    m.tile_sigma.assign(nt, 0.0);
    m.tile_state.assign(nt, 0);
    const double min_nz = std::cos(p.max_slope_deg * M_PI / 180.0);
    const double refine_window = 2.0 * p.plane_distance;
    const double min_spread2 = 0.25 * p.tile_size * 0.25 * p.tile_size / 4.0;
    m.queue.clear();
    m.queue.push_back(static_cast<std::uint32_t>(start));
    m.tile_state[start] = 1;
    for (std::size_t qi = 0; qi < m.queue.size(); ++qi) {
      const std::uint32_t t = m.queue[qi];
      const Plane predicted = m.tile_plane[t];
      auto seedFit = [&](const Plane& ref, double window, Plane* out, Eigen::Vector3d* ev) {
        PlaneAccumulator acc;
        for (std::uint32_t k = m.tile_start[t]; k < m.tile_start[t + 1]; ++k) {
          const std::uint32_t v = m.tile_voxels[k];
          if (std::abs(ref.distance(m.vxmean[v], m.vymean[v], m.vzmean[v])) < window) {
            acc.add(m.vxmean[v], m.vymean[v], m.vzmean[v], m.vstart[v + 1] - m.vstart[v]);
          }
        }
        return acc.fit(out, ev);
      };
      // Shrinking windows make the fit robust to flat non-ground seeds (car hoods, low walls).
      Plane fine = predicted;
      Eigen::Vector3d ev;
      bool ok = true;
      double window = p.seed_window;
      for (int pass = 0; ok; ++pass) {
        Plane next;
        ok = seedFit(fine, window, &next, &ev);
        if (ok) fine = next;
        if (window <= refine_window) break;
        window = std::max(refine_window, window * 0.5);
      }
      if (ok && fine.normal.z() >= min_nz && ev(1) >= min_spread2) {
        m.tile_plane[t] = fine;
        // Residual statistics of the seed points, for the mean +- std band.
        double sum = 0.0, sum2 = 0.0;
        std::size_t cnt = 0;
        for (std::uint32_t k = m.tile_start[t]; k < m.tile_start[t + 1]; ++k) {
          const std::uint32_t v = m.tile_voxels[k];
          if (std::abs(fine.distance(m.vxmean[v], m.vymean[v], m.vzmean[v])) >= refine_window) continue;
          for (std::uint32_t i = m.vstart[v]; i < m.vstart[v + 1]; ++i) {
            const std::uint32_t s = m.order[i];
            const double dist = fine.distance(m.px[s], m.py[s], m.pz[s]);
            sum += dist;
            sum2 += dist * dist;
            ++cnt;
          }
        }
        m.tile_mu[t] = cnt ? sum / cnt : 0.0;
        m.tile_sigma[t] = cnt > 1 ? std::sqrt(std::max(0.0, sum2 / cnt - m.tile_mu[t] * m.tile_mu[t])) : 0.0;
      }
      const std::int64_t tx = t / nty, ty = t % nty;
      for (int dx = -1; dx <= 1; ++dx) {
        for (int dy = -1; dy <= 1; ++dy) {
          const std::int64_t ux = tx + dx, uy = ty + dy;
          if (ux < 0 || uy < 0 || ux >= static_cast<std::int64_t>(ntx) ||
              uy >= static_cast<std::int64_t>(nty)) {
            continue;
          }
          const std::size_t u = static_cast<std::size_t>(ux * nty + uy);
          if (m.tile_state[u]) continue;
          m.tile_state[u] = 1;
          m.tile_plane[u] = m.tile_plane[t];
          m.tile_mu[u] = m.tile_mu[t];
          m.tile_sigma[u] = m.tile_sigma[t];
          m.queue.push_back(static_cast<std::uint32_t>(u));
        }
      }
    }
  };

  // ---- 7. plane(s) and per-point distance test
  t0 = Clock::now();
  m.ground.assign(n, 0);
  if (best_segment >= 0) {
    // Paper: least-squares plane of the largest segment.
    PlaneAccumulator acc;
    for (std::size_t v = 0; v < nv; ++v) {
      if (m.vsegment[v] != best_segment) continue;
      for (std::uint32_t i = m.vstart[v]; i < m.vstart[v + 1]; ++i) {
        const std::uint32_t s = m.order[i];
        acc.add(m.px[s], m.py[s], m.pz[s]);
      }
    }
    Plane global_plane;
    if (acc.fit(&global_plane)) {
      if (p.local_planes) {
        fitTilePlanes(global_plane, best_segment, nx, ny, shift_x, shift_y, mask_y);
      } else {
        m.tile_of_voxel.assign(nv, 0);
        m.tile_plane.assign(1, global_plane);
        m.tile_mu.assign(1, 0.0);
        m.tile_sigma.assign(1, 0.0);
        residualStats(global_plane, [&](std::size_t v) { return m.vsegment[v] == best_segment; },
                      0, nv, &m.tile_mu[0], &m.tile_sigma[0]);
      }
      const double band_k = p.std_multiplier;
#pragma omp parallel for num_threads(threads) schedule(static) if (threads > 1)
      for (std::size_t s = 0; s < n; ++s) {
        const std::int32_t t = m.tile_of_voxel[m.voxel_of[s]];
        const double dist = m.tile_plane[t].distance(m.px[s], m.py[s], m.pz[s]);
        bool g = std::abs(dist) < p.plane_distance;
        if (g && p.std_filter && m.tile_sigma[t] > 0.0) {
          g = std::abs(dist - m.tile_mu[t]) <= band_k * m.tile_sigma[t];
        }
        m.ground[s] = g ? 1 : 0;
      }
    }
  }
  st.stage_ms.emplace_back("planes", msSince(t0));

  // ---- 8. final 26-neighbourhood majority vote per voxel (point-weighted).
  t0 = Clock::now();
  if (p.majority_vote) {
    m.vground.assign(nv, 0);
    for (std::size_t s = 0; s < n; ++s) m.vground[m.voxel_of[s]] += m.ground[s];
    for (std::size_t v = 0; v < nv; ++v) {
      std::uint64_t g = m.vground[v];
      std::uint64_t tot = m.vstart[v + 1] - m.vstart[v];
      for (std::uint32_t a = m.adj_start[v]; a < m.adj_start[v + 1]; ++a) {
        const std::uint32_t w = m.adj[a];
        g += m.vground[w];
        tot += m.vstart[w + 1] - m.vstart[w];
      }
      if (2 * g == tot) continue;  // tie: keep the per-point labels
      const std::uint8_t label = 2 * g > tot ? 1 : 0;
      for (std::uint32_t i = m.vstart[v]; i < m.vstart[v + 1]; ++i) m.ground[m.order[i]] = label;
    }
  }
  st.stage_ms.emplace_back("vote", msSince(t0));

  std::size_t ground_count = 0;
  for (std::size_t s = 0; s < n; ++s) {
    if (m.ground[s]) {
      (*labels)[m.point_index[s]] = kGround;
      ++ground_count;
    }
  }
  st.ground_points = ground_count;
  st.total_ms = msSince(t_start);
}

}  // namespace ground_filter
