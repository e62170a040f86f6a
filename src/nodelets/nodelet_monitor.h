#ifndef GROUND_FILTER_SRC_NODELETS_NODELET_MONITOR_H
#define GROUND_FILTER_SRC_NODELETS_NODELET_MONITOR_H

#include <diagnostic_updater/diagnostic_updater.h>
#include <ros/time.h>
#include <std_msgs/Header.h>

#include <array>
#include <atomic>
#include <cstdint>
#include <mutex>
#include <string>
#include <vector>

#include "input_gap_counter.h"
#include "point_cloud2.h"

namespace ground_filter {

/// \brief What a ground filter nodelet counts and reports: counters, per-kind log throttles,
///        stream checks and the /diagnostics status. Thread-safe; publishes and logs nothing
///        itself (the nodelet logs under its own name).
class NodeletMonitor {
 public:
  /// \brief The counters by name: T = std::uint64_t for values at one moment (copied,
  ///        subtracted, logged), T = std::atomic<std::uint64_t> for the live counters.
  template <class T>
  struct CounterSet {
    T clouds_in{0};            ///< clouds received
    T clouds_out{0};           ///< clouds split and published
    T clouds_rejected{0};      ///< dropped: malformed clouds
    T clouds_no_transform{0};  ///< dropped: no transform to the gravity frame
    T not_cloud{0};            ///< dropped: input messages that are no PointCloud2
    T filter_errors{0};        ///< filter threw: published all non-ground
    T invalid_points{0};       ///< NaN/Inf points sent to non-ground
    T out_of_range_points{0};  ///< points outside the working volume -> non-ground
    T near_points{0};          ///< points within min_range or the body box -> non-ground
    T config_rejected{0};      ///< parameter sets refused by validation
    T frame_changes{0};        ///< clouds whose frame_id differs from the last
    T stamps_backwards{0};     ///< clouds stamped before the previous one
    T fallbacks{0};            ///< clouds with a FilterStats::note (fallback)
    T buffer_releases{0};      ///< filter buffers dropped after a large cloud (BufferReleasePolicy)
    T clouds_lost{0};          ///< never received: lost before the callback (InputGapCounter)

    /// \brief Every counter above, in order (copies walk this list).
    static const std::array<T CounterSet::*, 15>& all() {
      static const std::array<T CounterSet::*, 15> members = {
          &CounterSet::clouds_in,        &CounterSet::clouds_out,
          &CounterSet::clouds_rejected,  &CounterSet::clouds_no_transform,
          &CounterSet::not_cloud,        &CounterSet::filter_errors,
          &CounterSet::invalid_points,   &CounterSet::out_of_range_points,
          &CounterSet::config_rejected,  &CounterSet::frame_changes,
          &CounterSet::stamps_backwards, &CounterSet::fallbacks,
          &CounterSet::buffer_releases,  &CounterSet::near_points,
          &CounterSet::clouds_lost};
      return members;
    }
    /// \brief Clouds received but not published, all reasons.
    std::uint64_t dropped() const { return clouds_rejected + clouds_no_transform + not_cloud; }
  };
  /// \brief Counter values at one moment.
  using CounterValues = CounterSet<std::uint64_t>;

  /// \brief Counters since start (updated and read from any thread).
  struct Counters : CounterSet<std::atomic<std::uint64_t>> {
    /// \brief The current values (each read atomically; not one snapshot of all).
    CounterValues values() const;
  };

  /// \brief Log throttle slots: one per CloudRejectReason, then the stream problems.
  enum LogSlot : int {
    kNoTransform = static_cast<int>(CloudRejectReason::kCount),
    kNotCloud,
    kFrameChange,
    kStampBack,
    kLabeled,
    kLost,
    kLogSlotCount
  };

  /// \brief How a cloud's header differs from the previous cloud's.
  struct StreamChange {
    bool frame_changed = false;
    std::string old_frame;   ///< previous frame_id, when it changed
    bool went_back = false;  ///< stamp before the previous one
    double back_s = 0.0;     ///< by how much [s]
    using Gap = InputGapCounter::Gap;
    Gap gap;  ///< clouds lost before this one (gap.lost, counted by the caller)
  };

  /// \brief Seconds between two log lines of the same slot.
  static constexpr double kLogPeriodS = 5.0;

  NodeletMonitor();

  /// \brief Live counters (callers increment them directly).
  Counters& counters() { return counters_; }
  const Counters& counters() const { return counters_; }

  /// \brief True when a message of this slot may be logged now (wall time); counts the
  ///        suppressed ones and returns their number since the last message in `suppressed`.
  bool logNow(int slot, std::uint64_t* suppressed = nullptr);

  /// \brief `note` with every number in it replaced by '#', into `kind` (its capacity reused):
  ///        what a filter note says without the values it measured, so that a note repeated
  ///        with other numbers (a ground leaning 7.7 deg, then 7.5 deg on the next scan) counts
  ///        as the same reason.
  static void noteKind(const std::string& note, std::string* kind);

  /// \brief Compares `header` with the previous cloud's and remembers it.
  StreamChange checkStream(const std_msgs::Header& header);

  /// \brief The input was (re)subscribed: the next cloud is not compared with the last one.
  void restartStream();

  /// \brief Records one published cloud: callback-to-publish time [ms], the backend that ran
  ///        and its fallback note (empty: none); the scan type it ran as and why (FilterStats).
  void recordCloud(double ms, const std::string& backend, const std::string& note,
                   const std::string& scan_type = std::string());

  /// \brief Remembers why the last parameter set was refused (the "last refused parameter set"
  ///        entry: `dynparam set` shows no reason, it exits 0 and only the reply holds the kept
  ///        values).
  void recordRefused(const std::string& why);

  /// \brief Remembers where the last cloud lies, for the "cloud centre [m]" entry: the middle of
  ///        its bounding box in `frame_id`, or nullptr when it had no finite point. Formatted
  ///        only when the status is filled.
  void recordCentre(const double* centre, const std::string& frame_id);

  /// \brief Fills the status: rates and times since the previous call, drops and stream
  ///        problems (WARN while they occur), totals; ERROR without a filter configuration.
  void diagnose(diagnostic_updater::DiagnosticStatusWrapper& status, const std::string& method,
                const std::string& gravity_frame, bool have_config);

 private:
  std::mutex mutex_;  // guards everything below (short sections, never held while filtering)
  std::string last_frame_id_;  // stream checks
  ros::Time last_stamp_;
  bool have_last_ = false;
  InputGapCounter gaps_;             // lost clouds from seq / stamp gaps
  ros::WallTime last_arrival_;       // callback entry of the previous cloud (checkStream)
  double window_arrival_sum_ = 0.0;  // wall time between consecutive clouds in this window [s]
  std::uint64_t window_arrivals_ = 0;
  double window_ms_sum_ = 0.0;  // processing times since the last diagnostic update
  double window_ms_max_ = 0.0;
  std::uint64_t window_clouds_ = 0;
  std::string backend_;        // FilterStats::backend of the last cloud
  std::string fallback_note_;  // last non-empty FilterStats::note
  std::string scan_type_;      // FilterStats::scan_type and scan_reason of the last cloud
  std::string refused_;        // why the last parameter set was refused
  enum class Centre { kNoCloud, kNoFinitePoint, kKnown };
  Centre centre_state_ = Centre::kNoCloud;  // recordCentre() of the last cloud
  double centre_[3] = {0.0, 0.0, 0.0};
  std::string centre_frame_;
  ros::WallTime last_diagnose_;
  CounterValues last_counts_;  // at the previous diagnostic update
  ros::WallTime last_log_[kLogSlotCount];
  std::uint64_t suppressed_[kLogSlotCount] = {};

  Counters counters_;
};

}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_NODELETS_NODELET_MONITOR_H
