#ifndef GROUND_FILTER_SRC_NODELETS_GROUND_FILTER_NODELET_H
#define GROUND_FILTER_SRC_NODELETS_GROUND_FILTER_NODELET_H

#include <diagnostic_updater/diagnostic_updater.h>
#include <dynamic_reconfigure/server.h>
#include <nodelet_topic_tools/nodelet_lazy.h>
#include <ros/ros.h>
#include <sensor_msgs/PointCloud2.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_listener.h>

#include <Eigen/Geometry>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

#include "ground_filter/cloud_view.h"
#include "ground_filter/ground_filter.h"

namespace ground_filter {

/// \brief Why a PointCloud2 was rejected (one throttle slot per reason).
enum class CloudRejectReason : int {
  kNone = 0,
  kBigEndian,     ///< is_bigendian set (records are read as little-endian)
  kMissingField,  ///< no field named x, y or z
  kFieldType,     ///< x/y/z not FLOAT32, or a field of unknown datatype
  kFieldCount,    ///< x/y/z with count != 1
  kFieldExtent,   ///< a field reaches past point_step
  kRowStep,       ///< row_step < width * point_step
  kDataSize,      ///< data.size() != row_step * height
  kCount          ///< number of reasons (array size)
};

/// \brief Where x/y/z sit in a validated PointCloud2 and how its rows are laid out.
struct CloudLayout {
  std::size_t x_offset = 0;    ///< byte offset of float32 x inside a record
  std::size_t y_offset = 4;    ///< byte offset of float32 y
  std::size_t z_offset = 8;    ///< byte offset of float32 z
  std::size_t width = 0;       ///< records per row
  std::size_t height = 0;      ///< rows
  std::size_t point_step = 0;  ///< bytes per record
  std::size_t row_step = 0;    ///< bytes per row (>= width * point_step)
  std::size_t points = 0;      ///< width * height
  bool contiguous = true;      ///< every record at i * point_step (no padding between rows)
};

/// \brief Checks a PointCloud2 before any byte of it is read.
///
/// Accepts float32 x/y/z (count 1, any offset and order) in records whose fields all fit inside
/// point_step, row_step >= width * point_step and data.size() == row_step * height; little-endian.
/// \param layout filled when the cloud is valid.
/// \param message filled with a human-readable reason when it is not.
/// \return kNone when valid, the reason otherwise.
CloudRejectReason checkPointCloud2(const sensor_msgs::PointCloud2& cloud, CloudLayout* layout,
                                   std::string* message);

/// \brief A CloudView over a validated cloud: zero-copy when rows are contiguous; otherwise x/y/z
///        are packed once into `scratch` (organised clouds with row padding).
CloudView makeCloudView(const sensor_msgs::PointCloud2& cloud, const CloudLayout& layout,
                        std::vector<float>* scratch);

/// \brief Point counts of one split.
struct SplitCounts {
  std::size_t ground = 0;     ///< records copied to the ground cloud
  std::size_t nonground = 0;  ///< records copied to the non-ground cloud (invalid ones included)
  std::size_t invalid = 0;    ///< NaN/Inf records (all in non-ground)
};

/// \brief Copies every record of `in` whole (point_step bytes) into exactly one of `ground` and
///        `nonground`, in input order.
///
/// A record goes to ground when its label is not kNonGround and its x/y/z are finite; NaN/Inf
/// records always go to non-ground. `labels` is normalised in place to the labels actually
/// applied (kGround / kNonGround). Outputs get the input header, fields, point_step and
/// endianness, height 1, and is_dense true unless they hold a NaN/Inf record.
/// \pre `labels->size() == layout.points`.
SplitCounts splitPointCloud2(const sensor_msgs::PointCloud2& in, const CloudLayout& layout,
                             std::vector<std::uint8_t>* labels, sensor_msgs::PointCloud2* ground,
                             sensor_msgs::PointCloud2* nonground);

/// \brief A CloudView of the cloud's x/y/z mapped through `transform` (e.g. sensor -> gravity
///        frame), packed into `scratch`; NaN/Inf points stay non-finite. Only the view moves: the
///        cloud itself (and so every output record) is left as it is.
CloudView makeTransformedCloudView(const sensor_msgs::PointCloud2& cloud, const CloudLayout& layout,
                                   const Eigen::Isometry3d& transform, std::vector<float>* scratch);

/// \brief Checks that `len` bytes are one serialized sensor_msgs/PointCloud2: every length field
///        fits in the buffer and the message ends exactly at its end (so deserialising it can
///        neither overrun nor allocate a size read from garbage).
/// \param why set to the first problem found when it returns false.
bool checkSerializedPointCloud2(const std::uint8_t* buf, std::uint32_t len, std::string* why);

/// \brief Name of the per-point label field of the `~labeled` output.
constexpr char kLabelFieldName[] = "ground";

/// \brief The input cloud with a uint8 field `ground` (1 ground, 0 non-ground) per record.
///
/// Width, height, header and every input field are kept; row padding is dropped. Without a
/// `ground` field in the input, it is appended after the input record (point_step grows to the
/// next multiple of 4); an input uint8 `ground` field (count 1) is overwritten in place.
/// \return false, with `why` set, when the input has a `ground` field of another type.
/// \pre `labels.size() == layout.points` (labels as normalised by splitPointCloud2()).
bool makeLabeledCloud(const sensor_msgs::PointCloud2& in, const CloudLayout& layout,
                      const std::vector<std::uint8_t>& labels, sensor_msgs::PointCloud2* out,
                      std::string* why);

/// \brief Base of the ground filter nodelets: `~input` (sensor_msgs/PointCloud2) is split into
///        `~ground` and `~nonground`, subscribed lazily (only while an output has subscribers, or
///        always with `~lazy: false`).
///
/// Owns validation, the zero-copy view, the zero-loss split, timing and the swap of filter
/// configurations. A leaf only builds its filter: in onInitFilter() it starts its
/// dynamic_reconfigure server, whose callback validates the new parameters and calls
/// setFilterFactory(). Clouds are processed with a private filter object (scratch buffers are
/// kept between clouds), rebuilt when the factory changed.
///
/// Leaves may advertise more lazy outputs with advertise<>() in onInitFilter().
///
/// Private parameters (read once at start): `~queue_size` (int, default 3) of the input
/// subscription; `~lazy` (bool, default true) from NodeletLazy; `~gravity_frame` (string,
/// default "": off) frame whose z axis points up: each cloud is classified after a tf2 transform
/// into it (outputs keep the input frame, header and records); `~tf_timeout` (double, default
/// 0.1 s, wall time) wait for that transform before the cloud is dropped and counted;
/// `~diagnostic_period` (double, default 1 s) of the /diagnostics status.
/// Extra outputs: `~labeled` (lazy; the input cloud plus a uint8 `ground` field, see
/// makeLabeledCloud()); `~processing_time_ms` (std_msgs/Float64, callback entry to publish of
/// the outputs; published only while it has subscribers; not watched by the lazy subscription).
/// Diagnostics (diagnostic_updater, /diagnostics, status "NODELET_NAME: METHOD ground filter"):
/// input/output rate, processing time mean/max, drop counts by reason, NaN/Inf points, backend
/// fallbacks and the backend in use; WARN while clouds are dropped or the stream is irregular.
///
/// Bad streams never stop the nodelet: input messages whose bytes are no PointCloud2 (e.g. a bag
/// holding other messages on the cloud topic) are dropped before any allocation; a frame_id
/// that changes or a stamp that goes back (a bag loop) is processed as usual; each gives a
/// throttled warning and is counted.
class GroundFilterNodelet : public nodelet_topic_tools::NodeletLazy {
 public:
  /// \brief Builds a new filter object from an already validated parameter set.
  using FilterFactory = std::function<std::unique_ptr<GroundFilter>()>;

  GroundFilterNodelet();
  ~GroundFilterNodelet() override;

  /// \brief Counters since start (read at any time, from any thread).
  struct Counters {
    std::atomic<std::uint64_t> clouds_in{0};            ///< clouds received
    std::atomic<std::uint64_t> clouds_out{0};           ///< clouds split and published
    std::atomic<std::uint64_t> clouds_rejected{0};      ///< malformed clouds dropped
    std::atomic<std::uint64_t> clouds_failed{0};        ///< clouds dropped: no filter configured
    std::atomic<std::uint64_t> filter_errors{0};        ///< filter threw: published all non-ground
    std::atomic<std::uint64_t> invalid_points{0};       ///< NaN/Inf points sent to non-ground
    std::atomic<std::uint64_t> config_rejected{0};      ///< parameter sets refused by validation
    std::atomic<std::uint64_t> clouds_no_transform{0};  ///< dropped: no transform to gravity frame
    std::atomic<std::uint64_t> not_cloud{0};  ///< input messages that are no PointCloud2, dropped
    std::atomic<std::uint64_t> frame_changes{0};  ///< clouds whose frame_id differs from the last
    std::atomic<std::uint64_t> stamps_backwards{0};  ///< clouds stamped before the previous one
    std::atomic<std::uint64_t> fallbacks{0};         ///< clouds with a FilterStats::note (fallback)
  };

 protected:
  /// \brief Sets up node handles, outputs, the leaf (onInitFilter) and the lazy subscription.
  void onInit() final;

  /// \brief Leaf hook, called from onInit() before the input is subscribed: start the
  ///        dynamic_reconfigure server; its first callback must call setFilterFactory().
  virtual void onInitFilter() = 0;

  /// \brief Method name for logs ("voxel", "normal").
  virtual std::string methodName() const = 0;

  /// \brief Installs a new filter configuration (thread-safe; takes effect on the next cloud).
  /// \param description one line for the log, e.g. "voxel_size=0.1 ...".
  void setFilterFactory(FilterFactory factory, const std::string& description);

  /// \brief Logs a refused parameter set (NODELET_ERROR) and counts it.
  void reportRejectedConfig(const std::string& what);

  void subscribe() override;
  void unsubscribe() override;

  /// \brief Counters for logs and diagnostics.
  const Counters& counters() const { return counters_; }

 private:
  /// One installed configuration; its address identifies it, so the cloud callback can tell
  /// when its filter object is stale.
  struct FilterConfig {
    FilterFactory make;
    std::string description;
  };

  void cloudCallback(const sensor_msgs::PointCloud2ConstPtr& msg);
  void logRejected(CloudRejectReason reason, const std::string& message);
  // Stream problems with their own WARN throttle (wall time, per nodelet instance).
  enum StreamWarning : int {
    kNoTransform = 0,
    kNotCloud,
    kFrameChange,
    kStampBack,
    kLabeled,
    kStreamWarningCount
  };
  // True when a warning of this kind may be logged now (at most one per kStreamLogPeriodS).
  bool warnNow(StreamWarning kind);
  // Counts and warns about frame_id changes and stamps going back between consecutive clouds.
  void checkStream(const std_msgs::Header& header);
  // Transform gravity_frame_ <- header.frame_id at header.stamp, waiting up to tf_timeout_.
  bool lookupGravityTransform(const std_msgs::Header& header, Eigen::Isometry3d* transform,
                              std::string* error);
  // An input message that is no PointCloud2 (see the subscription helper in the .cpp).
  void onNotCloud(const std::string& what, const std::string& publisher);
  void diagnose(diagnostic_updater::DiagnosticStatusWrapper& status);

  ros::Subscriber sub_input_;
  ros::Publisher pub_ground_;
  ros::Publisher pub_nonground_;
  ros::Publisher pub_time_;
  ros::Publisher pub_labeled_;
  int queue_size_ = 3;

  std::string gravity_frame_;  // empty: classify in the input frame
  double tf_timeout_ = 0.1;    // [s] wall time
  std::unique_ptr<tf2_ros::Buffer> tf_buffer_;
  std::unique_ptr<tf2_ros::TransformListener> tf_listener_;

  std::mutex stream_mutex_;  // guards the last frame/stamp seen
  std::string last_frame_id_;
  ros::Time last_stamp_;
  bool have_last_ = false;

  std::unique_ptr<diagnostic_updater::Updater> updater_;
  ros::WallTimer diagnostic_timer_;
  std::mutex diag_mutex_;  // guards the window below (reset at every diagnostic update)
  double window_ms_sum_ = 0.0;
  double window_ms_max_ = 0.0;
  std::uint64_t window_clouds_ = 0;
  std::string backend_;        // FilterStats::backend of the last cloud
  std::string fallback_note_;  // last non-empty FilterStats::note
  std::string logged_note_;    // last backend note written to the log (cloud thread only)
  ros::WallTime last_diagnose_;
  // Counter values at the previous diagnostic update: in, out, then the drop and stream reasons.
  std::uint64_t last_counts_[8] = {};

  std::mutex config_mutex_;  // guards config_
  std::shared_ptr<const FilterConfig> config_;

  // Touched only by the cloud callback; the mutex covers callbacks of an old and a new
  // subscription overlapping after unsubscribe()/subscribe().
  std::mutex process_mutex_;
  std::shared_ptr<const FilterConfig> filter_config_;
  std::unique_ptr<GroundFilter> filter_;
  std::vector<std::uint8_t> labels_;
  std::vector<float> xyz_scratch_;

  std::mutex log_mutex_;  // guards the per-reason throttle below
  ros::WallTime last_reject_log_[static_cast<int>(CloudRejectReason::kCount)];
  std::uint64_t suppressed_rejects_[static_cast<int>(CloudRejectReason::kCount)] = {};
  ros::WallTime last_stream_warning_[kStreamWarningCount];

  Counters counters_;
};

/// \brief A leaf's parameter plumbing, shared by every filter nodelet: a dynamic_reconfigure
///        server of `Config` whose accepted sets become `Filter(Params)`. A set that passes the
///        .cfg ranges but not `Params::validate()` is refused: the last good set stays in use and
///        is reported back to the client (the .cfg defaults when the first set is refused).
template <typename Config, typename Params, typename Filter>
class ReconfigurableFilterNodelet : public GroundFilterNodelet {
 protected:
  /// \brief Maps every cfg field onto the params struct (no validation).
  virtual Params paramsFromConfig(const Config& config) const = 0;
  /// \brief One log line "name=value ..." of all parameters.
  virtual std::string describeParams(const Params& params) const = 0;
  /// \brief Called with every accepted set before it is installed (e.g. a backend warning).
  virtual void onParamsAccepted(const Params& /*params*/) {}

  void onInitFilter() override {
    server_ = std::make_unique<dynamic_reconfigure::Server<Config>>(*pnh_);
    // The server calls back at once with the parameter-server values: that installs the filter.
    server_->setCallback([this](Config& config, uint32_t level) { reconfigure(config, level); });
  }

 private:
  void reconfigure(Config& config, uint32_t /*level*/) {
    Params params = paramsFromConfig(config);
    try {
      params.validate();
    } catch (const std::invalid_argument& e) {
      reportRejectedConfig(e.what());
      // The server publishes `config` after this returns: show what is really in use.
      if (have_good_) {
        config = last_good_;
        return;
      }
      config = Config::__getDefault__();  // the .cfg defaults are the library's
      params = paramsFromConfig(config);
    }
    last_good_ = config;
    have_good_ = true;
    onParamsAccepted(params);
    setFilterFactory([params]() { return std::make_unique<Filter>(params); },
                     describeParams(params));
  }

  std::unique_ptr<dynamic_reconfigure::Server<Config>> server_;
  Config last_good_;  // reported back when a new set is refused
  bool have_good_ = false;
};

}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_NODELETS_GROUND_FILTER_NODELET_H
