#include "ground_filter/voxel_ground_filter.h"

#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>

#include "airborne/airborne_mode.h"
#include "airborne/scan_type.h"
#include "common/densest_centre.h"
#include "common/ground_tilt.h"
#include "common/threads_timing.h"
#include "ground_filter/param_parse.h"
#include "ground_filter/working_volume_params.h"
#include "voxel/classify.h"
#include "voxel/ground_model.h"
#include "voxel/segments.h"
#include "voxel/vegetation.h"
#include "voxel/vote.h"
#include "voxel/voxel_grid.h"
#include "voxel/voxelize.h"
#include "voxel/worker_pool.h"

namespace ground_filter {

namespace {

// Below this share of the points under the origin's height the origin is no sensor above the
// ground (sensor frames: 7 % and more, the OS-128 dev scan whose origin lies on the ground; a
// map frame's origin behind the scan: 0 %).
constexpr double kSensorBelowShare = 0.02;
// Where it is none, the start segment's plane must pass below a point this far above the ground
// at the densest area's centre: the ground under a sensor there, not a crown's or a roof's
// underside [m]. The middle of the 1-2 m range where no map-frame placement of the sensor sweep
// loses more than 3 points (0.75 and 2.5 m lose 26; docs/voxel_method.md).
constexpr float kSensorAboveGround = 1.5f;
// A densest cell (scan_type's sample) this far from the origin: the origin is no spinning
// sensor either, whatever lies below it (a map frame's origin above the ground under the scan)
// [m]; a sensor's densest cell holds it or lies next to it, at most about 10 m away.
constexpr double kFarDensest = 20.0;

/// Writes the labels `gr` (by sorted position) in input order: sorted position -> slot (low bits
/// of a packed key, or `order`) -> input index (identity when every point is valid); returns the
/// ground count.
std::size_t labelsToInputOrder(const voxel::VoxelGrid& g, const std::uint8_t* gr, std::size_t n,
                               std::vector<std::uint8_t>* labels) {
  std::size_t ground_count = 0;
  const std::uint64_t* keys = g.keys.data();
  const std::uint64_t slot_mask = (std::uint64_t{1} << g.slot_bits) - 1;
  const std::uint32_t* ord = g.order.data();
  const std::uint32_t* idx = g.point_index.data();
  std::uint8_t* out = labels->data();
  if (g.packed && g.all_valid) {  // the common case, without the layout tests per point
    for (std::size_t i = 0; i < n; ++i) {
      out[keys[i] & slot_mask] = gr[i];
      ground_count += gr[i];
    }
  } else {
    for (std::size_t i = 0; i < n; ++i) {
      const std::uint32_t slot =
          g.packed ? static_cast<std::uint32_t>(keys[i] & slot_mask) : ord[i];
      out[g.all_valid ? slot : idx[slot]] = gr[i];
      ground_count += gr[i];
    }
  }
  return ground_count;
}

}  // namespace

// ------------------------------------------------------------------------------------ filter

// The stages (src/core/voxel/), each holding only its own scratch buffers, and the results they
// pass on (kept, so a repeated scan allocates nothing).
struct VoxelGroundFilter::Impl {
  // Stages, in run() order.
  voxel::Voxelizer voxelizer;
  voxel::Segmenter segmenter;
  voxel::GroundModel model;
  voxel::Classifier classifier;
  voxel::Voter voter;
  voxel::VegetationRule vegetation;  // veg_filter only
  // Results: written by one stage, read (or rewritten) by the later ones.
  voxel::VoxelGrid grid;                  // Voxelizer: points, voxels, columns, flat, seeds
  voxel::CellGrid cells;                  // Voxelizer: cells holding voxels
  voxel::SegmentResult segments;          // Segmenter: segment per flat voxel, ground plane
  voxel::GroundModelResult ground_model;  // GroundModel: plane per cell
  voxel::ClassifyResult classified;       // Classifier: labels (vote, vegetation rewrite them)
  voxel::WorkerPool pool;                 // threads > 1 only
  MorphGround morph;                      // airborne scans only
  ScanTypeSwitch scan;                    // scan_type: this scan's mode
  DensestCentre centre;                   // the sensor where the origin is none (a map frame)
  GroundTiltEstimator tilt;               // 0: a sensor mounted tilted (level_tilt)
  std::vector<float> levelled_xyz;        // 0: the scan turned onto its ground, packed xyz
  CloudView levelled_view;                // 0: a view of it
  explicit Impl(const VoxelGroundFilterParams& p) : scan(p.scan_type, p.morph_ground) {}
  // 0: `cloud`, or where its ground leans level_tilt or more (a single scan: the sensor at the
  // origin), the scan turned about the sensor onto that ground; a note says so (stats only).
  const CloudView& levelled(const VoxelGroundFilterParams& p, const ScanDecision& decision,
                            const CloudView& cloud, FilterStats* stats);
};

const CloudView& VoxelGroundFilter::Impl::levelled(const VoxelGroundFilterParams& p,
                                                   const ScanDecision& decision,
                                                   const CloudView& cloud, FilterStats* stats) {
  const float* o = scan.origin();
  if (!GroundTiltEstimator::applies(p.level_tilt, decision.registered, o)) return cloud;
  const auto t0 = Clock::now();
  const GroundTilt t = tilt.estimate(cloud, o);
  const bool turn = t.turns(p.level_tilt);
  if (turn) levelled_view = GroundTiltEstimator::level(cloud, o, t, &levelled_xyz);
  if (stats) {
    if (turn) GroundTiltEstimator::appendTurnNote(t.tilt_deg, p.level_tilt, &stats->note);
    stats->stage_ms.emplace_back("level", msSince(t0));
  }
  return turn ? levelled_view : cloud;
}

VoxelGroundFilter::VoxelGroundFilter(const VoxelGroundFilterParams& params) : params_(params) {
  params_.validate();
  impl_ = std::make_unique<Impl>(params_);
}

VoxelGroundFilter::~VoxelGroundFilter() = default;

void VoxelGroundFilter::filter(const CloudView& cloud, std::vector<std::uint8_t>* labels,
                               FilterStats* stats) {
  run(cloud, nullptr, labels, stats);
}

bool VoxelGroundFilter::filterInside(const CloudView& cloud, const WorkingVolume& volume,
                                     std::vector<std::uint8_t>* labels, FilterStats* stats) {
  impl_->scan.setOrigin(volume.origin[0], volume.origin[1], volume.origin[2]);
  return impl_->scan.pin(cloud).type != ScanType::kAirborne && run(cloud, &volume, labels, stats);
}

void VoxelGroundFilter::setSensorOrigin(float x, float y, float z) {
  impl_->scan.setOrigin(x, y, z);
}

bool VoxelGroundFilter::noSensorAtOrigin(const CloudView& cloud) {
  const ScanDecision& d = impl_->scan.pin(cloud);
  return d.type == ScanType::kAirborne || d.registered;
}

bool VoxelGroundFilter::run(const CloudView& cloud, const WorkingVolume* volume,
                            std::vector<std::uint8_t>* labels, FilterStats* stats) {
  const auto t_start = Clock::now();
  Impl& m = *impl_;
  voxel::VoxelGrid& g = m.grid;
  // Stage timings only when asked for; a reused FilterStats keeps its capacity (no allocation
  // after the first scan, see the docs).
  FilterStats local_stats;
  FilterStats& st = stats ? *stats : local_stats;
  st.stage_ms.clear();
  st.backend.clear();
  st.note.clear();
  st.invalid_points = st.ground_points = 0;
  st.total_ms = 0.0;
  st.input_points = cloud.size();
  auto stage = [&](const char* name, Clock::time_point t0) {
    if (stats) st.stage_ms.emplace_back(name, msSince(t0));
  };
  labels->assign(cloud.size(), kNonGround);
  const VoxelGroundFilterParams& p = params_;
  const int threads = resolveThreads(p.threads);
  const ScanDecision& scan = m.scan.decide(cloud);
  if (stats) {  // reserved once: reused stats allocate nothing
    st.scan_type = scanTypeName(scan.type);
    st.scan_reason.reserve(ScanTypeClassifier::kReasonRoom);
    st.scan_reason = scan.reason;
  }
  if (scan.type == ScanType::kAirborne) {  // the morphological surface replaces steps 1-8
    runAirborneMode(cloud, airborneSettings(p), &m.morph, t_start, stats != nullptr, labels, &st);
    return true;
  }

  // ---- 0. a sensor mounted tilted (no gravity frame): the scan turned onto its ground, whose
  //      voxels would not be flat (a ball about the sensor, `volume`, turns onto itself)
  const CloudView& in = m.levelled(p, scan, cloud, stats ? &st : nullptr);

  // ---- 1. valid points, bounds (inside `volume`?), voxel keys
  auto t0 = Clock::now();
  const std::size_t n = m.voxelizer.prepare(in, p.voxel_size, threads, &m.pool, volume, &g);
  if (n == voxel::Voxelizer::kOutside) return false;
  st.invalid_points = cloud.size() - n;
  stage("prepare", t0);
  if (n == 0) {
    st.total_ms = msSince(t_start);
    return true;
  }
  m.cells.setup(p, g.nx, g.ny);

  // ---- 2. voxels (sorted keys, runs), 3. flat voxels and seed candidates
  t0 = Clock::now();
  m.voxelizer.build(p, threads, &m.pool, &g, &m.cells);
  stage("voxelize", t0);
  if (g.flat.size() == 0 && n >= ScanTypeClassifier::kMinPoints) {
    // Not one voxel holds min_points_per_voxel points: the cloud is sampled more coarsely than
    // voxel_size (a map thinned to an even grid), so no ground model can grow. The
    // morphological surface needs no density: it labels the scan instead of nothing.
    runAirborneMode(cloud, airborneSettings(p), &m.morph, t_start, stats != nullptr, labels, &st);
    if (stats) st.note = "no voxel holds min_points_per_voxel points: the morphological surface";
    return true;
  }

  // ---- 4. height filter, 5. region growing, largest segment
  t0 = Clock::now();
  voxel::SegmentResult& seg = m.segments;
  m.segmenter.run(p, &g, &seg);
  stage("segments", t0);

  // ---- 6. plane of the largest segment (paper), local ground model
  t0 = Clock::now();
  const float* origin = m.scan.origin();  // NaN: none (the paper mode's normalised segments)
  float sensor[3] = {origin[0], origin[1], origin[2]};
  bool below_sensor = !scan.registered && std::isfinite(origin[0]) && std::isfinite(origin[1]) &&
                      std::isfinite(origin[2]);
  if (below_sensor && (scan.below_share < kSensorBelowShare || scan.densest_offset > kFarDensest)) {
    // Almost no point below the origin, or the points densest far from it: no sensor above the
    // ground there (a map frame's origin beside the scan), where "below the sensor" would take
    // a plane extrapolated under it. A spinning sensor sits over the densest area's centre,
    // kSensorAboveGround above its ground.
    below_sensor = m.centre.find(in, sensor);
    sensor[2] += kSensorAboveGround;
  }
  m.segmenter.globalPlane(p, g, below_sensor ? sensor : nullptr, &seg);
  const bool have_plane = seg.have_plane;
  if (have_plane) {
    if (p.local_planes) {
      m.model.grow(p, g, m.cells, seg, &m.ground_model);
    } else {
      m.model.setGlobal(seg, &m.ground_model);
    }
  }
  stage("ground_model", t0);

  // ---- 7. per-point distance to the (cell) plane, optional mean +- std band
  t0 = Clock::now();
  voxel::ClassifyResult& cls = m.classified;
  if (have_plane) {
    m.classifier.run(p, g, m.cells, m.ground_model, seg, threads, &m.pool, &cls);
  } else {
    cls.ground.assign(n, 0);
  }
  stage("classify", t0);

  // ---- 8. final 26-neighbourhood majority vote per voxel (point-weighted)
  t0 = Clock::now();
  if (p.majority_vote && have_plane) m.voter.run(g, threads, &m.pool, &cls);
  stage("vote", t0);

  // ---- 9. (added, veg_filter) ground points under porous clutter become non-ground
  if (p.veg_filter && have_plane) {
    t0 = Clock::now();
    m.vegetation.run(p, g, m.ground_model, threads, &m.pool, &cls);
    stage("vegetation", t0);
  }

  const std::size_t ground_count = labelsToInputOrder(g, cls.ground.data(), n, labels);
  st.ground_points = ground_count;
  st.total_ms = msSince(t_start);
  return true;
}

}  // namespace ground_filter
