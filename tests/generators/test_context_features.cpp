// Context features (generators/sweep/context_features.hpp) on hand-built scenes:
// a building across the corridor lands in the cells it covers with its
// height and material, a vehicle in the corridor in the slot with its
// position and size, and nothing the tracer computed is read.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "dataset_fixtures.hpp"
#include "generators/dataset/dataset_writer.hpp"
#include "generators/formats.hpp"
#include "generators/hdf5/checked_file.hpp"
#include "generators/sweep/context_features.hpp"
#include "meshkit/errors.hpp"
#include "scene_fixtures.hpp"
#include "tracer/trace_scene.hpp"

namespace rg = raysweep::generators;
namespace fs = std::filesystem;
using raysweep::meshkit::Scene;

namespace {

// Ground 200 x 200 m at z = 0; a concrete block across the x axis
// (x 40..50, y -30..30, 12 m high) and a glass kiosk left of it (x 60..62,
// y 5..8, 6 m high).
Scene city() {
  Scene s;
  std::uint32_t face = 0;
  auto& ground = s.mesh_for("medium_dry_ground", "ground");
  const std::uint32_t g = s.add_object("ground", "ground");
  ground.vertices = {{-50, -100, 0}, {150, -100, 0}, {150, 100, 0}, {-50, 100, 0}};
  ground.triangles = {{0, 1, 2}, {0, 2, 3}};
  ground.triangle_object = {g, g};
  ground.triangle_face = {face, face};
  ++face;
  raysweep::test::add_box(s.mesh_for("concrete", "buildings"), {40, -30, 0}, {50, 30, 12},
                          s.add_object("building", "way/1"), face);
  raysweep::test::add_box(s.mesh_for("glass", "buildings"), {60, 5, 0}, {62, 8, 6}, s.add_object("building", "way/2"),
                          face);
  return s;
}

rg::NodeInfo vehicle(const std::string& id, const char* vclass, float l, float w, float h) {
  rg::NodeInfo n;
  n.id = id;
  n.vclass = vclass;
  n.length_m = l, n.width_m = w, n.height_m = h;
  return n;
}

// A vehicle heading east (SUMO 90 degrees) whose body is centred at (cx, cy).
rg::NodeState east(std::uint32_t node, double cx, double cy, float length) {
  rg::NodeState s;
  s.node = node;
  s.x = cx + length / 2, s.y = cy;
  s.heading_deg = 90;
  return s;
}

struct Traffic {
  std::vector<rg::NodeInfo> nodes;
  std::vector<rg::NodeState> states;
};

// tx centred at the origin, rx 100 m east, a truck in the corridor at
// (70, 3), a car 30 m to the side and one behind tx.
Traffic traffic() {
  Traffic t;
  t.nodes = {vehicle("tx", "passenger", 4, 1.8f, 1.5f), vehicle("rx", "passenger", 4, 1.8f, 1.5f),
             vehicle("truck", "truck", 6, 2.5f, 3.2f), vehicle("aside", "passenger", 4, 1.8f, 1.5f),
             vehicle("behind", "bus", 12, 2.5f, 3.4f)};
  t.states = {east(0, 0, 0, 4), east(1, 100, 0, 4), east(2, 70, 3, 6), east(3, 50, 30, 4), east(4, -10, 0, 12)};
  return t;
}

std::vector<rg::FeatureNode> feature_nodes(const Traffic& t) {
  std::vector<rg::FeatureNode> out;
  for (const auto& s : t.states) out.push_back(rg::feature_node(t.nodes[s.node], s));
  return out;
}

struct ContextFeatures : ::testing::Test {
  Scene scene = city();
  raysweep::tracer::TraceScene traced{scene};
  rg::FeatureGridSpec spec;
  rg::HeightMap map = rg::HeightMap::build(traced, scene.bounds(), spec.map_resolution_m);
};

}  // namespace

TEST_F(ContextFeatures, ABuildingAcrossTheCorridorFillsTheCellsItCoversWithItsHeightAndMaterial) {
  const Traffic t = traffic();
  const rg::LinkFeatures f = rg::link_features(spec, map, feature_nodes(t), 0, 1);
  EXPECT_FLOAT_EQ(f.distance_2d_m, 100.f);
  const std::uint32_t C = spec.across_cells;
  const double cell = 100.0 / spec.along_cells;
  for (std::uint32_t i = 0; i < spec.along_cells; ++i) {
    const double along = (i + 0.5) * cell;
    for (std::uint32_t j = 0; j < C; ++j) {
      const double across = -spec.half_width_m + (j + 0.5) * 2 * spec.half_width_m / C;
      int want_h = 0, want_m = 0;
      if (along > 40 && along < 50) want_h = 48, want_m = rg::material_code("concrete");  // 12 m / 0.25 m
      if (along > 60 && along < 62 && across > 5 && across < 8) want_h = 24, want_m = rg::material_code("glass");
      EXPECT_EQ(f.height[i * C + j], want_h) << "cell " << i << ", " << j;
      EXPECT_EQ(f.material[i * C + j], want_m) << "cell " << i << ", " << j;
    }
  }
  EXPECT_NE(rg::material_code("glass"), rg::material_code("concrete"));
  EXPECT_EQ(rg::material_code("unobtainium"), rg::material_code("other"));
}

// A damaged input's NaN position reads as open ground, not as an index
// (found by fuzz_dataset_h5 under UBSan: NaN passed every < / >= test).
TEST_F(ContextFeatures, ANanPositionReadsAsOpenGround) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const rg::HeightMap empty;
  for (const auto& [x, y] : {std::pair{nan, 45.0}, std::pair{45.0, nan}, std::pair{nan, nan}})
    for (const rg::HeightMap* h : {static_cast<const rg::HeightMap*>(&map), &empty}) {
      EXPECT_EQ(h->at(x, y).height_m, 0.f);
      EXPECT_EQ(h->at(x, y).material, 0);
    }
  EXPECT_FLOAT_EQ(map.at(45, 0).height_m, 12.f);  // inside the concrete building, the map does answer
}

TEST_F(ContextFeatures, AVehicleInTheCorridorAppearsWithItsPositionSizeAndClass) {
  const Traffic t = traffic();
  const rg::LinkFeatures f = rg::link_features(spec, map, feature_nodes(t), 0, 1);
  EXPECT_EQ(f.in_corridor, 1u);  // the truck; not the car 30 m aside nor the bus behind tx
  ASSERT_EQ(f.vehicles.size(), 1u);
  const rg::CorridorVehicle& v = f.vehicles[0];
  EXPECT_NEAR(v.along_m, 70, 1e-4);
  EXPECT_NEAR(v.across_m, 3, 1e-4);  // left of tx -> rx (east): +y
  EXPECT_FLOAT_EQ(v.height_m, 3.2f);
  EXPECT_FLOAT_EQ(v.length_m, 6.f);
  EXPECT_FLOAT_EQ(v.width_m, 2.5f);
  EXPECT_NEAR(v.yaw_rad, 0, 1e-6);
  EXPECT_EQ(v.vclass, rg::vehicle_class_code("truck"));
  EXPECT_FLOAT_EQ(f.height_m[0], 1.5f);

  // Seen from rx towards tx the truck is at along 30, on the right.
  const rg::LinkFeatures back = rg::link_features(spec, map, feature_nodes(t), 1, 0);
  ASSERT_EQ(back.vehicles.size(), 1u);
  EXPECT_NEAR(back.vehicles[0].along_m, 30, 1e-4);
  EXPECT_NEAR(back.vehicles[0].across_m, -3, 1e-4);
  EXPECT_NEAR(std::abs(back.vehicles[0].yaw_rad), M_PI, 1e-6);
}

TEST_F(ContextFeatures, TheSlotsKeepTheVehiclesNearestTheLineInOrderAlongIt) {
  Traffic t = traffic();
  t.states.resize(2);
  t.nodes.resize(2);
  const double across[4] = {10, -2, 1, 5}, along[4] = {20, 40, 60, 80};
  for (int k = 0; k < 4; ++k) {
    t.nodes.push_back(vehicle("v" + std::to_string(k), "passenger", 4, 1.8f, 1.5f));
    t.states.push_back(east(2 + k, along[k], across[k], 4));
  }
  spec.max_vehicles = 2;
  const rg::LinkFeatures f = rg::link_features(spec, map, feature_nodes(t), 0, 1);
  EXPECT_EQ(f.in_corridor, 4u);
  ASSERT_EQ(f.vehicles.size(), 2u);
  EXPECT_NEAR(f.vehicles[0].along_m, 40, 1e-4);  // across -2
  EXPECT_NEAR(f.vehicles[1].along_m, 60, 1e-4);  // across 1
}

namespace {

// The traffic above as a one-frame channel dataset with the tracer's
// columns made up by `variant`, at store level `level`.
void write_dataset(const fs::path& path, int variant, rg::StoreLevel level) {
  const Traffic t = traffic();
  rg::DatasetHeader h = rg::fixtures::test_header();
  h.cfr_subcarriers = 0;
  h.store = level;
  rg::DatasetWriter w(path, h);
  rg::FrameRecord f;
  f.time_s = 1.0;
  f.nodes = t.states;
  for (std::uint32_t a = 0; a < 5; ++a)
    for (std::uint32_t b = a + 1; b < 5; ++b) {
      rg::LinkRecord l;
      l.tx = a, l.rx = b;
      l.los_class = static_cast<std::uint8_t>((a + b + variant) % 3);
      l.los_class_fresnel = l.los_class;
      l.gain_coherent_db = l.gain_incoherent_db = -70.f - 10.f * static_cast<float>(variant);
      l.first_delay_s = 1e-7;
      l.path_count = static_cast<std::uint32_t>(variant + 1);
      for (std::uint32_t p = 0; p < l.path_count; ++p) f.paths.push_back(rg::PathRecord{});
      f.links.push_back(l);
    }
  w.append(f);
  std::vector<std::string> objects{"ground", "way/1", "way/2"};
  for (const auto& n : t.nodes) objects.push_back(n.id);
  w.finish(t.nodes, objects);
}

std::string bytes_of(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

}  // namespace

TEST_F(ContextFeatures, TheFileReadsNothingTheTracerComputedAndValidates) {
  const fs::path dir = rg::fixtures::tmp_dir("context_features");
  write_dataset(dir / "a.h5", 0, rg::StoreLevel::full);
  write_dataset(dir / "b.h5", 1, rg::StoreLevel::links);  // other labels, gains, path counts; no paths
  rg::FeaturesHeader h;
  h.raysweep_version = "test";
  h.git_hash = "0";
  h.config = {{"along_cells", spec.along_cells}};
  h.inputs = nlohmann::json::array();
  h.provenance = {{"stage", "features"}};
  const auto sa = rg::write_features(spec, map, dir / "a.h5", dir / "fa.h5", h);
  rg::write_features(spec, map, dir / "b.h5", dir / "fb.h5", h);
  EXPECT_EQ(sa.rows, 10u);
  EXPECT_EQ(bytes_of(dir / "fa.h5"), bytes_of(dir / "fb.h5"));
  EXPECT_TRUE(rg::validate_dataset((dir / "fa.h5").string()).empty());

  // The row of link (tx 0, rx 1) holds what link_features gives.
  raysweep::generators::hdf5::CheckedFile f((dir / "fa.h5").string());
  f.open();
  const auto count = f.dataset("/vehicles/count").read_all<std::uint8_t>(10);
  const auto along = f.dataset("/vehicles/along_m").read_all<float>(10, spec.max_vehicles);
  const auto height = f.dataset("/corridor/height").read<std::uint8_t>(0, 1, spec.cells());
  EXPECT_EQ(count[0], 1);
  EXPECT_NEAR(along[0], 70, 1e-4);
  EXPECT_TRUE(std::isnan(along[1]));
  const rg::LinkFeatures direct = rg::link_features(spec, map, feature_nodes(traffic()), 0, 1);
  EXPECT_EQ(height, direct.height);
  EXPECT_TRUE(rg::finished_features_provenance(dir / "fa.h5").has_value());
  EXPECT_FALSE(rg::finished_features_provenance(dir / "a.h5").has_value());

  // Not a channel dataset: an error naming the file.
  try {
    rg::write_features(spec, map, dir / "fa.h5", dir / "fc.h5", h);
    FAIL() << "a feature file taken for a dataset";
  } catch (const raysweep::meshkit::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("fa.h5"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("not a channel dataset"), std::string::npos) << e.what();
  }
  fs::remove_all(dir);
}
