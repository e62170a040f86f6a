// demo_monitor: prints one line per filtered scan (points in, ground, non-ground, filter time,
// latency and, when the clouds carry a `gt_ground` field, accuracy / precision / recall / F1)
// and a summary at exit.
//
// Topics: ~ground, ~nonground (sensor_msgs/PointCloud2, paired by exact header stamp),
//         ~processing_time_ms (std_msgs/Float64 of the filter nodelet, optional).
// Parameters:
//   ~max_scans (int, 0)       print the summary and shut down after this many scans (0 = never)
//   ~timeout (double, 60)     give up (exit code 1) when no scan arrives for this long [s]
//   ~shutdown_launch (bool, false)  when done, stop the roslaunch that started this node (its
//                             parent process, SIGINT = Ctrl-C) instead of exiting alone, so a
//                             launch with this required node ends without "REQUIRED process
//                             has died"; exits by itself if not stopped within 15 s.
// Exit status: 0 only when scans were received (and max_scans reached, when given).
#include <message_filters/subscriber.h>
#include <message_filters/sync_policies/exact_time.h>
#include <message_filters/synchronizer.h>
#include <ros/ros.h>
#include <sensor_msgs/PointCloud2.h>
#include <signal.h>
#include <std_msgs/Float64.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <deque>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "eval/metrics.h"

namespace {

constexpr std::uint8_t kTruthIgnore = 255;

namespace gf = ground_filter;

// A fraction as a percentage with two decimals; "-" where it is undefined (NaN, e.g. precision
// when nothing was labelled ground).
std::string percent(double fraction) {
  if (std::isnan(fraction)) return "-";
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.2f", 100.0 * fraction);
  return buf;
}

// Counts gt_ground values of every record of `cloud`; returns false when the field is missing
// or not uint8.
bool countTruth(const sensor_msgs::PointCloud2& cloud, std::uint64_t* truth_ground,
                std::uint64_t* truth_nonground, std::uint64_t* ignored) {
  const sensor_msgs::PointField* field = nullptr;
  for (const auto& f : cloud.fields) {
    if (f.name == "gt_ground") field = &f;
  }
  if (!field || field->datatype != sensor_msgs::PointField::UINT8 ||
      field->offset >= cloud.point_step) {
    return false;
  }
  if (cloud.data.size() < static_cast<std::size_t>(cloud.row_step) * cloud.height) return false;
  for (std::size_t r = 0; r < cloud.height; ++r) {
    for (std::size_t c = 0; c < cloud.width; ++c) {
      const std::uint8_t v = cloud.data[r * cloud.row_step + c * cloud.point_step + field->offset];
      if (v == 1) {
        ++*truth_ground;
      } else if (v == 0) {
        ++*truth_nonground;
      } else if (v == kTruthIgnore) {
        ++*ignored;
      } else {
        ++*truth_nonground;  // any other value: not ground
      }
    }
  }
  return true;
}

// True when process `pid` runs roslaunch (its command line names it).
bool isRoslaunch(pid_t pid) {
  std::ifstream f("/proc/" + std::to_string(pid) + "/cmdline", std::ios::binary);
  const std::string cmdline((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  return cmdline.find("roslaunch") != std::string::npos;
}

class DemoMonitor {
 public:
  DemoMonitor() : pnh_("~"), sync_(Policy(10), sub_ground_, sub_nonground_) {
    pnh_.param("max_scans", max_scans_, 0);
    pnh_.param("timeout", timeout_s_, 60.0);
    pnh_.param("shutdown_launch", shutdown_launch_, false);
    sub_ground_.subscribe(pnh_, "ground", 5);
    sub_nonground_.subscribe(pnh_, "nonground", 5);
    sync_.registerCallback(&DemoMonitor::pairCallback, this);
    sub_time_ = pnh_.subscribe("processing_time_ms", 20, &DemoMonitor::timeCallback, this);
    // Pairs wait briefly for their processing-time message; this also drives the timeout.
    timer_ = pnh_.createWallTimer(ros::WallDuration(0.02), &DemoMonitor::flush, this);
    last_activity_ = ros::WallTime::now();
    std::printf("[demo_monitor] waiting for %s and %s (max_scans %d)\n",
                sub_ground_.getTopic().c_str(), sub_nonground_.getTopic().c_str(), max_scans_);
    std::printf("%5s %15s %8s %8s %10s %9s %9s %8s %8s %8s %8s\n", "scan", "stamp", "points",
                "ground", "nonground", "filter_ms", "latency", "acc%", "prec%", "rec%", "F1%");
    std::fflush(stdout);
  }

  /// Exit status: 0 when scans were received and the monitor did not give up waiting for the
  /// requested ones (scripts/demo.sh exits with it).
  int status() const { return failed_ || scans_ == 0 ? 1 : 0; }

  /// Prints the summary if it was not printed yet (e.g. after Ctrl-C).
  void finishOnExit() {
    if (!done_) {
      done_ = true;
      printSummary();
    }
  }

  void printSummary() const {
    std::printf("[demo_monitor] summary: %zu scans", scans_);
    if (scans_ == 0) {
      std::printf(" (nothing received)\n");
      std::fflush(stdout);
      return;
    }
    std::printf(", mean %.0f points, mean filter %s ms, mean latency %.1f ms\n",
                static_cast<double>(total_points_) / scans_,
                timed_scans_ ? formatMs(sum_filter_ms_ / timed_scans_).c_str() : "n/a",
                sum_latency_ms_ / scans_);
    if (scored_scans_ > 0) {
      const gf::Metrics m = gf::computeMetrics(pooled_);
      std::printf(
          "[demo_monitor] accuracy over %zu labelled scans: mean F1 %s %%; pooled "
          "accuracy %s %%, precision %s %%, recall %s %%, F1 %s %% "
          "(tp %llu fp %llu tn %llu fn %llu, ignored %llu)\n",
          scored_scans_, percent(sum_f1_ / scored_scans_).c_str(), percent(m.accuracy).c_str(),
          percent(m.precision).c_str(), percent(m.recall).c_str(), percent(m.f1).c_str(),
          static_cast<unsigned long long>(pooled_.tp), static_cast<unsigned long long>(pooled_.fp),
          static_cast<unsigned long long>(pooled_.tn), static_cast<unsigned long long>(pooled_.fn),
          static_cast<unsigned long long>(pooled_ignored_));
    } else {
      std::printf("[demo_monitor] no scan carried gt_ground labels: accuracy not measured\n");
    }
    std::fflush(stdout);
  }

 private:
  using Policy =
      message_filters::sync_policies::ExactTime<sensor_msgs::PointCloud2, sensor_msgs::PointCloud2>;

  struct Pending {
    ros::WallTime arrival;
    double stamp;  // header stamp [s] (seq is rewritten by every roscpp publisher)
    double latency_ms;
    std::size_t ground, nonground;
    gf::Confusion confusion;  // ground the positive class, ignored points left out
    std::uint64_t ignored = 0;
    bool scored = false;  // false when a cloud had no usable gt_ground field
  };
  struct Timing {
    ros::WallTime arrival;
    double ms;
  };

  static std::string formatMs(double ms) {
    char buf[32];
    std::snprintf(buf, sizeof(buf), "%.2f", ms);
    return buf;
  }

  void pairCallback(const sensor_msgs::PointCloud2ConstPtr& ground,
                    const sensor_msgs::PointCloud2ConstPtr& nonground) {
    if (done_) return;  // waiting for roslaunch to stop us: no more lines
    Pending p;
    p.arrival = ros::WallTime::now();
    p.stamp = ground->header.stamp.toSec();
    p.latency_ms = (ros::Time::now() - ground->header.stamp).toSec() * 1e3;
    p.ground = static_cast<std::size_t>(ground->width) * ground->height;
    p.nonground = static_cast<std::size_t>(nonground->width) * nonground->height;
    // Ground output: truth ground = TP, truth non-ground = FP; non-ground output: FN / TN.
    std::uint64_t ign_g = 0, ign_n = 0;
    const bool ok_g = countTruth(*ground, &p.confusion.tp, &p.confusion.fp, &ign_g);
    const bool ok_n = countTruth(*nonground, &p.confusion.fn, &p.confusion.tn, &ign_n);
    // An empty output has no way to show its fields: it is fine when the other one has them;
    // a scan whose points are all ignored is not scored.
    p.scored = (ok_g || p.ground == 0) && (ok_n || p.nonground == 0) && (ok_g || ok_n) &&
               p.confusion.total() > 0;
    p.ignored = ign_g + ign_n;
    pending_.push_back(p);
    last_activity_ = p.arrival;
    flush(ros::WallTimerEvent());
  }

  void timeCallback(const std_msgs::Float64ConstPtr& msg) {
    timings_.push_back({ros::WallTime::now(), msg->data});
    flush(ros::WallTimerEvent());
  }

  // Prints the oldest pairs in order, each with its processing time, or n/a. The nodelet
  // publishes both outputs and then the time, which has no header: for large clouds the small
  // time message overtakes the clouds, for small ones it comes just after. So a pair takes the
  // last time that arrived before it (since the previous pair), else the next one within kWaitS.
  void flush(const ros::WallTimerEvent&) {
    constexpr double kWaitS = 0.2;
    const ros::WallTime now = ros::WallTime::now();
    if (done_) {
      if (!launch_stop_deadline_.isZero() && now > launch_stop_deadline_) ros::shutdown();
      return;
    }
    while (!pending_.empty()) {
      const Pending& p = pending_.front();
      // Times that came before the previous pair belong to it or to scans never seen here.
      while (!timings_.empty() && timings_.front().arrival < previous_pair_arrival_) {
        timings_.pop_front();
      }
      std::size_t pick = timings_.size();
      for (std::size_t i = 0; i < timings_.size() && timings_[i].arrival <= p.arrival; ++i) {
        pick = i;
      }
      if (pick == timings_.size() && !timings_.empty()) pick = 0;
      if (pick == timings_.size() && (now - p.arrival).toSec() < kWaitS) {
        break;  // its time may still be on the way
      }
      double ms = -1.0;
      if (pick < timings_.size()) {
        ms = timings_[pick].ms;
        timings_.erase(timings_.begin(), timings_.begin() + static_cast<long>(pick) + 1);
      }
      previous_pair_arrival_ = p.arrival;
      report(p, ms);
      pending_.pop_front();
      if (done_) return;
    }
    if (!done_ && (now - last_activity_).toSec() > timeout_s_) {
      std::printf(
          "[demo_monitor] ERROR: no filtered scan for %.0f s (is the filter running and "
          "its input publishing?)\n",
          timeout_s_);
      failed_ = max_scans_ > 0;
      finish();
    }
  }

  void report(const Pending& p, double ms) {
    ++scans_;
    const std::size_t points = p.ground + p.nonground;
    total_points_ += points;
    sum_latency_ms_ += p.latency_ms;
    if (ms >= 0.0) {
      sum_filter_ms_ += ms;
      ++timed_scans_;
    }
    std::printf("%5zu %15.3f %8zu %8zu %10zu %9s %9.1f", scans_, p.stamp, points, p.ground,
                p.nonground, ms >= 0.0 ? formatMs(ms).c_str() : "n/a", p.latency_ms);
    if (p.scored) {
      const gf::Metrics m = gf::computeMetrics(p.confusion);
      std::printf(" %8s %8s %8s %8s\n", percent(m.accuracy).c_str(), percent(m.precision).c_str(),
                  percent(m.recall).c_str(), percent(m.f1).c_str());
      pooled_.add(p.confusion);
      pooled_ignored_ += p.ignored;
      sum_f1_ += m.f1;
      ++scored_scans_;
    } else {
      std::printf(" %8s %8s %8s %8s\n", "n/a", "n/a", "n/a", "n/a");
    }
    std::fflush(stdout);
    if (max_scans_ > 0 && scans_ >= static_cast<std::size_t>(max_scans_)) finish();
  }

  void finish() {
    if (done_) return;
    done_ = true;
    printSummary();
    const pid_t parent = getppid();
    if (shutdown_launch_ && parent > 1 && isRoslaunch(parent) && ::kill(parent, SIGINT) == 0) {
      // roslaunch stops every node (this one too) and ends cleanly; exit alone if it does not.
      std::printf("[demo_monitor] done: stopping the launch\n");
      std::fflush(stdout);
      launch_stop_deadline_ = ros::WallTime::now() + ros::WallDuration(15.0);
      return;
    }
    ros::shutdown();
  }

  ros::NodeHandle pnh_;
  message_filters::Subscriber<sensor_msgs::PointCloud2> sub_ground_, sub_nonground_;
  message_filters::Synchronizer<Policy> sync_;
  ros::Subscriber sub_time_;
  ros::WallTimer timer_;

  int max_scans_ = 0;
  double timeout_s_ = 60.0;
  ros::WallTime last_activity_;
  ros::WallTime previous_pair_arrival_;
  std::deque<Pending> pending_;
  std::deque<Timing> timings_;

  std::size_t scans_ = 0, timed_scans_ = 0, scored_scans_ = 0;
  std::uint64_t total_points_ = 0;
  double sum_filter_ms_ = 0.0, sum_latency_ms_ = 0.0, sum_f1_ = 0.0;
  gf::Confusion pooled_;
  std::uint64_t pooled_ignored_ = 0;
  bool done_ = false;
  bool failed_ = false;
  bool shutdown_launch_ = false;
  ros::WallTime launch_stop_deadline_;  // zero until the launch was asked to stop
};

}  // namespace

int main(int argc, char** argv) {
  ros::init(argc, argv, "demo_monitor");
  int status = 0;
  {
    DemoMonitor monitor;
    ros::spin();
    // Ctrl-C before max_scans: still print what was seen.
    monitor.finishOnExit();
    status = monitor.status();
  }
  return status;
}
