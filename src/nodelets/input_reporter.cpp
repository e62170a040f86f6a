#include "input_reporter.h"

#include <nodelet/nodelet.h>

#include <cstdio>

namespace ground_filter {

InputReporter::InputReporter(const std::string& name, const std::string& method,
                             const std::string& topic, int queue_size, NodeletMonitor* monitor)
    : name_(name), method_(method), topic_(topic), queue_size_(queue_size), monitor_(monitor) {}

void InputReporter::rejected(CloudRejectReason reason, const std::string& why) {
  ++monitor_->counters().clouds_rejected;
  std::uint64_t suppressed = 0;
  if (!monitor_->logNow(static_cast<int>(reason), &suppressed)) return;
  std::string more;
  if (suppressed) {
    more = " (" + std::to_string(suppressed) + " more with this reason since the last message)";
  }
  NODELET_ERROR("rejected PointCloud2 on %s (%s): %s; nothing published for it%s", topic_.c_str(),
                reasonName(reason), why.c_str(), more.c_str());
}

void InputReporter::countAndWarn(std::atomic<std::uint64_t>* counter, int slot,
                                 const std::string& what, const char* then) {
  const auto n = ++*counter;
  if (monitor_->logNow(slot)) {
    NODELET_WARN("%s: %s (%llu so far)%s", method_.c_str(), what.c_str(),
                 static_cast<unsigned long long>(n), then);
  }
}

void InputReporter::checkStream(const std_msgs::Header& header) {
  const NodeletMonitor::StreamChange change = monitor_->checkStream(header);
  NodeletMonitor::Counters& counters = monitor_->counters();
  if (change.frame_changed) {
    countAndWarn(
        &counters.frame_changes, NodeletMonitor::kFrameChange,
        "input frame_id changed from '" + change.old_frame + "' to '" + header.frame_id + "'",
        "; every cloud is processed and published in its own frame");
  }
  if (change.gap.lost) {
    const NodeletMonitor::StreamChange::Gap& gap = change.gap;
    const auto n = (counters.clouds_lost += gap.lost);
    if (monitor_->logNow(NodeletMonitor::kLost)) {
      char how[96];
      if (gap.by_seq) {
        std::snprintf(how, sizeof(how), "seq %u -> %u", gap.seq_from, gap.seq_to);
      } else {
        std::snprintf(how, sizeof(how), "stamp step %.3f s, input period %.3f s", gap.step_s,
                      gap.period_s);
      }
      NODELET_WARN(
          "%s: %llu input cloud%s lost before the filter (%s; %llu so far): the input queue "
          "(~queue_size %d) was full while the filter was busy, or the sender skipped them",
          method_.c_str(), static_cast<unsigned long long>(gap.lost), gap.lost == 1 ? "" : "s", how,
          static_cast<unsigned long long>(n), queue_size_);
    }
  }
  if (change.went_back) {
    char by[64];
    std::snprintf(by, sizeof(by), "%.3f s", change.back_s);
    countAndWarn(
        &counters.stamps_backwards, NodeletMonitor::kStampBack,
        std::string("input stamp went back by ") + by + " (a bag loop or a restarted driver?)",
        "; the cloud is processed as usual");
  }
}

void InputReporter::notCloud(const std::string& what, const std::string& publisher) {
  countAndWarn(&monitor_->counters().not_cloud, NodeletMonitor::kNotCloud,
               "dropped a message on " + topic_ + " from " +
                   (publisher.empty() ? std::string("an unknown publisher") : publisher) + ": " +
                   what,
               "");
}

void InputReporter::noTransform(const sensor_msgs::PointCloud2& cloud,
                                const std::string& gravity_frame, const std::string& why) {
  char when[48];
  std::snprintf(when, sizeof(when), "' at t=%.3f: ", cloud.header.stamp.toSec());
  countAndWarn(&monitor_->counters().clouds_no_transform, NodeletMonitor::kNoTransform,
               "no transform from '" + cloud.header.frame_id + "' to gravity frame '" +
                   gravity_frame + when + why + "; cloud dropped",
               "");
}

}  // namespace ground_filter
