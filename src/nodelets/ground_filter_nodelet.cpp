#include "ground_filter_nodelet.h"

#include <diagnostic_msgs/DiagnosticStatus.h>
#include <geometry_msgs/TransformStamped.h>
#include <ros/serialization.h>
#include <ros/subscription_callback_helper.h>
#include <sensor_msgs/PointField.h>
#include <std_msgs/Float64.h>
#include <tf2/exceptions.h>

#include <algorithm>
#include <boost/make_shared.hpp>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <exception>
#include <sstream>
#include <typeinfo>
#include <utility>

namespace ground_filter {

namespace {

// Seconds between two ERROR lines for the same rejection reason.
constexpr double kRejectLogPeriodS = 5.0;
// Seconds between two WARN lines about the same kind of stream problem.
constexpr double kStreamLogPeriodS = 5.0;

// Subscription helper of ~input: deserialises sensor_msgs/PointCloud2 like roscpp's own helper,
// but checks the bytes first, so that a message that is no PointCloud2 (a bag replaying other
// messages on the cloud topic puts their bytes on the PointCloud2 connection) is counted and
// reported by the nodelet instead of failing inside roscpp unseen, or allocating gigabytes.
// It reports PointCloud2's type_info, so same-process PointCloud2 publishers keep zero-copy
// delivery (roscpp then hands over the shared pointer and never calls deserialize()). The
// subscription itself stays typed: a "*" subscription would take the md5sum of whichever
// publisher connects first and could then refuse the real PointCloud2 publishers.
class CloudSubscriptionHelper : public ros::SubscriptionCallbackHelper {
 public:
  using CloudCallback = std::function<void(const sensor_msgs::PointCloud2ConstPtr&)>;
  using ProblemCallback = std::function<void(const std::string& what, const std::string& from)>;

  CloudSubscriptionHelper(CloudCallback on_cloud, ProblemCallback on_not_cloud)
      : on_cloud_(std::move(on_cloud)), on_not_cloud_(std::move(on_not_cloud)) {}

  ros::VoidConstPtr deserialize(
      const ros::SubscriptionCallbackHelperDeserializeParams& params) override {
    std::string type, md5, callerid;
    if (params.connection_header) {
      const ros::M_string& h = *params.connection_header;
      auto get = [&h](const char* key) {
        const auto it = h.find(key);
        return it == h.end() ? std::string() : it->second;
      };
      type = get("type");
      md5 = get("md5sum");
      callerid = get("callerid");
    }
    const std::string want_md5 = ros::message_traits::md5sum<sensor_msgs::PointCloud2>();
    if (!md5.empty() && md5 != "*" && md5 != want_md5) {
      on_not_cloud_("a connection of type " + type + " (md5sum " + md5 + ")", callerid);
      return ros::VoidConstPtr();  // roscpp skips the callback for a null message
    }
    std::string why;
    if (!checkSerializedPointCloud2(params.buffer, params.length, &why)) {
      on_not_cloud_("bytes that do not decode as a PointCloud2: " + why, callerid);
      return ros::VoidConstPtr();
    }
    auto msg = boost::make_shared<sensor_msgs::PointCloud2>();
    try {
      ros::serialization::IStream stream(params.buffer, params.length);
      ros::serialization::deserialize(stream, *msg);
    } catch (const std::exception& e) {
      on_not_cloud_(std::string("bytes that do not decode as a PointCloud2: ") + e.what(),
                    callerid);
      return ros::VoidConstPtr();
    }
    return msg;
  }

  void call(ros::SubscriptionCallbackHelperCallParams& params) override {
    on_cloud_(
        boost::static_pointer_cast<const sensor_msgs::PointCloud2>(params.event.getConstMessage()));
  }

  const std::type_info& getTypeInfo() override { return typeid(sensor_msgs::PointCloud2); }
  bool isConst() override { return true; }
  bool hasHeader() override { return true; }

 private:
  CloudCallback on_cloud_;
  ProblemCallback on_not_cloud_;
};

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

bool checkSerializedPointCloud2(const std::uint8_t* buf, std::uint32_t len, std::string* why) {
  std::size_t pos = 0;
  auto fail = [&](const char* what) {
    *why = std::string(what) + " at byte " + std::to_string(pos) + " of " + std::to_string(len);
    return false;
  };
  auto skip = [&](std::size_t n) {
    if (n > len - pos) return false;
    pos += n;
    return true;
  };
  auto u32 = [&](std::uint32_t* v) {
    if (len - pos < 4) return false;
    std::memcpy(v, buf + pos, 4);
    pos += 4;
    return true;
  };
  std::uint32_t n = 0;
  if (!skip(12)) return fail("header seq/stamp truncated");  // seq, stamp.sec, stamp.nsec
  if (!u32(&n) || !skip(n)) return fail("header frame_id truncated");
  if (!skip(8)) return fail("height/width truncated");
  std::uint32_t fields = 0;
  if (!u32(&fields)) return fail("field count truncated");
  if (fields > (len - pos) / 13) return fail("field count too large");  // >= 13 bytes each
  for (std::uint32_t i = 0; i < fields; ++i) {
    if (!u32(&n) || !skip(n)) return fail("field name truncated");
    if (!skip(9)) return fail("field offset/datatype/count truncated");
  }
  if (!skip(9)) return fail("is_bigendian/point_step/row_step truncated");
  if (!u32(&n) || !skip(n)) return fail("data truncated");
  if (!skip(1)) return fail("is_dense missing");
  if (pos != len) return fail("bytes left over");
  return true;
}

CloudView makeTransformedCloudView(const sensor_msgs::PointCloud2& cloud, const CloudLayout& layout,
                                   const Eigen::Isometry3d& transform,
                                   std::vector<float>* scratch) {
  if (layout.points == 0) return CloudView();
  // Double precision for the products: KITTI ranges reach 80 m and the labels must not depend
  // on float rounding of the rotation.
  const Eigen::Matrix3d r = transform.linear();
  const Eigen::Vector3d t = transform.translation();
  scratch->resize(3 * layout.points);
  float* out = scratch->data();
  for (std::size_t row = 0; row < layout.height; ++row) {
    const std::uint8_t* rec = cloud.data.data() + row * layout.row_step;
    for (std::size_t c = 0; c < layout.width; ++c, rec += layout.point_step) {
      const Eigen::Vector3d p(loadFloat(rec + layout.x_offset), loadFloat(rec + layout.y_offset),
                              loadFloat(rec + layout.z_offset));
      const Eigen::Vector3d q = r * p + t;  // NaN/Inf stay non-finite
      *out++ = static_cast<float>(q.x());
      *out++ = static_cast<float>(q.y());
      *out++ = static_cast<float>(q.z());
    }
  }
  return CloudView::packedXyz(scratch->data(), layout.points);
}

bool makeLabeledCloud(const sensor_msgs::PointCloud2& in, const CloudLayout& layout,
                      const std::vector<std::uint8_t>& labels, sensor_msgs::PointCloud2* out,
                      std::string* why) {
  const sensor_msgs::PointField* existing = nullptr;
  for (const auto& f : in.fields) {
    if (f.name == kLabelFieldName) existing = &f;
  }
  std::size_t label_offset = layout.point_step;
  std::size_t step = (layout.point_step + 1 + 3) / 4 * 4;  // keep records 4-byte aligned
  out->fields = in.fields;
  if (existing) {
    if (existing->datatype != sensor_msgs::PointField::UINT8 || existing->count != 1) {
      if (why) {
        *why = std::string("the input already has a field '") + kLabelFieldName +
               "' that is not a single uint8";
      }
      return false;
    }
    label_offset = existing->offset;
    step = layout.point_step;
  } else {
    sensor_msgs::PointField f;
    f.name = kLabelFieldName;
    f.offset = static_cast<std::uint32_t>(label_offset);
    f.datatype = sensor_msgs::PointField::UINT8;
    f.count = 1;
    out->fields.push_back(f);
  }
  out->header = in.header;
  out->height = in.height;
  out->width = in.width;
  out->is_bigendian = in.is_bigendian;
  out->is_dense = in.is_dense;
  out->point_step = static_cast<std::uint32_t>(step);
  out->row_step = static_cast<std::uint32_t>(step * layout.width);
  out->data.assign(step * layout.points, 0);
  std::uint8_t* dst = out->data.data();
  for (std::size_t r = 0, i = 0; r < layout.height; ++r) {
    const std::uint8_t* rec = in.data.data() + r * layout.row_step;
    for (std::size_t c = 0; c < layout.width; ++c, ++i, rec += layout.point_step, dst += step) {
      std::memcpy(dst, rec, layout.point_step);
      dst[label_offset] = labels[i] == kGround ? 1 : 0;
    }
  }
  return true;
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
  pub_labeled_ = advertise<sensor_msgs::PointCloud2>(*pnh_, "labeled", 1);

  pnh_->param<std::string>("gravity_frame", gravity_frame_, "");
  pnh_->param("tf_timeout", tf_timeout_, 0.1);
  if (!(tf_timeout_ >= 0.0 && tf_timeout_ <= 10.0)) {
    NODELET_WARN("~tf_timeout %g s is outside [0, 10] s, using 0.1 s", tf_timeout_);
    tf_timeout_ = 0.1;
  }
  if (!gravity_frame_.empty()) {
    tf_buffer_ = std::make_unique<tf2_ros::Buffer>();
    tf_listener_ = std::make_unique<tf2_ros::TransformListener>(*tf_buffer_, *nh_);
    NODELET_INFO(
        "%s: clouds are classified in gravity frame '%s' (tf timeout %.3f s); outputs "
        "keep the input frame",
        methodName().c_str(), gravity_frame_.c_str(), tf_timeout_);
  }

  double period = 1.0;
  pnh_->param("diagnostic_period", period, 1.0);
  if (!(period > 0.0)) period = 1.0;
  updater_ = std::make_unique<diagnostic_updater::Updater>(*nh_, *pnh_, getName());
  updater_->setHardwareID("none");
  updater_->add(methodName() + " ground filter", this, &GroundFilterNodelet::diagnose);
  last_diagnose_ = ros::WallTime::now();
  // Wall time and force_update(): the status keeps coming while a bag's simulated clock is
  // paused or over (Updater::update() would wait for the simulated period).
  diagnostic_timer_ = nh_->createWallTimer(
      ros::WallDuration(period), [this](const ros::WallTimerEvent&) { updater_->force_update(); });

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
  ros::SubscribeOptions ops;
  ops.topic = "input";
  ops.queue_size = queue_size_;
  ops.md5sum = ros::message_traits::md5sum<sensor_msgs::PointCloud2>();
  ops.datatype = ros::message_traits::datatype<sensor_msgs::PointCloud2>();
  ops.helper = boost::make_shared<CloudSubscriptionHelper>(
      [this](const sensor_msgs::PointCloud2ConstPtr& msg) { cloudCallback(msg); },
      [this](const std::string& what, const std::string& from) { onNotCloud(what, from); });
  sub_input_ = pnh_->subscribe(ops);
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

bool GroundFilterNodelet::warnNow(StreamWarning kind) {
  const ros::WallTime now = ros::WallTime::now();
  std::lock_guard<std::mutex> lock(log_mutex_);
  ros::WallTime& last = last_stream_warning_[kind];
  if (!last.isZero() && (now - last).toSec() < kStreamLogPeriodS) return false;
  last = now;
  return true;
}

void GroundFilterNodelet::checkStream(const std_msgs::Header& header) {
  std::string old_frame;
  double back_s = 0.0;
  bool frame_changed = false, went_back = false;
  {
    std::lock_guard<std::mutex> lock(stream_mutex_);
    if (have_last_) {
      frame_changed = header.frame_id != last_frame_id_;
      went_back = header.stamp < last_stamp_;
      if (frame_changed) old_frame = last_frame_id_;
      if (went_back) back_s = (last_stamp_ - header.stamp).toSec();
    }
    last_frame_id_ = header.frame_id;
    last_stamp_ = header.stamp;
    have_last_ = true;
  }
  if (frame_changed) {
    const auto n = ++counters_.frame_changes;
    if (warnNow(kFrameChange)) {
      NODELET_WARN(
          "%s: input frame_id changed from '%s' to '%s' (%llu changes so far); every "
          "cloud is processed and published in its own frame",
          methodName().c_str(), old_frame.c_str(), header.frame_id.c_str(),
          static_cast<unsigned long long>(n));
    }
  }
  if (went_back) {
    const auto n = ++counters_.stamps_backwards;
    if (warnNow(kStampBack)) {
      NODELET_WARN(
          "%s: input stamp went back by %.3f s (a bag loop or a restarted driver?) "
          "(%llu times so far); the cloud is processed as usual",
          methodName().c_str(), back_s, static_cast<unsigned long long>(n));
    }
  }
}

bool GroundFilterNodelet::lookupGravityTransform(const std_msgs::Header& header,
                                                 Eigen::Isometry3d* transform, std::string* error) {
  // Polled against wall time: tf2's own timeout runs on ros::Time, which never advances while a
  // bag's simulated clock is paused or over, and the nodelet would hang in this callback.
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(tf_timeout_);
  while (true) {
    try {
      const geometry_msgs::TransformStamped t =
          tf_buffer_->lookupTransform(gravity_frame_, header.frame_id, header.stamp);
      const auto& q = t.transform.rotation;
      const auto& v = t.transform.translation;
      transform->linear() = Eigen::Quaterniond(q.w, q.x, q.y, q.z).normalized().toRotationMatrix();
      transform->translation() = Eigen::Vector3d(v.x, v.y, v.z);
      transform->makeAffine();
      return true;
    } catch (const tf2::TransformException& e) {
      *error = e.what();
    }
    if (ros::WallTime::now() >= deadline || !ros::ok()) return false;
    ros::WallDuration(0.005).sleep();
  }
}

void GroundFilterNodelet::onNotCloud(const std::string& what, const std::string& publisher) {
  const auto n = ++counters_.not_cloud;
  if (warnNow(kNotCloud)) {
    NODELET_WARN("%s: dropped a message on %s from %s: %s (%llu such messages so far)",
                 methodName().c_str(), sub_input_.getTopic().c_str(),
                 publisher.empty() ? "an unknown publisher" : publisher.c_str(), what.c_str(),
                 static_cast<unsigned long long>(n));
  }
}

void GroundFilterNodelet::cloudCallback(const sensor_msgs::PointCloud2ConstPtr& msg) {
  const auto t0 = std::chrono::steady_clock::now();
  ++counters_.clouds_in;
  checkStream(msg->header);

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

  // Looked up before the filter lock: it may wait up to tf_timeout_.
  Eigen::Isometry3d to_gravity = Eigen::Isometry3d::Identity();
  const bool transform = !gravity_frame_.empty() && msg->header.frame_id != gravity_frame_;
  if (transform && !lookupGravityTransform(msg->header, &to_gravity, &why)) {
    const auto n = ++counters_.clouds_no_transform;
    if (warnNow(kNoTransform)) {
      NODELET_WARN(
          "%s: no transform from '%s' to gravity frame '%s' at t=%.3f within %.3f s: "
          "%s; cloud dropped (%llu so far)",
          methodName().c_str(), msg->header.frame_id.c_str(), gravity_frame_.c_str(),
          msg->header.stamp.toSec(), tf_timeout_, why.c_str(), static_cast<unsigned long long>(n));
    }
    return;
  }

  auto ground = boost::make_shared<sensor_msgs::PointCloud2>();
  auto nonground = boost::make_shared<sensor_msgs::PointCloud2>();
  sensor_msgs::PointCloud2Ptr labeled;
  const bool want_labeled = pub_labeled_.getNumSubscribers() > 0;
  SplitCounts counts;
  FilterStats stats;
  {
    std::lock_guard<std::mutex> lock(process_mutex_);
    try {
      if (config != filter_config_ || !filter_) {
        filter_ = config->make();
        filter_config_ = config;
      }
      const CloudView view = transform
                                 ? makeTransformedCloudView(*msg, layout, to_gravity, &xyz_scratch_)
                                 : makeCloudView(*msg, layout, &xyz_scratch_);
      filter_->filter(view, &labels_, &stats);
    } catch (const std::exception& e) {
      // Lose nothing: the cloud still goes out, every point as non-ground.
      ++counters_.filter_errors;
      filter_.reset();  // rebuilt from scratch for the next cloud
      labels_.assign(layout.points, kNonGround);
      NODELET_ERROR_THROTTLE(kRejectLogPeriodS,
                             "%s filter failed on a %zu-point cloud (published as all "
                             "non-ground): %s",
                             methodName().c_str(), layout.points, e.what());
    }
    if (labels_.size() != layout.points) {
      ++counters_.filter_errors;
      NODELET_ERROR_THROTTLE(kRejectLogPeriodS,
                             "%s filter returned %zu labels for %zu points; published as all "
                             "non-ground",
                             methodName().c_str(), labels_.size(), layout.points);
      labels_.assign(layout.points, kNonGround);
    }
    counts = splitPointCloud2(*msg, layout, &labels_, ground.get(), nonground.get());
    if (want_labeled) {
      labeled = boost::make_shared<sensor_msgs::PointCloud2>();
      if (!makeLabeledCloud(*msg, layout, labels_, labeled.get(), &why)) {
        labeled.reset();
        if (warnNow(kLabeled)) {
          NODELET_WARN("%s: ~labeled not published: %s", methodName().c_str(), why.c_str());
        }
      }
    }
  }

  pub_ground_.publish(sensor_msgs::PointCloud2ConstPtr(ground));
  pub_nonground_.publish(sensor_msgs::PointCloud2ConstPtr(nonground));
  if (labeled) pub_labeled_.publish(sensor_msgs::PointCloud2ConstPtr(labeled));
  ++counters_.clouds_out;
  counters_.invalid_points += counts.invalid;
  if (!stats.note.empty()) {
    ++counters_.fallbacks;
    // A new reason (no device, a CUDA error) is logged at once; a repeated one once a minute.
    if (stats.note != logged_note_) {
      NODELET_WARN("%s: %s", methodName().c_str(), stats.note.c_str());
      logged_note_ = stats.note;
    } else {
      NODELET_WARN_THROTTLE(60.0, "%s: %s", methodName().c_str(), stats.note.c_str());
    }
  }

  const double ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  {
    std::lock_guard<std::mutex> lock(diag_mutex_);
    window_ms_sum_ += ms;
    window_ms_max_ = std::max(window_ms_max_, ms);
    ++window_clouds_;
    backend_ = stats.backend;
    if (!stats.note.empty()) fallback_note_ = stats.note;
  }
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

void GroundFilterNodelet::diagnose(diagnostic_updater::DiagnosticStatusWrapper& status) {
  using ull = unsigned long long;
  const ros::WallTime now = ros::WallTime::now();
  // in, out, then the reasons a cloud is dropped, then the stream irregularities.
  const std::uint64_t counts[8] = {counters_.clouds_in,       counters_.clouds_out,
                                   counters_.clouds_rejected, counters_.clouds_no_transform,
                                   counters_.not_cloud,       counters_.clouds_failed,
                                   counters_.frame_changes,   counters_.stamps_backwards};
  static const char* const kDropNames[4] = {"malformed", "no transform", "not PointCloud2",
                                            "filter failed"};
  static const char* const kStreamNames[2] = {"frame_id changes", "stamps going back"};
  double ms_sum, ms_max, dt;
  std::uint64_t clouds, delta[8];
  std::string backend, note;
  {
    std::lock_guard<std::mutex> lock(diag_mutex_);
    ms_sum = window_ms_sum_;
    ms_max = window_ms_max_;
    clouds = window_clouds_;
    window_ms_sum_ = window_ms_max_ = 0.0;
    window_clouds_ = 0;
    backend = backend_;
    note = fallback_note_;
    dt = std::max(1e-6, (now - last_diagnose_).toSec());
    last_diagnose_ = now;
    for (int i = 0; i < 8; ++i) {
      delta[i] = counts[i] - last_counts_[i];
      last_counts_[i] = counts[i];
    }
  }
  bool have_config;
  {
    std::lock_guard<std::mutex> lock(config_mutex_);
    have_config = static_cast<bool>(config_);
  }

  char head[128];
  std::snprintf(head, sizeof(head), "%.1f Hz in, %.1f Hz out", delta[0] / dt, delta[1] / dt);
  std::string problems;
  for (int i = 0; i < 4; ++i) {
    if (delta[2 + i]) {
      problems += (problems.empty() ? "" : ", ") + std::to_string(delta[2 + i]) + " dropped (" +
                  kDropNames[i] + ")";
    }
  }
  for (int i = 0; i < 2; ++i) {
    if (delta[6 + i]) {
      problems +=
          (problems.empty() ? "" : ", ") + std::to_string(delta[6 + i]) + " " + kStreamNames[i];
    }
  }
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

  status.add("method", methodName());
  status.add("backend", backend.empty() ? std::string("n/a (no neighbour search)") : backend);
  status.add("gravity frame",
             gravity_frame_.empty() ? std::string("(input frame)") : gravity_frame_);
  status.addf("input rate [Hz]", "%.2f", delta[0] / dt);
  status.addf("output rate [Hz]", "%.2f", delta[1] / dt);
  if (clouds) {
    status.addf("processing time mean [ms]", "%.2f", ms_sum / clouds);
    status.addf("processing time max [ms]", "%.2f", ms_max);
  } else {
    status.add("processing time mean [ms]", "n/a (no cloud)");
    status.add("processing time max [ms]", "n/a (no cloud)");
  }
  status.add("clouds in", static_cast<ull>(counts[0]));
  status.add("clouds out", static_cast<ull>(counts[1]));
  status.add("dropped", static_cast<ull>(counts[2] + counts[3] + counts[4] + counts[5]));
  for (int i = 0; i < 4; ++i) {
    status.add(std::string("dropped: ") + kDropNames[i], static_cast<ull>(counts[2 + i]));
  }
  status.add("invalid points (NaN/Inf)", static_cast<ull>(counters_.invalid_points.load()));
  status.add("filter errors (published as non-ground)",
             static_cast<ull>(counters_.filter_errors.load()));
  status.add("fallbacks", static_cast<ull>(counters_.fallbacks.load()));
  status.add("last fallback", note.empty() ? std::string("none") : note);
  for (int i = 0; i < 2; ++i) {
    status.add(kStreamNames[i], static_cast<ull>(counts[6 + i]));
  }
  status.add("refused parameter sets", static_cast<ull>(counters_.config_rejected.load()));
}

}  // namespace ground_filter
