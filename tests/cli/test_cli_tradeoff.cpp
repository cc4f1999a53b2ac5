// `raysweep tradeoff` end to end on a tiny synthetic input (ground, a few
// buildings, four cars on a street for a few frames, a one-class vehicle
// library with two LODs): the CSV, the reference row, the Pareto flags, the
// chart and the provenance; bad input exits 2 naming the problem and writes
// nothing.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <map>
#include <sstream>
#include <vector>

#include "meshkit/gltf_io.hpp"
#include "meshkit/scene_simplify.hpp"
#include "test_util.hpp"
#include "tracer_fixtures.hpp"

using namespace raysweep::test;
using nlohmann::json;

namespace {

void add_bumped_block(raysweep::meshkit::Scene& s, double x0, double bump, const std::string& name);

// Scene folder, vehicle library, FCD and config in `dir`.
struct Inputs {
  fs::path scene, vehicles, fcd, config;
  std::string args() const {
    return "--scene " + scene.string() + " --vehicles " + vehicles.string() + " --fcd " + fcd.string() +
           " --config " + config.string();
  }
};

Inputs make_inputs(const fs::path& dir) {
  Inputs in{dir / "scene", dir / "vehicles", dir / "fcd.xml", dir / "c.toml"};
  raysweep::meshkit::Scene s;
  add_ground(s, 120);
  // A street along y = 0 between buildings; one with a glass front.
  add_box_object(s, {-40, 8, 0}, {-10, 20, 12}, "concrete", "way/1");
  add_box_object(s, {0, 8, 0}, {25, 18, 9}, "brick", "way/2");
  add_box_object(s, {-30, -22, 0}, {5, -9, 15}, "concrete", "way/3");
  add_box_object(s, {15, -20, 0}, {40, -10, 6}, "glass", "way/4");
  // Past the street's end, a roof that simplification flattens (the
  // static rows need an object they change).
  add_bumped_block(s, 60, 0.3, "way/5");
  fs::create_directories(in.scene);
  raysweep::meshkit::write_glb(s, (in.scene / "scene.glb").string());

  write_text(dir / "v.toml", "[vehicles]\nclasses = [\"passenger\"]\nlod_ratios = [1.0, 0.5]\n");
  auto r = run_raysweep("-q vehicles --no-preview --out " + in.vehicles.string() + " --config " +
                        (dir / "v.toml").string());
  EXPECT_EQ(r.exit_code, 0) << r.output;

  // Four cars, 1 s apart, for 6 s; the first frame has a single car (not a snapshot).
  std::ostringstream fcd;
  fcd << "<?xml version=\"1.0\"?>\n<fcd-export>\n";
  for (int t = 0; t <= 6; ++t) {
    fcd << "<timestep time=\"" << t << ".00\">\n";
    const int cars = t == 0 ? 1 : 4;
    for (int c = 0; c < cars; ++c) {
      const double x = -50 + 12 * c + 5 * t, y = c % 2 ? 2.5 : -2.5;
      fcd << "<vehicle id=\"car" << c << "\" x=\"" << x << "\" y=\"" << y
          << "\" angle=\"90\" type=\"DEFAULT_VEHTYPE\" speed=\"5\"/>\n";
    }
    fcd << "</timestep>\n";
  }
  fcd << "</fcd-export>\n";
  write_text(in.fcd, fcd.str());
  // The base leaves diffuse and diffraction off, so the toggles add them.
  write_text(in.config, "[radio]\nantenna = \"dipole\"\n[tracer]\nrays_per_source = 1024\nmax_depth = 2\n"
                        "diffuse = false\ndiffraction = false\n");
  return in;
}

std::vector<std::string> split(const std::string& line, char sep = ',') {
  std::vector<std::string> out;
  std::stringstream in(line);
  std::string item;
  while (std::getline(in, item, sep)) out.push_back(item);
  return out;
}

std::vector<std::map<std::string, std::string>> read_csv(const fs::path& p, std::string* header) {
  std::stringstream in(read_text(p));
  std::string line;
  std::getline(in, line);
  *header = line;
  const auto cols = split(line);
  std::vector<std::map<std::string, std::string>> rows;
  while (std::getline(in, line)) {
    const auto cells = split(line);
    EXPECT_EQ(cells.size(), cols.size()) << line;
    std::map<std::string, std::string> row;
    for (std::size_t i = 0; i < cols.size() && i < cells.size(); ++i) row[cols[i]] = cells[i];
    rows.push_back(row);
  }
  return rows;
}

// A closed 10 x 10 x 5 m block whose roof peaks `bump` metres at its centre (14 triangles).
void add_bumped_block(raysweep::meshkit::Scene& s, double x0, double bump, const std::string& name) {
  auto& m = s.mesh_for("concrete", "buildings");
  const auto obj = s.add_object("building", name);
  const auto b = static_cast<std::uint32_t>(m.vertices.size());
  for (int i = 0; i < 8; ++i) m.vertices.push_back({x0 + (i & 1 ? 10 : 0), i & 2 ? 10.0 : 0.0, i & 4 ? 5.0 : 0.0});
  m.vertices.push_back({x0 + 5, 5, 5 + bump});  // b + 8
  const std::vector<raysweep::meshkit::Tri> tris = {
      {b + 0, b + 2, b + 3}, {b + 0, b + 3, b + 1},                          // floor (down)
      {b + 0, b + 1, b + 5}, {b + 0, b + 5, b + 4}, {b + 2, b + 6, b + 7}, {b + 2, b + 7, b + 3},  // y walls
      {b + 0, b + 4, b + 6}, {b + 0, b + 6, b + 2}, {b + 1, b + 3, b + 7}, {b + 1, b + 7, b + 5},  // x walls
      {b + 4, b + 5, b + 8}, {b + 5, b + 7, b + 8}, {b + 7, b + 6, b + 8}, {b + 6, b + 4, b + 8}};  // roof
  for (const auto& t : tris) {
    m.triangles.push_back(t);
    m.triangle_object.push_back(obj);
    m.triangle_face.push_back(static_cast<std::uint32_t>(m.triangle_face.size()));
  }
}

}  // namespace

TEST(SceneSimplify, DecimatesEachObjectWithinTheErrorBound) {
  raysweep::meshkit::Scene s;
  add_ground(s, 60);
  add_bumped_block(s, 0, 0.3, "way/1");
  add_bumped_block(s, 20, 1.5, "way/2");
  const auto before = s.triangle_count();
  raysweep::meshkit::SimplifyStats st;
  // 0.5 m flattens the 0.3 m roof peak, not the 1.5 m one; the ground quad stays.
  const auto out = raysweep::meshkit::simplify_scene(s, 0.5, &st);
  EXPECT_EQ(st.triangles_before, before);
  EXPECT_EQ(st.triangles_after, before - 2);
  EXPECT_EQ(st.objects_simplified, 1u);
  EXPECT_EQ(out.objects.size(), s.objects.size());
  EXPECT_EQ(out.meshes.size(), s.meshes.size());
  for (const auto& m : out.meshes) {
    ASSERT_EQ(m.triangle_object.size(), m.triangles.size());
    ASSERT_EQ(m.triangle_face.size(), m.triangles.size());
    // Still closed (the ground is an open quad, on its own object).
    for (std::uint32_t obj = 0; obj < out.objects.size(); ++obj) {
      if (out.objects[obj].source_id == "ground" ||
          std::count(m.triangle_object.begin(), m.triangle_object.end(), obj) == 0)
        continue;
      EXPECT_TRUE(raysweep::meshkit::edge_report(m, obj).watertight()) << out.objects[obj].source_id;
    }
  }
  // Planar faces are regrouped: the flattened roof is one face, face ids never span objects.
  std::map<std::uint32_t, std::uint32_t> face_object;
  std::size_t faces_of_first_block = 0;
  for (const auto& m : out.meshes)
    for (std::size_t t = 0; t < m.triangles.size(); ++t) {
      auto [it, fresh] = face_object.emplace(m.triangle_face[t], m.triangle_object[t]);
      EXPECT_EQ(it->second, m.triangle_object[t]);
      if (fresh && out.objects[m.triangle_object[t]].source_id == "way/1") ++faces_of_first_block;
    }
  EXPECT_EQ(faces_of_first_block, 6u);  // a box again
  // A tighter bound keeps both peaks; 0 returns the scene as it is.
  EXPECT_EQ(raysweep::meshkit::simplify_scene(s, 0.1).triangle_count(), before);
  EXPECT_EQ(raysweep::meshkit::simplify_scene(s, 0).triangle_count(), before);
}

TEST(CliTradeoff, QuickGridWritesCsvJsonAndChart) {
  auto dir = scratch_dir("quick");
  const Inputs in = make_inputs(dir);
  const fs::path out = dir / "out";
  auto r = run_raysweep("-j 2 tradeoff " + in.args() + " --quick --out " + out.string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("suggested"), std::string::npos) << r.output;

  std::string header;
  const auto rows = read_csv(out / "tradeoff.csv", &header);
  EXPECT_EQ(header.rfind("label,rays,depth,diffuse,diffraction,refraction,lod,static_simplification,"
                         "time_per_snapshot_s,err_median_db,err_p95_db,los_agreement,power_fraction,"
                         "power_fraction_median,paths,pareto",
                         0),
            0u)
      << header;
  // Reference + rays {256, 1024} x depths {1, 2} + diffuse, diffraction,
  // the vehicles' knife edges (on the direct path, on reflected paths), the
  // vehicles' UTD edges and refraction toggled + all mechanisms + the
  // multi-bounce table off + the vehicle bundles off (all, and through
  // faces) + the sampled search alone + the coarser LOD + static geometry at 2 m.
  ASSERT_EQ(rows.size(), 18u);
  std::map<std::string, const std::map<std::string, std::string>*> by_label;
  for (const auto& row : rows) by_label[row.at("label")] = &row;
  for (const char* label : {"reference", "r256 d1", "r256 d2", "r1024 d1", "r1024 d2", "r1024 d2 +diffuse",
                            "r1024 d2 +diffraction", "r1024 d2 -vehicle knife edges", "r1024 d2 +reflected knife edges",
                            "r1024 d2 +vehicle edges", "r1024 d2 -refraction",
                            "r1024 d2 all mechanisms", "r1024 d2 -vehicle multi-bounce", "r1024 d2 -vehicle bundles",
                            "r1024 d2 -vehicle bundles via faces",
                            "r1024 d2 sbr search", "r1024 d2 lod1",
                            "r1024 d2 static 2m"})
    EXPECT_TRUE(by_label.count(label)) << label;

  const auto& ref = *by_label.at("reference");
  EXPECT_EQ(ref.at("rays"), "4096");  // 4 x the largest grid value
  EXPECT_EQ(ref.at("depth"), "3");    // the largest grid depth + 1
  EXPECT_EQ(ref.at("diffuse"), "1");
  EXPECT_EQ(ref.at("diffraction"), "1");
  EXPECT_EQ(ref.at("refraction"), "1");
  EXPECT_EQ(ref.at("lod"), "0");
  EXPECT_EQ(std::stod(ref.at("err_median_db")), 0.0);
  EXPECT_EQ(std::stod(ref.at("err_p95_db")), 0.0);
  EXPECT_EQ(std::stod(ref.at("los_agreement")), 1.0);
  EXPECT_EQ(std::stod(ref.at("power_fraction")), 1.0);
  EXPECT_EQ(by_label.at("r1024 d2 lod1")->at("lod"), "1");
  EXPECT_EQ(by_label.at("r1024 d2 static 2m")->at("static_simplification"), "2");
  EXPECT_EQ(by_label.at("r1024 d2 -refraction")->at("refraction"), "0");

  std::vector<double> time, err;
  for (const auto& row : rows) {
    for (const char* c : {"time_per_snapshot_s", "err_median_db", "err_p95_db", "los_agreement", "power_fraction",
                          "power_fraction_median", "paths"}) {
      const double v = std::stod(row.at(c));
      EXPECT_TRUE(std::isfinite(v)) << row.at("label") << " " << c;
      EXPECT_GE(v, 0) << row.at("label") << " " << c;
    }
    EXPECT_LE(std::stod(row.at("los_agreement")), 1.0);
    EXPECT_LE(std::stod(row.at("power_fraction")), 1.0 + 1e-12);
    EXPECT_LE(std::stod(row.at("err_median_db")), std::stod(row.at("err_p95_db")) + 1e-9) << row.at("label");
    EXPECT_GT(std::stod(row.at("time_per_snapshot_s")), 0) << row.at("label");
    time.push_back(std::stod(row.at("time_per_snapshot_s")));
    err.push_back(std::stod(row.at("err_p95_db")));
  }
  // The Pareto flags: not dominated in (time, p95 error).
  for (std::size_t i = 0; i < rows.size(); ++i) {
    bool dominated = false;
    for (std::size_t j = 0; j < rows.size(); ++j)
      if (j != i && time[j] <= time[i] && err[j] <= err[i] && (time[j] < time[i] || err[j] < err[i])) dominated = true;
    EXPECT_EQ(rows[i].at("pareto"), dominated ? "0" : "1") << rows[i].at("label");
  }
  EXPECT_EQ(ref.at("pareto"), "1");  // nothing else has zero error

  // The chart is a PNG.
  for (const char* name : {"tradeoff.png", "tradeoff.coherence.png"}) {
    const std::string png = read_text(out / name);
    ASSERT_GT(png.size(), 1000u) << name;
    EXPECT_EQ(png.substr(1, 3), "PNG") << name;
  }

  // JSON: the same rows, the snapshots and provenance.
  const json doc = json::parse(read_text(out / "tradeoff.json"));
  ASSERT_EQ(doc["rows"].size(), rows.size());
  EXPECT_EQ(doc["rows"][0]["label"], "reference");
  EXPECT_EQ(doc["snapshots"].size(), 2u);  // --quick
  for (const auto& s : doc["snapshots"]) EXPECT_EQ(s["vehicles"].size(), 4u);  // frame 0 (one car) is never one
  EXPECT_EQ(doc["threads"], 2);
  const json& prov = doc["provenance"];
  EXPECT_EQ(prov["tool"], "raysweep");
  EXPECT_EQ(prov["stage"], "tradeoff");
  EXPECT_FALSE(prov["version"].get<std::string>().empty());
  std::map<std::string, std::string> roles;
  for (const auto& f : prov["inputs"]) {
    EXPECT_EQ(f["sha256"].get<std::string>().size(), 64u);
    roles[f["role"]] = f["path"];
  }
  for (const char* role : {"scene", "fcd", "config", "vehicle_manifest"}) EXPECT_TRUE(roles.count(role)) << role;
  EXPECT_EQ(prov["config"]["tradeoff"]["reference_rays"], 4096);
  EXPECT_EQ(prov["config"]["tradeoff"]["coherence_window"], 4);  // --quick
  // The coherence toggle: 4 frames swept with coherence off, on with K = 1
  // and 4 (--quick), each against the reference rays' coherent sweep.
  EXPECT_EQ(prov["config"]["tradeoff"]["lattice_frames"], json::array({1, 4}));
  const json& coh = doc["coherence"];
  EXPECT_EQ(coh["frames"], 4);
  EXPECT_GT(coh["pair_frames"].get<int>(), 0);
  EXPECT_EQ(coh["reference_rays"], 4096);
  EXPECT_GT(coh["reference_trace_s"].get<double>(), 0);
  ASSERT_EQ(coh["sweeps"].size(), 3u);
  const json &off = coh["sweeps"][0], &k1 = coh["sweeps"][1], &k4 = coh["sweeps"][2];
  EXPECT_EQ(off["label"], "off");
  EXPECT_EQ(k4["label"], "K=4");
  for (const json& s : coh["sweeps"]) {
    EXPECT_TRUE(s["same_links"].get<bool>()) << s;
    EXPECT_GT(s["trace_s"].get<double>(), 0) << s;
    for (const char* k : {"los_agreement", "fresnel_agreement"}) {
      EXPECT_GE(s[k].get<double>(), 0) << k;
      EXPECT_LE(s[k].get<double>(), 1) << k;
    }
    EXPECT_LE(s["gain_diff_p50_db"].get<double>(), s["gain_diff_p99_db"].get<double>()) << s;
    EXPECT_LE(s["gain_diff_p99_db"].get<double>(), s["gain_diff_max_db"].get<double>()) << s;
  }
  // K = 1 carries nothing and shoots the one lattice: the from-scratch sweep.
  EXPECT_EQ(k1["carried_sequences"], 0);
  EXPECT_EQ(k1["gain_diff_p99_db"], off["gain_diff_p99_db"]);
  EXPECT_EQ(k1["gain_diff_max_db"], off["gain_diff_max_db"]);
  EXPECT_GT(k4["carried_sequences"].get<int>(), 0) << "the coherent sweep carried nothing";
  EXPECT_NE(r.output.find("coherence over 4 frames"), std::string::npos) << r.output;
  EXPECT_EQ(prov["config"]["tracer"]["rays_per_source"], 1024);
  // Nothing left over from the atomic writes.
  for (const auto& e : fs::directory_iterator(out))
    EXPECT_NE(e.path().filename().string().find("tradeoff."), std::string::npos) << e.path();
}

TEST(CliTradeoff, ExplicitListsAndBuiltInModels) {
  auto dir = scratch_dir("lists");
  const Inputs in = make_inputs(dir);
  const fs::path out = dir / "out";
  // Built-in models (no library): no LOD variant; one snapshot; custom lists.
  auto r = run_raysweep("tradeoff --scene " + in.scene.string() + " --fcd " + in.fcd.string() + " --config " +
                        in.config.string() + " --rays 512 --depths 0,1 --simplify 0.1,1 --snapshots 1 "
                        "--reference-rays 2048 --reference-depth 2 --no-chart --out " + out.string() +
                        " --coherence-window 3 --lattice-frames 1");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  std::string header;
  const auto rows = read_csv(out / "tradeoff.csv", &header);
  // reference, r512 d0, r512 d1, six toggles, all mechanisms and the
  // sampled search around r512 d1, static 1m. Not static 0.1m: it changes
  // no object (the default's scene; its row would chart timer noise).
  ASSERT_EQ(rows.size(), 12u);
  EXPECT_NE(r.output.find("static 0.1m leaves every object as it is"), std::string::npos) << r.output;
  EXPECT_EQ(rows[0].at("rays"), "2048");
  EXPECT_EQ(rows[0].at("depth"), "2");
  EXPECT_EQ(rows[1].at("label"), "r512 d0");
  EXPECT_EQ(rows.back().at("label"), "r512 d1 static 1m");
  EXPECT_FALSE(fs::exists(out / "tradeoff.png"));
  EXPECT_FALSE(fs::exists(out / "tradeoff.coherence.png"));
  const json doc = json::parse(read_text(out / "tradeoff.json"));
  EXPECT_EQ(doc["snapshots"].size(), 1u);
  // Only K = 1 on the axis: it carries nothing and shoots the one lattice,
  // so it is the sweep with coherence off to the bit.
  const json& coh = doc["coherence"];
  EXPECT_EQ(coh["frames"], 3);
  EXPECT_GT(coh["pair_frames"].get<int>(), 0);
  ASSERT_EQ(coh["sweeps"].size(), 2u);
  const json &off = coh["sweeps"][0], &k1 = coh["sweeps"][1];
  EXPECT_EQ(k1["carried_sequences"], 0);
  for (const char* k : {"gain_diff_p50_db", "gain_diff_p99_db", "gain_diff_max_db", "los_agreement"})
    EXPECT_EQ(off[k], k1[k]) << k;
}

TEST(CliTradeoff, BadInputExitsTwoAndWritesNothing) {
  auto dir = scratch_dir("bad");
  const Inputs in = make_inputs(dir);
  const fs::path out = dir / "out";
  auto expect_fails = [&](const std::string& args, const std::string& needle) {
    auto r = run_raysweep("tradeoff " + args);
    EXPECT_EQ(r.exit_code, 2) << args << "\n" << r.output;
    EXPECT_NE(r.output.find(needle), std::string::npos) << args << "\n" << r.output;
    EXPECT_FALSE(fs::exists(out)) << args;
  };
  const std::string ok = in.args() + " --quick --out " + out.string();
  expect_fails(ok + " --bogus", "--bogus");
  expect_fails(ok + " --rays 0", "--rays");
  expect_fails(ok + " --rays 256,x", "'x'");
  expect_fails(ok + " --depths 1,99", "--depths");
  expect_fails(ok + " --simplify -1", "--simplify");
  expect_fails(ok + " --lattice-frames 0,4", "--lattice-frames");
  expect_fails(ok + " --snapshots 0", "--snapshots");
  expect_fails("--scene " + in.scene.string() + " --fcd " + (dir / "none.xml").string() + " --out " + out.string(),
               "none.xml");
  expect_fails("--scene " + (dir / "nowhere").string() + " --fcd " + in.fcd.string() + " --out " + out.string(),
               "scene.glb");
  write_text(dir / "typo.toml", "[tracer]\nrays_per_sorce = 10\n");
  expect_fails("--scene " + in.scene.string() + " --fcd " + in.fcd.string() + " --config " +
                   (dir / "typo.toml").string() + " --out " + out.string(),
               "rays_per_sorce");

  // A city whose `raysweep run` outputs are not there.
  const fs::path demo = source_dir() / "datasets/demo";
  write_text(dir / "city.toml", "[city]\nname = \"nowhere\"\nosm = \"" + (demo / "kirchberg.osm").string() +
                                    "\"\nnet = \"" + (demo / "kirchberg.net.xml").string() + "\"\nout = \"" +
                                    (dir / "city_out").string() + "\"\n");
  auto r = run_raysweep("tradeoff " + (dir / "city.toml").string() + " --quick");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("raysweep run " + (dir / "city.toml").string()), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(dir / "city_out"));
  // A city file and explicit inputs together.
  r = run_raysweep("tradeoff " + (dir / "city.toml").string() + " --scene " + in.scene.string() + " --out " +
                   out.string());
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_FALSE(fs::exists(out));
}
