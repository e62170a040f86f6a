#ifndef GROUND_FILTER_SRC_NODELETS_HAG_OUTPUTS_H
#define GROUND_FILTER_SRC_NODELETS_HAG_OUTPUTS_H

// Height above ground in the nodelets (docs/height_above_ground.md): the `height_above_ground`
// field of ~labeled (and, with ~hag_field, of ~ground / ~nonground / ~obstacles), the lazy
// ~ground_surface and ~obstacles outputs. The cloud-building functions need no ROS graph (tested
// alone); the HagOutputs class holds the publishers, the start parameters and the obstacle band.

#include <ros/ros.h>
#include <sensor_msgs/PointCloud2.h>

#include <Eigen/Geometry>
#include <mutex>
#include <string>
#include <vector>

#include "ground_filter/height_above_ground.h"
#include "param_check.h"
#include "point_cloud2.h"

namespace ground_filter {

/// \brief Name of the per-point float32 field written by the height-above-ground outputs.
constexpr char kHeightFieldName[] = "height_above_ground";

/// \brief The obstacle band of `~obstacles` (dynamic_reconfigure obstacle_min_height,
///        obstacle_max_height).
struct ObstacleBand {
  double min_height = 0.2;  ///< lowest height above ground of an obstacle point [m]
  double max_height = 2.5;  ///< highest height above ground of an obstacle point [m]
  /// \throws std::invalid_argument unless min_height < max_height (both finite).
  void validate() const;
};

/// \brief One record per occupied cell of `surface`: x, y, z (float32, cell centre at the
///        ground elevation), points (uint32, ground points in the cell), confidence (float32,
///        0..1), in `header` (its frame is the frame the surface was built in).
/// \param shift when not null, added to x, y, z: what the points were moved by before the
///        surface was built (CloudProcessingBuffers::shift).
/// \param wide x, y, z as float64 (the input's were: a map in projected coordinates keeps its
///        precision).
void makeSurfaceCloud(const GroundSurface& surface, const std_msgs::Header& header,
                      sensor_msgs::PointCloud2* out, const double* shift = nullptr,
                      bool wide = false);

/// \brief The whole records of `in` labelled non-ground whose height (one per record, input
///        order) lies in [band.min_height, band.max_height]; NaN heights never do. The output
///        has the input's header and fields, height 1, no row padding.
/// \param field when not null, each kept record also carries its height in a float32 field of
///        this name, written as it is copied (fieldSlot(): appended, gap bytes 0, or an existing
///        float32 field of that name overwritten).
/// \return false, `why` set and the records kept without the field, when `in` has a field of
///         that name of another type or count.
bool makeObstacleCloud(const sensor_msgs::PointCloud2& in, const CloudLayout& layout,
                       const std::vector<std::uint8_t>& labels, const std::vector<float>& heights,
                       const ObstacleBand& band, sensor_msgs::PointCloud2* out,
                       const char* field = nullptr, std::string* why = nullptr);

/// \brief The private start parameters of HagOutputs (hag_field, hag_cell, hag_radius), checked
///        with the base's (baseParamChecks()).
std::vector<ParamCheck> hagParamChecks();

/// \brief ~ground_surface and ~obstacles of one cloud (null when not built).
struct HagClouds {
  sensor_msgs::PointCloud2Ptr surface;
  sensor_msgs::PointCloud2Ptr obstacles;
  std::string error;  ///< non-empty: ~obstacles' height field could not be added (logged)
};

/// \brief The height-above-ground part of a filter nodelet.
///
/// Private parameters (read at start): `~hag_field` (bool, false) also add the field to
/// ~ground, ~nonground and ~obstacles (always published, so it costs the surface on every cloud);
/// `~hag_cell` (double, 1.0 m) and `~hag_radius` (double, 5.0 m): GroundSurfaceParams.
/// Nothing is computed for a cloud unless ~labeled, ~ground_surface or ~obstacles has
/// subscribers or ~hag_field is set.
class HagOutputs {
 public:
  /// \brief Takes the (lazy) publishers of ~ground_surface and ~obstacles and reads the
  ///        private parameters (range-checked before by the nodelet).
  void init(const ros::NodeHandle& pnh, const ros::Publisher& surface,
            const ros::Publisher& obstacles);
  /// \brief Installs a validated band (thread-safe; from the next cloud on).
  void setBand(const ObstacleBand& band);
  /// \brief Builds the surface, the heights and ~ground_surface / ~obstacles as far as wanted,
  ///        between filterPointCloud2() and writeOutputs() (which writes the heights into the
  ///        copies). `buffers->labels` as normalised by filterPointCloud2(); `xyz`: its scratch
  ///        (the transformed or packed view, when there was one).
  /// \param frame frame the heights are taken in (the gravity frame, else the input frame).
  /// \param filtered what filterPointCloud2() reported: a filter_error (every height NaN, no
  ///        surface), and the scan type (an airborne scan's surface skips the shadow test).
  /// \param want_labeled whether ~labeled will be written (it carries the heights).
  /// \return the heights, one per input record, for writeOutputs(); null when no output
  ///         carries them.
  const std::vector<float>* process(const sensor_msgs::PointCloud2& in, const CloudLayout& layout,
                                    const Eigen::Isometry3d* to_gravity,
                                    const CloudProcessingBuffers& buffers, const std::string& frame,
                                    const ProcessedCloud& filtered, bool want_labeled,
                                    HagClouds* clouds);
  /// \brief Whether ~ground and ~nonground carry the heights too (`~hag_field`).
  bool fieldInSplit() const { return hag_field_; }
  /// \brief Publishes what process() built.
  void publish(const HagClouds& clouds);

 private:
  ros::Publisher pub_surface_, pub_obstacles_;
  bool hag_field_ = false;
  GroundSurfaceParams params_;
  std::mutex band_mutex_;
  ObstacleBand band_;
  GroundSurface surface_;       // buffers kept between clouds
  std::vector<float> heights_;  // one per input record
};

}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_NODELETS_HAG_OUTPUTS_H
