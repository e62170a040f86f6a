#include "point_cloud2.h"

#include <ros/serialization.h>
#include <sensor_msgs/PointField.h>

#include <algorithm>
#include <boost/make_shared.hpp>
#include <cmath>
#include <cstring>
#include <exception>
#include <sstream>
#include <stdexcept>

namespace ground_filter {

namespace {

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

const char* reasonName(CloudRejectReason r) {
  // In the order of CloudRejectReason.
  static const char* const kNames[] = {"none",        "big-endian",   "missing field", "field type",
                                       "field count", "field extent", "row_step",      "data size"};
  static_assert(sizeof(kNames) / sizeof(kNames[0]) == static_cast<int>(CloudRejectReason::kCount),
                "one name per CloudRejectReason");
  const int i = static_cast<int>(r);
  return i > 0 && i < static_cast<int>(CloudRejectReason::kCount) ? kNames[i] : "none";
}

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
    // No rows to walk when there is no point: a cloud of width 0 and height 4e9 must not cost
    // 4e9 empty row iterations in every pass (found by fuzzing: seconds per message).
    layout->height = cloud.width == 0 ? 0 : cloud.height;
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

bool sampledCentre(const sensor_msgs::PointCloud2& cloud, const CloudLayout& layout,
                   std::size_t max_samples, double centre[3]) {
  if (layout.points == 0 || layout.width == 0 || max_samples == 0) return false;
  const std::size_t step = (layout.points + max_samples - 1) / max_samples;  // <= max_samples reads
  double lo[3] = {0.0, 0.0, 0.0}, hi[3] = {0.0, 0.0, 0.0};
  bool any = false;
  for (std::size_t i = 0; i < layout.points; i += step) {
    const std::uint8_t* rec = cloud.data.data() + (i / layout.width) * layout.row_step +
                              (i % layout.width) * layout.point_step;
    const double p[3] = {loadFloat(rec + layout.x_offset), loadFloat(rec + layout.y_offset),
                         loadFloat(rec + layout.z_offset)};
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

bool deserializePointCloud2(const std::uint8_t* buf, std::uint32_t len,
                            sensor_msgs::PointCloud2* msg, std::string* why) {
  if (!checkSerializedPointCloud2(buf, len, why)) return false;
  try {
    ros::serialization::IStream stream(const_cast<std::uint8_t*>(buf), len);
    ros::serialization::deserialize(stream, *msg);
  } catch (const std::exception& e) {
    *why = e.what();
    return false;
  }
  return true;
}

void processPointCloud2(const sensor_msgs::PointCloud2& in, const CloudLayout& layout,
                        GroundFilter* filter, const Eigen::Isometry3d* transform, bool want_labeled,
                        CloudProcessingBuffers* buffers, ProcessedCloud* out) {
  std::vector<std::uint8_t>& labels = buffers->labels;
  out->stats = FilterStats();
  out->filter_error.clear();
  out->labeled_error.clear();
  try {
    if (!filter) throw std::runtime_error("no filter");
    const CloudView view = transform
                               ? makeTransformedCloudView(in, layout, *transform, &buffers->xyz)
                               : makeCloudView(in, layout, &buffers->xyz);
    filter->filter(view, &labels, &out->stats);
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
  out->ground = boost::make_shared<sensor_msgs::PointCloud2>();
  out->nonground = boost::make_shared<sensor_msgs::PointCloud2>();
  out->counts = splitPointCloud2(in, layout, &labels, out->ground.get(), out->nonground.get());
  out->labeled.reset();
  if (want_labeled) {
    out->labeled = boost::make_shared<sensor_msgs::PointCloud2>();
    if (!makeLabeledCloud(in, layout, labels, out->labeled.get(), &out->labeled_error)) {
      out->labeled.reset();
    }
  }
}

}  // namespace ground_filter
