#ifndef GROUND_FILTER_SRC_CORE_NORMAL_VOTE_H
#define GROUND_FILTER_SRC_CORE_NORMAL_VOTE_H

#include <cstddef>
#include <cstdint>
#include <vector>

#include "ground_filter/neighbor_search.h"
#include "knn/neighbor_list_store.h"

namespace ground_filter {
namespace normal {

/// \brief Stage 4 ("vote"): naive-Bayes vote of each point's neighbourhood over the candidates.
///        Holds only scratch memory, reused between scans.
class VoteStage {
 public:
  /// \brief voted[i] for the `len` points of a segment from their lists (`lists`, or those in
  ///        `kept`, the search's NeighborListStore, when it has them; may be null) and the
  ///        `candidates` flagged in `candidate`; without `bayes` the candidates are copied.
  void run(NeighborListStore* kept, const NeighborLists& lists, const std::uint8_t* candidate,
           std::size_t len, std::size_t candidates, bool bayes, int threads, std::uint8_t* voted);

 private:
  std::vector<std::uint16_t> flagged_, size_;  // per-point counts from the kept lists
};

}  // namespace normal
}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_NORMAL_VOTE_H
