// `raysweep radiomap` and `raysweep render`: the radio map against closed
// forms (Friis; a single wall by the image method with P.2040 slab
// coefficients) at voxel centres read back through OpenVDB's reader, against
// the per-point tracer on the demo city, sparse storage, bad settings; the
// Blender picture headless.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <complex>
#include <set>

#include "closed_forms.hpp"
#include "meshkit/gltf_io.hpp"
#include "meshkit/sumo_net.hpp"
#include "pipeline/radiomap_vdb.hpp"
#include "pipeline/render_stage.hpp"
#include "test_util.hpp"
#include "tracer/tracer.hpp"
#include "tracer_fixtures.hpp"

using namespace raysweep;
using namespace raysweep::test;
using namespace raysweep::test::closed_form;

namespace {

constexpr double kFreq = 5.9e9;
constexpr double kLambda = tracer::kSpeedOfLight / kFreq;

fs::path write_scene(const meshkit::Scene& s, const fs::path& dir) {
  fs::create_directories(dir);
  meshkit::write_glb(s, (dir / "scene.glb").string());
  return dir;
}

// Two small markers far below the map (they span the scene box; no path
// from them reaches a voxel above): the map is free space.
void add_markers(meshkit::Scene& s, double half) {
  add_quad(s, "metal", "marker-a", {-half, -half, -50}, {-half, -half + 0.5, -50}, {-half + 0.5, -half + 0.5, -50},
           {-half + 0.5, -half, -50});
  add_quad(s, "metal", "marker-b", {half - 0.5, half - 0.5, -50}, {half - 0.5, half, -50}, {half, half, -50},
           {half, half - 0.5, -50});
}

std::string map_config(const fs::path& dir, const std::string& extra) {
  const fs::path p = dir / "map.toml";
  write_text(p, "[radio]\nfrequency_hz = 5.9e9\n[tracer]\ndiffuse = false\n" + extra +
                    "\n[radiomap]\nregion = \"all\"\nvoxel_m = 1.0\nz_min_m = 1.5\nz_max_m = 1.5\n");
  return p.string();
}

double db(double x) { return 10 * std::log10(x); }

}  // namespace

TEST(RadioMap, FreeSpaceMatchesFriisAtVoxelCentres) {
  const auto dir = scratch_dir("free");
  meshkit::Scene s;
  add_markers(s, 20.25);
  write_scene(s, dir / "scene");
  const auto map = dir / "map.vdb";
  auto r = run_raysweep("-q radiomap --scene " + (dir / "scene").string() + " --tx t0,0.3,0.2,1.5 --out " +
                        map.string() + " --config " + map_config(dir, "diffraction = false"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const auto vox = pipeline::read_vdb_voxels(map.string(), "path_gain_db.t0");
  ASSERT_EQ(vox.size(), 41u * 41u);  // the box [-20.25, 20.25]^2 at one layer
  double worst = 0;
  for (const auto& v : vox) {
    EXPECT_DOUBLE_EQ(v.world[2], 1.5);
    EXPECT_DOUBLE_EQ(v.world[0], v.ijk[0] * 1.0);
    const double d = std::hypot(v.world[0] - 0.3, v.world[1] - 0.2, v.world[2] - 1.5);
    const double friis = 20 * std::log10(kLambda / (4 * kPi * d));
    worst = std::max(worst, std::fabs(v.value - friis));
  }
  EXPECT_LT(worst, 1e-3);  // float storage
  const auto los = pipeline::read_vdb_voxels(map.string(), "los_class.t0");
  for (const auto& v : los) EXPECT_EQ(v.value, 0);
}

TEST(RadioMap, SingleWallMatchesImageMethodWithSlabCoefficients) {
  const auto dir = scratch_dir("wall");
  meshkit::Scene s;
  add_wall_x(s, 20, 200, "concrete", "wall");  // normal -x, towards the map
  add_markers(s, 30);
  write_scene(s, dir / "scene");
  const auto map = dir / "map.vdb";
  const tracer::Vec3 tx{0.0, 0.0, 1.5};
  auto r = run_raysweep("-q radiomap --scene " + (dir / "scene").string() + " --tx w,0,0,1.5 --out " + map.string() +
                        " --config " + map_config(dir, ""));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const auto eta = tracer::radio_material("concrete", kFreq).eta();
  const double d_slab = tracer::radio_material("concrete", kFreq).thickness_m;
  std::size_t n = 0;
  double worst = 0;
  for (const auto& v : pipeline::read_vdb_voxels(map.string(), "path_gain_db.w")) {
    const auto& p = v.world;
    if (p[0] > 18 || std::fabs(p[1]) > 40 || (p[0] == 0 && p[1] == 0)) continue;
    // Direct path plus the reflection at the image (40, 0, 1.5); the field is
    // vertical and the plane of incidence horizontal: TE.
    const double d = std::hypot(p[0] - tx[0], p[1] - tx[1]);
    const double l = std::hypot(p[0] - 40, p[1]);
    const double cos_i = (40 - p[0]) / l;
    const auto refl = slab(eta, d_slab, cos_i, true, kLambda).r;
    const double g = std::pow(kLambda / (4 * kPi * d), 2) + std::norm(refl) * std::pow(kLambda / (4 * kPi * l), 2);
    worst = std::max(worst, std::fabs(v.value - db(g)));
    ++n;
  }
  EXPECT_GT(n, 1500u);
  EXPECT_LT(worst, 0.02);  // far wall borders diffract a little (< 0.02 dB here)
}

TEST(RadioMap, BadSettingsExitTwoWithAClearMessage) {
  const auto dir = scratch_dir("bad");
  meshkit::Scene s;
  add_markers(s, 20);
  add_box_object(s, {5, 5, 0}, {10, 10, 8}, "brick", "house");
  write_scene(s, dir / "scene");
  const std::string base = "-q radiomap --scene " + (dir / "scene").string() + " --out " + (dir / "m.vdb").string();
  auto bad = [&](const std::string& toml, const std::string& tx, const std::string& needle) {
    write_text(dir / "c.toml", toml);
    auto r = run_raysweep(base + " --tx " + tx + " --config " + (dir / "c.toml").string());
    EXPECT_EQ(r.exit_code, 2) << r.output;
    EXPECT_NE(r.output.find(needle), std::string::npos) << r.output;
    EXPECT_FALSE(fs::exists(dir / "m.vdb"));
  };
  bad("[radiomap]\nvoxel_m = 0\nregion = \"all\"\n", "a,0,0,2", "c.toml:2: radiomap.voxel_m: expected a finite number > 0, got 0");
  bad("[radiomap]\nz_min_m = 3\nz_max_m = 1\nregion = \"all\"\n", "a,0,0,2", "must not exceed radiomap.z_max_m");
  bad("[radiomap]\nregion = \"all\"\n", "a,7,7,2", "transmitter a at (7.000000, 7.000000, 2.000000) is inside a building");
  bad("[radiomap]\nregion = \"roads\"\n", "a,0,0,2", "radiomap.region");
  bad("[radiomap]\nregion = \"all\"\n", "a,0,x,2", "--tx 'a,0,x,2'");
  bad("[radiomap]\nregion = \"streets\"\n", "a,0,0,2", "needs a SUMO network");
}

namespace {

fs::path demo_scene() {
  static const fs::path dir = build_demo_scene("radiomap_demo_scene");
  return dir;
}

}  // namespace

TEST(RadioMap, DemoStreetsSparseAndAgreeWithTrace) {
  const auto dir = scratch_dir("demo");
  const auto map = dir / "demo.vdb";
  // The demo's tracer settings, diffuse scattering on (gathered per 2 m
  // block: the default) and off: the map agrees with `trace` both ways.
  write_text(dir / "c.toml", "[radio]\nfrequency_hz = 5.9e9\nbandwidth_hz = 10e6\nantenna = \"dipole\"\n"
                             "[tracer]\nmax_depth = 3\nrays_per_source = 4096\n"
                             "[radiomap]\nstreet_margin_m = 3.0\n");
  auto r = run_raysweep("radiomap --scene " + demo_scene().string() + " --tx rsu1,120,70,6 --out " + map.string() +
                        " --config " + (dir / "c.toml").string() + " --check 200 --png " + (dir / "s.png").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const auto sum = pipeline::read_radiomap_vdb(map.string());
  const auto check = nlohmann::json::parse(sum.meta.at("check_vs_trace").get<std::string>());
  EXPECT_GT(check["above_sensitivity"].get<int>(), 150);
  EXPECT_LE(check["median_abs_db"].get<double>(), 0.5) << check.dump();
  // The map leaves out diffraction-reflection (docs/radiomap.md: 2.15 dB at
  // the 90th percentile here, 3.13 without any reflected diffraction).
  EXPECT_LE(check["p90_abs_db"].get<double>(), 2.5) << check.dump();
  EXPECT_GE(check["los_class_agreement"].get<double>(), 0.99) << check.dump();
  // Sparse: exactly the street voxels (lane distance by hand), none inside a building.
  const auto net = meshkit::read_sumo_network((source_dir() / "datasets/demo/kirchberg.net.xml").string());
  auto near_lane = [&](double x, double y) {
    for (const auto& lane : net.lane_shapes)
      for (std::size_t k = 0; k + 1 < lane.size(); ++k) {
        const double ax = lane[k][0], ay = lane[k][1], dx = lane[k + 1][0] - ax, dy = lane[k + 1][1] - ay;
        const double t = std::clamp(((x - ax) * dx + (y - ay) * dy) / (dx * dx + dy * dy), 0.0, 1.0);
        if (std::hypot(ax + t * dx - x, ay + t * dy - y) <= 3.0) return true;
      }
    return false;
  };
  std::set<std::array<std::int32_t, 2>> columns;
  for (int i = -10; i <= 215; ++i)
    for (int j = -10; j <= 165; ++j)
      if (near_lane(i, j)) columns.insert({i, j});
  const auto vox = pipeline::read_vdb_voxels(map.string(), "rss_dbm");
  std::size_t in_streets = 0;
  for (const auto& v : vox) in_streets += columns.count({v.ijk[0], v.ijk[1]});
  EXPECT_EQ(in_streets, vox.size());
  EXPECT_LE(vox.size(), columns.size() * 3);   // 3 layers: 0.5, 1.5, 2.5 m
  EXPECT_GE(vox.size(), columns.size() * 3 * 95 / 100);  // a few street voxels lie in buildings
  for (const auto& g : sum.grids) {
    EXPECT_EQ(g.active, vox.size()) << g.name;
    EXPECT_EQ(g.voxel_m, 1.0);
  }
  std::set<std::string> names;
  for (const auto& g : sum.grids) names.insert(g.name + ":" + g.type);
  EXPECT_EQ(names, (std::set<std::string>{"path_gain_db.rsu1:float", "los_class.rsu1:int32", "rss_dbm:float",
                                          "best_server:int32", "density:float"}));
  for (const auto& key : {"carrier_hz", "bandwidth_hz", "tx", "voxel_m", "tracer_config", "provenance"})
    EXPECT_TRUE(sum.meta.contains(key)) << key;
  for (const auto& g : sum.grids)
    if (g.name == "density") {
      EXPECT_GE(g.min, 0.0);
      EXPECT_LE(g.max, 1.0);
      EXPECT_EQ(g.max, 1.0);
    }
  EXPECT_GT(fs::file_size(dir / "s.png"), 10000u);

  // Python's OpenVDB reader sees the same float grid.
  if (run_command("/usr/bin/python3 -c 'import pyopenvdb'").exit_code == 0) {
    auto py = run_command("/usr/bin/python3 -c \"import pyopenvdb as v; g = v.read('" + map.string() +
                          "', 'rss_dbm'); print(g.activeVoxelCount())\"");
    EXPECT_EQ(py.output, std::to_string(vox.size()) + "\n");
  }
}

TEST(Render, HeadlessPictureShowsMaterialColours) {
  if (pipeline::find_blender().empty()) GTEST_SKIP() << "blender not installed";
  const auto dir = scratch_dir("render");
  meshkit::Scene s;
  add_ground(s, 30);
  add_box_object(s, {-8, -8, 0}, {8, 8, 10}, "brick", "house");
  write_scene(s, dir / "scene");
  auto r = run_raysweep("-q render --scene " + (dir / "scene").string() + " --out " + (dir / "r.png").string() +
                        " --camera top --size 160,120 --samples 1");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  ASSERT_GT(fs::file_size(dir / "r.png"), 1000u);
  // Brick red (#b5533c) on the roof, the ground's green-grey around it.
  auto py = run_command("/usr/bin/python3 -c \"import matplotlib.image as m; a = m.imread('" + (dir / "r.png").string() +
                        "')[..., :3]; r, g, b = a[..., 0], a[..., 1], a[..., 2]; "
                        "print(int(((r > g + 0.15) & (r > b + 0.15)).sum()), int(((g >= r) & (g > b)).sum()))\"");
  ASSERT_EQ(py.exit_code, 0) << py.output;
  int red = 0, green = 0;
  ASSERT_EQ(std::sscanf(py.output.c_str(), "%d %d", &red, &green), 2) << py.output;
  EXPECT_GT(red, 160 * 120 / 20) << py.output;
  EXPECT_GT(green, 160 * 120 / 20) << py.output;
}

TEST(Render, MissingInputsAreClearErrors) {
  const auto dir = scratch_dir("render-missing");
  auto r = run_raysweep("-q render --scene " + (dir / "none").string() + " --out " + (dir / "r.png").string());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("no scene.glb"), std::string::npos) << r.output;
  meshkit::Scene s;
  add_ground(s, 10);
  write_scene(s, dir / "scene");
  r = run_raysweep("-q render --scene " + (dir / "scene").string() + " --paths " + (dir / "t.json").string() +
                   " --out " + (dir / "r.png").string());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("--paths " + (dir / "t.json").string() + ": no such file"), std::string::npos) << r.output;
  r = run_command("PATH=/nonexistent RAYSWEEP_BLENDER= " + std::string(RAYSWEEP_BINARY) + " -q render --scene " +
                  (dir / "scene").string() + " --out " + (dir / "r.png").string());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("apt-get install"), std::string::npos) << r.output;
}
