#include "ground_filter/voxel_ground_filter.h"

#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>

#include "airborne/airborne_mode.h"
#include "airborne/origin_view.h"
#include "airborne/scan_type.h"
#include "common/densest_centre.h"
#include "common/ground_tilt.h"
#include "common/scan_lines.h"
#include "common/threads_timing.h"
#include "ground_filter/param_parse.h"
#include "ground_filter/working_volume_params.h"
#include "voxel/classify.h"
#include "voxel/ground_model.h"
#include "voxel/line_walls.h"
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
// Fewer flat seed voxels than this share of the seed voxels: the scan is too sparse for its
// voxels (scans of the dev data and the generated kinds: 0.15-0.71; sparse sensors 3-4 m up
// whose ground starts 12-20 m out: 0.001-0.07), so they are made two, then three times as
// large (kMaxCoarser steps: 0.1 -> 0.2 -> 0.3 m; 0.4 m loses 1.3 points on KITTI thinned by a
// 0.3 m VoxelGrid, whose flat share at 0.2 m is 0.09).
constexpr double kMinFlatSeeds = 0.1;
constexpr int kMaxCoarser = 2;

void appendCoarserNote(double voxel_size, std::string* note) {
  char text[160];
  std::snprintf(text, sizeof text,
                "%sfew seed voxels flat (a sparse scan): voxel_size %.2f m for this scan",
                note->empty() ? "" : "; ", voxel_size);
  note->append(text);
}

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
  voxel::LineWalls line_walls;       // a sparse spinning sensor's lowest line on a wall
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
  OriginView origin_view;                 // a side view's origin: one scan's sensor after all?
  VoxelGroundFilterParams coarse;         // 2: params_ with a coarser voxel_size
  GroundTiltEstimator tilt;               // 0: a sensor mounted tilted (level_tilt)
  std::vector<float> levelled_xyz;        // 0: the scan turned onto its ground, packed xyz
  CloudView levelled_view;                // 0: a view of it
  StreamScanLines lines;                  // 10: a sparse spinning sensor's scan lines
  explicit Impl(const VoxelGroundFilterParams& p) : scan(p.scan_type, p.morph_ground), coarse(p) {}
  // 0: `cloud`, or where its ground leans level_tilt or more (a single scan: the sensor at the
  // origin), the scan turned about the sensor onto that ground; a note says so (stats only).
  const CloudView& levelled(const VoxelGroundFilterParams& p, const ScanDecision& decision,
                            const CloudView& cloud, FilterStats* stats);
  // 2b: `p`, or where the scan is too sparse for its voxels, `coarse` with the voxels that
  // steps 1-3 were run again with (stage times and a note into `stats` where given).
  const VoxelGroundFilterParams& coarser(const VoxelGroundFilterParams& p, const CloudView& in,
                                         const WorkingVolume* volume, int threads,
                                         FilterStats* stats);
  // 10: the lowest scan line on a wall, seen from the sensor whose lines `cloud` shows around
  // the origin (StreamScanLines; nothing where the origin is not finite), relabelled in
  // `classified`.
  void lineWalls(const CloudView& cloud);
  // 5: the sensor the start segment must pass below (written to `sensor`), or nullptr.
  const float* startSensor(const ScanDecision& decision, const CloudView& in, float sensor[3]);
};

const VoxelGroundFilterParams& VoxelGroundFilter::Impl::coarser(const VoxelGroundFilterParams& p,
                                                                const CloudView& in,
                                                                const WorkingVolume* volume,
                                                                int threads, FilterStats* stats) {
  // Steps 1-3 again with voxels two, then three times as large where the scan is sampled too
  // sparsely for them: hardly a seed voxel holds the two points that the flatness test needs,
  // so the ground forms no segment to start from (a 16-beam sensor 3 m up sees the ground from
  // 8-20 m out, its points 10-25 cm apart along a ring).
  const VoxelGroundFilterParams* q = &p;
  voxel::VoxelGrid& g = grid;
  for (int k = 0; k < kMaxCoarser && p.local_planes && g.seeds.size() > 0 &&
                  static_cast<double>(g.flat.size()) < kMinFlatSeeds * g.seeds.size();
       ++k) {
    const auto t0 = Clock::now();
    coarse.voxel_size = p.voxel_size * (k + 2);  // a copy of p made once: no allocation
    q = &coarse;
    voxelizer.prepare(in, q->voxel_size, threads, &pool, volume, &g);
    cells.setup(*q, g.nx, g.ny);
    voxelizer.build(*q, threads, &pool, &g, &cells);
    if (stats) {
      stats->stage_ms.emplace_back("coarser_voxels", msSince(t0));  // short: no allocation
      appendCoarserNote(q->voxel_size, &stats->note);
    }
  }
  return *q;
}

const float* VoxelGroundFilter::Impl::startSensor(const ScanDecision& decision, const CloudView& in,
                                                  float sensor[3]) {
  const float* origin = scan.origin();  // NaN: none (the paper mode's normalised segments)
  for (int a = 0; a < 3; ++a) sensor[a] = origin[a];
  bool below_sensor =
      std::isfinite(origin[0]) && std::isfinite(origin[1]) && std::isfinite(origin[2]);
  // A side view read from the density alone (rule 4) is one scan all the same where its origin
  // hides almost nothing (the normal method's plane rule asks the same): a sparse sensor high
  // on a truck, whose ground starts 8-12 m out, leaves its cells as even as a merged cloud's;
  // without the sensor, the largest segment may start the model on a roof or a wall's line.
  if (below_sensor && decision.registered) {
    below_sensor =
        decision.side_view && origin_view.streamShare(in, origin) < OriginView::kHiddenCut;
  }
  if (below_sensor &&
      (decision.below_share < kSensorBelowShare || decision.densest_offset > kFarDensest)) {
    // Almost no point below the origin, or the points densest far from it: no sensor above the
    // ground there (a map frame's origin beside the scan), where "below the sensor" would take
    // a plane extrapolated under it. A spinning sensor sits over the densest area's centre,
    // kSensorAboveGround above its ground.
    below_sensor = centre.find(in, sensor);
    sensor[2] += kSensorAboveGround;
  }
  return below_sensor ? sensor : nullptr;
}

void VoxelGroundFilter::Impl::lineWalls(const CloudView& cloud) {
  const float* o = scan.origin();
  if (!(std::isfinite(o[0]) && std::isfinite(o[1]) && std::isfinite(o[2]))) return;
  const ScanLines& l = lines.of(cloud, o);
  float sensor[3];
  if (l.sensor(o, sensor)) line_walls.run(grid, sensor, l.line_deg, &classified);
}

const CloudView& VoxelGroundFilter::Impl::levelled(const VoxelGroundFilterParams& p,
                                                   const ScanDecision& decision,
                                                   const CloudView& cloud, FilterStats* stats) {
  const float* o = scan.origin();
  if (!GroundTiltEstimator::applies(p.level_tilt, decision.registered, o)) return cloud;
  const auto t0 = Clock::now();
  const GroundTilt t = tilt.estimate(cloud, o, p.level_tilt);
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
  st.threads = threads;
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
  // ---- 2b. the same with coarser voxels where the scan is too sparse for them
  const VoxelGroundFilterParams& pv = m.coarser(p, in, volume, threads, stats ? &st : nullptr);
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
  m.segmenter.run(pv, &g, &seg);
  stage("segments", t0);

  // ---- 6. plane of the largest segment (paper), local ground model
  t0 = Clock::now();
  float sensor[3];
  m.segmenter.globalPlane(pv, g, m.startSensor(scan, in, sensor), &seg);
  const bool have_plane = seg.have_plane;
  if (have_plane) {
    if (p.local_planes) {
      m.model.grow(pv, g, m.cells, seg, &m.ground_model);
    } else {
      m.model.setGlobal(seg, &m.ground_model);
    }
  }
  stage("ground_model", t0);

  // ---- 7. per-point distance to the (cell) plane, optional mean +- std band
  t0 = Clock::now();
  voxel::ClassifyResult& cls = m.classified;
  if (have_plane) {
    m.classifier.run(pv, g, m.cells, m.ground_model, seg, threads, &m.pool, &cls);
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
    m.vegetation.run(pv, g, m.ground_model, threads, &m.pool, &cls);
    stage("vegetation", t0);
  }

  // ---- 10. (added) a sparse spinning sensor's lowest scan line on a wall or a car's side, seen
  //      from the sensor: the origin of a single scan (or where its lines show it, a base frame)
  if (p.local_planes && have_plane && !scan.registered) {
    t0 = Clock::now();
    m.lineWalls(in);
    stage("line_walls", t0);
  }

  const std::size_t ground_count = labelsToInputOrder(g, cls.ground.data(), n, labels);
  st.ground_points = ground_count;
  st.total_ms = msSince(t_start);
  return true;
}

}  // namespace ground_filter
