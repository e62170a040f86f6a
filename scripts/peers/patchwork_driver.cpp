// patchwork_driver: Patchwork (LimHyungTae/patchwork, the ROS 2 header patchwork.hpp, built
// unchanged against the stand-ins in ros2_standins/) with its config/velodyne64.yaml (KITTI's
// HDL-64E: sensor_height 1.723, ATAT on); the Patchwork row of docs/evaluation.md's held-out
// table. Driver interface of scripts/peers/README.md:
//   patchwork_driver --out DIR [--repeats N] [--set config=FILE] [--set NAME=VALUE]... FILE...
// NAME: any parameter patchwork.hpp declares (dotted: ATAT.ATAT_ON, czm.elevation_thresholds);
// one it does not declare is refused. Each file runs in a process of its own: patchwork.hpp keeps
// function-local statics (the zone model's ring index, the first frame's seed margin).
#include <sys/wait.h>
#include <tbb/global_control.h>
#include <unistd.h>

#include <algorithm>
#include <fstream>
#include <map>
#include <memory>
#include <patchwork/patchwork.hpp>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "driver_common.h"

#ifndef PATCHWORK_CONFIG
#define PATCHWORK_CONFIG ""
#endif

namespace {

/// \brief The parameters of a ROS 2 YAML file ("/**: ros__parameters: ..."), nested keys
///        joined with '.', each value as text (a list as "[a, b, ...]", also over several lines).
std::map<std::string, std::string> readYaml(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path + ": cannot open");
  std::map<std::string, std::string> out;
  std::vector<std::pair<std::size_t, std::string>> open;  // (indent, key) of enclosing maps
  std::string line;
  while (std::getline(in, line)) {
    line = line.substr(0, line.find('#'));
    const std::string t = peers::trimmed(line);
    if (t.empty()) continue;
    const std::size_t indent = line.find_first_not_of(' ');
    const std::size_t colon = t.find(':');
    if (colon == std::string::npos) throw std::runtime_error(path + ": cannot read: " + t);
    std::string key = peers::trimmed(t.substr(0, colon)),
                value = peers::trimmed(t.substr(colon + 1));
    while (!open.empty() && open.back().first >= indent) open.pop_back();
    if (value.empty()) {
      open.emplace_back(indent, key);
      continue;
    }
    while (value.front() == '[' && value.find(']') == std::string::npos && std::getline(in, line)) {
      value += " " + peers::trimmed(line.substr(0, line.find('#')));
    }
    std::string name;
    for (const auto& o : open) {
      if (o.second != "/**" && o.second != "ros__parameters") name += o.second + ".";
    }
    out[name + key] = value;
  }
  return out;
}

/// \brief One file, in the calling (child) process: labels from the warm-up call, then
///        `repeats` timed calls; prints PARAMS first when `params_line`.
void runFile(const peers::Args& args, const std::string& file, bool params_line) {
  tbb::global_control one_thread(tbb::global_control::max_allowed_parallelism, 1);
  std::string config = PATCHWORK_CONFIG;
  for (const auto& kv : args.sets) {
    if (kv.first == "config") config = kv.second;
  }
  rclcpp::Node node;
  if (!config.empty()) node.params = readYaml(config);
  for (const auto& kv : args.sets) {
    if (kv.first != "config") node.params[kv.first] = kv.second;
  }
  node.params["visualize"] = "false";
  PatchWork<pcl::PointXYZL> peer(&node);
  for (const auto& kv : args.sets) {
    const bool declared =
        kv.first == "config" ||
        std::any_of(node.used.begin(), node.used.end(), [&](const std::string& u) {
          return u.compare(0, kv.first.size() + 1, kv.first + "=") == 0;
        });
    if (!declared)
      throw std::invalid_argument("unknown --set " + kv.first + " (not a Patchwork parameter)");
  }
  if (params_line) {
    std::printf("PARAMS patchwork config=%s", config.c_str());
    for (const auto& u : node.used) std::printf(" %s", u.c_str());
    std::printf(" threads=1\n");
  }
  const peers::Scan scan = peers::readScan(file);
  pcl::PointCloud<pcl::PointXYZL> cloud;
  for (std::size_t i = 0; i < scan.size(); ++i) {
    if (!scan.given(i)) continue;
    pcl::PointXYZL p;
    p.x = scan.x[i];
    p.y = scan.y[i];
    p.z = scan.z[i];
    p.label = static_cast<std::uint32_t>(i);  // the input index: ground maps back to input points
    cloud.push_back(p);
  }
  std::vector<unsigned char> labels(scan.size(), 0);
  std::size_t n_ground = 0;
  std::vector<double> ms;
  for (int r = 0; r <= args.repeats; ++r) {
    pcl::PointCloud<pcl::PointXYZL> ground, nonground;
    const double t = peers::timeMs([&] { peer.estimate_ground(cloud, ground, nonground); });
    if (r > 0) {
      ms.push_back(t);
      continue;
    }
    for (const auto& p : ground.points) labels.at(p.label) = 1;
    n_ground = ground.size();
  }
  peers::writeGnd(args.out, file, labels);
  peers::printResult("patchwork", file, scan.size(), n_ground, ms, args.repeats);
}

int run(int argc, char** argv) {
  const peers::Args args = peers::parseArgs(
      argc, argv,
      "usage: patchwork_driver --out DIR [--repeats N] [--set config=FILE] [--set NAME=VALUE] "
      "FILE...");
  for (std::size_t f = 0; f < args.files.size(); ++f) {
    std::fflush(stdout);
    const pid_t pid = fork();
    if (pid < 0) throw std::runtime_error("fork failed");
    if (pid == 0) {
      int status = 0;
      try {
        runFile(args, args.files[f], f == 0);
      } catch (const std::exception& e) {
        std::fprintf(stderr, "patchwork_driver: %s\n", e.what());
        status = 1;
      }
      std::fflush(stdout);
      std::fflush(stderr);
      _exit(status);
    }
    int status = 0;
    if (waitpid(pid, &status, 0) != pid || !WIFEXITED(status) || WEXITSTATUS(status) != 0) {
      throw std::runtime_error(args.files[f] + ": failed (see above)");
    }
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) { return peers::runDriver("patchwork_driver", run, argc, argv); }
