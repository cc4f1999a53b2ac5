// `raysweep vehicles` end to end: every class, LOD files, manifest, vTypes,
// determinism and bad input.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "meshkit/gltf_io.hpp"
#include "meshkit/vehicle_classes.hpp"
#include "meshkit/vehicle_model.hpp"
#include "test_util.hpp"

using namespace raysweep::test;
using nlohmann::json;

TEST(CliVehicles, BuiltInLibraryHasEveryClassWithLods) {
  auto dir = scratch_dir("veh");
  auto r = run_raysweep("-q vehicles --out " + (dir / "lib").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  json m = json::parse(read_text(dir / "lib/manifest.json"));
  ASSERT_EQ(m["vehicles"].size(), raysweep::meshkit::vehicle_classes().size());
  EXPECT_TRUE(fs::exists(dir / "lib/preview.png"));
  for (const auto& v : m["vehicles"]) {
    const auto* info = raysweep::meshkit::find_vehicle_class(v["vclass"]);
    ASSERT_TRUE(info);
    EXPECT_NEAR(v["dims"]["length"].get<double>(), info->dims.length, 1e-6) << v["name"];
    EXPECT_NEAR(v["dims"]["height"].get<double>(), info->dims.height, 1e-6) << v["name"];
    ASSERT_GE(v["lods"].size(), 1u);
    for (const auto& lod : v["lods"]) {
      ASSERT_TRUE(fs::exists(dir / "lib" / lod["file"].get<std::string>())) << lod["file"];
      EXPECT_EQ(lod["boundary_edges"], 0) << "parametric models stay closed: " << lod["file"];
    }
    EXPECT_LT(v["default_lod"].get<int>(), static_cast<int>(v["lods"].size()));
    // The GLB carries parts and materials back.
    auto scene = raysweep::meshkit::read_glb((dir / "lib" / v["lods"][0]["file"].get<std::string>()).string());
    auto model = raysweep::meshkit::from_scene(scene, v["name"]);
    EXPECT_EQ(model.parts.size(), v["parts"].size());
    std::size_t tris = 0;
    for (const auto& p : v["parts"]) tris += p["triangles"].get<std::size_t>();
    EXPECT_EQ(model.triangle_count(), tris);
  }
  EXPECT_GE(m["custom_materials"].size(), 3u);
  EXPECT_TRUE(m["provenance"].contains("config"));
}

TEST(CliVehicles, VTypesBecomeEntriesWithTheirDimensions) {
  auto dir = scratch_dir("veh");
  write_text(dir / "types.add.xml",
             "<additional>\n"
             "  <vType id=\"smallcar\" vClass=\"passenger\" length=\"4.2\" width=\"1.7\" height=\"1.4\"/>\n"
             "  <vType id=\"walker\" vClass=\"pedestrian\"/>\n"
             "</additional>\n");
  write_text(dir / "c.toml", "[vehicles]\nclasses = [\"passenger\"]\n");
  auto r = run_raysweep("-q vehicles --no-preview --config " + (dir / "c.toml").string() + " --vtypes " +
                        (dir / "types.add.xml").string() + " --out " + (dir / "lib").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("walker"), std::string::npos) << "unmodelled classes are warned about";
  json m = json::parse(read_text(dir / "lib/manifest.json"));
  ASSERT_EQ(m["vehicles"].size(), 2u);
  EXPECT_EQ(m["vehicles"][1]["name"], "smallcar");
  EXPECT_NEAR(m["vehicles"][1]["dims"]["length"].get<double>(), 4.2, 1e-9);
  EXPECT_NEAR(m["vehicles"][1]["dims"]["width"].get<double>(), 1.7, 1e-9);
  EXPECT_NEAR(m["vehicles"][1]["antenna"][2].get<double>(), 1.45, 1e-9);
}

TEST(CliVehicles, SameInputsGiveIdenticalBytes) {
  auto dir = scratch_dir("veh");
  write_text(dir / "c.toml", "[vehicles]\nclasses = [\"passenger\", \"bus\"]\n");
  for (const char* o : {"a", "b"})
    ASSERT_EQ(run_raysweep("-q vehicles --no-preview --config " + (dir / "c.toml").string() + " --out " +
                           (dir / o).string()).exit_code, 0);
  for (const char* f : {"passenger_lod0.glb", "bus_lod0.glb"})
    EXPECT_EQ(read_text(dir / "a" / f), read_text(dir / "b" / f)) << f;
  json a = json::parse(read_text(dir / "a/manifest.json")), b = json::parse(read_text(dir / "b/manifest.json"));
  a["provenance"].erase("command");
  b["provenance"].erase("command");
  EXPECT_EQ(a, b);
}

TEST(CliVehicles, BadInputIsAClearErrorAndWritesNothing) {
  auto dir = scratch_dir("veh");
  auto r = run_raysweep("vehicles --model passenger=" + (dir / "nope.glb").string() + " --out " + (dir / "lib").string());
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("nope.glb"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(dir / "lib"));

  r = run_raysweep("vehicles --model hovercraft=x.glb --out " + (dir / "lib").string());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("hovercraft"), std::string::npos) << r.output;

  write_text(dir / "c.toml", "[vehicles]\nlod_ratio = [0.5]\n");
  r = run_raysweep("vehicles --config " + (dir / "c.toml").string() + " --out " + (dir / "lib").string());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("lod_ratio"), std::string::npos) << r.output;

  write_text(dir / "d.toml", "[[vehicles.rules]]\nfield = \"part\"\npattern = \"glass\"\nmaterial = \"adamantium\"\n");
  r = run_raysweep("vehicles --config " + (dir / "d.toml").string() + " --out " + (dir / "lib").string());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("adamantium"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(dir / "lib"));
}

// --model-unit and model_unit: the unit a model file is in reaches the
// manifest (unit_scale, unit_source) and the built dimensions; unknown units
// and classes without a model are usage errors.
TEST(CliVehicles, ModelUnitFromCliAndConfig) {
  auto dir = scratch_dir("veh_units");
  // A 4500 x 1800 x 1500 box: a car in millimetres.
  std::string obj;
  for (int i = 0; i < 8; ++i)
    obj += "v " + std::to_string(i & 1 ? 4500 : 0) + " " + std::to_string(i & 2 ? 1800 : 0) + " " +
           std::to_string(i & 4 ? 1500 : 0) + "\n";
  obj += "f 1 3 4 2\nf 5 6 8 7\nf 1 2 6 5\nf 3 7 8 4\nf 1 5 7 3\nf 2 4 8 6\n";
  write_text(dir / "car.obj", obj);
  write_text(dir / "c.toml", "[vehicles]\nclasses = [\"passenger\"]\nscale_to_class = false\n");
  const std::string base = "-q vehicles --no-preview --config " + (dir / "c.toml").string() + " --model passenger=" +
                           (dir / "car.obj").string();
  auto manifest_entry = [&](const std::string& lib) {
    return json::parse(read_text(dir / lib / "manifest.json"))["vehicles"][0];
  };
  auto r = run_raysweep(base + " --out " + (dir / "guess").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  json v = manifest_entry("guess");
  EXPECT_DOUBLE_EQ(v["unit_scale"].get<double>(), 0.001);
  EXPECT_EQ(v["unit_source"], "guessed from the size");
  EXPECT_NEAR(v["dims"]["length"].get<double>(), 4.5, 1e-6);

  r = run_raysweep(base + " --model-unit cm --out " + (dir / "cm").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  v = manifest_entry("cm");
  EXPECT_DOUBLE_EQ(v["unit_scale"].get<double>(), 0.01);
  EXPECT_EQ(v["unit_source"], "given");
  EXPECT_NE(r.output.find("implausible for a passenger"), std::string::npos) << r.output;

  write_text(dir / "d.toml", "[vehicles]\nclasses = [\"passenger\"]\nscale_to_class = false\n"
                             "[vehicles.class.passenger]\nmodel_unit = \"mm\"\n");
  r = run_raysweep("-q vehicles --no-preview --config " + (dir / "d.toml").string() + " --model passenger=" +
                   (dir / "car.obj").string() + " --model-unit cm --out " + (dir / "cfg").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  v = manifest_entry("cfg");
  EXPECT_DOUBLE_EQ(v["unit_scale"].get<double>(), 0.001) << "the class's model_unit wins over a bare --model-unit";
  r = run_raysweep("-q vehicles --no-preview --config " + (dir / "d.toml").string() + " --model passenger=" +
                   (dir / "car.obj").string() + " --model-unit passenger=cm --out " + (dir / "cli").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_DOUBLE_EQ(manifest_entry("cli")["unit_scale"].get<double>(), 0.01) << "CLASS=UNIT wins over the config";

  r = run_raysweep(base + " --model-unit furlong --out " + (dir / "bad").string());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("furlong"), std::string::npos) << r.output;
  r = run_raysweep(base + " --model-unit bus=mm --out " + (dir / "bad").string());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("no --model for 'bus'"), std::string::npos) << r.output;
  write_text(dir / "e.toml", "[vehicles.class.bus]\nmodel_unit = \"cubit\"\n");
  r = run_raysweep("-q vehicles --config " + (dir / "e.toml").string() + " --out " + (dir / "bad").string());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("model_unit"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(dir / "bad"));
}
