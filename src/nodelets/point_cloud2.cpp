#include "point_cloud2.h"

#include <sensor_msgs/PointField.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <exception>
#include <stdexcept>

#include "ground_filter/point_field.h"

namespace ground_filter {

namespace {

// One coordinate of a record: float32, or float64 where the layout says so.
double loadCoord(const std::uint8_t* p, bool float64) {
  if (float64) {
    double v;
    std::memcpy(&v, p, sizeof(double));
    return v;
  }
  float v;
  std::memcpy(&v, p, sizeof(float));
  return v;
}

void loadXyz(const std::uint8_t* rec, const CloudLayout& layout, double p[3]) {
  p[0] = loadCoord(rec + layout.x_offset, layout.float64);
  p[1] = loadCoord(rec + layout.y_offset, layout.float64);
  p[2] = loadCoord(rec + layout.z_offset, layout.float64);
}

// Output cloud with the input's header and fields, room for `n` records of `step` bytes.
void prepareOutput(const sensor_msgs::PointCloud2& in, std::size_t n, std::size_t step,
                   sensor_msgs::PointCloud2* out) {
  out->header = in.header;
  out->fields = in.fields;
  out->is_bigendian = in.is_bigendian;
  out->point_step = static_cast<std::uint32_t>(step);
  out->height = 1;
  out->width = static_cast<std::uint32_t>(n);
  out->row_step = static_cast<std::uint32_t>(n * step);
  out->data.resize(n * step);
}

// Records sampled for packShift().
constexpr std::size_t kShiftSamples = 8192;

// What a packed view is moved by (subtracted, whole metres) so that its float32 keep the
// precision of far float64 coordinates (a map or survey tile in projected coordinates, or a
// gravity frame far from the sensor): the trimmed middle (trimmedMiddle()) of at most
// kShiftSamples records through `transform`, where it lies beyond the working volume's hard box
// on some axis; else 0 (a cloud near its frame's origin is packed as it is).
void packShift(const sensor_msgs::PointCloud2& cloud, const CloudLayout& layout,
               const Eigen::Isometry3d* transform, double shift[3]) {
  std::fill_n(shift, 3, 0.0);
  const std::size_t step = std::max<std::size_t>(1, layout.points / kShiftSamples);
  std::vector<double> axis[3];
  for (std::size_t i = 0; i < layout.points; i += step) {
    const std::uint8_t* rec = cloud.data.data() + (i / layout.width) * layout.row_step +
                              (i % layout.width) * layout.point_step;
    Eigen::Vector3d p;
    loadXyz(rec, layout, p.data());
    if (transform) p = *transform * p;
    if (!p.allFinite()) continue;
    for (int a = 0; a < 3; ++a) axis[a].push_back(p[a]);
  }
  if (axis[0].empty()) return;
  double middle[3];
  for (int a = 0; a < 3; ++a) middle[a] = trimmedMiddle(&axis[a]);
  if (moveOntoMiddle(middle, kWorkingVolumeHardLimit)) std::copy_n(middle, 3, shift);
}

}  // namespace

CloudView makeCloudView(const sensor_msgs::PointCloud2& cloud, const CloudLayout& layout,
                        std::vector<float>* scratch, double* shift) {
  if (shift) std::fill_n(shift, 3, 0.0);
  if (layout.points == 0) return CloudView();
  if (!layout.packed()) {
    return CloudView(cloud.data.data(), layout.points, layout.point_step, layout.x_offset,
                     layout.y_offset, layout.z_offset);
  }
  // Rows are padded (one stride cannot describe them) or x/y/z are doubles: pack them once,
  // doubles far from the origin moved first (in double) where the caller takes the shift.
  double move[3] = {0.0, 0.0, 0.0};
  if (shift && layout.float64) {
    packShift(cloud, layout, nullptr, move);
    std::copy_n(move, 3, shift);
  }
  scratch->resize(3 * layout.points);
  float* out = scratch->data();
  for (std::size_t r = 0; r < layout.height; ++r) {
    const std::uint8_t* rec = cloud.data.data() + r * layout.row_step;
    for (std::size_t c = 0; c < layout.width; ++c, rec += layout.point_step) {
      double p[3];
      loadXyz(rec, layout, p);
      *out++ = narrowCoordinate(p[0] - move[0]);
      *out++ = narrowCoordinate(p[1] - move[1]);
      *out++ = narrowCoordinate(p[2] - move[2]);
    }
  }
  return CloudView::packedXyz(scratch->data(), layout.points);
}

bool sampledCentre(const sensor_msgs::PointCloud2& cloud, const CloudLayout& layout,
                   std::size_t max_samples, double centre[3]) {
  if (layout.points == 0 || layout.width == 0 || max_samples == 0) return false;
  const std::size_t step = (layout.points + max_samples - 1) / max_samples;  // <= max_samples reads
  double lo[3] = {0.0, 0.0, 0.0}, hi[3] = {0.0, 0.0, 0.0};
  bool any = false;
  for (std::size_t i = 0; i < layout.points; i += step) {
    const std::uint8_t* rec = cloud.data.data() + (i / layout.width) * layout.row_step +
                              (i % layout.width) * layout.point_step;
    double p[3];
    loadXyz(rec, layout, p);
    if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2])) continue;
    for (int a = 0; a < 3; ++a) {
      lo[a] = any ? std::min(lo[a], p[a]) : p[a];
      hi[a] = any ? std::max(hi[a], p[a]) : p[a];
    }
    any = true;
  }
  if (!any) return false;
  for (int a = 0; a < 3; ++a) centre[a] = 0.5 * (lo[a] + hi[a]);
  return true;
}

SplitCounts splitPointCloud2(const sensor_msgs::PointCloud2& in, const CloudLayout& layout,
                             std::vector<std::uint8_t>* labels, sensor_msgs::PointCloud2* ground,
                             sensor_msgs::PointCloud2* nonground) {
  const SplitCounts counts = finalizeLabels(in, layout, labels);
  copySplit(in, layout, *labels, counts, ground, nonground);
  return counts;
}

SplitCounts finalizeLabels(const sensor_msgs::PointCloud2& in, const CloudLayout& layout,
                           std::vector<std::uint8_t>* labels) {
  SplitCounts counts;
  const std::size_t step = layout.point_step;
  std::vector<std::uint8_t>& final_labels = *labels;
  for (std::size_t r = 0, i = 0; r < layout.height; ++r) {
    const std::uint8_t* rec = in.data.data() + r * layout.row_step;
    for (std::size_t c = 0; c < layout.width; ++c, ++i, rec += step) {
      double p[3];
      loadXyz(rec, layout, p);
      const bool finite = std::isfinite(p[0]) && std::isfinite(p[1]) && std::isfinite(p[2]);
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
  return counts;
}

bool copySplit(const sensor_msgs::PointCloud2& in, const CloudLayout& layout,
               const std::vector<std::uint8_t>& labels, const SplitCounts& counts,
               sensor_msgs::PointCloud2* ground, sensor_msgs::PointCloud2* nonground,
               const RecordFloatField* field, std::string* why) {
  const std::size_t in_step = layout.point_step;
  FloatFieldSlot slot;
  bool with_field = field && field->values;
  const bool refused = with_field && !slot.place(in.fields, in_step, in_step, field->name, why);
  with_field = with_field && !refused;
  const std::size_t step = with_field ? slot.step : in_step;
  prepareOutput(in, counts.ground, step, ground);
  prepareOutput(in, counts.nonground, step, nonground);
  if (with_field) {
    slot.addField(&ground->fields, field->name);
    slot.addField(&nonground->fields, field->name);
  }
  ground->is_dense = true;
  nonground->is_dense = counts.invalid == 0;
  std::uint8_t* dst[2] = {nonground->data.data(), ground->data.data()};
  if (!with_field) {
    // Runs of equally labelled records within each row: one memcpy per run.
    for (std::size_t r = 0, i = 0; r < layout.height; ++r) {
      const std::uint8_t* row = in.data.data() + r * layout.row_step;
      std::size_t c = 0;
      while (c < layout.width) {
        const std::uint8_t label = labels[i + c];
        std::size_t end = c + 1;
        while (end < layout.width && labels[i + end] == label) ++end;
        const std::size_t bytes = (end - c) * in_step;
        std::memcpy(dst[label], row + c * in_step, bytes);
        dst[label] += bytes;
        c = end;
      }
      i += layout.width;
    }
    return !refused;
  }
  // Record by record, the value written as each record lands (no second pass over the outputs).
  const float* v = field->values->data();
  for (std::size_t r = 0, i = 0; r < layout.height; ++r) {
    const std::uint8_t* rec = in.data.data() + r * layout.row_step;
    for (std::size_t c = 0; c < layout.width; ++c, ++i, rec += in_step) {
      std::uint8_t*& d = dst[labels[i]];
      slot.copy(d, rec, v[i]);
      d += step;
    }
  }
  return true;
}

CloudView makeTransformedCloudView(const sensor_msgs::PointCloud2& cloud, const CloudLayout& layout,
                                   const Eigen::Isometry3d& transform, std::vector<float>* scratch,
                                   double* shift) {
  if (shift) std::fill_n(shift, 3, 0.0);
  if (layout.points == 0) return CloudView();
  // Double precision for the products: KITTI ranges reach 80 m and the labels must not depend
  // on float rounding of the rotation. A frame far from the points is moved out in double too
  // (float32 points can only get there through the translation: the usual frame, near the
  // sensor, takes no sample pass).
  double move[3] = {0.0, 0.0, 0.0};
  if (shift &&
      (layout.float64 || transform.translation().cwiseAbs().maxCoeff() > kWorkingVolumeHardLimit)) {
    packShift(cloud, layout, &transform, move);
    std::copy_n(move, 3, shift);
  }
  const Eigen::Matrix3d r = transform.linear();
  const Eigen::Vector3d t = transform.translation() - Eigen::Vector3d(move[0], move[1], move[2]);
  scratch->resize(3 * layout.points);
  float* out = scratch->data();
  for (std::size_t row = 0; row < layout.height; ++row) {
    const std::uint8_t* rec = cloud.data.data() + row * layout.row_step;
    for (std::size_t c = 0; c < layout.width; ++c, rec += layout.point_step) {
      Eigen::Vector3d p;
      loadXyz(rec, layout, p.data());
      const Eigen::Vector3d q = r * p + t;  // NaN/Inf stay non-finite
      *out++ = static_cast<float>(q.x());
      *out++ = static_cast<float>(q.y());
      *out++ = static_cast<float>(q.z());
    }
  }
  return CloudView::packedXyz(scratch->data(), layout.points);
}

sensor_msgs::PointField makePointField(const char* name, std::uint32_t offset,
                                       std::uint8_t datatype) {
  return singleValueField<sensor_msgs::PointField>(name, offset, datatype);
}

bool fieldSlot(const std::vector<sensor_msgs::PointField>& fields, std::size_t point_step,
               const char* name, std::uint8_t datatype, std::size_t size, std::size_t* offset,
               std::size_t* step, bool* append, std::string* why) {
  const sensor_msgs::PointField* existing = nullptr;
  for (const auto& f : fields) {
    if (f.name == name) existing = &f;
  }
  *append = existing == nullptr;
  *step = point_step;
  if (existing) {
    if (existing->datatype != datatype || existing->count != 1) {
      if (why) {
        *why = std::string("the input already has a field '") + name + "' that is not a single " +
               (datatype == sensor_msgs::PointField::UINT8 ? "uint8" : "float32");
      }
      return false;
    }
    *offset = existing->offset;
  } else {
    *offset = (point_step + size - 1) / size * size;  // the value aligned to its size
    *step = (*offset + size + 3) / 4 * 4;             // records stay 4-byte aligned
  }
  return true;
}

bool FloatFieldSlot::place(const std::vector<sensor_msgs::PointField>& fields, std::size_t src,
                           std::size_t point_step, const char* name, std::string* why) {
  src_step = src;
  return fieldSlot(fields, point_step, name, sensor_msgs::PointField::FLOAT32, sizeof(float),
                   &offset, &step, &append, why);
}

void FloatFieldSlot::addField(std::vector<sensor_msgs::PointField>* fields,
                              const char* name) const {
  if (append) {
    fields->push_back(
        makePointField(name, static_cast<std::uint32_t>(offset), sensor_msgs::PointField::FLOAT32));
  }
}

bool makeLabeledCloud(const sensor_msgs::PointCloud2& in, const CloudLayout& layout,
                      const std::vector<std::uint8_t>& labels, sensor_msgs::PointCloud2* out,
                      std::string* why, const RecordFloatField* field, std::string* field_why) {
  const std::size_t in_step = layout.point_step;
  std::size_t label_offset = 0, step = 0;
  bool append = false;
  if (!fieldSlot(in.fields, in_step, kLabelFieldName, sensor_msgs::PointField::UINT8, 1,
                 &label_offset, &step, &append, why)) {
    return false;
  }
  out->fields = in.fields;
  if (append) {
    out->fields.push_back(makePointField(kLabelFieldName, static_cast<std::uint32_t>(label_offset),
                                         sensor_msgs::PointField::UINT8));
  }
  // The float field after the label (or in place), in the same copy.
  FloatFieldSlot slot;
  const bool with_field =
      field && field->values && slot.place(out->fields, in_step, step, field->name, field_why);
  if (with_field) {
    slot.addField(&out->fields, field->name);
    step = slot.step;
  }
  out->header = in.header;
  out->height = in.height;
  out->width = in.width;
  out->is_bigendian = in.is_bigendian;
  out->is_dense = in.is_dense;
  out->point_step = static_cast<std::uint32_t>(step);
  out->row_step = static_cast<std::uint32_t>(step * in.width);
  out->data.resize(step * layout.points);  // every byte written below (gaps zeroed)
  const float* v = with_field ? field->values->data() : nullptr;
  std::uint8_t* dst = out->data.data();
  for (std::size_t r = 0, i = 0; r < layout.height; ++r) {
    const std::uint8_t* rec = in.data.data() + r * layout.row_step;
    for (std::size_t c = 0; c < layout.width; ++c, ++i, rec += in_step, dst += step) {
      if (v) {
        slot.copy(dst, rec, v[i]);
      } else {
        std::memcpy(dst, rec, in_step);
        if (step > in_step) std::memset(dst + in_step, 0, step - in_step);
      }
      dst[label_offset] = labels[i] == kGround ? 1 : 0;
    }
  }
  return true;
}

void processPointCloud2(const sensor_msgs::PointCloud2& in, const CloudLayout& layout,
                        GroundFilter* filter, const Eigen::Isometry3d* transform, bool want_labeled,
                        CloudProcessingBuffers* buffers, ProcessedCloud* out, OutputPools* pools) {
  filterPointCloud2(in, layout, filter, transform, buffers, out);
  writeOutputs(in, layout, want_labeled, buffers, out, pools);
}

void filterPointCloud2(const sensor_msgs::PointCloud2& in, const CloudLayout& layout,
                       GroundFilter* filter, const Eigen::Isometry3d* transform,
                       CloudProcessingBuffers* buffers, ProcessedCloud* out) {
  std::vector<std::uint8_t>& labels = buffers->labels;
  out->stats = FilterStats();
  out->filter_error.clear();
  std::fill_n(buffers->shift, 3, 0.0);
  try {
    if (!filter) throw std::runtime_error("no filter");
    double* shift = buffers->shift;
    const CloudView view =
        transform ? makeTransformedCloudView(in, layout, *transform, &buffers->xyz, shift)
                  : makeCloudView(in, layout, &buffers->xyz, shift);
    const bool moved = shift[0] != 0.0 || shift[1] != 0.0 || shift[2] != 0.0;
    if (moved) {
      // The sensor stays where it is: at the frame's origin (or the gravity frame's sensor
      // position), now -shift from the moved points; set again for the next cloud below.
      const Eigen::Vector3d o =
          transform ? transform->translation() : Eigen::Vector3d(0.0, 0.0, 0.0);
      filter->setSensorOrigin(narrowCoordinate(o.x() - shift[0]),
                              narrowCoordinate(o.y() - shift[1]),
                              narrowCoordinate(o.z() - shift[2]));
      filter->filter(view, &labels, &out->stats);
      filter->setSensorOrigin(narrowCoordinate(o.x()), narrowCoordinate(o.y()),
                              narrowCoordinate(o.z()));
      char note[128];
      std::snprintf(note, sizeof(note), "; x/y/z moved by -(%.0f %.0f %.0f) in double first",
                    shift[0], shift[1], shift[2]);
      out->stats.scan_reason += note;
    } else {
      filter->filter(view, &labels, &out->stats);
    }
    if (labels.size() != layout.points) {
      throw std::runtime_error("the filter returned " + std::to_string(labels.size()) +
                               " labels for " + std::to_string(layout.points) + " points");
    }
  } catch (const std::exception& e) {
    // Lose nothing: the cloud still goes out, every point as non-ground.
    out->filter_error = e.what();
    out->stats = FilterStats();
    labels.assign(layout.points, kNonGround);
  }
  out->counts = finalizeLabels(in, layout, &labels);
}

void writeOutputs(const sensor_msgs::PointCloud2& in, const CloudLayout& layout, bool want_labeled,
                  CloudProcessingBuffers* buffers, ProcessedCloud* out, OutputPools* pools,
                  const RecordFloatField* field, bool field_in_split) {
  const std::vector<std::uint8_t>& labels = buffers->labels;
  out->labeled_error.clear();
  out->field_error.clear();
  // A pooled message's buffer is sized for about the whole cloud (with room for the float field
  // where it goes): the first clouds' split varies.
  const std::size_t extra = field ? layout.points * (sizeof(float) + 3) : 0;
  const std::size_t bytes = layout.points * layout.point_step;
  const std::size_t split_bytes = bytes + (field_in_split ? extra : 0);
  out->ground = takeCloud(pools ? &pools->ground : nullptr, split_bytes);
  out->nonground = takeCloud(pools ? &pools->nonground : nullptr, split_bytes);
  copySplit(in, layout, labels, out->counts, out->ground.get(), out->nonground.get(),
            field_in_split ? field : nullptr, &out->field_error);
  out->labeled.reset();
  if (want_labeled) {
    out->labeled = takeCloud(pools ? &pools->labeled : nullptr, bytes + layout.points * 4 + extra);
    if (!makeLabeledCloud(in, layout, labels, out->labeled.get(), &out->labeled_error, field,
                          &out->field_error)) {
      out->labeled.reset();
    }
  }
}

void setSensorPose(WorkingVolumeFilter* filter, const Eigen::Isometry3d& pose) {
  const Eigen::Vector3d o = pose.translation();
  const Eigen::Matrix3d r = pose.linear();
  const float origin[3] = {static_cast<float>(o.x()), static_cast<float>(o.y()),
                           static_cast<float>(o.z())};
  float rotation[9];
  for (int i = 0; i < 9; ++i) rotation[i] = static_cast<float>(r(i / 3, i % 3));
  filter->setPose(origin, rotation);
}

}  // namespace ground_filter
