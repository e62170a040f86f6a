#ifndef GROUND_FILTER_SRC_NODELETS_INPUT_GAP_COUNTER_H
#define GROUND_FILTER_SRC_NODELETS_INPUT_GAP_COUNTER_H

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace ground_filter {

/// \brief Counts input clouds that were lost before the filter's callback saw them, from gaps in
///        header.seq and header.stamp. roscpp drops the oldest message of a full subscription
///        queue (`~queue_size`) without telling the subscriber, so a filter slower than its input
///        loses scans in silence; the gaps are their only trace. Not thread-safe (the monitor
///        holds its mutex); no ROS calls, unit-tested on its own.
///
/// The rule, one step() per cloud in arrival order:
///  - seq: a step of d in [1, kMaxSeqStep] means d - 1 clouds lost, once seq is known to count
///    (rospy, rosbag and make_bag.py keep a counter there; many C++ drivers leave it 0):
///    kSeqConfirm or more such steps in a row, kSeqConfirm - 1 of them +1. The gaps of those
///    first steps count when the counter is confirmed (a bag whose second scan was lost). Any other
///    step (0, going back, a restart at 0, a larger jump) counts nothing by seq and starts the
///    confirmation again. The arithmetic is uint32, so the wrap 2^32 - 1 -> 0 is +1.
///  - stamps, on the steps where seq does not look like a counter: the input period is the median
///    of the last kWindow positive stamp steps (at least kMinSteps of them); a step above 1.5
///    periods means round(step / period) - 1 clouds lost. A stamp that goes back or repeats (a
///    bag loop, a restarted driver), or a step above kMaxGapPeriods periods (a hole in a
///    recording) counts nothing. Estimated: a sensor that itself skipped a scan counts too.
///  - a frame_id change (two sensors on one topic) forgets the previous cloud and the period;
///    restart() (the lazy subscription started again) forgets the previous cloud only.
/// When the filter loses a scan after nearly every one, the median step is itself two periods and
/// nothing is counted; the monitor's "cannot keep up" rule (processing time against the wall time
/// between clouds) covers that case.
class InputGapCounter {
 public:
  static constexpr int kSeqConfirm = 3;
  static constexpr std::uint32_t kMaxSeqStep = 1000;
  static constexpr std::size_t kWindow = 15;
  static constexpr std::size_t kMinSteps = 5;
  static constexpr double kMaxGapPeriods = 20.0;

  /// \brief What one cloud's header says about the clouds before it.
  struct Gap {
    std::uint64_t lost = 0;  ///< clouds missing between the previous cloud and this one
    bool by_seq = false;     ///< counted from seq (exact) rather than from stamps
    std::uint32_t seq_from = 0, seq_to = 0;  ///< the seq step, when by_seq
    double step_s = 0.0;                     ///< the stamp step [s]
    double period_s = 0.0;                   ///< the input period then [s] (0: not known yet)
  };

  /// \brief Takes one cloud's header fields; returns the gap before it.
  Gap step(std::uint32_t seq, double stamp_s, const std::string& frame_id);
  /// \brief The next cloud is not compared with the last one (the input was unsubscribed).
  void restart() { have_last_ = false; }
  /// \brief Median of the recent stamp steps [s], 0 while fewer than kMinSteps are known.
  double period() const;

 private:
  bool have_last_ = false;
  std::uint32_t last_seq_ = 0;
  double last_stamp_ = 0.0;
  std::string frame_;
  int seq_run_ = 0;                     // seq steps in a row within [1, kMaxSeqStep]
  int seq_ones_ = 0;                    // of which +1
  bool seq_counting_ = false;           // seq confirmed as a counter
  std::uint64_t seq_pending_ = 0;       // clouds missing while it was not confirmed yet
  std::uint32_t seq_pending_from_ = 0;  // seq before the first of those steps
  std::vector<double> steps_;           // recent positive stamp steps, ring of kWindow
  std::size_t next_ = 0;                // ring position
};

}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_NODELETS_INPUT_GAP_COUNTER_H
