#include "hag_outputs.h"

#include <sensor_msgs/PointField.h>

#include <boost/make_shared.hpp>
#include <cmath>
#include <cstring>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "ground_filter/point_field.h"

namespace ground_filter {

void ObstacleBand::validate() const {
  if (!(std::isfinite(min_height) && std::isfinite(max_height) && min_height < max_height)) {
    std::ostringstream os;
    os << "obstacle_min_height (" << min_height << " m) must be below obstacle_max_height ("
       << max_height << " m)";
    throw std::invalid_argument(os.str());
  }
}

void makeSurfaceCloud(const GroundSurface& surface, const std_msgs::Header& header,
                      sensor_msgs::PointCloud2* out, const double* shift, bool wide) {
  using PF = sensor_msgs::PointField;
  const std::vector<SurfaceCell>& cells = surface.cells();
  const double zero[3] = {0.0, 0.0, 0.0};
  if (!shift) shift = zero;
  const std::uint32_t w = wide ? 8 : 4, step = 3 * w + 8;
  const std::uint8_t type = wide ? PF::FLOAT64 : PF::FLOAT32;
  out->header = header;
  out->fields = {makePointField("x", 0, type), makePointField("y", w, type),
                 makePointField("z", 2 * w, type), makePointField("points", 3 * w, PF::UINT32),
                 makePointField("confidence", 3 * w + 4, PF::FLOAT32)};
  out->is_bigendian = false;
  out->is_dense = true;
  out->point_step = step;
  out->height = 1;
  out->width = static_cast<std::uint32_t>(cells.size());
  out->row_step = out->point_step * out->width;
  out->data.resize(std::size_t{out->row_step});
  std::uint8_t* dst = out->data.data();
  for (const SurfaceCell& c : cells) {
    if (wide) {
      const double xyz[3] = {c.x + shift[0], c.y + shift[1], c.z + shift[2]};
      std::memcpy(dst, xyz, sizeof(xyz));
    } else {
      const float xyz[3] = {narrowCoordinate(c.x + shift[0]), narrowCoordinate(c.y + shift[1]),
                            narrowCoordinate(c.z + shift[2])};
      std::memcpy(dst, xyz, sizeof(xyz));
    }
    std::memcpy(dst + 3 * w, &c.points, 4);
    std::memcpy(dst + 3 * w + 4, &c.confidence, 4);
    dst += step;
  }
}

bool makeObstacleCloud(const sensor_msgs::PointCloud2& in, const CloudLayout& layout,
                       const std::vector<std::uint8_t>& labels, const std::vector<float>& heights,
                       const ObstacleBand& band, sensor_msgs::PointCloud2* out, const char* field,
                       std::string* why) {
  const float lo = static_cast<float>(band.min_height), hi = static_cast<float>(band.max_height);
  auto inBand = [&](std::size_t i) {
    return labels[i] == kNonGround && heights[i] >= lo && heights[i] <= hi;  // NaN: false
  };
  std::size_t n = 0;
  for (std::size_t i = 0; i < layout.points; ++i) n += inBand(i) ? 1 : 0;
  const std::size_t in_step = layout.point_step;
  FloatFieldSlot slot;
  const bool refused = field && !slot.place(in.fields, in_step, in_step, field, why);
  const bool with_field = field && !refused;
  const std::size_t step = with_field ? slot.step : in_step;
  out->header = in.header;
  out->fields = in.fields;
  if (with_field) slot.addField(&out->fields, field);
  out->is_bigendian = in.is_bigendian;
  out->is_dense = true;  // a NaN/Inf record has a NaN height
  out->point_step = static_cast<std::uint32_t>(step);
  out->height = 1;
  out->width = static_cast<std::uint32_t>(n);
  out->row_step = static_cast<std::uint32_t>(n * step);
  out->data.resize(n * step);
  std::uint8_t* dst = out->data.data();
  for (std::size_t r = 0, i = 0; r < layout.height; ++r) {
    const std::uint8_t* rec = in.data.data() + r * layout.row_step;
    for (std::size_t c = 0; c < layout.width; ++c, ++i, rec += in_step) {
      if (!inBand(i)) continue;
      if (with_field) {
        slot.copy(dst, rec, heights[i]);
      } else {
        std::memcpy(dst, rec, in_step);
      }
      dst += step;
    }
  }
  return !refused;
}

std::vector<ParamCheck> hagParamChecks() {
  std::vector<ParamCheck> out(3);
  out[0].name = "hag_field";
  out[0].type = ParamCheck::Type::kBool;
  out[1].name = "hag_cell";  // GroundSurfaceParams::validate()'s ranges
  out[1].ranged = true;
  out[1].min = 0.05;
  out[1].max = 100.0;
  out[2].name = "hag_radius";
  out[2].ranged = true;
  out[2].min = 0.0;
  out[2].max = 1000.0;
  return out;
}

void HagOutputs::init(const ros::NodeHandle& pnh, const ros::Publisher& surface,
                      const ros::Publisher& obstacles) {
  pub_surface_ = surface;
  pub_obstacles_ = obstacles;
  pnh.param("hag_field", hag_field_, false);
  pnh.param("hag_cell", params_.cell, 1.0);
  pnh.param("hag_radius", params_.radius, 5.0);
}

void HagOutputs::setBand(const ObstacleBand& band) {
  std::lock_guard<std::mutex> lock(band_mutex_);
  band_ = band;
}

const std::vector<float>* HagOutputs::process(const sensor_msgs::PointCloud2& in,
                                              const CloudLayout& layout,
                                              const Eigen::Isometry3d* to_gravity,
                                              const CloudProcessingBuffers& buffers,
                                              const std::string& frame,
                                              const ProcessedCloud& filtered, bool want_labeled,
                                              HagClouds* clouds) {
  const std::string& filter_error = filtered.filter_error;
  const bool want_surface = pub_surface_.getNumSubscribers() > 0;
  const bool want_obstacles = pub_obstacles_.getNumSubscribers() > 0;
  const bool want_heights = want_labeled || hag_field_ || want_obstacles;
  if (!want_heights && !want_surface) return nullptr;  // no surface build when no output wants it
  const std::vector<std::uint8_t>& labels = buffers.labels;
  // The view the filter saw: the transformed or packed x/y/z when there was one.
  CloudView view;
  if (layout.points && (to_gravity || layout.packed())) {
    view = CloudView::packedXyz(buffers.xyz.data(), layout.points);
  } else if (layout.points) {
    view = CloudView(in.data.data(), layout.points, layout.point_step, layout.x_offset,
                     layout.y_offset, layout.z_offset);
  }
  // A failed filter labelled everything non-ground (and may have left `xyz` stale): no
  // ground, no surface, every height NaN.
  const bool failed =
      !filter_error.empty() || view.size() != labels.size() ||
      (view.size() && (to_gravity || layout.packed()) && buffers.xyz.size() < 3 * layout.points);
  if (failed) view = CloudView();
  // Occlusion shadows (the shadow spike test) only where a sensor stood among the points.
  params_.setScanType(filtered.stats.scan_type);
  params_.threads = filtered.stats.threads;  // the filter's own (the method's `threads`)
  surface_.build(view, failed ? std::vector<std::uint8_t>() : labels, params_);
  if (want_surface) {
    clouds->surface = boost::make_shared<sensor_msgs::PointCloud2>();
    std_msgs::Header header = in.header;
    header.frame_id = frame;
    // In the input's frame (or the gravity frame), float64 where the input's x/y/z are.
    makeSurfaceCloud(surface_, header, clouds->surface.get(), buffers.shift, layout.float64);
  }
  if (!want_heights) return nullptr;
  if (failed) {
    heights_.assign(layout.points, std::numeric_limits<float>::quiet_NaN());
  } else {
    surface_.heights(view, &heights_);
  }
  if (want_obstacles) {
    ObstacleBand band;
    {
      std::lock_guard<std::mutex> lock(band_mutex_);
      band = band_;
    }
    clouds->obstacles = boost::make_shared<sensor_msgs::PointCloud2>();
    // With ~hag_field the obstacles carry the field as ~nonground does (they are a part of it).
    makeObstacleCloud(in, layout, labels, heights_, band, clouds->obstacles.get(),
                      hag_field_ ? kHeightFieldName : nullptr, &clouds->error);
  }
  // ~labeled, ~ground and ~nonground get them as their records are copied (writeOutputs()),
  // like ~obstacles above: no second pass over an output (docs/height_above_ground.md#cost).
  return &heights_;
}

void HagOutputs::publish(const HagClouds& clouds) {
  if (clouds.surface) pub_surface_.publish(sensor_msgs::PointCloud2ConstPtr(clouds.surface));
  if (clouds.obstacles) {
    pub_obstacles_.publish(sensor_msgs::PointCloud2ConstPtr(clouds.obstacles));
  }
}

}  // namespace ground_filter
