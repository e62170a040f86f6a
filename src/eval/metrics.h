#ifndef GROUND_FILTER_SRC_EVAL_METRICS_H
#define GROUND_FILTER_SRC_EVAL_METRICS_H

#include <cstdint>
#include <vector>

namespace ground_filter {

/// \brief Ground-truth value of a point that is left out of every count (unlabelled, outlier, ...).
constexpr std::int8_t kTruthIgnored = -1;

/// \brief Confusion counts of a ground segmentation, ground being the positive class.
struct Confusion {
  std::uint64_t tp = 0;  ///< ground labelled ground
  std::uint64_t fp = 0;  ///< non-ground labelled ground
  std::uint64_t tn = 0;  ///< non-ground labelled non-ground
  std::uint64_t fn = 0;  ///< ground labelled non-ground

  /// \brief Adds `other`'s counts (pooling over files).
  void add(const Confusion& other) {
    tp += other.tp;
    fp += other.fp;
    tn += other.tn;
    fn += other.fn;
  }
  /// \brief Points counted (ignored points excluded).
  std::uint64_t total() const { return tp + fp + tn + fn; }
};

/// \brief Counts labels (1 ground, anything else non-ground) against truth (1 ground, 0 non-ground,
///        kTruthIgnored or any other value: left out of every count).
/// \throws std::invalid_argument when the two vectors differ in size.
Confusion countConfusion(const std::vector<std::uint8_t>& labels,
                         const std::vector<std::int8_t>& truth);

/// \brief Scores derived from a Confusion, each a fraction in [0, 1].
///
/// accuracy = (TP+TN)/all, precision = TP/(TP+FP), recall = TP/(TP+FN),
/// f1 = 2TP/(2TP+FP+FN) (equal to 2PR/(P+R) wherever that is defined, and 0 when TP = 0 but
/// something was counted), iou = TP/(TP+FP+FN).
/// A ratio whose denominator is 0 is undefined and is NaN (e.g. precision when nothing was
/// labelled ground); callers print it as "-" / JSON null. No value is ever invented for 0/0.
struct Metrics {
  double accuracy = 0.0;   ///< (TP+TN)/(TP+FP+TN+FN)
  double precision = 0.0;  ///< TP/(TP+FP)
  double recall = 0.0;     ///< TP/(TP+FN)
  double f1 = 0.0;         ///< 2TP/(2TP+FP+FN)
  double iou = 0.0;        ///< TP/(TP+FP+FN)
};

/// \brief Computes the Metrics of `c` (NaN for each ratio with a zero denominator).
Metrics computeMetrics(const Confusion& c);

/// \brief Points of one (class, truth) group of a labelled scan and how many of them a filter
///        labelled ground: the recall of a ground class, the false-positive share of another.
struct ClassCount {
  std::uint16_t cls = 0;              ///< semantic class id (e.g. SemanticKITTI)
  std::int8_t truth = 0;              ///< 1 ground, 0 non-ground under the scan's protocol
  std::uint64_t points = 0;           ///< counted points of this group
  std::uint64_t labelled_ground = 0;  ///< of them, labelled ground by the filter
};

/// \brief Adds per (class, truth) counts of one scan to `table`, which stays sorted by class
///        and then truth (ignored points are left out, as in countConfusion).
/// \throws std::invalid_argument when the three vectors differ in size.
void addClassCounts(const std::vector<std::uint8_t>& labels, const std::vector<std::int8_t>& truth,
                    const std::vector<std::uint16_t>& semantic, std::vector<ClassCount>* table);

}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_EVAL_METRICS_H
