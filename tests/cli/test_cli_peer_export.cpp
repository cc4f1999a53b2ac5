// `raysweep trace --mitsuba DIR`: the snapshot a peer tracer reads
// (pipeline/peer_export.hpp), read back through the Mitsuba reader and
// checked against independent truth: the scene's own triangles, the
// vehicle models' dimensions at their poses, the antennas where they were
// put, and P.2040's formulas for the materials.
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <regex>
#include <set>
#include <string>

#include <nlohmann/json.hpp>

#include "meshkit/gltf_io.hpp"
#include "meshkit/mitsuba_io.hpp"
#include "meshkit/vehicle_library.hpp"
#include "test_util.hpp"

using namespace raysweep;
using namespace raysweep::test;
using nlohmann::json;

namespace {

fs::path demo_scene() {
  static const fs::path dir = build_demo_scene("cli_peer_export_scene");
  return dir;
}

// Poses: a car heading east (yaw 0) and a bus heading north; a road-side unit.
const char* kPoses = "id,class,x,y,heading_deg,speed_mps\ncar1,passenger,120,40,90,10\nbus1,bus,140,20,0,8\n";
const char* kNodes = "id,x,y,z\nrsu,150,60,6\n";

struct Box {
  double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
};

Box bounds_of(const meshkit::Scene& s, const std::string& prefix) {
  Box b;
  for (const auto& m : s.meshes) {
    if (m.name.rfind(prefix, 0) != 0) continue;
    for (const auto& t : m.triangles)
      for (auto v : t)
        for (int k = 0; k < 3; ++k) {
          b.lo[k] = std::min(b.lo[k], m.vertices[v][k]);
          b.hi[k] = std::max(b.hi[k], m.vertices[v][k]);
        }
  }
  return b;
}

// The float props of each bsdf in scene.xml, by bsdf id.
std::map<std::string, std::map<std::string, double>> bsdf_props(const std::string& xml) {
  std::map<std::string, std::map<std::string, double>> out;
  const std::regex bsdf(R"re(<bsdf type="radio-material" id="([^"]+)"[^>]*>([\s\S]*?)</bsdf>)re");
  const std::regex prop(R"re(<float name="([a-z_]+)" value="([^"]+)"/>)re");
  for (std::sregex_iterator it(xml.begin(), xml.end(), bsdf), end; it != end; ++it) {
    const std::string body = (*it)[2];
    for (std::sregex_iterator p(body.begin(), body.end(), prop); p != end; ++p)
      out[(*it)[1]][(*p)[1]] = std::stod((*p)[2]);
  }
  return out;
}

struct Export {
  fs::path dir;
  meshkit::Scene scene;
  json peer;
  std::string xml;
};

Export export_snapshot(const std::string& tag, const std::string& extra = "") {
  Export e;
  const auto work = scratch_dir(tag);
  write_text(work / "poses.csv", kPoses);
  write_text(work / "nodes.csv", kNodes);
  e.dir = work / "peer";
  const auto r = run_raysweep("-q trace --scene " + demo_scene().string() + " --poses " + (work / "poses.csv").string() +
                              " --nodes " + (work / "nodes.csv").string() + " --mitsuba " + e.dir.string() + extra);
  EXPECT_EQ(r.exit_code, 0) << r.output;
  e.scene = meshkit::read_mitsuba((e.dir / "scene.xml").string());
  e.peer = json::parse(read_text(e.dir / "peer.json"));
  e.xml = read_text(e.dir / "scene.xml");
  return e;
}

}  // namespace

TEST(CliPeerExport, StaticSceneRoundTripsWithItsMaterials) {
  const Export e = export_snapshot("static");
  // Only the export: no trace document, no temporary left behind.
  std::size_t entries = 0;
  for ([[maybe_unused]] const auto& f : fs::directory_iterator(e.dir.parent_path())) ++entries;
  EXPECT_EQ(entries, 3u);  // poses.csv, nodes.csv, peer/
  const meshkit::Scene original = meshkit::read_glb((demo_scene() / "scene.glb").string());
  std::map<std::string, std::size_t> want, got;
  for (const auto& m : original.meshes) want[m.material] += m.triangles.size();
  for (const auto& m : e.scene.meshes) {
    // Each mesh is one material, named after it, and read back as it.
    const auto dash = m.name.find('-');
    ASSERT_NE(dash, std::string::npos) << m.name;
    EXPECT_EQ(m.name.substr(dash + 1), m.material);
    if (m.name.rfind("static-", 0) == 0) got[m.material] += m.triangles.size();
  }
  EXPECT_EQ(got, want);
  const auto a = bounds_of(original, ""), b = bounds_of(e.scene, "static-");
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(a.lo[k], b.lo[k], 1e-3);
    EXPECT_NEAR(a.hi[k], b.hi[k], 1e-3);
  }
  // peer.json lists the same shapes and triangle counts.
  std::size_t listed = 0;
  for (const auto& s : e.peer["shapes"]) {
    const std::string name = s["id"].get<std::string>().substr(5);
    const auto it = std::find_if(e.scene.meshes.begin(), e.scene.meshes.end(),
                                 [&](const meshkit::Mesh& m) { return m.name == name; });
    ASSERT_NE(it, e.scene.meshes.end()) << name;
    EXPECT_EQ(s["triangles"].get<std::size_t>(), it->triangles.size());
    ++listed;
  }
  EXPECT_EQ(listed, e.scene.meshes.size());
}

TEST(CliPeerExport, MaterialsCarryP2040ValuesAtTheCarrier) {
  for (const double f_ghz : {5.9, 3.5}) {
    // At 3.5 GHz without diffuse scattering: smooth surfaces, S = 0 in the XML.
    const bool rough = f_ghz == 5.9;
    const std::string extra = rough ? "" : " --set radio.frequency_hz=3.5e9 --set tracer.diffuse=false";
    const Export e = export_snapshot("materials" + std::to_string(static_cast<int>(f_ghz * 10)), extra);
    const auto props = bsdf_props(e.xml);
    // P.2040-3 Table 3: concrete 5.24, 0.0462 f^0.7822; glass 6.31,
    // 0.0036 f^1.3394; metal: sigma 1e7 S/m. Thickness: concrete 0.3 m,
    // glass 5 mm; the ground (a half space) as a 1 m slab.
    const auto& concrete = props.at("mat-raysweep_concrete");
    EXPECT_NEAR(concrete.at("relative_permittivity"), 5.24, 1e-12);
    EXPECT_NEAR(concrete.at("conductivity"), 0.0462 * std::pow(f_ghz, 0.7822), 1e-9);
    EXPECT_NEAR(concrete.at("thickness"), 0.3, 1e-12);
    EXPECT_NEAR(concrete.at("scattering_coefficient"), rough ? 0.4 : 0.0, 1e-12);
    EXPECT_EQ(e.peer["materials"]["concrete"]["scattering_coefficient"].get<double>(), 0.4);
    EXPECT_EQ(e.peer["materials"]["concrete"]["exported_scattering_coefficient"].get<double>(), rough ? 0.4 : 0.0);
    const auto& glass = props.at("mat-raysweep_glass");
    EXPECT_NEAR(glass.at("relative_permittivity"), 6.31, 1e-12);
    EXPECT_NEAR(glass.at("conductivity"), 0.0036 * std::pow(f_ghz, 1.3394), 1e-9);
    EXPECT_NEAR(glass.at("thickness"), 0.005, 1e-12);
    EXPECT_NEAR(props.at("mat-raysweep_metal").at("conductivity"), 1e7, 1e-3);
    EXPECT_NEAR(props.at("mat-raysweep_medium_dry_ground").at("thickness"), 1.0, 1e-12);
    EXPECT_EQ(e.peer["materials"]["medium_dry_ground"]["thickness_m"].get<double>(), 0.0);
    EXPECT_NEAR(e.peer["radio"]["frequency_hz"].get<double>(), f_ghz * 1e9, 1.0);
    // peer.json says the same as the XML.
    for (const auto& [id, p] : props)
      EXPECT_EQ(p.at("conductivity"), e.peer["materials"][id.substr(13)]["conductivity"].get<double>()) << id;
  }
}

TEST(CliPeerExport, VehiclesStandAtTheirPosesWithTheirAntennas) {
  const Export e = export_snapshot("vehicles");
  meshkit::VehicleLibrary library;
  const auto car = library.model("passenger").dims(), bus = library.model("bus").dims();
  // The car heads east from its front bumper at (120, 40); the bus north
  // from (140, 20). SUMO's point is the front bumper's centre.
  const Box c = bounds_of(e.scene, "veh0-"), b = bounds_of(e.scene, "veh1-");
  EXPECT_NEAR(c.hi[0], 120, 0.05);
  EXPECT_NEAR(c.lo[0], 120 - car.length, 0.05);
  EXPECT_NEAR(c.lo[1], 40 - car.width / 2, 0.05);
  EXPECT_NEAR(c.hi[1], 40 + car.width / 2, 0.05);
  EXPECT_NEAR(c.hi[2] - c.lo[2], car.height, 0.05);
  EXPECT_NEAR(b.hi[1], 20, 0.05);
  EXPECT_NEAR(b.lo[1], 20 - bus.length, 0.05);
  EXPECT_NEAR(b.lo[0], 140 - bus.width / 2, 0.05);
  EXPECT_NEAR(b.hi[2] - b.lo[2], bus.height, 0.05);
  // Every part keeps its material: metal body, glass windows, rubber tyres.
  std::set<std::string> car_materials;
  for (const auto& m : e.scene.meshes)
    if (m.name.rfind("veh0-", 0) == 0) car_materials.insert(m.material);
  EXPECT_TRUE(car_materials.count("metal") && car_materials.count("glass")) << car_materials.size();
  // Antennas: on each roof, inside the footprint; the RSU where it was put.
  const auto& nodes = e.peer["nodes"];
  ASSERT_EQ(nodes.size(), 3u);
  const Box boxes[] = {c, b};
  for (int v = 0; v < 2; ++v) {
    EXPECT_EQ(nodes[v]["vehicle"].get<int>(), v);
    const auto p = nodes[v]["position"];
    EXPECT_GT(p[0].get<double>(), boxes[v].lo[0]);
    EXPECT_LT(p[0].get<double>(), boxes[v].hi[0]);
    EXPECT_GT(p[1].get<double>(), boxes[v].lo[1]);
    EXPECT_LT(p[1].get<double>(), boxes[v].hi[1]);
    EXPECT_GE(p[2].get<double>(), boxes[v].hi[2] - 0.3);
    EXPECT_LE(p[2].get<double>(), boxes[v].hi[2] + 0.5);
  }
  EXPECT_EQ(nodes[0]["id"], "car1");
  EXPECT_NEAR(nodes[0]["velocity"][0].get<double>(), 10, 1e-9);
  EXPECT_EQ(nodes[2]["id"], "rsu");
  EXPECT_EQ(nodes[2]["vehicle"].get<int>(), -1);
  EXPECT_EQ(nodes[2]["position"], json({150.0, 60.0, 6.0}));
}

TEST(CliPeerExport, NothingToWriteIsAnError) {
  const auto work = scratch_dir("none");
  write_text(work / "nodes.csv", kNodes + std::string("rsu2,160,60,6\n"));
  const auto r = run_raysweep("-q trace --scene " + demo_scene().string() + " --nodes " + (work / "nodes.csv").string());
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("--out and/or --mitsuba"), std::string::npos) << r.output;
}

// The rules the Sionna comparison applies to both tools' paths
// (bench/peers/sionna/peer_rules.py), on hand-made paths; no peer needed.
TEST(CliPeerExport, PeerRulesClassifyAndFilterHandMadePaths) {
  const fs::path src = source_dir();
  const auto r = run_command("PYTHONPATH='" + (src / "bench/peers/sionna").string() + ":" + (src / "python").string() +
                             "' /usr/bin/python3 '" +
                             (src / "tests/python/test_peer_rules.py").string() + "'");
  EXPECT_EQ(r.exit_code, 0) << r.output;
}
