#include "ground_filter/normal_ground_filter.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "airborne/airborne_mode.h"
#include "airborne/origin_view.h"
#include "airborne/scan_type.h"
#include "common/ground_tilt.h"
#include "common/scan_lines.h"
#include "common/side_task.h"
#include "common/threads_timing.h"
#include "knn/knn_backend.h"
#include "normal/cpu_gpu_common.h"
#include "normal/filter_executor.h"
#include "normal/lattice.h"
#include "normal/line_walls.h"
#include "normal/local_ground.h"
#include "normal/neighborhoods.h"
#include "normal/normal_settings.h"
#include "normal/order.h"
#include "normal/plane.h"
#include "normal/sample.h"
#include "normal/scatter_labels.h"
#include "normal/stage_times.h"
#include "normal/vegetation.h"
#include "normal/vote.h"

namespace ground_filter {

// ------------------------------------------------------------------------------------ filter
// One file per stage under normal/; this file only wires them together. A stage object holds
// only its scratch memory; what a stage produces goes into the named results below, which the
// next stages take as arguments (all memory kept between scans: no allocation per scan).

struct NormalGroundFilter::Impl {
  std::unique_ptr<KnnBackend> search;              // the CPU stages' neighbour search
  std::unique_ptr<NormalFilterExecutor> executor;  // whole filter elsewhere (GPU), or null
  // Settings derived from the params once (normal_settings.h).
  double min_abs_nz = 0.0;
  // Stages (scratch memory only).
  normal::OrderStage order;
  normal::SampleStage sample;  // sample_stride > 1 only
  normal::NeighborhoodStage neighborhoods;
  normal::VoteStage vote;
  normal::PlaneStage plane;
  normal::LocalGroundStage local_ground;    // local_ground_min > 0 only
  normal::VegetationStage vegetation;       // veg_filter only
  normal::LineWalls line_walls;             // 7: sparse scan lines only
  MorphGround morph;                        // airborne scans only
  ScanTypeSwitch scan;                      // scan_type: this scan's mode
  normal::LatticeMeter lattice;             // coordinates on a coarse lattice (0.)
  double lattice_var[3] = {0.0, 0.0, 0.0};  // this scan's: step^2 / 12 per axis [m^2]
  bool on_lattice = false;
  GroundTiltEstimator tilt;         // 0a: a sensor mounted tilted (level_tilt)
  GroundTilt tilt_found;            // 0a: this scan's ground around the sensor
  double tilt_ms = 0.0;             // 0a: the time its estimate took
  SideTask side;                    // 0a beside the executor (executeBeside())
  std::vector<float> levelled_xyz;  // 0a: the scan turned onto its ground, packed xyz
  CloudView levelled_view;          // 0a: a view of it
  // Per-scan results, in stage order.
  normal::OrderedPoints ordered;  // 1: valid points in column order
  NeighborLists lists;            // 2: neighbour lists of one segment
  std::vector<std::uint8_t> candidate, voted,
      ground;                  // 3 (sample_stride 1), 4, 5: per ordered point
  std::vector<float> heights;  // 5: above the tile plane, veg_filter only
  normal::StageTimes times;    // per scan, memory kept
  FilterStats own_stats;       // filled when the caller passes none
  // 1a: the scan lines, kept for the next scans of the same sensor (scan_lines.h).
  StreamScanLines scan_lines;
  Impl(const NormalGroundFilterParams& p, std::unique_ptr<KnnBackend> backend,
       std::unique_ptr<NormalFilterExecutor> exec)
      : search(std::move(backend)),
        executor(std::move(exec)),
        min_abs_nz(normal::minAbsNormalZ(p)),
        scan(p.scan_type, p.morph_ground) {
    if (!search) throw std::invalid_argument("NormalGroundFilter: null neighbour backend");
    // A GPU backend keeps the lists in GPU memory; PCA and vote counts then run there. The
    // local-ground stage needs them on the host. (A GPU search serves the CPU stages only where
    // the whole filter has no GPU executor: with one, the stages search on the kd-tree.)
    const bool host_lists = p.local_ground_min > 0 && search->name() == "gpu";
    if (NeighborListStore* kept = search->listStore()) kept->keepLists(!host_lists);
  }
  // The sensor's x, y, z where the scan has one at its origin, else null: no ground plane may
  // pass above it (normal/plane.h). Asked of the cloud where auto decided (origin_view.h,
  // stage "view"): none where many points lie behind nearer ones seen from the origin (merged
  // stations or sweeps), one where few do (also in a cloud read as registered by its side
  // view); a note says where that overrules the scan type.
  const double* sensorOf(const ScanDecision& decision, const CloudView& cloud, const double from[3],
                         FilterStats* st);
  double sensor_xyz[3] = {0.0, 0.0, 0.0};
  OriginView origin_view;
  // Steps 1b-4 on every segment of the `n` ordered points with `stride`; returns the
  // candidates among the sampled points, their number in *sampled, adds the vote's time to
  // *vote_ms.
  std::size_t normalsAndVotes(const NormalGroundFilterParams& p, std::size_t n, int stride,
                              int threads, std::size_t* sampled, double* vote_ms);
  // 0a applies: level_tilt > 0 and a single scan with its sensor at a finite origin.
  bool checksTilt(const NormalGroundFilterParams& p, const ScanDecision& decision) const;
  // 0a: tilt_found and tilt_ms of `cloud`.
  void estimateTilt(const CloudView& cloud, double level_tilt);
  // 0a: tilt_found leans level_tilt or more.
  bool turns(const NormalGroundFilterParams& p) const { return tilt_found.turns(p.level_tilt); }
  // 0a: `cloud` turned about the sensor onto tilt_found's ground (levelled_view); a note says so.
  const CloudView& levelTo(const NormalGroundFilterParams& p, const CloudView& cloud,
                           FilterStats* st);
  // What the stages after 0a take from 1a and the sensor.
  struct Prepared {
    int stride = 1;                    // 1a: the sample stride the scan lines ask for
    const ScanLines* lines = nullptr;  // 1a: the scan lines measured, or null
    const double* sensor = nullptr;    // the sensor's x, y, z, or null
  };
  // 1a, the sensor and 0 on `in`, then the executor where there is one: true when it labelled
  // the scan.
  bool prepareAndExecute(const NormalGroundFilterParams& p, const ScanDecision& decision,
                         const CloudView& in, std::vector<std::uint8_t>* labels, FilterStats* st,
                         Prepared* prep);
  // 0a beside the executor: the scan as it comes runs on the executor while a thread of its own
  // estimates the tilt (its check then costs the host's waits on the device, not their sum).
  // Where the scan turns, that run is dropped (stats, notes and the scan lines kept back as
  // they were) and false returned: the caller runs the turned scan.
  bool executeBeside(const NormalGroundFilterParams& p, const ScanDecision& decision,
                     const CloudView& cloud, std::vector<std::uint8_t>* labels, FilterStats* st,
                     Prepared* prep);
  // 7: the lowest scan line on a wall, seen from the sensor whose sparse lines 1a measured
  // (none: nothing done), relabelled in `labels` (per point of `in`; `ordered` holds its
  // points in column order, or is sorted here where `sorted` is false: the executor's scan);
  // stage "line_walls".
  void lineWalls(const NormalGroundFilterParams& p, const CloudView& in, const Prepared& prep,
                 bool sorted, int threads, std::vector<std::uint8_t>* labels, FilterStats* st);
  // on_lattice (returned) and lattice_var of `cloud`; a note names the steps.
  bool measureLattice(const CloudView& cloud, std::string* note);
};

namespace {

// "sample_stride A -> B: ..." onto *note, appended in place (a reused FilterStats allocates
// nothing).
void appendStrideNote(const NormalGroundFilterParams& p, int stride, const ScanLines& lines,
                      std::string* note) {
  char text[280], above[96] = "";
  if (lines.from[0] != 0.0 || lines.from[1] != 0.0) {
    std::snprintf(above, sizeof above, " (seen from %.1f, %.1f, %.2f m off the origin)",
                  lines.from[0], lines.from[1], lines.from[2]);
  } else if (lines.from[2] > 0.0) {
    std::snprintf(above, sizeof above, " (seen from %.2f m above the origin)", lines.from[2]);
  }
  std::snprintf(text, sizeof text,
                "%ssample_stride %d -> %d: scan lines %.2f deg apart, %.3f deg between the points "
                "of a line%s (max_line_ratio %g)",
                note->empty() ? "" : "; ", p.sample_stride, stride, lines.line_deg,
                lines.firing_deg, above, p.max_line_ratio);
  note->append(text);
}

}  // namespace

bool NormalGroundFilter::Impl::measureLattice(const CloudView& cloud, std::string* note) {
  double step[3];
  on_lattice = lattice.measure(cloud, step);
  if (!on_lattice) return false;
  for (int a = 0; a < 3; ++a) lattice_var[a] = step[a] * step[a] / 12.0;
  char text[200];
  std::snprintf(text, sizeof text,
                "%sx/y/z on a %g / %g / %g m lattice (float32 far from the origin?): the "
                "neighbourhoods' covariance takes its variance back; the CPU's stages",
                note->empty() ? "" : "; ", step[0], step[1], step[2]);
  note->append(text);
  return true;
}

bool NormalGroundFilter::Impl::checksTilt(const NormalGroundFilterParams& p,
                                          const ScanDecision& decision) const {
  return GroundTiltEstimator::applies(p.level_tilt, decision.registered, scan.origin());
}

void NormalGroundFilter::Impl::estimateTilt(const CloudView& cloud, double level_tilt) {
  const auto t0 = Clock::now();
  tilt_found = tilt.estimate(cloud, scan.origin(), level_tilt);
  tilt_ms = msSince(t0);
}

const CloudView& NormalGroundFilter::Impl::levelTo(const NormalGroundFilterParams& p,
                                                   const CloudView& cloud, FilterStats* st) {
  levelled_view = GroundTiltEstimator::level(cloud, scan.origin(), tilt_found, &levelled_xyz);
  GroundTiltEstimator::appendTurnNote(tilt_found.tilt_deg, p.level_tilt, &st->note);
  return levelled_view;
}

bool NormalGroundFilter::Impl::prepareAndExecute(const NormalGroundFilterParams& p,
                                                 const ScanDecision& decision, const CloudView& in,
                                                 std::vector<std::uint8_t>* labels, FilterStats* st,
                                                 Prepared* prep) {
  // 1a. a sparse spinning sensor's scan lines: the stride its normals need (scan_lines.h);
  //     where the origin lies on the ground below the sensor, they show the sensor's height.
  int stride = p.sample_stride;
  const ScanLines* lines = nullptr;
  if (p.max_line_ratio > 0.0 && !decision.registered) {
    const auto t_lines = Clock::now();
    lines = &scan_lines.of(in, scan.origin());
    stride = normal::strideForScanLines(*lines, p.max_line_ratio, stride);
    st->stage_ms.emplace_back("lines", msSince(t_lines));
  }
  // null: no sensor at the origin, nor where sparse lines, seen from above it, put it
  const double none[3] = {0.0, 0.0, 0.0};
  prep->sensor = sensorOf(decision, in, stride != p.sample_stride ? lines->from : none, st);
  if (stride != p.sample_stride) appendStrideNote(p, stride, *lines, &st->note);
  prep->stride = stride;
  prep->lines = lines;
  // 0. coordinates on a coarse lattice (float32 far from the origin): the PCA adds back the
  //    spread its steps hide (normal/lattice.h; 0.03 ms a KITTI frame), on the CPU. Then the
  //    whole filter on the executor (GPU) when the filter has one; when it declines the scan
  //    (a device fault) the caller's stages run it on the CPU.
  if (measureLattice(in, &st->note) || !executor) return false;
  if (executor->run(in, stride, prep->sensor, labels, st)) return true;
  st->note += (st->note.empty() ? "" : "; ") + executor->lastNote();
  return false;
}

bool NormalGroundFilter::Impl::executeBeside(const NormalGroundFilterParams& p,
                                             const ScanDecision& decision, const CloudView& cloud,
                                             std::vector<std::uint8_t>* labels, FilterStats* st,
                                             Prepared* prep) {
  const StreamScanLines::Kept lines_before = scan_lines.kept();
  const std::size_t note_size = st->note.size(), stages = st->stage_ms.size();
  auto check = [this, &cloud, &p] { estimateTilt(cloud, p.level_tilt); };
  side.start(&check);
  bool done = false;
  try {
    done = prepareAndExecute(p, decision, cloud, labels, st, prep);
  } catch (...) {
    side.wait();  // `check` reads `cloud`
    throw;
  }
  side.wait();
  if (!turns(p)) return done;
  scan_lines.restore(lines_before);
  st->note.resize(note_size);
  st->stage_ms.resize(stages);
  labels->assign(cloud.size(), kNonGround);
  return false;
}

void NormalGroundFilter::Impl::lineWalls(const NormalGroundFilterParams& p, const CloudView& in,
                                         const Prepared& prep, bool sorted, int threads,
                                         std::vector<std::uint8_t>* labels, FilterStats* st) {
  float sensor[3];
  if (!prep.lines || !(prep.lines->line_deg > 0.0) || !prep.lines->sensor(scan.origin(), sensor)) {
    return;
  }
  const auto t0 = Clock::now();
  // The executor's scan: its own column order where it keeps one (one download), else sorted
  // here.
  const bool gathered = !sorted && executor && executor->lastColumnOrder(&ordered.source);
  if (gathered) {
    normal::OrderStage::fromOrder(in, p.cell_size, &ordered);
  } else if (!sorted) {
    order.run(in, p.cell_size, false, p.segment_points, threads, &ordered);
  }
  const std::uint64_t* columns = gathered ? nullptr : order.columnKeys();
  st->ground_points -= line_walls.run(ordered, columns, sorted ? ground.data() : nullptr, sensor,
                                      prep.lines->line_deg, labels);
  st->stage_ms.emplace_back("line_walls", msSince(t0));
}

const double* NormalGroundFilter::Impl::sensorOf(const ScanDecision& decision,
                                                 const CloudView& cloud, const double from[3],
                                                 FilterStats* st) {
  // The sensor: the origin, or `from` off it where sparse scan lines showed it there.
  const float* origin = scan.origin();
  const float o[3] = {static_cast<float>(origin[0] + from[0]),
                      static_cast<float>(origin[1] + from[1]),
                      static_cast<float>(origin[2] + from[2])};
  for (int a = 0; a < 3; ++a) sensor_xyz[a] = o[a];
  const bool finite = std::isfinite(o[0]) && std::isfinite(o[1]) && std::isfinite(o[2]);
  // Set or far from the points: no sensor there. Read from a side view's density alone: the
  // origin may be one all the same (a single scan under a high ceiling), asked below.
  if (!finite || (decision.registered && !decision.side_view)) return nullptr;
  const auto t_view = Clock::now();
  const double hidden = origin_view.streamShare(cloud, o);
  st->stage_ms.emplace_back("view", msSince(t_view));
  const bool sensor = hidden < OriginView::kHiddenCut;
  if (sensor == !decision.registered) return sensor ? sensor_xyz : nullptr;
  char text[240];
  std::snprintf(text, sizeof text,
                sensor
                    ? "%sonly %.1f %% of the points lie behind nearer ones seen from the "
                      "origin (one scan?): the planes are judged with a sensor there"
                    : "%s%.0f %% of the points lie behind nearer ones seen from the origin "
                      "(merged stations or sweeps, or second echoes?): the planes are judged as a "
                      "registered cloud's",
                st->note.empty() ? "" : "; ", 100.0 * hidden);
  st->note.append(text);
  return sensor ? sensor_xyz : nullptr;
}

std::size_t NormalGroundFilter::Impl::normalsAndVotes(const NormalGroundFilterParams& p,
                                                      std::size_t n, int stride, int threads,
                                                      std::size_t* sampled, double* vote_ms) {
  // With sampling, the candidate flags and votes of the sampled points live in `sample`.
  if (stride <= 1) candidate.assign(n, 0);
  voted.assign(n, 0);
  const normal::ColumnGrid grid = normal::columnGrid(ordered);  // a dense column is capped
  std::size_t candidates_all = 0;
  *sampled = 0;
  for (const auto& sg : ordered.segments) {
    const std::size_t b = sg.first, len = sg.second - sg.first;
    const float* pts = ordered.xyz.data() + 3 * b;
    std::uint8_t* cand;
    std::uint8_t* vote_out;
    std::size_t m = len;
    if (stride > 1) {
      auto t0 = Clock::now();
      m = sample.gather(pts, len, stride, normal::columnSampleCap(p.k), grid, threads);
      pts = sample.sampledXyz();
      cand = sample.candidates();
      vote_out = sample.votes();
      times.add("sample", msSince(t0));
    } else {
      cand = candidate.data() + b;
      vote_out = voted.data() + b;
    }
    const std::size_t candidates =
        neighborhoods.run(search.get(), pts, m, p.k, threads, p.min_planarity, min_abs_nz,
                          on_lattice ? lattice_var : nullptr, &lists, cand, &times);
    auto t0 = Clock::now();
    vote.run(search->listStore(), lists, cand, m, candidates, p.bayes_vote, threads, vote_out);
    if (stride > 1) sample.spread(voted.data() + b);
    *vote_ms += msSince(t0);
    *sampled += m;
    candidates_all += candidates;
  }
  return candidates_all;
}

namespace {

// st = FilterStats(), keeping the memory of its strings and stage list (no allocation per scan).
void resetStats(FilterStats* st) {
  std::string backend = std::move(st->backend), note = std::move(st->note);
  std::string scan_type = std::move(st->scan_type), scan_reason = std::move(st->scan_reason);
  std::vector<std::pair<std::string, double>> stage_ms = std::move(st->stage_ms);
  *st = FilterStats();
  st->backend = std::move(backend);
  st->note = std::move(note);
  st->scan_type = std::move(scan_type);
  st->scan_reason = std::move(scan_reason);
  st->stage_ms = std::move(stage_ms);
  st->backend.clear();
  st->note.clear();
  st->scan_type.clear();
  st->scan_reason.clear();
  st->stage_ms.clear();
}

}  // namespace

NormalGroundFilter::NormalGroundFilter(const NormalGroundFilterParams& params) : params_(params) {
  params_.validate();
  // knn_backend gpu with settings the GPU honours: the whole filter on the GPU, its CPU stages
  // (for a scan it declines) on the kd-tree; otherwise the stages with the requested search.
  std::unique_ptr<NormalFilterExecutor> executor;
  if (params_.knn_backend == "gpu" && normal::gpuSupports(params_)) {
    executor = makeGpuNormalExecutor(params_, normal::minAbsNormalZ(params_));
  }
  impl_ = std::make_unique<Impl>(
      params_,
      makeKnnBackend(executor ? "kdtree" : params_.knn_backend, params_.threads, &backend_note_),
      std::move(executor));
}

NormalGroundFilter::NormalGroundFilter(const NormalGroundFilterParams& params,
                                       std::unique_ptr<KnnBackend> search)
    : NormalGroundFilter(params, std::move(search), nullptr) {}

NormalGroundFilter::NormalGroundFilter(const NormalGroundFilterParams& params,
                                       std::unique_ptr<KnnBackend> search,
                                       std::unique_ptr<NormalFilterExecutor> executor)
    : params_(params) {
  params_.validate();
  impl_ = std::make_unique<Impl>(params_, std::move(search), std::move(executor));
}

NormalGroundFilter::~NormalGroundFilter() = default;

std::string NormalGroundFilter::backend() const {
  return impl_->executor ? impl_->executor->name() : impl_->search->name();
}

void NormalGroundFilter::setSensorOrigin(float x, float y, float z) {
  impl_->scan.setOrigin(x, y, z);
}

bool NormalGroundFilter::noSensorAtOrigin(const CloudView& cloud) {
  const ScanDecision& d = impl_->scan.pin(cloud);
  return d.type == ScanType::kAirborne || d.registered;
}

void NormalGroundFilter::filter(const CloudView& cloud, std::vector<std::uint8_t>* labels,
                                FilterStats* stats) {
  const auto t_start = Clock::now();
  Impl& im = *impl_;
  const NormalGroundFilterParams& p = params_;
  const int threads = resolveThreads(p.threads);
  FilterStats& st = stats ? *stats : im.own_stats;
  resetStats(&st);
  st.input_points = cloud.size();
  st.threads = threads;
  st.backend = backend();
  st.note = backend_note_;
  labels->assign(cloud.size(), kNonGround);

  // ---- airborne mode: the morphological surface replaces the normals and tile planes (on a
  //      nadir scan the lowest return per cell is the better ground evidence, see the docs).
  //      scan_type decides per scan (morph_ground: always); the GPU pipeline never sees these.
  const ScanDecision& scan = im.scan.decide(cloud);
  st.scan_type = scanTypeName(scan.type);
  st.scan_reason = scan.reason;
  if (scan.type == ScanType::kAirborne) {
    runAirborneMode(cloud, airborneSettings(p), &im.morph, t_start, true, labels, &st);
    return;
  }

  // ---- 0a. a sensor mounted tilted (no gravity frame): the scan turned onto its ground, which
  //      the angle window would miss; every later stage (and the GPU) sees the turned points.
  //      With an executor (GPU) the check runs beside it on the scan as it comes.
  // ---- 1a, the sensor's position, 0 (coordinates on a lattice) and the executor:
  //      prepareAndExecute().
  const CloudView* turned = nullptr;
  Impl::Prepared prep;
  bool ran = false, done = false;  // ran: 1a to the executor ran on the scan the stages see
  if (im.checksTilt(p, scan)) {
    if (im.executor) {
      done = im.executeBeside(p, scan, cloud, labels, &st, &prep);
      ran = !im.turns(p);
    } else {
      im.estimateTilt(cloud, p.level_tilt);
    }
    st.stage_ms.emplace_back("level", im.tilt_ms);
    if (im.turns(p)) turned = &im.levelTo(p, cloud, &st);
  }
  const CloudView& in = turned ? *turned : cloud;
  if (!ran) done = im.prepareAndExecute(p, scan, in, labels, &st, &prep);
  if (done) {
    im.lineWalls(p, in, prep, false, threads, labels, &st);
    st.total_ms = msSince(t_start);
    return;
  }
  int stride = prep.stride;
  const double* sensor = prep.sensor;

  // 1. Valid points in grid-column order, cut into segments.
  auto t0 = Clock::now();
  const std::size_t n =
      im.order.run(in, p.cell_size, p.use_segments, p.segment_points, threads, &im.ordered);
  const normal::OrderedPoints& ordered = im.ordered;
  st.invalid_points = in.size() - n;
  st.stage_ms.emplace_back("sort", msSince(t0));
  if (n == 0) {
    st.total_ms = msSince(t_start);
    return;
  }

  // 2-4. Per segment: the sampled points (1b, every sample_stride-th), their neighbours
  //      (computed once), PCA + candidates, naive-Bayes vote; each other point is voted when
  //      the sampled point before or after it is.
  normal::StageTimes& times = im.times;
  times.clear();
  double vote_ms = 0.0;
  const int lines_stride = stride;
  for (;;) {  // again with a wider stride while the normals come out along scan lines
    std::size_t sampled = 0;
    const std::size_t candidates = im.normalsAndVotes(p, n, stride, threads, &sampled, &vote_ms);
    const int wider = normal::sparseLinesStride(candidates, sampled, p.min_candidate_share, stride);
    if (wider == 0) break;
    stride = wider;
  }
  if (stride != lines_stride) normal::appendSparseLinesNote(lines_stride, stride, &st.note);
  // The backend that really ran (a GPU search may fall back to the kd-tree for one scan).
  st.backend = im.search->lastBackend();
  const std::string last_note = im.search->lastNote();
  if (!last_note.empty()) st.note += (st.note.empty() ? "" : "; ") + last_note;
  for (const auto& e : times.stages()) st.stage_ms.push_back(e);
  st.stage_ms.emplace_back("vote", vote_ms);

  // 5. Plane(s) through the voted points and the distance test; none above the sensor.
  t0 = Clock::now();
  im.plane.run(ordered.xyz, im.voted, ordered.extent, p, im.min_abs_nz, threads, &im.ground,
               p.veg_filter ? &im.heights : nullptr, sensor);
  st.stage_ms.emplace_back("plane", msSince(t0));

  // 5a. Local ground plane (one neighbourhood set only: the lists of the last segment are kept).
  if (p.local_ground_min > 0 && ordered.segments.size() == 1) {
    t0 = Clock::now();
    const std::int32_t* rows = nullptr;
    const std::uint32_t* row_points = nullptr;
    const NeighborListStore* kept = im.search->listStore();
    if (!(kept && kept->keptRows(&rows, &row_points)) && !im.lists.indices.empty()) {
      rows = im.lists.indices.data();
    }
    im.local_ground.run(ordered.xyz, rows, row_points, im.lists.points, im.lists.k,
                        stride > 1 ? im.sample.sampledIndex() : nullptr, p.local_ground_min,
                        p.local_ground_below, p.local_ground_above, im.min_abs_nz, threads,
                        &im.ground);
    st.stage_ms.emplace_back("local_ground", msSince(t0));
  }

  // 5b. Optional bush-base rule (off by default; the GPU pipeline declines when it is on).
  if (p.veg_filter) {
    t0 = Clock::now();
    im.vegetation.run(ordered.xyz, im.heights, ordered.extent, p, threads, &im.ground);
    st.stage_ms.emplace_back("vegetation", msSince(t0));
  }

  // 6. Labels in input order.
  st.ground_points = normal::scatterLabels(im.ground, ordered.source, labels, threads);

  // 7. A sparse sensor's lowest scan line on a wall (line_walls.h).
  im.lineWalls(p, in, prep, true, threads, labels, &st);
  st.total_ms = msSince(t_start);
}

}  // namespace ground_filter
