#ifndef GROUND_FILTER_SRC_NODELETS_GROUND_FILTER_NODELET_H
#define GROUND_FILTER_SRC_NODELETS_GROUND_FILTER_NODELET_H

#include <nodelet_topic_tools/nodelet_lazy.h>
#include <ros/ros.h>
#include <sensor_msgs/PointCloud2.h>

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
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
/// Extension points for later features: leaves or this class may advertise more lazy outputs with
/// advertise<>() in onInitFilter() (e.g. a labelled cloud), and makeCloudView()'s packed scratch
/// is where a cloud transformed into a gravity frame would go.
///
/// Private parameters (read once at start): `~queue_size` (int, default 3) of the input
/// subscription; `~lazy` (bool, default true) from NodeletLazy.
/// Extra output: `~processing_time_ms` (std_msgs/Float64, callback entry to publish of both
/// outputs; published only while it has subscribers; not watched by the lazy subscription).
class GroundFilterNodelet : public nodelet_topic_tools::NodeletLazy {
 public:
  /// \brief Builds a new filter object from an already validated parameter set.
  using FilterFactory = std::function<std::unique_ptr<GroundFilter>()>;

  GroundFilterNodelet();
  ~GroundFilterNodelet() override;

  /// \brief Counters since start (read at any time, from any thread).
  struct Counters {
    std::atomic<std::uint64_t> clouds_in{0};        ///< clouds received
    std::atomic<std::uint64_t> clouds_out{0};       ///< clouds split and published
    std::atomic<std::uint64_t> clouds_rejected{0};  ///< malformed clouds dropped
    std::atomic<std::uint64_t> clouds_failed{0};    ///< clouds dropped because the filter threw
    std::atomic<std::uint64_t> invalid_points{0};   ///< NaN/Inf points sent to non-ground
    std::atomic<std::uint64_t> config_rejected{0};  ///< parameter sets refused by validation
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

  ros::Subscriber sub_input_;
  ros::Publisher pub_ground_;
  ros::Publisher pub_nonground_;
  ros::Publisher pub_time_;
  int queue_size_ = 3;

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

  Counters counters_;
};

}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_NODELETS_GROUND_FILTER_NODELET_H
