// SoakDriver: a sensor driver's stand-in inside the nodelet manager, for `scripts/soak.sh
// --driver-in-manager` (docs/ros_integration.md, "A robot's load").
//
// A LiDAR driver that runs as a nodelet (ouster_ros, velodyne_pointcloud) hands its clouds to the
// nodelets of its manager by pointer: nothing is serialised. This nodelet does the same with one
// scan file: a new message with a new stamp at a fixed rate, from a thread of its own (a driver
// has its own; the manager's worker threads stay the filters'). It also checks, in the same
// manager, the outputs of the filter nodelets named in ~filters: the /NAME/ground and
// /NAME/nonground of each cloud must together hold all its points. Its counts go to
// /diagnostics every second through a diagnostic_updater, as the filters' status (status
// "NODELET_NAME: outputs"), where scripts/soak.py reads them.
//
// Parameters:
//   ~input (string)              the scan (.bin, .pcd, .ply), read once
//   ~rate (double, 10)           clouds per second [Hz], (0, 1000]
//   ~frame_id (string, os_sensor) header frame_id
//   ~filters (string, "")        filter nodelet names, separated by commas or spaces
// Topics: ~output (sensor_msgs/PointCloud2, out); ~pause (std_msgs/Bool, in: true stops the
// clouds, false resumes them).
#include <diagnostic_updater/diagnostic_updater.h>
#include <nodelet/nodelet.h>
#include <pcl_conversions/pcl_conversions.h>
#include <ros/ros.h>
#include <sensor_msgs/PointCloud2.h>
#include <std_msgs/Bool.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <pluginlib/class_list_macros.hpp>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "eval/scan_io.h"

namespace ground_filter {

/// \brief Publishes one scan at a fixed rate and checks the filters' outputs (file comment).
class SoakDriverNodelet : public nodelet::Nodelet {
 public:
  ~SoakDriverNodelet() override {
    {
      std::lock_guard<std::mutex> lock(wake_mutex_);
      stop_ = true;
    }
    wake_.notify_all();
    if (thread_.joinable()) thread_.join();
  }

 private:
  /// One filter's outputs not yet paired (stamp in ns -> points) and its counts.
  struct Filter {
    std::string name;
    std::map<std::uint64_t, std::uint64_t> ground, nonground;
    std::uint64_t pairs = 0, not_conserved = 0;
    ros::Subscriber ground_sub, nonground_sub;
  };

  void onInit() override {
    ros::NodeHandle& pnh = getPrivateNodeHandle();
    std::string input, filters;
    pnh.param<std::string>("input", input, "");
    pnh.param<std::string>("frame_id", frame_id_, "os_sensor");
    pnh.param("rate", rate_, 10.0);
    pnh.param<std::string>("filters", filters, "");
    if (!(rate_ > 0.0 && rate_ <= 1000.0)) {
      NODELET_FATAL("~rate = %g is out of range (0, 1000] Hz; publishing nothing", rate_);
      return;
    }
    try {
      Scan scan = loadScan(input, /*keep_float64=*/true);
      pcl_conversions::moveFromPCL(scan.cloud, scan_);
    } catch (const std::exception& e) {
      NODELET_FATAL("~input: %s; publishing nothing", e.what());
      return;
    }
    scan_.header.frame_id = frame_id_;
    points_ = static_cast<std::uint64_t>(scan_.width) * scan_.height;
    std::string name;
    std::istringstream names(filters);
    while (std::getline(names, name, ',')) {
      std::istringstream words(name);
      std::string word;
      while (words >> word) filters_.push_back(Filter{word, {}, {}, 0, 0, {}, {}});
    }
    ros::NodeHandle& nh = getNodeHandle();
    for (std::size_t f = 0; f < filters_.size(); ++f) {
      const std::string& n = filters_[f].name;
      filters_[f].ground_sub = nh.subscribe<sensor_msgs::PointCloud2>(
          "/" + n + "/ground", 10,
          [this, f](const sensor_msgs::PointCloud2ConstPtr& m) { onOutput(m, f, true); });
      filters_[f].nonground_sub = nh.subscribe<sensor_msgs::PointCloud2>(
          "/" + n + "/nonground", 10,
          [this, f](const sensor_msgs::PointCloud2ConstPtr& m) { onOutput(m, f, false); });
    }
    pub_ = pnh.advertise<sensor_msgs::PointCloud2>("output", 2);
    // As the filters' status: the updater names it "NAME: outputs" after this nodelet.
    updater_ = std::make_unique<diagnostic_updater::Updater>(nh, pnh, getName());
    updater_->setHardwareID(getName().substr(1));
    updater_->add("outputs", this, &SoakDriverNodelet::report);
    pause_sub_ = pnh.subscribe<std_msgs::Bool>(
        "pause", 10, [this](const std_msgs::BoolConstPtr& m) { paused_ = m->data; });
    report_timer_ = nh.createWallTimer(
        ros::WallDuration(1.0), [this](const ros::WallTimerEvent&) { updater_->force_update(); });
    NODELET_INFO("publishing %s (%llu points) at %g Hz; checking the outputs of %zu filter(s)",
                 input.c_str(), static_cast<unsigned long long>(points_), rate_, filters_.size());
    thread_ = std::thread([this] { publishLoop(); });
  }

  /// The clouds, on schedule (a late one moves the schedule, as a driver that fell behind).
  void publishLoop() {
    using Clock = std::chrono::steady_clock;
    const auto period =
        std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(1.0 / rate_));
    // Clouds published before the filters have subscribed would count as lost. The manager's
    // nodelets share one subscription of a topic: one subscriber, however many filters (soak.py
    // loads this nodelet once they have all subscribed).
    const auto deadline = Clock::now() + std::chrono::seconds(30);
    while (pub_.getNumSubscribers() == 0 && Clock::now() < deadline &&
           !waitFor(std::chrono::milliseconds(50))) {
    }
    if (waitFor(std::chrono::milliseconds(500))) return;
    auto next = Clock::now();
    Clock::time_point last{};
    bool have_last = false;
    while (true) {
      if (!paused_) {
        auto msg = boost::make_shared<sensor_msgs::PointCloud2>(scan_);  // a new cloud
        msg->header.stamp = ros::Time::now();
        msg->header.seq = static_cast<std::uint32_t>(published_);
        pub_.publish(sensor_msgs::PointCloud2ConstPtr(msg));
        const auto now = Clock::now();
        // Seconds between consecutive clouds without the pauses: kept / active is the rate
        // kept while publishing.
        if (have_last &&
            now - last <= std::max<Clock::duration>(std::chrono::seconds(1), 5 * period)) {
          active_ns_ += std::chrono::duration_cast<std::chrono::nanoseconds>(now - last).count();
          ++intervals_;
        }
        last = now;
        have_last = true;
        ++published_;
      } else {
        have_last = false;
      }
      next += period;
      const auto now = Clock::now();
      if (next < now) next = now;
      if (waitUntil(next)) return;
    }
  }

  /// Sleeps until t; true when the nodelet is being unloaded.
  bool waitUntil(std::chrono::steady_clock::time_point t) {
    std::unique_lock<std::mutex> lock(wake_mutex_);
    return wake_.wait_until(lock, t, [this] { return stop_; });
  }
  template <class D>
  bool waitFor(D d) {
    return waitUntil(std::chrono::steady_clock::now() + d);
  }

  void onOutput(const sensor_msgs::PointCloud2ConstPtr& m, std::size_t f, bool ground) {
    std::lock_guard<std::mutex> lock(mutex_);
    Filter& flt = filters_[f];
    const std::uint64_t stamp = m->header.stamp.toNSec();
    const std::uint64_t points = static_cast<std::uint64_t>(m->width) * m->height;
    auto& mine = ground ? flt.ground : flt.nonground;
    auto& other = ground ? flt.nonground : flt.ground;
    const auto it = other.find(stamp);
    if (it == other.end()) {
      mine[stamp] = points;
      return;
    }
    ++flt.pairs;
    if (it->second + points != points_) ++flt.not_conserved;
    other.erase(it);
  }

  void report(diagnostic_updater::DiagnosticStatusWrapper& st) {
    st.add("published", std::to_string(published_.load()));
    st.add("intervals", std::to_string(intervals_.load()));
    st.add("active seconds", std::to_string(active_ns_.load() * 1e-9));
    st.add("points per cloud", std::to_string(points_));
    bool ok = true;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      for (const Filter& f : filters_) {
        st.add(f.name + " pairs", std::to_string(f.pairs));
        st.add(f.name + " points not conserved", std::to_string(f.not_conserved));
        st.add(f.name + " unpaired", std::to_string(f.ground.size() + f.nonground.size()));
        ok &= f.not_conserved == 0;
      }
    }
    st.summary(
        ok ? diagnostic_msgs::DiagnosticStatus::OK : diagnostic_msgs::DiagnosticStatus::ERROR,
        ok ? "every pair conserved its points" : "points not conserved");
  }

  sensor_msgs::PointCloud2 scan_;
  std::string frame_id_;
  double rate_ = 10.0;
  std::uint64_t points_ = 0;
  std::vector<Filter> filters_;
  std::mutex mutex_;  // filters_' maps and counts (the output callbacks, report())
  ros::Publisher pub_;
  std::unique_ptr<diagnostic_updater::Updater> updater_;
  ros::Subscriber pause_sub_;
  ros::WallTimer report_timer_;
  std::atomic<bool> paused_{false};
  std::atomic<std::uint64_t> published_{0}, intervals_{0};
  std::atomic<std::int64_t> active_ns_{0};
  std::thread thread_;
  std::mutex wake_mutex_;
  std::condition_variable wake_;
  bool stop_ = false;
};

}  // namespace ground_filter

PLUGINLIB_EXPORT_CLASS(ground_filter::SoakDriverNodelet, nodelet::Nodelet)
