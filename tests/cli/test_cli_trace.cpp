// `raysweep poses` and `raysweep trace` end to end on the demo city (and the
// VaN3Twin ring road when ../shared is present): output fields, determinism,
// provenance, the vehicle library, and bad input.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <stdexcept>
#include <vector>

#include <nlohmann/json.hpp>
#include <unistd.h>

#include "test_util.hpp"

using namespace raysweep::test;
using nlohmann::json;

namespace {

// Built once per process: ctest runs each test in its own process, in parallel.
fs::path demo_scene() {
  static const fs::path dir = build_demo_scene("cli_trace_demo_scene");
  return dir;
}

std::string demo_net() { return (source_dir() / "datasets/demo/kirchberg.net.xml").string(); }

}  // namespace

TEST(CliTrace, DemoSnapshotHasEveryPairWithDocumentedFields) {
  auto dir = scratch_dir("trace");
  auto r = run_raysweep("-q poses --net " + demo_net() + " --count 8 --seed 4 --classes passenger:3,bus:1 --out " +
                        (dir / "poses.csv").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  write_text(dir / "nodes.csv", "id,x,y,z\nrsu1,150,60,6\n");
  const std::string args = "-q trace --scene " + demo_scene().string() + " --poses " + (dir / "poses.csv").string() +
                           " --nodes " + (dir / "nodes.csv").string();
  r = run_raysweep(args + " --out " + (dir / "a.json").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const json j = json::parse(read_text(dir / "a.json"));
  ASSERT_EQ(j["pairs"].size(), 9u * 8u / 2u);
  std::set<std::string> classes;
  std::size_t paths = 0;
  for (const auto& p : j["pairs"]) {
    for (const char* key : {"tx", "rx", "los_class", "path_gain_db", "path_gain_incoherent_db", "delay_s", "n_paths",
                            "paths", "blockers", "rms_delay_spread_s"})
      ASSERT_TRUE(p.contains(key)) << key;
    classes.insert(p["los_class"]);
    EXPECT_EQ(p["n_paths"].get<std::size_t>(), p["paths"].size());
    if (p["los_class"] == "LOS") EXPECT_TRUE(p["blockers"].empty());
    else EXPECT_FALSE(p["blockers"].empty());
    for (const auto& path : p["paths"]) {
      for (const char* key : {"a_re", "a_im", "tau_s", "theta_t", "phi_t", "theta_r", "phi_r", "doppler_hz"})
        ASSERT_TRUE(path[key].is_number()) << key;
      for (const auto& i : path["interactions"]) {
        EXPECT_TRUE(i["type"] == "specular" || i["type"] == "refraction" || i["type"] == "diffuse" ||
                    i["type"] == "diffraction")
            << i;
        EXPECT_TRUE(i["object"].is_string());
        EXPECT_TRUE(i["material"].is_string());
      }
      EXPECT_GE(path["tau_s"].get<double>(), p["delay_s"].get<double>());
      ++paths;
    }
  }
  EXPECT_GT(paths, j["pairs"].size());
  EXPECT_TRUE(classes.count("LOS"));
  EXPECT_TRUE(classes.count("NLOS"));
  // Provenance names every input with its hash.
  std::set<std::string> roles;
  for (const auto& in : j["provenance"]["inputs"]) roles.insert(in["role"]);
  EXPECT_TRUE(roles.count("scene") && roles.count("poses") && roles.count("nodes"));
  // Same inputs, same numbers (the command line differs only in --out).
  r = run_raysweep(args + " --out " + (dir / "b.json").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  // Streamed, yet the text nlohmann's dump(1) gives of the same document.
  EXPECT_EQ(read_text(dir / "a.json"), j.dump(1) + "\n");
  json a = j, b = json::parse(read_text(dir / "b.json"));
  a["provenance"].erase("command");
  b["provenance"].erase("command");
  EXPECT_EQ(a.dump(), b.dump());
}

TEST(CliTrace, UsesAVehicleLibraryFolder) {
  auto dir = scratch_dir("lib");
  write_text(dir / "v.toml", "[vehicles]\nclasses = [\"passenger\", \"bus\"]\n");
  auto r = run_raysweep("-q vehicles --no-preview --config " + (dir / "v.toml").string() + " --out " +
                        (dir / "lib").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  write_text(dir / "poses.csv",
             "id,class,x,y,heading_deg,speed_mps\ncar1,passenger,120,40,90,10\nbus1,bus,140,40,90,8\n");
  write_text(dir / "nodes.csv", "rsu,160,40,5\n");
  for (const char* lod : {"0", "3"}) {
    r = run_raysweep("-q trace --scene " + demo_scene().string() + " --vehicles " + (dir / "lib").string() +
                     " --lod " + lod + " --poses " + (dir / "poses.csv").string() + " --nodes " +
                     (dir / "nodes.csv").string() + " --out " + (dir / "t.json").string());
    ASSERT_EQ(r.exit_code, 0) << r.output;
    const json j = json::parse(read_text(dir / "t.json"));
    EXPECT_EQ(j["pairs"].size(), 3u);
    bool library_file = false;
    for (const auto& in : j["provenance"]["inputs"]) library_file |= in["role"] == "vehicle_model";
    EXPECT_TRUE(library_file);
  }
}

TEST(CliTrace, BadInputIsAClearErrorAndWritesNothing) {
  auto dir = scratch_dir("bad");
  const auto out = dir / "t.json";
  const std::string base = "-q trace --scene " + demo_scene().string() + " --out " + out.string();
  write_text(dir / "nodes.csv", "a,100,40,2\nb,150,40,2\n");
  const std::string nodes = " --nodes " + (dir / "nodes.csv").string();

  write_text(dir / "poses.csv", "id,class,x,y,heading_deg,speed_mps\nv1,passenger,1,2,90,3\nv2,passenger,1,2,east,3\n");
  auto r = run_raysweep(base + " --poses " + (dir / "poses.csv").string());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("poses.csv:3"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("heading_deg"), std::string::npos) << r.output;

  write_text(dir / "poses.csv", "v1,spaceship,1,2,90,3\n");
  r = run_raysweep(base + " --poses " + (dir / "poses.csv").string() + nodes);
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("spaceship"), std::string::npos) << r.output;

  write_text(dir / "c.toml", "[tracer]\nmax_dept = 3\n");
  r = run_raysweep(base + nodes + " --config " + (dir / "c.toml").string());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("tracer.max_dept"), std::string::npos) << r.output;

  write_text(dir / "c.toml", "[tracer]\ndiffuse_integration = \"voxels\"\n");
  r = run_raysweep(base + nodes + " --config " + (dir / "c.toml").string());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("tracer.diffuse_integration"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("\"tiles\", \"rays\" or \"hybrid\""), std::string::npos) << r.output;

  write_text(dir / "c.toml", "[tracer]\ndiffuse_tile_m = 0\n");
  r = run_raysweep(base + nodes + " --config " + (dir / "c.toml").string());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("tracer.diffuse_tile_m"), std::string::npos) << r.output;

  write_text(dir / "c.toml", "[radio]\nfrequency_hz = 28e9\n");
  r = run_raysweep(base + nodes + " --config " + (dir / "c.toml").string());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("ground"), std::string::npos) << r.output;  // ground types end at 10 GHz

  write_text(dir / "c.toml", "[materials.concrete]\nthickness_m = \"thick\"\n");
  r = run_raysweep(base + nodes + " --config " + (dir / "c.toml").string());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("materials.concrete.thickness_m"), std::string::npos) << r.output;

  r = run_raysweep("-q trace --scene " + demo_scene().string() + nodes + " --out " + (dir / "t.csv").string());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find(".json"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find(".h5"), std::string::npos) << r.output;
  r = run_raysweep("-q trace --scene " + demo_scene().string() + nodes + " --config " + (dir / "c.toml").string() +
                   " --out " + (dir / "t.h5").string());
  EXPECT_EQ(r.exit_code, 2);

  r = run_raysweep("-q trace --scene " + (dir / "nowhere").string() + nodes + " --out " + out.string());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("scene.glb"), std::string::npos) << r.output;

  EXPECT_FALSE(fs::exists(out));
  EXPECT_FALSE(fs::exists(dir / "t.h5"));
  EXPECT_FALSE(fs::exists(dir / "t.csv"));
}

TEST(CliTrace, DiffuseByTilesIsRecordedAndReciprocal) {
  auto dir = scratch_dir("tiles");
  write_text(dir / "nodes.csv", "a,100,40,2\nb,150,45,2\nc,120,70,1.5\n");
  write_text(dir / "c.toml", "[tracer]\ndiffuse_integration = \"tiles\"\ndiffuse_tile_m = 2\n");
  write_text(dir / "rev.csv", "c,120,70,1.5\nb,150,45,2\na,100,40,2\n");
  json runs[2];
  int k = 0;
  for (const char* nodes : {"nodes.csv", "rev.csv"}) {
    auto r = run_raysweep("-q trace --scene " + demo_scene().string() + " --nodes " + (dir / nodes).string() +
                          " --config " + (dir / "c.toml").string() + " --out " + (dir / "t.json").string());
    ASSERT_EQ(r.exit_code, 0) << r.output;
    runs[k++] = json::parse(read_text(dir / "t.json"));
  }
  const auto& cfg = runs[0]["provenance"]["config"]["tracer"];
  EXPECT_EQ(cfg["diffuse_integration"], "tiles");
  EXPECT_EQ(cfg["diffuse_tile_m"], 2.0);
  // Pair a-b is (0, 1) in one run and (1, 2) in the other, so each pair is
  // computed from the other end: the tiles' diffuse records are bitwise the
  // same (their integration is symmetric by construction); specular and
  // diffraction paths are the same paths, equal to rounding (1e-15).
  auto pair = [](const json& j, const std::string& x, const std::string& y) -> const json& {
    for (const auto& p : j["pairs"]) {
      const std::string tx = p["tx"], rx = p["rx"];
      if ((tx == x && rx == y) || (tx == y && rx == x)) return p;
    }
    throw std::runtime_error("no pair " + x + "-" + y);
  };
  auto diffuse = [](const json& p) {
    std::vector<std::array<double, 3>> d;
    for (const auto& path : p["paths"])
      if (path["interactions"].size() == 1 && path["interactions"][0]["type"] == "diffuse")
        d.push_back({path["tau_s"].get<double>(), path["a_re"].get<double>(), path["a_im"].get<double>()});
    std::sort(d.begin(), d.end());
    return d;
  };
  std::size_t diffuse_records = 0;
  for (auto [x, y] : {std::pair{"a", "b"}, std::pair{"a", "c"}, std::pair{"b", "c"}}) {
    const json &p0 = pair(runs[0], x, y), &p1 = pair(runs[1], x, y);
    EXPECT_LT(p0["path_gain_incoherent_db"].get<double>(), -40) << x << "-" << y;
    EXPECT_NEAR(p0["path_gain_incoherent_db"].get<double>(), p1["path_gain_incoherent_db"].get<double>(), 1e-9)
        << x << "-" << y;
    EXPECT_EQ(p0["paths"].size(), p1["paths"].size()) << x << "-" << y;
    const auto d0 = diffuse(p0);
    EXPECT_EQ(d0, diffuse(p1)) << x << "-" << y;
    diffuse_records += d0.size();
  }
  EXPECT_GT(diffuse_records, 0u);
}

TEST(CliTrace, FrequencyResponseOnOfdmGrids) {
  auto dir = scratch_dir("cfr");
  write_text(dir / "nodes.csv", "a,100,40,2\nb,150,45,2\n");
  for (auto [spec, n] : {std::pair{"80211p", 64u}, std::pair{"nr:2:10", 120u}}) {
    auto r = run_raysweep("-q trace --scene " + demo_scene().string() + " --nodes " + (dir / "nodes.csv").string() +
                          " --cfr " + spec + " --out " + (dir / "t.json").string());
    ASSERT_EQ(r.exit_code, 0) << r.output;
    const json j = json::parse(read_text(dir / "t.json"));
    const auto& p = j["pairs"][0];
    ASSERT_EQ(p["cfr_re"].size(), n);
    // The carrier subcarrier (n/2) is the coherent narrowband channel.
    const double re = p["cfr_re"][n / 2], im = p["cfr_im"][n / 2];
    EXPECT_NEAR(10 * std::log10(re * re + im * im), p["path_gain_db"].get<double>(), 1e-6);
  }
  auto r = run_raysweep("-q trace --scene " + demo_scene().string() + " --nodes " + (dir / "nodes.csv").string() +
                        " --cfr nr:9:10 --out " + (dir / "t.json").string());
  EXPECT_EQ(r.exit_code, 2) << r.output;
}

// --out X.h5: the snapshot as a one-frame channel dataset, the same links and
// paths as the JSON document, with its frequency responses.
TEST(CliTrace, WritesTheOneFrameChannelDataset) {
  auto dir = scratch_dir("h5");
  auto r = run_raysweep("-q poses --net " + demo_net() + " --count 6 --seed 2 --out " + (dir / "poses.csv").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  write_text(dir / "nodes.csv", "rsu1,150,60,6\n");
  const std::string args = "-q trace --scene " + demo_scene().string() + " --poses " + (dir / "poses.csv").string() +
                           " --nodes " + (dir / "nodes.csv").string() + " --cfr 80211p --out ";
  r = run_raysweep(args + (dir / "t.json").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  r = run_raysweep(args + (dir / "t.h5").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_FALSE(fs::exists(dir / "t.h5.tmp.h5"));
  r = run_raysweep("validate " + (dir / "t.h5").string());
  EXPECT_EQ(r.exit_code, 0) << r.output;
  r = run_raysweep("info --json " + (dir / "t.h5").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const json info = json::parse(r.output), j = json::parse(read_text(dir / "t.json"));
  std::size_t paths = 0;
  for (const auto& p : j["pairs"]) paths += p["n_paths"].get<std::size_t>();
  EXPECT_EQ(info["frames"], 1);
  EXPECT_EQ(info["nodes"], 7);
  EXPECT_EQ(info["vehicles"], 6);
  EXPECT_EQ(info["rsus"], 1);
  EXPECT_EQ(info["links"].get<std::size_t>(), j["pairs"].size());
  EXPECT_EQ(info["paths"].get<std::size_t>(), paths);
  EXPECT_TRUE(info["has_cfr"].get<bool>());
}

// The models' precomputed tables and the decoded scene land in the scene's
// cache/ and the next process loads them; a damaged one is rebuilt with a
// warning. The document is the same each time.
TEST(CliTrace, KeepsModelTablesBesideTheScene) {
  auto dir = scratch_dir("cache");
  fs::copy(demo_scene(), dir / "scene", fs::copy_options::recursive);
  fs::remove_all(dir / "scene" / "cache");
  write_text(dir / "poses.csv",
             "id,class,x,y,heading_deg,speed_mps\ncar1,passenger,120,40,90,10\nbus1,bus,140,40,90,8\n");
  const std::string args = "trace --scene " + (dir / "scene").string() + " --poses " + (dir / "poses.csv").string();
  auto strip = [](json j) {
    j.erase("provenance");
    return j.dump();
  };
  auto r = run_raysweep(args + " --out " + (dir / "a.json").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  std::vector<fs::path> tables, scenes;
  for (const auto& e : fs::directory_iterator(dir / "scene" / "cache"))
    (e.path().filename().string().rfind("scene-", 0) == 0 ? scenes : tables).push_back(e.path());
  ASSERT_EQ(tables.size(), 4u);  // two models: a mount list and a bounce table each
  ASSERT_EQ(scenes.size(), 1u);  // scene.glb decoded (pipeline/scene_cache.hpp)
  const auto stamp = fs::last_write_time(tables[0]), scene_stamp = fs::last_write_time(scenes[0]);
  r = run_raysweep(args + " --out " + (dir / "b.json").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(fs::last_write_time(tables[0]), stamp);  // loaded, not written again
  EXPECT_EQ(fs::last_write_time(scenes[0]), scene_stamp);
  EXPECT_EQ(strip(json::parse(read_text(dir / "a.json"))), strip(json::parse(read_text(dir / "b.json"))));
  fs::resize_file(tables[1], fs::file_size(tables[1]) / 2);
  r = run_raysweep(args + " --out " + (dir / "c.json").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find(tables[1].filename().string()), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("rebuilding"), std::string::npos) << r.output;
  EXPECT_EQ(strip(json::parse(read_text(dir / "a.json"))), strip(json::parse(read_text(dir / "c.json"))));
  EXPECT_GT(fs::file_size(tables[1]), 24u);  // stored whole again
}

TEST(CliTrace, PosesAreDeterministicAndOnTheLanes) {
  auto dir = scratch_dir("poses");
  for (const char* name : {"a.csv", "b.csv"}) {
    auto r = run_raysweep("-q poses --net " + demo_net() + " --count 120 --seed 9 --out " + (dir / name).string());
    ASSERT_EQ(r.exit_code, 0) << r.output;
  }
  EXPECT_EQ(read_text(dir / "a.csv"), read_text(dir / "b.csv"));
  auto r = run_raysweep("-q poses --net " + demo_net() + " --count 5000 --out " + (dir / "c.csv").string());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("cannot place"), std::string::npos) << r.output;
}

TEST(CliTrace, Van3TwinRingRoadWithVehiclesOnItsLanes) {
  const auto root = shared_data() / "van3twin/DriveX-devs_VaN3Twin/src";
  const auto xml = root / "sionna/scenarios/SionnaCircleScenario/scene.xml";
  const auto net = root / "automotive/examples/sumo_files_v2v_map/map.net.xml";
  if (!fs::exists(xml) || !fs::exists(net)) GTEST_SKIP() << "../shared/data/van3twin absent";
  auto dir = scratch_dir("ring");
  auto r = run_raysweep("-q scene --no-preview --from-mitsuba " + xml.string() + " --out " + (dir / "scene").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  r = run_raysweep("-q poses --net " + net.string() + " --count 20 --seed 1 --out " + (dir / "poses.csv").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  r = run_raysweep("-q trace --scene " + (dir / "scene").string() + " --poses " + (dir / "poses.csv").string() +
                   " --exclude-objects car_ --out " + (dir / "t.json").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const json j = json::parse(read_text(dir / "t.json"));
  EXPECT_EQ(j["pairs"].size(), 190u);
  std::size_t paths = 0, building_hits = 0;
  for (const auto& p : j["pairs"])
    for (const auto& path : p["paths"]) {
      ++paths;
      for (const auto& i : path["interactions"]) {
        const std::string obj = i["object"];
        EXPECT_EQ(obj.find("car_"), std::string::npos) << "placeholder car left in the scene: " << obj;
        building_hits += i["material"] == "brick";
      }
    }
  EXPECT_GT(paths, 190u);
  EXPECT_GT(building_hits, 0u);
}

TEST(CliTrace, SetChangesASettingLikeTheSameLineInAFile) {
  auto dir = scratch_dir("set");
  write_text(dir / "nodes.csv", "a,100,40,2\nb,150,45,2\nc,120,80,2\n");
  const std::string base = "-q trace --scene " + demo_scene().string() + " --nodes " + (dir / "nodes.csv").string();
  auto r = run_raysweep(base + " --out " + (dir / "default.json").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  r = run_raysweep(base + " --set tracer.specular=false --set tracer.max_depth=1 --out " + (dir / "set.json").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  write_text(dir / "c.toml", "[tracer]\nspecular = false\nmax_depth = 1\n");
  r = run_raysweep(base + " --config " + (dir / "c.toml").string() + " --out " + (dir / "file.json").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  json def = json::parse(read_text(dir / "default.json")), set = json::parse(read_text(dir / "set.json")),
       file = json::parse(read_text(dir / "file.json"));
  EXPECT_NE(def["pairs"], set["pairs"]);   // the option changed the output...
  EXPECT_EQ(file["pairs"], set["pairs"]);  // ...as the line in a file does
  EXPECT_EQ(set["provenance"]["config"], file["provenance"]["config"]);
  EXPECT_EQ(set["provenance"]["config"]["tracer"]["specular"], false);
  EXPECT_EQ(set["provenance"]["set"], json({"tracer.specular=false", "tracer.max_depth=1"}));
  // A bad option is the schema's error, naming the option, and writes nothing.
  r = run_raysweep(base + " --set tracer.max_depth=99 --out " + (dir / "bad.json").string());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("--set tracer.max_depth: tracer.max_depth: expected an integer in [0, 16], got 99"),
            std::string::npos)
      << r.output;
  r = run_raysweep(base + " --set tracer.spekular=false --out " + (dir / "bad.json").string());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("unknown key (did you mean 'specular'?)"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(dir / "bad.json"));
}
