// The vehicle stage's model builder (pipeline/vehicles_stage.cpp) on the BMW
// OpenMATERIAL models: real size, front, segmentation and materials, scaling.
#include <gtest/gtest.h>

#include <filesystem>

#include "meshkit/materials.hpp"
#include "meshkit/vehicle_model.hpp"
#include "pipeline/vehicles_stage.hpp"
#include "test_util.hpp"

using namespace raysweep::meshkit;

// ---- BMW OpenMATERIAL models (skipped without ../shared) -------------------

namespace {

struct BmwCase {
  const char* file;
  const char* vclass;
  // Size the geometry implies, from tests/data/gltf_bbox.py (an independent
  // numpy walk of the node hierarchy): length, width, height in metres.
  double length, width, height;
};

void check_bmw(const BmwCase& c) {
  const auto path = raysweep::test::shared_data() / "openmaterial-validation-vehicles/objects" / c.file;
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "../shared data absent";
  raysweep::pipeline::VehiclesSettings cfg;
  cfg.scale_to_class = false;  // keep the model's own size
  auto built = raysweep::pipeline::build_vehicle(c.vclass, c.vclass, path.string(), cfg);
  const auto& m = built.model;
  const VehicleDims d = m.dims();
  EXPECT_NEAR(d.length, c.length, 0.02 * c.length);
  EXPECT_NEAR(d.width, c.width, 0.02 * c.width);
  EXPECT_NEAR(d.height, c.height, 0.02 * c.height);
  // Library frame: the front lamps are at the front (x near 0).
  const Bounds b = m.bounds();
  EXPECT_NEAR(b.max[0], 0, 1e-9);
  EXPECT_NEAR(b.min[2], 0, 1e-9);
  double front_lamp_x = -1e9, rear_lamp_x = 1e9;
  for (const auto& p : m.parts) {
    if (p.vertices.empty()) continue;
    double x = 0;
    for (const auto& v : p.vertices) x += v[0] / p.vertices.size();
    if (p.name.find("_FL") != std::string::npos && p.name.find("Light") != std::string::npos)
      front_lamp_x = std::max(front_lamp_x, x);
    if (p.name.find("_BL") != std::string::npos && p.name.find("Light") != std::string::npos)
      rear_lamp_x = std::min(rear_lamp_x, x);
  }
  EXPECT_GT(front_lamp_x, -0.25 * d.length) << "front lamps near the front bumper";
  EXPECT_LT(rear_lamp_x, -0.75 * d.length) << "rear lamps near the rear";
  // Every part mapped by a rule; windows glass, body metal, tyres rubber.
  EXPECT_EQ(built.record["segmentation"]["by_default"], 0) << built.record["warnings"].dump();
  EXPECT_FALSE(built.record["segmentation"]["geometric"].get<bool>());
  int windows = 0, tyres = 0;
  for (const auto& p : m.parts) {
    EXPECT_TRUE(is_radio_material(p.material)) << p.name;
    if (p.name.rfind("Window", 0) == 0) {
      EXPECT_EQ(p.material, "glass") << p.name;
      ++windows;
    }
    if (p.name.rfind("Tire", 0) == 0) {
      EXPECT_EQ(p.material, "rubber") << p.name;
      ++tyres;
    }
    if (p.name == "Body" || p.name.rfind("Door", 0) == 0 || p.name.rfind("Cabin", 0) == 0)
      EXPECT_EQ(p.material, "metal") << p.name;
  }
  EXPECT_GE(windows, 4);
  EXPECT_GE(tyres, 4);
  // Antenna on the roof line, inside the footprint.
  EXPECT_GT(m.antenna[2], 0.5 * d.height);
  EXPECT_LT(m.antenna[0], 0);
  EXPECT_GT(m.antenna[0], -d.length);
}

}  // namespace

TEST(BmwModels, CarLoadsWithRealSizeAndMaterials) {
  check_bmw({"vehicle_example.gltf", "passenger", 3.181690 + 0.672877, 2 * 0.808840, 0.965954 + 0.330420});
}

TEST(BmwModels, TruckLoadsWithRealSizeAndMaterials) {
  check_bmw({"truck_example.gltf", "truck", 6.986021 + 1.453267, 1.437871 + 1.437870, 2.837388 + 0.545193});
}

TEST(BmwModels, ScaledToClassDimensions) {
  const auto path = raysweep::test::shared_data() / "openmaterial-validation-vehicles/objects/vehicle_example.gltf";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "../shared data absent";
  raysweep::pipeline::VehiclesSettings cfg;
  cfg.entries["passenger"].dims = {4.3, 1.8, 1.3};
  auto built = raysweep::pipeline::build_vehicle("passenger", "passenger", path.string(), cfg);
  const VehicleDims d = built.model.dims();
  EXPECT_NEAR(d.length, 4.3, 1e-6);
  EXPECT_NEAR(d.width, 1.8, 1e-6);
  EXPECT_NEAR(d.height, 1.3, 1e-6);
}
