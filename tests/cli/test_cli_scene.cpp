// `raysweep scene` end to end through the real binary: outputs, provenance,
// determinism, exit codes, and nothing half-written on failure.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "test_util.hpp"

using namespace raysweep::test;
using nlohmann::json;

namespace {
const fs::path kDemo = source_dir() / "datasets/demo";
std::string demo_args() {
  return "--osm " + (kDemo / "kirchberg.osm").string() + " --net " + (kDemo / "kirchberg.net.xml").string();
}
}  // namespace

TEST(CliScene, DemoWritesGlbMitsubaAndManifest) {
  auto dir = scratch_dir("cli");
  auto r = run_raysweep("-q scene " + demo_args() + " --out " + (dir / "scene").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(fs::exists(dir / "scene/scene.glb"));
  EXPECT_TRUE(fs::exists(dir / "scene/mitsuba/scene.xml"));
  // setup.sh installs Debian's matplotlib, so the preview is expected.
  EXPECT_TRUE(fs::exists(dir / "scene/preview.png"));
  EXPECT_EQ(read_text(dir / "scene/preview.png").substr(1, 3), "PNG");
  json m = json::parse(read_text(dir / "scene/manifest.json"));
  EXPECT_GT(m["buildings"]["kept"].get<int>(), 20);
  EXPECT_TRUE(m["topology"]["buildings_watertight"].get<bool>());
  EXPECT_EQ(m["projection"]["proj"], "+proj=utm +zone=32 +ellps=WGS84 +datum=WGS84 +units=m +no_defs");
  EXPECT_GT(m["triangle_count"].get<int>(), 0);
  EXPECT_TRUE(m["buildings"]["skipped_by_reason"].contains("too_few_nodes"));
  // Provenance: the recorded hash is the file's SHA-256 as sha256sum computes it.
  auto sum = run_command("sha256sum " + (kDemo / "kirchberg.osm").string());
  bool found = false;
  for (const auto& in : m["provenance"]["inputs"])
    if (in["role"] == "osm") {
      found = true;
      EXPECT_EQ(sum.output.substr(0, 64), in["sha256"].get<std::string>());
    }
  EXPECT_TRUE(found);
  EXPECT_TRUE(m["provenance"].contains("version"));
  EXPECT_TRUE(m["provenance"]["config"].contains("clip_distance_m"));
  EXPECT_EQ(m["files"]["preview"], "preview.png");
  // Only the final folder remains: no temporary siblings.
  for (const auto& e : fs::directory_iterator(dir)) EXPECT_EQ(e.path().filename(), "scene");
}

TEST(CliScene, SameInputsGiveIdenticalBytes) {
  auto dir = scratch_dir("cli");
  ASSERT_EQ(run_raysweep("-q scene --no-preview " + demo_args() + " --out " + (dir / "a").string()).exit_code, 0);
  ASSERT_EQ(run_raysweep("-q scene --no-preview " + demo_args() + " --out " + (dir / "b").string()).exit_code, 0);
  EXPECT_EQ(read_text(dir / "a/scene.glb"), read_text(dir / "b/scene.glb"));
  EXPECT_EQ(read_text(dir / "a/mitsuba/scene.xml"), read_text(dir / "b/mitsuba/scene.xml"));
  // Manifests differ only in the --out path recorded in the command line.
  json a = json::parse(read_text(dir / "a/manifest.json")), b = json::parse(read_text(dir / "b/manifest.json"));
  a["provenance"].erase("command");
  b["provenance"].erase("command");
  EXPECT_EQ(a, b);
}

TEST(CliScene, MalformedOsmFailsCleanlyAndKeepsPreviousOutput) {
  auto dir = scratch_dir("cli");
  write_text(dir / "bad.osm", "<?xml version='1.0'?>\n<osm version=\"0.6\">\n<node id=\"1\" lat=\"48.1\" lon=\"10.1\">\n</osm>\n");
  fs::create_directories(dir / "out");
  write_text(dir / "out/marker", "previous run");
  auto r = run_raysweep("scene --osm " + (dir / "bad.osm").string() + " --net " + (kDemo / "kirchberg.net.xml").string() +
                    " --out " + (dir / "out").string());
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("bad.osm"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("line 4"), std::string::npos) << r.output;
  EXPECT_EQ(read_text(dir / "out/marker"), "previous run");
  EXPECT_FALSE(fs::exists(dir / "out/manifest.json"));
  std::size_t entries = 0;
  for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir)) ++entries;
  EXPECT_EQ(entries, 2u) << "no temporary folder left behind";
}

TEST(CliScene, ExtractThatMissesTheNetworkIsAnError) {
  auto dir = scratch_dir("cli");
  // A building in Berlin against the Kirchberg network.
  write_text(dir / "berlin.osm",
             "<?xml version='1.0'?>\n<osm version=\"0.6\">\n"
             "<node id=\"1\" lat=\"52.5\" lon=\"13.4\"/><node id=\"2\" lat=\"52.5\" lon=\"13.4002\"/>"
             "<node id=\"3\" lat=\"52.5002\" lon=\"13.4002\"/>\n"
             "<way id=\"5\"><nd ref=\"1\"/><nd ref=\"2\"/><nd ref=\"3\"/><nd ref=\"1\"/><tag k=\"building\" v=\"yes\"/></way>\n"
             "</osm>\n");
  auto r = run_raysweep("scene --osm " + (dir / "berlin.osm").string() + " --net " +
                    (kDemo / "kirchberg.net.xml").string() + " --out " + (dir / "out").string());
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("does not overlap"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(dir / "out"));
}

TEST(CliScene, ConfigTyposAreErrorsNamingTheKey) {
  auto dir = scratch_dir("cli");
  write_text(dir / "c.toml", "[scene]\nclip_distance_m = 100\nground_materail = \"wet_ground\"\n");
  auto r = run_raysweep("scene " + demo_args() + " --config " + (dir / "c.toml").string() + " --out " +
                    (dir / "out").string());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("c.toml:3: scene.ground_materail: unknown key (did you mean 'ground_material'?)"),
            std::string::npos)
      << r.output;

  write_text(dir / "d.toml", "[scene]\nground_material = \"lava\"\n");
  r = run_raysweep("scene " + demo_args() + " --config " + (dir / "d.toml").string() + " --out " + (dir / "out").string());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("lava"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(dir / "out"));
}

TEST(CliScene, ConfigChangesTheScene) {
  auto dir = scratch_dir("cli");
  write_text(dir / "c.toml", "[scene]\nground_material = \"wet_ground\"\ndefault_material = \"brick\"\n");
  auto r = run_raysweep("-q scene " + demo_args() + " --config " + (dir / "c.toml").string() + " --out " +
                    (dir / "out").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  json m = json::parse(read_text(dir / "out/manifest.json"));
  auto mats = m["materials"].get<std::vector<std::string>>();
  EXPECT_NE(std::find(mats.begin(), mats.end(), "wet_ground"), mats.end());
  EXPECT_NE(std::find(mats.begin(), mats.end(), "brick"), mats.end());
  EXPECT_EQ(std::find(mats.begin(), mats.end(), "medium_dry_ground"), mats.end());
}

TEST(CliScene, ImportsVaN3TwinMitsubaScene) {
  const fs::path xml =
      shared_data() / "van3twin/DriveX-devs_VaN3Twin/src/sionna/scenarios/SionnaCircleScenario/scene.xml";
  if (!fs::exists(xml)) GTEST_SKIP() << "../shared data absent";
  auto dir = scratch_dir("cli");
  auto r = run_raysweep("-q scene --from-mitsuba " + xml.string() + " --out " + (dir / "ring").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  json m = json::parse(read_text(dir / "ring/manifest.json"));
  const std::string text = read_text(xml);
  std::size_t shapes = 0;
  for (std::size_t p = text.find("<shape"); p != std::string::npos; p = text.find("<shape", p + 1)) ++shapes;
  EXPECT_EQ(m["meshes"].size(), shapes);
  EXPECT_TRUE(fs::exists(dir / "ring/scene.glb"));
  EXPECT_TRUE(fs::exists(dir / "ring/mitsuba/scene.xml"));
}

TEST(CliScene, UsageErrorsExitNonZero) {
  EXPECT_NE(run_raysweep("scene --out /tmp/x").exit_code, 0);
  EXPECT_NE(run_raysweep("frobnicate").exit_code, 0);
  EXPECT_NE(run_raysweep("scene --osm " + (kDemo / "kirchberg.osm").string() + " --out /tmp/x").exit_code, 0)
      << "needs --net or --proj";
}
