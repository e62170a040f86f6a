#include "nodelet_monitor.h"

#include <diagnostic_msgs/DiagnosticStatus.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>

namespace ground_filter {

constexpr double NodeletMonitor::kLogPeriodS;

namespace {

// How busy the filter was in one diagnostic window; busy < 0: not known (no cloud).
struct Load {
  double busy = -1.0;
  double mean_ms = 0.0;
  double between_ms = 0.0;
};

// Cannot keep up: clouds lost before the callback (seq / stamp gaps, InputGapCounter), or the
// filter busy nearly all the wall time between the clouds' arrivals. A filter that keeps up idles
// between clouds; one that does not takes the next cloud as soon as it is done (the input queue
// fills and drops the oldest), so its processing time approaches the time between arrivals. Wall
// time: a bag played slower or faster is judged by what it really delivers. Appends the problems
// (", "-separated) to *problems.
Load loadCheck(std::uint64_t lost, std::uint64_t clouds, double ms_sum, std::uint64_t arrivals,
               double arrival_sum, std::string* problems) {
  Load load;
  if (clouds && arrivals && arrival_sum > 0.0) {
    load.mean_ms = ms_sum / clouds;
    load.between_ms = 1000.0 * arrival_sum / arrivals;
    load.busy = load.mean_ms / load.between_ms;
  }
  std::string text;
  if (lost) text = std::to_string(lost) + " lost before the filter (input queue full?)";
  if (load.busy >= 0.9) {
    char busy[160];
    std::snprintf(busy, sizeof(busy),
                  "filter busy %.0f %% of the time (%.1f ms a cloud, one every %.1f ms): it "
                  "cannot keep up with its input",
                  100.0 * load.busy, load.mean_ms, load.between_ms);
    text += (text.empty() ? "" : ", ") + std::string(busy);
  }
  if (!text.empty()) *problems += (problems->empty() ? "" : ", ") + text;
  return load;
}

void addLoad(diagnostic_updater::DiagnosticStatusWrapper& status, double period_s,
             const Load& load) {
  if (period_s > 0.0) {
    status.addf("input period [ms] (stamps)", "%.1f", 1000.0 * period_s);
  } else {
    status.add("input period [ms] (stamps)", "n/a (too few clouds)");
  }
  if (load.busy >= 0.0) {
    status.addf("busy [%] (processing / time between clouds)", "%.0f", 100.0 * load.busy);
  } else {
    status.add("busy [%] (processing / time between clouds)", "n/a (too few clouds)");
  }
}

}  // namespace

NodeletMonitor::CounterValues NodeletMonitor::Counters::values() const {
  CounterValues v;
  const auto& live = CounterSet<std::atomic<std::uint64_t>>::all();
  for (std::size_t i = 0; i < live.size(); ++i) v.*CounterValues::all()[i] = this->*live[i];
  return v;
}

NodeletMonitor::NodeletMonitor() : last_diagnose_(ros::WallTime::now()) {}

bool NodeletMonitor::logNow(int slot, std::uint64_t* suppressed) {
  const ros::WallTime now = ros::WallTime::now();
  std::lock_guard<std::mutex> lock(mutex_);
  ros::WallTime& last = last_log_[slot];
  if (!last.isZero() && (now - last).toSec() < kLogPeriodS) {
    ++suppressed_[slot];
    return false;
  }
  last = now;
  if (suppressed) *suppressed = suppressed_[slot];
  suppressed_[slot] = 0;
  return true;
}

NodeletMonitor::StreamChange NodeletMonitor::checkStream(const std_msgs::Header& header) {
  StreamChange change;
  std::lock_guard<std::mutex> lock(mutex_);
  if (have_last_) {
    change.frame_changed = header.frame_id != last_frame_id_;
    change.went_back = header.stamp < last_stamp_;
    if (change.frame_changed) change.old_frame = last_frame_id_;
    if (change.went_back) change.back_s = (last_stamp_ - header.stamp).toSec();
  }
  change.gap = gaps_.step(header.seq, header.stamp.toSec(), header.frame_id);
  const ros::WallTime now = ros::WallTime::now();
  if (!last_arrival_.isZero()) {
    window_arrival_sum_ += (now - last_arrival_).toSec();
    ++window_arrivals_;
  }
  last_arrival_ = now;
  last_frame_id_ = header.frame_id;
  last_stamp_ = header.stamp;
  have_last_ = true;
  return change;
}

void NodeletMonitor::restartStream() {
  std::lock_guard<std::mutex> lock(mutex_);
  gaps_.restart();
  last_arrival_ = ros::WallTime();
}

void NodeletMonitor::recordCloud(double ms, const std::string& backend, const std::string& note,
                                 const std::string& scan_type) {
  std::lock_guard<std::mutex> lock(mutex_);
  window_ms_sum_ += ms;
  window_ms_max_ = std::max(window_ms_max_, ms);
  ++window_clouds_;
  backend_ = backend;
  scan_type_ = scan_type;
  if (!note.empty()) fallback_note_ = note;
}

void NodeletMonitor::recordRefused(const std::string& why) {
  std::lock_guard<std::mutex> lock(mutex_);
  refused_ = why;
}

void NodeletMonitor::recordCentre(const double* centre, const std::string& frame_id) {
  std::lock_guard<std::mutex> lock(mutex_);
  centre_state_ = centre ? Centre::kKnown : Centre::kNoFinitePoint;
  if (centre) std::copy(centre, centre + 3, centre_);
  centre_frame_ = frame_id;
}

void NodeletMonitor::diagnose(diagnostic_updater::DiagnosticStatusWrapper& status,
                              const std::string& method, const std::string& gravity_frame,
                              bool have_config) {
  using ull = unsigned long long;
  const ros::WallTime now = ros::WallTime::now();
  const CounterValues total = counters_.values();
  CounterValues last;
  double ms_sum, ms_max, dt, arrival_sum, period_s;
  std::uint64_t clouds, arrivals;
  std::string backend, note, scan_type, refused;
  char centre[192] = "n/a (no cloud)";
  {
    std::lock_guard<std::mutex> lock(mutex_);
    ms_sum = window_ms_sum_;
    ms_max = window_ms_max_;
    clouds = window_clouds_;
    window_ms_sum_ = window_ms_max_ = 0.0;
    window_clouds_ = 0;
    arrival_sum = window_arrival_sum_;
    arrivals = window_arrivals_;
    window_arrival_sum_ = 0.0;
    window_arrivals_ = 0;
    period_s = gaps_.period();
    backend = backend_;
    note = fallback_note_;
    scan_type = scan_type_;
    refused = refused_;
    if (centre_state_ == Centre::kKnown) {
      std::snprintf(centre, sizeof(centre), "%.1f %.1f %.1f in '%s' (bounding box middle)",
                    centre_[0], centre_[1], centre_[2], centre_frame_.c_str());
    } else if (centre_state_ == Centre::kNoFinitePoint) {
      std::snprintf(centre, sizeof(centre), "n/a (no finite point)");
    }
    dt = std::max(1e-6, (now - last_diagnose_).toSec());
    last_diagnose_ = now;
    last = last_counts_;
    last_counts_ = total;
  }
  // Drop reasons and stream irregularities: name, count since start, count since last update.
  struct Item {
    const char* name;
    std::uint64_t total;
    std::uint64_t delta;
  };
  auto item = [&](const char* name, std::uint64_t CounterValues::*field) {
    return Item{name, total.*field, total.*field - last.*field};
  };
  const Item drops[] = {
      item("malformed", &CounterValues::clouds_rejected),
      item("no transform", &CounterValues::clouds_no_transform),
      item("not PointCloud2", &CounterValues::not_cloud),
  };
  const Item stream[] = {
      item("frame_id changes", &CounterValues::frame_changes),
      item("stamps going back", &CounterValues::stamps_backwards),
  };
  const Item lost = item("lost before the filter", &CounterValues::clouds_lost);
  const Item sets = item("parameter sets refused", &CounterValues::config_rejected);
  const double in_hz = (total.clouds_in - last.clouds_in) / dt;
  const double out_hz = (total.clouds_out - last.clouds_out) / dt;

  char head[128];
  std::snprintf(head, sizeof(head), "%.1f Hz in, %.1f Hz out", in_hz, out_hz);
  std::string problems;
  for (const Item& d : drops) {
    if (d.delta) {
      problems +=
          (problems.empty() ? "" : ", ") + std::to_string(d.delta) + " dropped (" + d.name + ")";
    }
  }
  for (const Item& s : stream) {
    if (s.delta)
      problems += (problems.empty() ? "" : ", ") + std::to_string(s.delta) + " " + s.name;
  }
  if (sets.delta) {
    problems += (problems.empty() ? "" : ", ") + std::to_string(sets.delta) + " " + sets.name;
  }
  const Load load = loadCheck(lost.delta, clouds, ms_sum, arrivals, arrival_sum, &problems);
  if (!have_config) {
    status.summary(diagnostic_msgs::DiagnosticStatus::ERROR, "no filter configuration");
  } else if (!problems.empty()) {
    char since[48];
    std::snprintf(since, sizeof(since), " in the last %.1f s", dt);
    status.summary(diagnostic_msgs::DiagnosticStatus::WARN,
                   std::string(head) + "; " + problems + since);
  } else {
    status.summary(diagnostic_msgs::DiagnosticStatus::OK, head);
  }

  status.add("method", method);
  status.add("backend", backend.empty() ? std::string("n/a (no neighbour search)") : backend);
  status.add("scan type", scan_type.empty() ? std::string("n/a (no cloud)") : scan_type);
  status.add("cloud centre [m]", std::string(centre));
  status.add("gravity frame", gravity_frame.empty() ? std::string("(input frame)") : gravity_frame);
  status.addf("input rate [Hz]", "%.2f", in_hz);
  status.addf("output rate [Hz]", "%.2f", out_hz);
  if (clouds) {
    status.addf("processing time mean [ms]", "%.2f", ms_sum / clouds);
    status.addf("processing time max [ms]", "%.2f", ms_max);
  } else {
    status.add("processing time mean [ms]", "n/a (no cloud)");
    status.add("processing time max [ms]", "n/a (no cloud)");
  }
  status.add("clouds in", static_cast<ull>(total.clouds_in));
  status.add("clouds out", static_cast<ull>(total.clouds_out));
  status.add("dropped", static_cast<ull>(total.dropped()));
  for (const Item& d : drops)
    status.add(std::string("dropped: ") + d.name, static_cast<ull>(d.total));
  // Never received, so neither in "clouds in" nor in "dropped".
  status.add("lost before the filter (seq/stamp gaps)", static_cast<ull>(lost.total));
  addLoad(status, period_s, load);
  status.add("invalid points (NaN/Inf)", static_cast<ull>(total.invalid_points));
  status.add("out of range points", static_cast<ull>(total.out_of_range_points));
  status.add("near points (min_range, body_box)", static_cast<ull>(total.near_points));
  status.add("filter errors (published as non-ground)", static_cast<ull>(total.filter_errors));
  status.add("fallbacks", static_cast<ull>(total.fallbacks));
  status.add("buffer releases (after a large cloud)", static_cast<ull>(total.buffer_releases));
  status.add("last fallback", note.empty() ? std::string("none") : note);
  for (const Item& s : stream) status.add(s.name, static_cast<ull>(s.total));
  status.add("refused parameter sets", static_cast<ull>(total.config_rejected));
  status.add("last refused parameter set", refused.empty() ? std::string("none") : refused);
}

void NodeletMonitor::noteKind(const std::string& note, std::string* kind) {
  kind->clear();
  auto digit = [&note](std::size_t i) {
    return std::isdigit(static_cast<unsigned char>(note[i])) != 0;
  };
  for (std::size_t i = 0; i < note.size();) {
    if (!digit(i)) {
      kind->push_back(note[i++]);
      continue;
    }
    // A number: its digits and the points between them ("7.7", "240000", "0.0625").
    while (i < note.size() &&
           (digit(i) || (note[i] == '.' && i + 1 < note.size() && digit(i + 1)))) {
      ++i;
    }
    kind->push_back('#');
  }
}

}  // namespace ground_filter
