#include "input_gap_counter.h"

#include <algorithm>
#include <cmath>

namespace ground_filter {

constexpr int InputGapCounter::kSeqConfirm;
constexpr std::uint32_t InputGapCounter::kMaxSeqStep;
constexpr std::size_t InputGapCounter::kWindow;
constexpr std::size_t InputGapCounter::kMinSteps;
constexpr double InputGapCounter::kMaxGapPeriods;

double InputGapCounter::period() const {
  if (steps_.size() < kMinSteps) return 0.0;
  std::vector<double> sorted = steps_;
  std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
  return sorted[sorted.size() / 2];
}

InputGapCounter::Gap InputGapCounter::step(std::uint32_t seq, double stamp_s,
                                           const std::string& frame_id) {
  Gap gap;
  if (have_last_ && frame_id != frame_) {  // another sensor: nothing to compare with
    have_last_ = false;
    steps_.clear();
    next_ = 0;
    seq_run_ = seq_ones_ = 0;
    seq_counting_ = false;
  }
  if (have_last_) {
    const std::uint32_t d = seq - last_seq_;  // uint32: the wrap 2^32 - 1 -> 0 is a step of 1
    const double dt = stamp_s - last_stamp_;
    gap.step_s = dt;
    gap.period_s = period();
    if (d >= 1 && d <= kMaxSeqStep) {  // seq may be a counter: it decides, not the stamps
      if (seq_run_ == 0) {
        seq_pending_ = 0;
        seq_pending_from_ = last_seq_;
      }
      ++seq_run_;
      if (d == 1) ++seq_ones_;
      if (seq_counting_) {
        gap.lost = d - 1;
        gap.seq_from = last_seq_;
      } else {
        seq_pending_ += d - 1;  // gaps before the counter is confirmed count once it is
        if (seq_run_ >= kSeqConfirm && seq_ones_ >= kSeqConfirm - 1) {
          seq_counting_ = true;
          gap.lost = seq_pending_;
          gap.seq_from = seq_pending_from_;
        }
      }
      gap.by_seq = gap.lost > 0;
      gap.seq_to = seq;
    } else {
      seq_run_ = seq_ones_ = 0;
      seq_counting_ = false;
      if (gap.period_s > 0.0 && dt > 1.5 * gap.period_s && dt <= kMaxGapPeriods * gap.period_s) {
        gap.lost = static_cast<std::uint64_t>(std::lround(dt / gap.period_s)) - 1;
      }
    }
    if (dt > 0.0) {  // the period from forward steps only (a bag loop goes back)
      if (steps_.size() < kWindow) {
        steps_.push_back(dt);
      } else {
        steps_[next_] = dt;
      }
      next_ = (next_ + 1) % kWindow;
    }
  }
  have_last_ = true;
  last_seq_ = seq;
  last_stamp_ = stamp_s;
  frame_ = frame_id;
  return gap;
}

}  // namespace ground_filter
