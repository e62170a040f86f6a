#ifndef GROUND_FILTER_SRC_NODELETS_POINT_CLOUD2_H
#define GROUND_FILTER_SRC_NODELETS_POINT_CLOUD2_H

// sensor_msgs/PointCloud2 at byte level, without any nodelet or ROS graph code: validation, the
// zero-copy view, the zero-loss split and the labelled output. Used by the nodelets and by the
// fuzz target (test/fuzz_point_cloud2.cpp).

#include <sensor_msgs/PointCloud2.h>

#include <Eigen/Geometry>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "cloud_pool.h"
#include "ground_filter/cloud_view.h"
#include "ground_filter/ground_filter.h"
#include "ground_filter/working_volume.h"

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
  std::size_t x_offset = 0;    ///< byte offset of x inside a record
  std::size_t y_offset = 4;    ///< byte offset of y
  std::size_t z_offset = 8;    ///< byte offset of z
  std::size_t width = 0;       ///< records per row
  std::size_t height = 0;      ///< rows to walk (0 when width is 0, whatever the header says)
  std::size_t point_step = 0;  ///< bytes per record
  std::size_t row_step = 0;    ///< bytes per row (>= width * point_step)
  std::size_t points = 0;      ///< width * height
  bool contiguous = true;      ///< every record at i * point_step (no padding between rows)
  bool float64 = false;        ///< x/y/z are float64 (then the offsets are of doubles)
  /// \brief Whether the filter's view is packed into scratch (padded rows, float64 x/y/z)
  ///        rather than the message's own bytes.
  bool packed() const { return !contiguous || float64; }
};

/// \brief Checks a PointCloud2 before any byte of it is read.
///
/// Accepts float32 (or all three float64) x/y/z (count 1, any offset and order) in records whose
/// fields all fit inside
/// point_step, row_step >= width * point_step and data.size() == row_step * height; little-endian.
/// \param layout filled when the cloud is valid.
/// \param message filled with a human-readable reason when it is not.
/// \return kNone when valid, the reason otherwise.
CloudRejectReason checkPointCloud2(const sensor_msgs::PointCloud2& cloud, CloudLayout* layout,
                                   std::string* message);

/// \brief A CloudView over a validated cloud: zero-copy when rows are contiguous and x/y/z
///        float32; otherwise x/y/z are packed once into `scratch` as float32 (organised clouds
///        with row padding, float64 x/y/z).
/// \param shift when not null: float64 x/y/z whose middle lies beyond the working volume's
///        hard box (projected coordinates) are moved by -shift in double before they are
///        narrowed, so float32 keep their millimetres; `shift` (3 values, whole metres) says by
///        what, 0 when not moved.
CloudView makeCloudView(const sensor_msgs::PointCloud2& cloud, const CloudLayout& layout,
                        std::vector<float>* scratch, double* shift = nullptr);

/// \brief Point counts of one split.
struct SplitCounts {
  std::size_t ground = 0;     ///< records copied to the ground cloud
  std::size_t nonground = 0;  ///< records copied to the non-ground cloud (invalid ones included)
  std::size_t invalid = 0;    ///< NaN/Inf records (all in non-ground)
};

/// \brief Float32 values, one per input record in input order, that the output copies write
///        into a field `name` as they copy the records (height_above_ground): no second pass.
struct RecordFloatField {
  const char* name = nullptr;                  ///< field name
  const std::vector<float>* values = nullptr;  ///< one per input record (input order)
};

/// \brief Copies every record of `in` whole (point_step bytes) into exactly one of `ground` and
///        `nonground`, in input order: finalizeLabels(), then copySplit().
///
/// A record goes to ground when its label is not kNonGround and its x/y/z are finite; NaN/Inf
/// records always go to non-ground. `labels` is normalised in place to the labels actually
/// applied (kGround / kNonGround). Outputs get the input header, fields, point_step and
/// endianness, height 1, and is_dense true unless they hold a NaN/Inf record.
/// \pre `labels->size() == layout.points`.
SplitCounts splitPointCloud2(const sensor_msgs::PointCloud2& in, const CloudLayout& layout,
                             std::vector<std::uint8_t>* labels, sensor_msgs::PointCloud2* ground,
                             sensor_msgs::PointCloud2* nonground);

/// \brief The first pass of splitPointCloud2(): `labels` normalised in place (NaN/Inf records
///        kNonGround, any other label but kNonGround kGround), and the counts.
/// \pre `labels->size() == layout.points`.
SplitCounts finalizeLabels(const sensor_msgs::PointCloud2& in, const CloudLayout& layout,
                           std::vector<std::uint8_t>* labels);

/// \brief The second pass of splitPointCloud2(): the records copied by their normalised
///        `labels` (`counts` from finalizeLabels()).
/// \param field when not null, every output record also carries it (fieldSlot(): an existing
///        float32 field of that name overwritten in place, or appended, gap bytes 0), written
///        during the copy.
/// \return false, `why` set and the records copied without the field, when `in` has a field
///         of that name of another type or count.
bool copySplit(const sensor_msgs::PointCloud2& in, const CloudLayout& layout,
               const std::vector<std::uint8_t>& labels, const SplitCounts& counts,
               sensor_msgs::PointCloud2* ground, sensor_msgs::PointCloud2* nonground,
               const RecordFloatField* field = nullptr, std::string* why = nullptr);

/// \brief The middle of the x/y/z bounding box of at most `max_samples` records spread evenly
///        over the cloud, finite ones only (diagnostics: where to point rviz at a survey tile
///        whose coordinates lie far from its frame's origin). Reads no more than `max_samples`.
/// \return false when the cloud is empty or no sampled record is finite.
bool sampledCentre(const sensor_msgs::PointCloud2& cloud, const CloudLayout& layout,
                   std::size_t max_samples, double centre[3]);

/// \brief A CloudView of the cloud's x/y/z mapped through `transform` (e.g. sensor -> gravity
///        frame), packed into `scratch`; NaN/Inf points stay non-finite. Only the view moves: the
///        cloud itself (and so every output record) is left as it is.
/// \param shift when not null: transformed points whose middle lies beyond the working
///        volume's hard box are moved by -shift (whole metres) in double, as makeCloudView().
CloudView makeTransformedCloudView(const sensor_msgs::PointCloud2& cloud, const CloudLayout& layout,
                                   const Eigen::Isometry3d& transform, std::vector<float>* scratch,
                                   double* shift = nullptr);

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
/// \param field when not null, a float32 field written into the records as well (after
///        `ground`, or in place: fieldSlot()); when `in` has a field of its name of another type
///        or count the cloud goes without it and `field_why` says why.
/// \return false, with `why` set, when the input has a `ground` field of another type.
/// \pre `labels.size() == layout.points` (labels as normalised by splitPointCloud2()).
bool makeLabeledCloud(const sensor_msgs::PointCloud2& in, const CloudLayout& layout,
                      const std::vector<std::uint8_t>& labels, sensor_msgs::PointCloud2* out,
                      std::string* why, const RecordFloatField* field = nullptr,
                      std::string* field_why = nullptr);

/// \brief Checks (checkSerializedPointCloud2()) and deserialises one serialised PointCloud2.
/// \return false, with `why` set, when the bytes are no PointCloud2 (`msg` is then unspecified).
bool deserializePointCloud2(const std::uint8_t* buf, std::uint32_t len,
                            sensor_msgs::PointCloud2* msg, std::string* why);

/// \brief Scratch memory of processPointCloud2(), kept between clouds.
struct CloudProcessingBuffers {
  std::vector<std::uint8_t> labels;  ///< one label per point
  std::vector<float> xyz;            ///< packed x/y/z (padded rows, transformed views)
  /// What the packed x/y/z were moved by (subtracted) to keep far float64 coordinates'
  /// precision (makeCloudView()); 0 when not moved.
  double shift[3] = {0.0, 0.0, 0.0};
};

/// \brief Where processPointCloud2() takes its two output messages from (cloud_pool.h).
struct OutputPools {
  CloudPool ground;     ///< ~ground
  CloudPool nonground;  ///< ~nonground
  CloudPool labeled;    ///< ~labeled
};

/// \brief Outputs of one cloud: ground / non-ground (always), ~labeled (when asked for).
struct ProcessedCloud {
  sensor_msgs::PointCloud2Ptr ground;     ///< records labelled ground
  sensor_msgs::PointCloud2Ptr nonground;  ///< every other record (NaN/Inf, out of range too)
  sensor_msgs::PointCloud2Ptr labeled;    ///< null unless asked for and possible
  SplitCounts counts;                     ///< what the split did
  FilterStats stats;                      ///< what the filter did (empty when it failed)
  std::string filter_error;   ///< non-empty: the filter failed, every record went to non-ground
  std::string labeled_error;  ///< non-empty: ~labeled was asked for but is not possible
  std::string field_error;    ///< non-empty: the extra float field could not be written
};

/// \brief Filters one validated cloud and splits it: the shared path of the nodelets and of
///        the fuzz target (filterPointCloud2(), then writeOutputs()).
///
/// The filter sees the cloud's x/y/z (mapped through `transform` when not null; far float64
/// coordinates moved near the origin in double, `buffers->shift`, with the filter's sensor
/// origin moved alike for the call and the scan reason naming the move). A filter that
/// throws or returns a wrong number of labels loses nothing: every record goes to non-ground
/// and `out->filter_error` says why. Every record lands in exactly one of the two outputs.
/// With `pools`, the two output messages come from them (reused buffers), else new ones.
void processPointCloud2(const sensor_msgs::PointCloud2& in, const CloudLayout& layout,
                        GroundFilter* filter, const Eigen::Isometry3d* transform, bool want_labeled,
                        CloudProcessingBuffers* buffers, ProcessedCloud* out,
                        OutputPools* pools = nullptr);

/// \brief The first half of processPointCloud2(): the filter's labels, normalised
///        (finalizeLabels()) in `buffers->labels`; `out`'s counts, stats and filter_error.
///        Nothing is copied yet: what the labels give (heights) can go into the copies.
void filterPointCloud2(const sensor_msgs::PointCloud2& in, const CloudLayout& layout,
                       GroundFilter* filter, const Eigen::Isometry3d* transform,
                       CloudProcessingBuffers* buffers, ProcessedCloud* out);

/// \brief The second half of processPointCloud2(): ~ground, ~nonground and (when wanted)
///        ~labeled from `buffers->labels`.
/// \param field when not null, written into ~labeled's records and, with `field_in_split`,
///        into ~ground's and ~nonground's, during the copies (`out->field_error` when refused).
void writeOutputs(const sensor_msgs::PointCloud2& in, const CloudLayout& layout, bool want_labeled,
                  CloudProcessingBuffers* buffers, ProcessedCloud* out,
                  OutputPools* pools = nullptr, const RecordFloatField* field = nullptr,
                  bool field_in_split = false);

/// \brief A PointField of one value.
sensor_msgs::PointField makePointField(const char* name, std::uint32_t offset,
                                       std::uint8_t datatype);

/// \brief Where a field `name` of one `datatype` value (`size` bytes) goes in records of
///        `point_step` bytes with `fields`: an existing field of that name, written in place
///        (`*step` = point_step, `*append` false), or a new one after the record at an offset
///        aligned to `size`, records padded to 4 bytes (`*append` true).
/// \returns false (reason in `why`) when `fields` has a field `name` of another type or count.
bool fieldSlot(const std::vector<sensor_msgs::PointField>& fields, std::size_t point_step,
               const char* name, std::uint8_t datatype, std::size_t size, std::size_t* offset,
               std::size_t* step, bool* append, std::string* why);

/// \brief Where a float32 field goes in output records copied from input records of `src_step`
///        bytes, and the copy of one record with its value: the one place the outputs that
///        carry height_above_ground (~ground, ~nonground, ~labeled, ~obstacles) write it.
struct FloatFieldSlot {
  std::size_t src_step = 0;  ///< bytes copied from the input record
  std::size_t offset = 0;    ///< the value's offset in the output record
  std::size_t step = 0;      ///< bytes per output record
  bool append = false;       ///< a new field (false: an existing float32 field overwritten)
  /// \brief fieldSlot() for a float32 `name` in records of `point_step` bytes (the copied
  ///        `src_step` bytes and any field the output adds before this one) with `fields`.
  /// \returns false (reason in `why`) when `fields` has a field `name` of another type or count.
  bool place(const std::vector<sensor_msgs::PointField>& fields, std::size_t src_step,
             std::size_t point_step, const char* name, std::string* why);
  /// \brief Adds the field to `fields` when it is a new one.
  void addField(std::vector<sensor_msgs::PointField>* fields, const char* name) const;
  /// \brief The input record whole, zeros up to `step`, `value` at `offset`.
  void copy(std::uint8_t* dst, const std::uint8_t* rec, float value) const {
    std::memcpy(dst, rec, src_step);
    if (step > src_step) std::memset(dst + src_step, 0, step - src_step);
    std::memcpy(dst + offset, &value, sizeof(float));
  }
};

/// \brief Sets the working volume's centre and axes on `filter`: the sensor's pose in the
///        filter's frame (the body box is given in the input frame).
void setSensorPose(WorkingVolumeFilter* filter, const Eigen::Isometry3d& pose);

/// \brief Short name of a rejection reason for logs ("row_step", ...).
const char* reasonName(CloudRejectReason reason);

}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_NODELETS_POINT_CLOUD2_H
