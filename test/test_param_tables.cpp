// Drift test: each filter's parameter table (the one list behind set(), validate() and the log
// line) against the dynamic_reconfigure description generated from cfg/*.cfg — names, types,
// ranges, units and defaults.
#include <gtest/gtest.h>

#include <boost/any.hpp>
#include <set>
#include <stdexcept>
#include <string>

#include "ground_filter/NormalGroundFilterConfig.h"
#include "ground_filter/VoxelGroundFilterConfig.h"
#include "ground_filter/normal_ground_filter_params.h"
#include "ground_filter/param_parse.h"
#include "ground_filter/voxel_ground_filter_params.h"

namespace gf = ground_filter;

namespace {

// cfg parameters that belong to the nodelet, not to a filter's params struct.
const std::set<std::string> kNodeletOnly = {"max_range", "min_range", "obstacle_min_height",
                                            "obstacle_max_height"};

double asDouble(const boost::any& v) {
  if (v.type() == typeid(double)) return boost::any_cast<double>(v);
  if (v.type() == typeid(int)) return boost::any_cast<int>(v);
  ADD_FAILURE() << "not a number";
  return 0.0;
}

template <class Config, class Params>
void expectTableMatchesCfg(const char* cfg_file) {
  const auto& table = Params::table();
  const Params defaults;
  std::set<std::string> rows;
  for (const auto& spec : table) rows.insert(spec.name);
  for (const auto& d : Config::__getParamDescriptions__()) {
    SCOPED_TRACE(std::string(cfg_file) + ": " + d->name);
    if (kNodeletOnly.count(d->name)) continue;
    EXPECT_TRUE(rows.count(d->name)) << "in the .cfg but not in " << typeid(Params).name();
  }
  for (const auto& spec : table) {
    SCOPED_TRACE(std::string(cfg_file) + ": " + spec.name);
    const typename Config::AbstractParamDescription* desc = nullptr;
    for (const auto& d : Config::__getParamDescriptions__()) {
      if (d->name == spec.name) desc = d.get();
    }
    ASSERT_NE(desc, nullptr) << "in the table but not in the .cfg";
    boost::any def, lo, hi;
    desc->getValue(Config::__getDefault__(), def);
    desc->getValue(Config::__getMin__(), lo);
    desc->getValue(Config::__getMax__(), hi);
    using Type = typename gf::ParamSpec<Params>::Type;
    if (spec.isNumber()) {
      EXPECT_EQ(desc->type, (spec.type == Type::kDouble ? "double" : "int"));
      EXPECT_DOUBLE_EQ(asDouble(def), spec.number(defaults)) << "default";
      EXPECT_DOUBLE_EQ(asDouble(lo), spec.min) << "min";
      EXPECT_DOUBLE_EQ(asDouble(hi), spec.max) << "max";
      // The unit in the table is the one the .cfg description states in brackets.
      const std::string unit = *spec.unit ? spec.unit : "-";
      EXPECT_NE(desc->description.find("[" + unit + "]"), std::string::npos)
          << "description lacks [" << unit << "]: " << desc->description;
    } else if (spec.type == Type::kBool) {
      EXPECT_EQ(desc->type, "bool");
      EXPECT_EQ(boost::any_cast<bool>(def), defaults.*spec.as_bool) << "default";
    } else {
      EXPECT_EQ(desc->type, "str");
      EXPECT_EQ(boost::any_cast<std::string>(def), defaults.*spec.as_string) << "default";
    }
  }
}

// Every value the table allows at each end passes validate(); just outside it fails.
template <class Params, class Fixup>
void expectRangesEnforced(Fixup fixup) {
  using Type = typename gf::ParamSpec<Params>::Type;
  for (const auto& spec : Params::table()) {
    if (!spec.isNumber()) continue;
    SCOPED_TRACE(spec.name);
    const bool is_int = spec.type == Type::kInt;
    auto with = [&](double v) {
      Params p;
      // The cross-field rules (tile_size >= 2 voxel_size, the vegetation band) are not tested here.
      fixup(spec.name, &p);
      if (is_int) {
        p.*spec.as_int = static_cast<int>(v);
      } else {
        p.*spec.as_double = v;
      }
      return p;
    };
    EXPECT_NO_THROW(with(spec.max).validate());
    EXPECT_NO_THROW(with(spec.min).validate());
    EXPECT_THROW(with(spec.max + (is_int ? 1 : spec.max * 1e-6)).validate(), std::invalid_argument);
    EXPECT_THROW(with(spec.min - (is_int ? 1 : 1e-9)).validate(), std::invalid_argument);
  }
}

}  // namespace

TEST(ParamTables, VoxelTableMatchesCfg) {
  expectTableMatchesCfg<gf::VoxelGroundFilterConfig, gf::VoxelGroundFilterParams>(
      "VoxelGroundFilter.cfg");
}

TEST(ParamTables, NormalTableMatchesCfg) {
  expectTableMatchesCfg<gf::NormalGroundFilterConfig, gf::NormalGroundFilterParams>(
      "NormalGroundFilter.cfg");
}

TEST(ParamTables, VoxelRangesEnforced) {
  expectRangesEnforced<gf::VoxelGroundFilterParams>(
      [](const std::string& name, gf::VoxelGroundFilterParams* p) {
        if (name == "voxel_size") p->tile_size = 1000.0;
        if (name == "tile_size") p->voxel_size = 0.005;
        if (name == "veg_min_height") p->veg_max_height = 10.0;  // the band's rule
        if (name == "veg_max_height") p->veg_min_height = 0.0;
      });
}

TEST(ParamTables, NormalRangesEnforced) {
  expectRangesEnforced<gf::NormalGroundFilterParams>(
      [](const std::string& name, gf::NormalGroundFilterParams* p) {
        if (name == "veg_min_height") p->veg_max_height = 10.0;  // the band's rule
        if (name == "veg_max_height") p->veg_min_height = 0.0;
      });
}

TEST(ParamTables, SetWritesTheFieldAndDescribeShowsIt) {
  gf::VoxelGroundFilterParams v;
  v.set("plane_distance", "0.25");
  v.set("majority_vote", "off");
  EXPECT_DOUBLE_EQ(v.plane_distance, 0.25);
  EXPECT_FALSE(v.majority_vote);
  EXPECT_NE(v.describe().find("plane_distance=0.25"), std::string::npos) << v.describe();
  EXPECT_NE(v.describe().find("majority_vote=false"), std::string::npos) << v.describe();
  gf::NormalGroundFilterParams n;
  n.set("knn_backend", "gpu");
  n.set("k", "20");
  EXPECT_EQ(n.knn_backend, "gpu");
  EXPECT_EQ(n.k, 20);
  EXPECT_THROW(n.set("no_such", "1"), std::invalid_argument);
  EXPECT_THROW(n.set("k", "many"), std::invalid_argument);
  n.knn_backend = "cpu";
  EXPECT_THROW(n.validate(), std::invalid_argument);
}

TEST(ParamTables, StringChoicesNameParameterValueAndChoices) {
  gf::NormalGroundFilterParams n;
  n.scan_type = "nadir";
  try {
    n.validate();
    ADD_FAILURE() << "scan_type 'nadir' accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_STREQ(e.what(),
                 "parameter 'scan_type' = 'nadir' is not one of: auto, ground, "
                 "airborne, tls, registered");
  }
  gf::VoxelGroundFilterParams v;
  v.scan_type = "tls";
  EXPECT_NO_THROW(v.validate());
  v.scan_type = "registered";
  EXPECT_NO_THROW(v.validate());
  v.scan_type = "";
  EXPECT_THROW(v.validate(), std::invalid_argument);
  EXPECT_THROW(gf::checkChoice("mode", "c", {"a", "b"}), std::invalid_argument);
  EXPECT_NO_THROW(gf::checkChoice("mode", "b", {"a", "b"}));
}

TEST(ParamTables, RowsOfBaseMembersKeepTheirType) {
  using Spec = gf::ParamSpec<gf::NormalGroundFilterParams>;
  std::set<std::string> seen;
  for (const auto& spec : gf::NormalGroundFilterParams::table()) {
    const std::string name = spec.name;
    // k and veg_filter come from the NormalFilterSettings base, morph_cell and scan_type from
    // MorphGroundParams, knn_backend from the struct itself.
    if (name == "k") EXPECT_EQ(spec.type, Spec::Type::kInt);
    if (name == "veg_filter") EXPECT_EQ(spec.type, Spec::Type::kBool);
    if (name == "morph_cell") EXPECT_EQ(spec.type, Spec::Type::kDouble);
    if (name == "scan_type" || name == "knn_backend") EXPECT_EQ(spec.type, Spec::Type::kString);
    seen.insert(name);
  }
  for (const char* name : {"k", "veg_filter", "morph_cell", "scan_type", "knn_backend"}) {
    EXPECT_EQ(seen.count(name), 1u) << name;
  }
  gf::NormalGroundFilterParams n;
  n.set("morph_cell", "2.5");
  n.set("k", "12");
  EXPECT_DOUBLE_EQ(n.morph_cell, 2.5);
  EXPECT_EQ(n.k, 12);
}
