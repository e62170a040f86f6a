// scene_publisher: streams scans as sensor_msgs/PointCloud2 for the demo and for tests.
//
// Source: the built-in procedural street scene (default; the sensor drives forward along the
// road, so consecutive scans differ) or real scan files (`~input`: a file, a directory of
// .bin/.pcd/.ply, or builtin:KIND[:SEED][:NAME=VALUE,...], e.g. a sensor of your own).
// Every cloud carries a uint8 field `gt_ground` (1 ground, 0 non-ground, 255 ignored) when ground
// truth is known, so that demo_monitor can score the filter's outputs (the filter copies every
// field to its outputs).
//
// Topic: ~output (sensor_msgs/PointCloud2).
// Parameters:
//   ~input (string, "")          scan file/directory/builtin:...; empty = generated LiDAR scene
//                                (a file's fields go out as they are: float64 x/y/z stay float64)
//   ~frame_id (string, velodyne) header frame_id
//   ~rate (double, 10)           scans per second [Hz]
//   ~loop (bool, true)           start over after the last file
//   ~max_scans (int, 0)          stop after this many scans (0 = unlimited)
//   ~wait_for_subscribers (bool, true)  publish only while ~output has a subscriber
//   generated scene only:
//   ~mode (string, lidar)        builtin scene kind: lidar (64-beam, moving), tls (tripod
//                                sweep), verge, offroad, trail (fixed scanner, new noise)
//   ~seed (int, 1)               scene layout seed
//   ~speed (double, 10)          sensor speed along the road [m/s]
//   ~tls_points (int, 2000000)   TLS point budget [points] (1 k..100 M)
//   ~nan_points (int, 0)         NaN points added to each scan (robustness demo) [points]
#include <pcl_conversions/pcl_conversions.h>
#include <ros/ros.h>
#include <sensor_msgs/PointCloud2.h>

#include <cstdint>
#include <cstring>
#include <exception>
#include <string>
#include <utility>
#include <vector>

#include "eval/scan_io.h"
#include "eval/scene_generator.h"

namespace {

constexpr std::uint8_t kTruthIgnore = 255;
constexpr char kTruthField[] = "gt_ground";

// The sensor drives over this stretch of the generated road and then starts over.
constexpr double kPathStartX = -10.0;
constexpr double kPathEndX = 40.0;

// Loaded scan -> PointCloud2 with all its fields, plus gt_ground when it has ground truth.
void toMessage(ground_filter::Scan* scan, sensor_msgs::PointCloud2* msg) {
  pcl::PCLPointCloud2& in = scan->cloud;
  if (scan->labelled()) {
    for (const auto& f : in.fields) {
      if (f.name == kTruthField) throw std::runtime_error("already has a gt_ground field");
    }
    // Append one byte to every record; rows are repacked without padding.
    const std::size_t n = scan->size(), old_step = in.point_step, new_step = old_step + 1;
    std::vector<std::uint8_t> data(n * new_step);
    for (std::size_t r = 0; r < in.height; ++r) {
      for (std::size_t c = 0; c < in.width; ++c) {
        const std::size_t i = r * in.width + c;
        std::memcpy(&data[i * new_step], &in.data[r * in.row_step + c * old_step], old_step);
        const std::int8_t t = scan->truth[i];
        data[i * new_step + old_step] = t < 0 ? kTruthIgnore : static_cast<std::uint8_t>(t);
      }
    }
    pcl::PCLPointField f;
    f.name = kTruthField;
    f.offset = static_cast<std::uint32_t>(old_step);
    f.datatype = pcl::PCLPointField::UINT8;
    f.count = 1;
    in.fields.push_back(f);
    in.point_step = static_cast<std::uint32_t>(new_step);
    in.row_step = static_cast<std::uint32_t>(new_step * in.width);
    in.data = std::move(data);
  }
  pcl_conversions::moveFromPCL(in, *msg);
}

// Generated scan -> PointCloud2 with x y z intensity (float32), ring (uint16), gt_ground (uint8).
void toMessage(ground_filter::GeneratedScan scene, sensor_msgs::PointCloud2* msg) {
  ground_filter::Scan scan = ground_filter::scanOf(std::move(scene));
  toMessage(&scan, msg);
}

/// The node's private parameters (see the file comment).
struct PublisherParams {
  std::string input, frame_id, mode;
  double rate = 10.0, speed = 10.0;
  bool loop = true, wait_for_subscribers = true;
  int max_scans = 0, seed = 1, tls_points = 2000000, nan_points = 0;
};

/// Reads and checks ~rate and the counts; false (logged) when one is out of range.
bool readParams(const ros::NodeHandle& pnh, PublisherParams* p) {
  pnh.param<std::string>("input", p->input, "");
  pnh.param<std::string>("frame_id", p->frame_id, "velodyne");
  pnh.param<std::string>("mode", p->mode, "lidar");
  pnh.param("rate", p->rate, p->rate);
  pnh.param("speed", p->speed, p->speed);
  pnh.param("loop", p->loop, p->loop);
  pnh.param("wait_for_subscribers", p->wait_for_subscribers, p->wait_for_subscribers);
  pnh.param("max_scans", p->max_scans, p->max_scans);
  pnh.param("seed", p->seed, p->seed);
  pnh.param("tls_points", p->tls_points, p->tls_points);
  pnh.param("nan_points", p->nan_points, p->nan_points);

  if (!(p->rate > 0.0 && p->rate <= 1000.0)) {
    ROS_FATAL("~rate = %g is out of range (0, 1000] Hz", p->rate);
    return false;
  }
  if (p->max_scans < 0 || p->seed < 0 || p->tls_points < 0 || p->nan_points < 0) {
    ROS_FATAL("~max_scans, ~seed, ~tls_points and ~nan_points must be >= 0");
    return false;
  }
  return true;
}

/// The generated scene of ~mode with ~seed, ~tls_points, ~nan_points; false (logged) if invalid.
bool sceneOf(const PublisherParams& p, ground_filter::SceneParams* scene) {
  try {
    *scene = ground_filter::builtinSceneParams(p.mode);  // scene layout and scanner of the kind
  } catch (const std::exception& e) {
    ROS_FATAL("~mode: %s", e.what());
    return false;
  }
  scene->seed = static_cast<std::uint32_t>(p.seed);
  scene->tls_points = static_cast<std::size_t>(p.tls_points);
  scene->nan_points = static_cast<std::size_t>(p.nan_points);
  try {
    scene->validate();
  } catch (const std::exception& e) {
    ROS_FATAL("scene parameters: %s", e.what());
    return false;
  }
  return true;
}

/// The scan files of ~input (none: the generated scene is published); false (logged) when
/// ~input cannot be listed or holds no scan.
bool inputFiles(const PublisherParams& p, std::vector<std::string>* files) {
  if (!p.input.empty()) {
    try {
      *files = ground_filter::listScanFiles(p.input);
    } catch (const std::exception& e) {
      ROS_FATAL("~input: %s", e.what());
      return false;
    }
    if (files->empty()) {
      ROS_FATAL("~input '%s' holds no .bin/.pcd/.ply scan", p.input.c_str());
      return false;
    }
    ROS_INFO("publishing %zu scan file(s) from %s at %g Hz%s", files->size(), p.input.c_str(),
             p.rate, p.loop ? " (looping)" : "");
  } else {
    ROS_INFO("publishing the generated '%s' scene (seed %d) at %g Hz", p.mode.c_str(), p.seed,
             p.rate);
  }
  return true;
}

/// The generated scene, one scan a call: the street scene's sensor drives along the path; the
/// tripod does not move, so its (large) scan is generated once and re-stamped.
class GeneratedSource {
 public:
  GeneratedSource(const PublisherParams& p, const ground_filter::SceneParams& scene)
      : scene_(scene), drives_(p.mode == "lidar"), speed_(p.speed), rate_(p.rate) {}

  /// Scan number `published` into `msg`; `what` describes it.
  void next(std::uint32_t published, sensor_msgs::PointCloud2* msg, std::string* what) {
    if (scene_.mode == ground_filter::SceneParams::Mode::kTls) {
      if (!tls_cached_) {
        toMessage(ground_filter::generateScene(scene_), &tls_cache_);
        tls_cached_ = true;
      }
      *msg = tls_cache_;
    } else {
      if (drives_) {
        const double span = kPathEndX - kPathStartX;
        scene_.sensor_x = kPathStartX + std::fmod(published * speed_ / rate_, span);
      }
      scene_.noise_seed = published;
      toMessage(ground_filter::generateScene(scene_), msg);
    }
    char buf[64];
    std::snprintf(buf, sizeof(buf), "generated (sensor at x = %.1f m)", scene_.sensor_x);
    *what = buf;
  }

 private:
  ground_filter::SceneParams scene_;
  bool drives_;  // only the street scene has a driving path
  double speed_, rate_;
  sensor_msgs::PointCloud2 tls_cache_;
  bool tls_cached_ = false;
};

/// The scan files in turn (from the first again with ~loop).
class FileSource {
 public:
  enum class Step { kScan, kSkip, kEnd, kFailed };

  FileSource(std::vector<std::string> files, bool loop) : files_(std::move(files)), loop_(loop) {}

  /// The next file into `msg`: kScan, kSkip (unreadable, logged), kEnd (all published, no
  /// loop) or kFailed (no file could be read, logged).
  Step next(sensor_msgs::PointCloud2* msg, std::string* what) {
    if (index_ >= files_.size()) {
      if (!loop_) return Step::kEnd;
      index_ = 0;
    }
    const std::string& path = files_[index_++];
    try {
      // float64 x/y/z (a map in UTM) go out as they are: the filter keeps their precision.
      ground_filter::Scan scan = ground_filter::loadScan(path, /*keep_float64=*/true);
      toMessage(&scan, msg);
      *what = path + (scan.labelled() ? "" : " (no labels)");
      failures_in_a_row_ = 0;
    } catch (const std::exception& e) {
      ROS_ERROR("skipping %s: %s", path.c_str(), e.what());
      if (++failures_in_a_row_ >= files_.size()) {
        ROS_FATAL("no scan of ~input could be read");
        return Step::kFailed;
      }
      return Step::kSkip;
    }
    return Step::kScan;
  }

 private:
  std::vector<std::string> files_;
  bool loop_;
  std::size_t index_ = 0, failures_in_a_row_ = 0;
};

}  // namespace

int main(int argc, char** argv) {
  ros::init(argc, argv, "scene_publisher");
  ros::NodeHandle pnh("~");
  PublisherParams p;
  ground_filter::SceneParams scene;
  std::vector<std::string> files;
  if (!readParams(pnh, &p) || !sceneOf(p, &scene) || !inputFiles(p, &files)) return 1;
  const bool generated = files.empty();
  GeneratedSource gen(p, scene);
  FileSource file_source(std::move(files), p.loop);

  ros::Publisher pub = pnh.advertise<sensor_msgs::PointCloud2>("output", 2);
  if (p.wait_for_subscribers) {
    ROS_INFO("waiting for a subscriber on %s", pub.getTopic().c_str());
  }
  ros::Rate loop_rate(p.rate);
  std::uint32_t published = 0;
  while (ros::ok()) {
    if (p.wait_for_subscribers && pub.getNumSubscribers() == 0) {
      ros::WallDuration(0.05).sleep();
      ros::spinOnce();
      continue;
    }
    auto msg = boost::make_shared<sensor_msgs::PointCloud2>();
    const ros::WallTime t0 = ros::WallTime::now();
    std::string what;
    if (generated) {
      gen.next(published, msg.get(), &what);
    } else {
      const FileSource::Step step = file_source.next(msg.get(), &what);
      if (step == FileSource::Step::kEnd) break;
      if (step == FileSource::Step::kFailed) return 1;
      if (step == FileSource::Step::kSkip) continue;
    }
    msg->header.frame_id = p.frame_id;
    msg->header.stamp = ros::Time::now();
    pub.publish(sensor_msgs::PointCloud2ConstPtr(msg));
    ROS_DEBUG("scan %u: %u points, %s, prepared in %.1f ms", published, msg->width * msg->height,
              what.c_str(), (ros::WallTime::now() - t0).toSec() * 1e3);
    ++published;
    if (p.max_scans > 0 && published >= static_cast<std::uint32_t>(p.max_scans)) break;
    ros::spinOnce();
    loop_rate.sleep();
  }
  ROS_INFO("published %u scan(s)", published);
  return 0;
}
