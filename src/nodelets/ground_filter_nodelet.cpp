#include "ground_filter_nodelet.h"

#include <sensor_msgs/PointField.h>
#include <std_msgs/Float64.h>

#include <boost/make_shared.hpp>
#include <chrono>
#include <cmath>
#include <cstring>
#include <exception>
#include <sstream>
#include <utility>

namespace ground_filter {

namespace {

// Seconds between two ERROR lines for the same rejection reason.
constexpr double kRejectLogPeriodS = 5.0;

std::size_t datatypeSize(std::uint8_t datatype) {
  switch (datatype) {
    case sensor_msgs::PointField::INT8:
    case sensor_msgs::PointField::UINT8:
      return 1;
    case sensor_msgs::PointField::INT16:
    case sensor_msgs::PointField::UINT16:
      return 2;
    case sensor_msgs::PointField::INT32:
    case sensor_msgs::PointField::UINT32:
    case sensor_msgs::PointField::FLOAT32:
      return 4;
    case sensor_msgs::PointField::FLOAT64:
      return 8;
    default:
      return 0;
  }
}

const char* reasonName(CloudRejectReason r) {
  switch (r) {
    case CloudRejectReason::kBigEndian:
      return "big-endian";
    case CloudRejectReason::kMissingField:
      return "missing field";
    case CloudRejectReason::kFieldType:
      return "field type";
    case CloudRejectReason::kFieldCount:
      return "field count";
    case CloudRejectReason::kFieldExtent:
      return "field extent";
    case CloudRejectReason::kRowStep:
      return "row_step";
    case CloudRejectReason::kDataSize:
      return "data size";
    default:
      return "none";
  }
}

float loadFloat(const std::uint8_t* p) {
  float v;
  std::memcpy(&v, p, sizeof(float));
  return v;
}

// Output cloud with the input's header and record layout, room for `n` records.
void prepareOutput(const sensor_msgs::PointCloud2& in, std::size_t n,
                   sensor_msgs::PointCloud2* out) {
  out->header = in.header;
  out->fields = in.fields;
  out->is_bigendian = in.is_bigendian;
  out->point_step = in.point_step;
  out->height = 1;
  out->width = static_cast<std::uint32_t>(n);
  out->row_step = static_cast<std::uint32_t>(n * in.point_step);
  out->data.resize(n * in.point_step);
}

}  // namespace

CloudRejectReason checkPointCloud2(const sensor_msgs::PointCloud2& cloud, CloudLayout* layout,
                                   std::string* message) {
  std::ostringstream why;
  auto reject = [&](CloudRejectReason r) {
    if (message) *message = why.str();
    return r;
  };
  if (cloud.is_bigendian) {
    why << "is_bigendian is true; only little-endian data is supported";
    return reject(CloudRejectReason::kBigEndian);
  }
  // x, y and z: float32, one element each, anywhere inside the record.
  const char* axes[3] = {"x", "y", "z"};
  std::size_t offsets[3] = {0, 0, 0};
  for (int a = 0; a < 3; ++a) {
    const sensor_msgs::PointField* found = nullptr;
    for (const auto& f : cloud.fields) {
      if (f.name == axes[a]) {
        found = &f;
        break;
      }
    }
    if (!found) {
      why << "no field '" << axes[a] << "' (fields:";
      for (const auto& f : cloud.fields) why << " " << f.name;
      why << ")";
      return reject(CloudRejectReason::kMissingField);
    }
    if (found->datatype != sensor_msgs::PointField::FLOAT32) {
      why << "field '" << axes[a] << "' has datatype " << static_cast<int>(found->datatype)
          << ", expected FLOAT32 (" << static_cast<int>(sensor_msgs::PointField::FLOAT32) << ")";
      return reject(CloudRejectReason::kFieldType);
    }
    if (found->count != 1) {
      why << "field '" << axes[a] << "' has count " << found->count << ", expected 1";
      return reject(CloudRejectReason::kFieldCount);
    }
    offsets[a] = found->offset;
  }
  // Every field (x/y/z and the ones only copied) must lie inside the record.
  for (const auto& f : cloud.fields) {
    const std::size_t size = datatypeSize(f.datatype);
    if (size == 0) {
      why << "field '" << f.name << "' has unknown datatype " << static_cast<int>(f.datatype);
      return reject(CloudRejectReason::kFieldType);
    }
    const std::uint64_t end = std::uint64_t{f.offset} + std::uint64_t{size} * f.count;
    if (end > cloud.point_step) {
      why << "point_step " << cloud.point_step << " is smaller than field '" << f.name
          << "' (offset " << f.offset << " + " << f.count << " x " << size << " bytes = " << end
          << ")";
      return reject(CloudRejectReason::kFieldExtent);
    }
  }
  const std::uint64_t min_row = std::uint64_t{cloud.width} * cloud.point_step;
  if (cloud.row_step < min_row) {
    why << "row_step " << cloud.row_step << " < width " << cloud.width << " * point_step "
        << cloud.point_step << " (" << min_row << ")";
    return reject(CloudRejectReason::kRowStep);
  }
  const std::uint64_t expected = std::uint64_t{cloud.row_step} * cloud.height;
  if (cloud.data.size() != expected) {
    why << "data size " << cloud.data.size() << " != row_step " << cloud.row_step << " * height "
        << cloud.height << " (" << expected << ")";
    return reject(CloudRejectReason::kDataSize);
  }
  if (layout) {
    layout->x_offset = offsets[0];
    layout->y_offset = offsets[1];
    layout->z_offset = offsets[2];
    layout->width = cloud.width;
    layout->height = cloud.height;
    layout->point_step = cloud.point_step;
    layout->row_step = cloud.row_step;
    layout->points = std::size_t{cloud.width} * cloud.height;
    layout->contiguous = cloud.height <= 1 || cloud.row_step == min_row;
  }
  if (message) message->clear();
  return CloudRejectReason::kNone;
}

CloudView makeCloudView(const sensor_msgs::PointCloud2& cloud, const CloudLayout& layout,
                        std::vector<float>* scratch) {
  if (layout.points == 0) return CloudView();
  if (layout.contiguous) {
    return CloudView(cloud.data.data(), layout.points, layout.point_step, layout.x_offset,
                     layout.y_offset, layout.z_offset);
  }
  // Rows are padded: one stride cannot describe them, so pack x/y/z once.
  scratch->resize(3 * layout.points);
  float* out = scratch->data();
  for (std::size_t r = 0; r < layout.height; ++r) {
    const std::uint8_t* rec = cloud.data.data() + r * layout.row_step;
    for (std::size_t c = 0; c < layout.width; ++c, rec += layout.point_step) {
      *out++ = loadFloat(rec + layout.x_offset);
      *out++ = loadFloat(rec + layout.y_offset);
      *out++ = loadFloat(rec + layout.z_offset);
    }
  }
  return CloudView::packedXyz(scratch->data(), layout.points);
}

SplitCounts splitPointCloud2(const sensor_msgs::PointCloud2& in, const CloudLayout& layout,
                             std::vector<std::uint8_t>* labels, sensor_msgs::PointCloud2* ground,
                             sensor_msgs::PointCloud2* nonground) {
  SplitCounts counts;
  const std::size_t step = layout.point_step;
  // Pass 1: final label per record (NaN/Inf forced to non-ground) and the output sizes.
  std::vector<std::uint8_t>& final_labels = *labels;
  for (std::size_t r = 0, i = 0; r < layout.height; ++r) {
    const std::uint8_t* rec = in.data.data() + r * layout.row_step;
    for (std::size_t c = 0; c < layout.width; ++c, ++i, rec += step) {
      const bool finite = std::isfinite(loadFloat(rec + layout.x_offset)) &&
                          std::isfinite(loadFloat(rec + layout.y_offset)) &&
                          std::isfinite(loadFloat(rec + layout.z_offset));
      if (!finite) {
        ++counts.invalid;
        final_labels[i] = kNonGround;
      } else if (final_labels[i] != kNonGround) {
        final_labels[i] = kGround;
      }
      if (final_labels[i] == kGround) ++counts.ground;
    }
  }
  counts.nonground = layout.points - counts.ground;
  prepareOutput(in, counts.ground, ground);
  prepareOutput(in, counts.nonground, nonground);
  ground->is_dense = true;
  nonground->is_dense = counts.invalid == 0;

  // Pass 2: copy runs of equally labelled records within each row with one memcpy per run.
  std::uint8_t* dst[2] = {nonground->data.data(), ground->data.data()};
  for (std::size_t r = 0, i = 0; r < layout.height; ++r) {
    const std::uint8_t* row = in.data.data() + r * layout.row_step;
    std::size_t c = 0;
    while (c < layout.width) {
      const std::uint8_t label = final_labels[i + c];
      std::size_t end = c + 1;
      while (end < layout.width && final_labels[i + end] == label) ++end;
      const std::size_t bytes = (end - c) * step;
      std::memcpy(dst[label], row + c * step, bytes);
      dst[label] += bytes;
      c = end;
    }
    i += layout.width;
  }
  return counts;
}

GroundFilterNodelet::GroundFilterNodelet() = default;
GroundFilterNodelet::~GroundFilterNodelet() = default;

void GroundFilterNodelet::onInit() {
  NodeletLazy::onInit();
  pnh_->param("queue_size", queue_size_, 3);
  if (queue_size_ < 1) {
    NODELET_WARN("~queue_size %d < 1, using 1", queue_size_);
    queue_size_ = 1;
  }
  pub_ground_ = advertise<sensor_msgs::PointCloud2>(*pnh_, "ground", 1);
  pub_nonground_ = advertise<sensor_msgs::PointCloud2>(*pnh_, "nonground", 1);
  // Plain advertise: a timing subscriber alone must not start the input subscription.
  pub_time_ = pnh_->advertise<std_msgs::Float64>("processing_time_ms", 10);
  onInitFilter();
  {
    std::lock_guard<std::mutex> lock(config_mutex_);
    if (!config_) {
      NODELET_FATAL("%s: the leaf installed no filter configuration", methodName().c_str());
    }
  }
  onInitPostProcess();
}

void GroundFilterNodelet::setFilterFactory(FilterFactory factory, const std::string& description) {
  auto config = std::make_shared<FilterConfig>();
  config->make = std::move(factory);
  config->description = description;
  {
    std::lock_guard<std::mutex> lock(config_mutex_);
    config_ = std::move(config);
  }
  NODELET_INFO("%s parameters: %s", methodName().c_str(), description.c_str());
}

void GroundFilterNodelet::reportRejectedConfig(const std::string& what) {
  ++counters_.config_rejected;
  NODELET_ERROR("%s: parameters refused, keeping the previous ones: %s", methodName().c_str(),
                what.c_str());
}

void GroundFilterNodelet::subscribe() {
  sub_input_ = pnh_->subscribe("input", queue_size_, &GroundFilterNodelet::cloudCallback, this);
}

void GroundFilterNodelet::unsubscribe() { sub_input_.shutdown(); }

void GroundFilterNodelet::logRejected(CloudRejectReason reason, const std::string& message) {
  const int slot = static_cast<int>(reason);
  const ros::WallTime now = ros::WallTime::now();
  std::uint64_t suppressed = 0;
  {
    std::lock_guard<std::mutex> lock(log_mutex_);
    if (!last_reject_log_[slot].isZero() &&
        (now - last_reject_log_[slot]).toSec() < kRejectLogPeriodS) {
      ++suppressed_rejects_[slot];
      return;
    }
    last_reject_log_[slot] = now;
    suppressed = suppressed_rejects_[slot];
    suppressed_rejects_[slot] = 0;
  }
  std::string more;
  if (suppressed) {
    more = " (" + std::to_string(suppressed) + " more with this reason since the last message)";
  }
  NODELET_ERROR("rejected PointCloud2 on %s (%s): %s; nothing published for it%s",
                sub_input_.getTopic().c_str(), reasonName(reason), message.c_str(), more.c_str());
}

void GroundFilterNodelet::cloudCallback(const sensor_msgs::PointCloud2ConstPtr& msg) {
  const auto t0 = std::chrono::steady_clock::now();
  ++counters_.clouds_in;

  CloudLayout layout;
  std::string why;
  const CloudRejectReason reason = checkPointCloud2(*msg, &layout, &why);
  if (reason != CloudRejectReason::kNone) {
    ++counters_.clouds_rejected;
    logRejected(reason, why);
    return;
  }

  std::shared_ptr<const FilterConfig> config;
  {
    std::lock_guard<std::mutex> lock(config_mutex_);
    config = config_;
  }
  if (!config) {
    ++counters_.clouds_failed;
    NODELET_ERROR_THROTTLE(kRejectLogPeriodS, "no filter configuration installed; cloud dropped");
    return;
  }

  auto ground = boost::make_shared<sensor_msgs::PointCloud2>();
  auto nonground = boost::make_shared<sensor_msgs::PointCloud2>();
  SplitCounts counts;
  FilterStats stats;
  {
    std::lock_guard<std::mutex> lock(process_mutex_);
    try {
      if (config != filter_config_ || !filter_) {
        filter_ = config->make();
        filter_config_ = config;
      }
      const CloudView view = makeCloudView(*msg, layout, &xyz_scratch_);
      filter_->filter(view, &labels_, &stats);
    } catch (const std::exception& e) {
      ++counters_.clouds_failed;
      filter_.reset();  // rebuilt from scratch for the next cloud
      NODELET_ERROR_THROTTLE(kRejectLogPeriodS, "%s filter failed on a %zu-point cloud: %s",
                             methodName().c_str(), layout.points, e.what());
      return;
    }
    if (labels_.size() != layout.points) {
      ++counters_.clouds_failed;
      NODELET_ERROR_THROTTLE(kRejectLogPeriodS,
                             "%s filter returned %zu labels for %zu points; cloud dropped",
                             methodName().c_str(), labels_.size(), layout.points);
      return;
    }
    counts = splitPointCloud2(*msg, layout, &labels_, ground.get(), nonground.get());
  }

  pub_ground_.publish(sensor_msgs::PointCloud2ConstPtr(ground));
  pub_nonground_.publish(sensor_msgs::PointCloud2ConstPtr(nonground));
  ++counters_.clouds_out;
  counters_.invalid_points += counts.invalid;

  const double ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  NODELET_DEBUG(
      "%s: %zu points in, %zu ground, %zu non-ground (%zu NaN/Inf), filter %.2f ms, "
      "total %.2f ms",
      methodName().c_str(), layout.points, counts.ground, counts.nonground, counts.invalid,
      stats.total_ms, ms);
  if (pub_time_.getNumSubscribers() > 0) {
    auto t = boost::make_shared<std_msgs::Float64>();
    t->data = ms;
    pub_time_.publish(std_msgs::Float64ConstPtr(t));
  }
}

}  // namespace ground_filter
