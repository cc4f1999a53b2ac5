// `raysweep traffic`, `sweep`, `run`, `validate` and `info` end to end on the
// demo city with real SUMO traffic: a valid dataset the Python reader loads,
// resume after kill -9 equal to an uninterrupted run, determinism across
// thread counts, up-to-date stages skipped, and bad input.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <unistd.h>
#include <zlib.h>

#include <sstream>

#include "test_util.hpp"

using namespace raysweep::test;
using nlohmann::json;

namespace {

fs::path demo() { return source_dir() / "datasets/demo"; }

// Built once per process: ctest runs each test in its own process, in parallel.
fs::path demo_scene() {
  static const fs::path dir = [] {
    fs::path d = fs::temp_directory_path() / "raysweep-tests" / ("cli_sweep_scene." + std::to_string(getpid()));
    fs::remove_all(d);
    auto r = run_raysweep("-q scene --no-preview --osm " + (demo() / "kirchberg.osm").string() + " --net " +
                          (demo() / "kirchberg.net.xml").string() + " --out " + d.string());
    EXPECT_EQ(r.exit_code, 0) << r.output;
    return d;
  }();
  return dir;
}

// 40 s of SUMO traffic on the demo network.
fs::path demo_traffic() {
  static const fs::path dir = [] {
    fs::path d = fs::temp_directory_path() / "raysweep-tests" / ("cli_sweep_traffic." + std::to_string(getpid()));
    fs::remove_all(d);
    auto r = run_raysweep("-q traffic --net " + (demo() / "kirchberg.net.xml").string() +
                          " --trips-seed 3 --end 40 --period 1.5 --out " + d.string());
    EXPECT_EQ(r.exit_code, 0) << r.output;
    return d;
  }();
  return dir;
}

std::string sweep_args(const fs::path& config) {
  return "sweep --scene " + demo_scene().string() + " --fcd " + (demo_traffic() / "fcd.xml.gz").string() +
         " --vtypes " + (demo_traffic() / "vtypes.add.xml").string() + " --config " + config.string();
}

void write_config(const fs::path& p, const std::string& sweep_table) {
  write_text(p, "[sweep]\n" + sweep_table + "\n[tracer]\nrays_per_source = 1024\nmax_depth = 2\n");
}

}  // namespace

TEST(CliSweep, TrafficIsRealSumoFcdWithProvenance) {
  const auto t = demo_traffic();
  ASSERT_TRUE(fs::exists(t / "fcd.xml.gz"));
  const json rec = json::parse(read_text(t / "traffic.json"));
  EXPECT_EQ(rec["provenance"]["config"]["seed"], 3);
  EXPECT_EQ(rec["vtype_files"][0], "vtypes.add.xml");
  // SUMO ran to the end and wrote vehicles at 10 Hz.
  gzFile f = gzopen((t / "fcd.xml.gz").c_str(), "rb");
  ASSERT_NE(f, nullptr);
  std::string text;
  char buf[65536];
  int n;
  while ((n = gzread(f, buf, sizeof buf)) > 0) text.append(buf, n);
  gzclose(f);
  EXPECT_NE(text.find("<timestep time=\"39.90\""), std::string::npos);
  EXPECT_NE(text.find("type=\"passenger\""), std::string::npos);
}

TEST(CliSweep, DatasetValidatesAndThePythonReaderLoadsIt) {
  auto dir = scratch_dir("sweep_valid");
  write_config(dir / "c.toml", "begin_s = 30\nend_s = 31.95\nblock_frames = 8\ncfr = \"80211p\"");
  auto r = run_raysweep(sweep_args(dir / "c.toml") + " --out " + (dir / "d.h5").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_FALSE(fs::exists(dir / "d.h5.parts"));
  r = run_raysweep("validate " + (dir / "d.h5").string());
  EXPECT_EQ(r.exit_code, 0) << r.output;
  r = run_raysweep("info --json " + (dir / "d.h5").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const json info = json::parse(r.output);
  EXPECT_EQ(info["frames"], 20);
  EXPECT_GT(info["links"].get<int>(), 20);
  EXPECT_TRUE(info["has_cfr"].get<bool>());
  const std::string py = "PYTHONPATH=" + (source_dir() / "python").string() +
                         " /usr/bin/python3 -c \"import raysweep_dataset as r; d = r.open_dataset('" +
                         (dir / "d.h5").string() +
                         "'); f = d.frame(0); print(d.frame_count, len(f['tx']))\"";
  r = run_command(py);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(r.output.substr(0, 3), "20 ");
}

// A coherent sweep (sequences carried from the frames before, diffuse
// lattices shared).
TEST(CliSweep, ResumeAfterKillEqualsUninterruptedAndThreadsDoNotMatter) {
  auto dir = scratch_dir("sweep_resume");
  fs::create_directories(dir / "a");
  fs::create_directories(dir / "b");
  write_config(dir / "c.toml", "begin_s = 30\nend_s = 32.95\nblock_frames = 6\ncache = \"per_pair\"\ncoherence = true\n"
                               "lattice_frames = 3\ndiffuse_frames = 2");
  const std::string cmd = sweep_args(dir / "c.toml") + " --out out.h5";
  // Uninterrupted, one thread.
  auto r = run_command("cd " + (dir / "a").string() + " && " + RAYSWEEP_BINARY + " -q -j 1 " + cmd);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  // Killed with SIGKILL right after its second block was committed...
  r = run_command("cd " + (dir / "b").string() + " && RAYSWEEP_KILL_AFTER_BLOCKS=2 " + RAYSWEEP_BINARY + " -q " + cmd);
  EXPECT_NE(r.exit_code, 0);
  EXPECT_FALSE(fs::exists(dir / "b/out.h5"));  // nothing half-written
  ASSERT_TRUE(fs::exists(dir / "b/out.h5.parts/block_000001.bin"));
  EXPECT_FALSE(fs::exists(dir / "b/out.h5.parts/block_000002.bin"));
  // ...then resumed: it keeps the two blocks and the result is the same file content.
  r = run_command("cd " + (dir / "b").string() + " && " + RAYSWEEP_BINARY + " " + cmd + " --resume");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("2 resumed blocks"), std::string::npos) << r.output;
  r = run_command("h5diff " + (dir / "a/out.h5").string() + " " + (dir / "b/out.h5").string());
  EXPECT_EQ(r.exit_code, 0) << r.output;
  // A resume under other settings refuses to mix runs.
  r = run_command("cd " + (dir / "b").string() + " && RAYSWEEP_KILL_AFTER_BLOCKS=1 " + RAYSWEEP_BINARY + " -q " + cmd);
  write_config(dir / "c.toml", "begin_s = 30\nend_s = 32.95\nblock_frames = 6\ncache = \"global\"");
  r = run_command("cd " + (dir / "b").string() + " && " + RAYSWEEP_BINARY + " " + cmd + " --resume");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("other inputs or settings"), std::string::npos) << r.output;
}

namespace {

// Two HDF5 files hold the same data: every top-level group alike (h5diff,
// attributes of the groups' datasets included); the root attributes, which
// carry the provenance, are left out.
void expect_same_data(const fs::path& a, const fs::path& b) {
  const auto groups = run_command("h5ls " + a.string() + " | awk '$2 == \"Group\" {print $1}'");
  ASSERT_EQ(groups.exit_code, 0) << groups.output;
  int compared = 0;
  std::istringstream in(groups.output);
  for (std::string g; std::getline(in, g);) {
    const auto r = run_command("h5diff " + a.string() + " " + b.string() + " /" + g + " /" + g);
    EXPECT_EQ(r.exit_code, 0) << a << " /" << g << "\n" << r.output;
    ++compared;
  }
  EXPECT_GT(compared, 2) << groups.output;
}

}  // namespace

// The default store level (cfr) against full: the same link columns and
// CFR, and the same SINR outcomes and ns-3 table from either; a links-level
// file is refused by ns3-table, which names the level and writes nothing.
TEST(CliSweep, StoreLevelsFeedTheSameSinrAndNs3Tables) {
  auto dir = scratch_dir("sweep_levels");
  const std::string base = "begin_s = 30\nend_s = 31.95\nblock_frames = 8\ncfr = \"80211p\"\n";
  for (const std::string level : {"default", "full", "links"}) {
    write_config(dir / (level + ".toml"), base + (level == "default" ? "" : "store = \"" + level + "\""));
    auto r = run_raysweep(sweep_args(dir / (level + ".toml")) + " --out " + (dir / (level + ".h5")).string());
    ASSERT_EQ(r.exit_code, 0) << r.output;
    EXPECT_NE(r.output.find(" at level " + (level == "default" ? std::string("cfr") : level)), std::string::npos)
        << r.output;
    EXPECT_EQ(run_raysweep("validate " + (dir / (level + ".h5")).string()).exit_code, 0) << level;
  }
  const fs::path cfr = dir / "default.h5", full = dir / "full.h5", links = dir / "links.h5";
  EXPECT_LT(fs::file_size(cfr), fs::file_size(full) / 2);
  for (const char* g : {"/links", "/cfr", "/frames", "/node_states"}) {
    const auto r = run_command("h5diff --exclude-path /path_offset " + cfr.string() + " " + full.string() + " " +
                               g + " " + g);
    EXPECT_EQ(r.exit_code, 0) << g << "\n" << r.output;
  }
  write_text(dir / "s.toml", "[sinr]\nseed = 7\nnr_fraction = 0.5\n");
  for (const fs::path& ds : {cfr, full}) {
    const std::string stem = ds.stem().string();
    auto r = run_raysweep("-q sinr --channels " + ds.string() + " --out " + (dir / (stem + "_sinr.h5")).string() +
                          " --config " + (dir / "s.toml").string());
    ASSERT_EQ(r.exit_code, 0) << r.output;
    r = run_raysweep("-q ns3-table --channels " + ds.string() + " --out " + (dir / (stem + "_ns3.h5")).string());
    ASSERT_EQ(r.exit_code, 0) << r.output;
  }
  expect_same_data(dir / "default_sinr.h5", dir / "full_sinr.h5");
  expect_same_data(dir / "default_ns3.h5", dir / "full_ns3.h5");
  // The links level has no frequency responses: ns3-table refuses it.
  const auto r = run_raysweep("ns3-table --channels " + links.string() + " --out " + (dir / "links_ns3.h5").string());
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("stores level links but ns3-table reads level cfr"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("--set sweep.store=cfr"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(dir / "links_ns3.h5"));
  // sinr reads only link columns: any level will do.
  EXPECT_EQ(run_raysweep("-q sinr --channels " + links.string() + " --out " + (dir / "links_sinr.h5").string() +
                         " --config " + (dir / "s.toml").string())
                .exit_code,
            0);
}

TEST(CliSweep, BadInputNamesFileAndLineAndWritesNothing) {
  auto dir = scratch_dir("sweep_bad");
  write_config(dir / "c.toml", "");
  const std::string head = "<fcd-export>\n";
  auto fcd = [&](const std::string& name, const std::string& body) {
    write_text(dir / name, "<?xml version=\"1.0\"?>\n" + head + body + "</fcd-export>\n");
    return "sweep --scene " + demo_scene().string() + " --fcd " + (dir / name).string() + " --config " +
           (dir / "c.toml").string() + " --out " + (dir / (name + ".h5")).string();
  };
  const std::string v1 = "<vehicle id=\"a\" x=\"50\" y=\"60\" angle=\"90\" type=\"DEFAULT_VEHTYPE\" speed=\"5\"/>\n";
  const std::string v2 = "<vehicle id=\"b\" x=\"120\" y=\"62\" angle=\"270\" type=\"lorry\" speed=\"5\"/>\n";
  // Unknown type: traced as a passenger car, with a warning naming the type.
  auto r = run_raysweep(fcd("unknown.xml", "<timestep time=\"0.00\">\n" + v1 + v2 + "</timestep>\n"));
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("'lorry'"), std::string::npos) << r.output;
  // A vehicle outside the scene: error naming file, line and vehicle.
  r = run_raysweep(fcd("outside.xml", "<timestep time=\"0.00\">\n" + v1 +
                                          "<vehicle id=\"far\" x=\"5000\" y=\"60\" angle=\"0\" speed=\"1\"/>\n"
                                          "</timestep>\n"));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("outside.xml: line 5 vehicle far"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(dir / "outside.xml.h5"));
  EXPECT_FALSE(fs::exists(dir / "outside.xml.h5.tmp"));
  // Time going backwards.
  r = run_raysweep(fcd("backwards.xml", "<timestep time=\"1.00\">\n" + v1 + "</timestep>\n<timestep time=\"0.50\">\n" +
                                            v1 + "</timestep>\n"));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("backwards.xml"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("line 6"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(dir / "backwards.xml.h5"));
  EXPECT_FALSE(fs::exists(dir / "backwards.xml.h5.tmp"));
  // A duplicate id in one frame.
  r = run_raysweep(fcd("dup.xml", "<timestep time=\"0.00\">\n" + v1 + v1 + "</timestep>\n"));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("line 5"), std::string::npos) << r.output;
  // Unknown config key and wrong type.
  write_config(dir / "bad.toml", "d0 = 1");
  r = run_raysweep("sweep --scene " + demo_scene().string() + " --fcd " + (dir / "unknown.xml").string() +
                   " --config " + (dir / "bad.toml").string() + " --out " + (dir / "x.h5").string());
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("bad.toml:2: sweep.d0: unknown key (did you mean 'd0_m'?)"), std::string::npos) << r.output;
  write_config(dir / "bad.toml", "d0_m = \"1 m\"");
  r = run_raysweep("sweep --scene " + demo_scene().string() + " --fcd " + (dir / "unknown.xml").string() +
                   " --config " + (dir / "bad.toml").string() + " --out " + (dir / "x.h5").string());
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("bad.toml:2: sweep.d0_m: expected a finite number >= 0, got \"1 m\""), std::string::npos)
      << r.output;
  // A truncated gzip trace.
  const std::string whole = read_text(demo_traffic() / "fcd.xml.gz");
  write_text(dir / "cut.xml.gz", whole.substr(0, whole.size() / 2));
  r = run_raysweep("sweep --scene " + demo_scene().string() + " --fcd " + (dir / "cut.xml.gz").string() +
                   " --config " + (dir / "c.toml").string() + " --out " + (dir / "cut.h5").string());
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("cut.xml.gz"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(dir / "cut.h5"));
  EXPECT_FALSE(fs::exists(dir / "cut.h5.tmp"));
  // No SUMO: a message that says how to install it.
  r = run_command("SUMO_BINARY=/nonexistent/sumo " + std::string(RAYSWEEP_BINARY) + " traffic --net " +
                  (demo() / "kirchberg.net.xml").string() + " --trips-seed 1 --out " + (dir / "t").string());
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("apt-get install sumo"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(dir / "t"));
}

TEST(CliSweep, RunSkipsStagesThatAreUpToDate) {
  auto dir = scratch_dir("city_run");
  write_text(dir / "city.toml", "[city]\nname = \"mini\"\nosm = \"" + (demo() / "kirchberg.osm").string() +
                                    "\"\nnet = \"" + (demo() / "kirchberg.net.xml").string() +
                                    "\"\n[traffic]\nseed = 5\nend_s = 30\nperiod_s = 2\n"
                                    "[sinr]\nactive_vehicles = 6\nmodels = [\"ray\", \"tr37885-urban\"]\n"
                                    "[sweep]\nbegin_s = 25\nend_s = 25.45\n[tracer]\nrays_per_source = 1024\n");
  auto r = run_raysweep("run " + (dir / "city.toml").string() + " --out " + (dir / "out").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("dataset: " + (dir / "out/dataset.h5").string()), std::string::npos) << r.output;
  EXPECT_EQ(run_raysweep("validate " + (dir / "out/dataset.h5").string()).exit_code, 0);
  // The [sinr] table adds SINR outcomes per model and their report.
  for (const char* f : {"sinr/ray.h5", "sinr/tr37885-urban.h5"})
    EXPECT_EQ(run_raysweep("validate " + (dir / "out" / f).string()).exit_code, 0) << f;
  EXPECT_TRUE(fs::exists(dir / "out/sinr/report/sinr_pdf.png"));
  EXPECT_TRUE(fs::exists(dir / "out/sinr/report/report.md"));
  r = run_raysweep("run " + (dir / "city.toml").string() + " --out " + (dir / "out").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  for (const char* stage : {"scene: up to date", "vehicles: up to date", "traffic: up to date", "sweep: up to date",
                            "sinr: up to date"})
    EXPECT_NE(r.output.find(stage), std::string::npos) << stage << "\n" << r.output;
  // Changing the sweep settings reruns only the sweep.
  write_text(dir / "city.toml", read_text(dir / "city.toml") + "max_depth = 2\n");
  r = run_raysweep("run " + (dir / "city.toml").string() + " --out " + (dir / "out").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("traffic: up to date"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("sweep: tracing"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("sinr: ray"), std::string::npos) << r.output;  // new channels, new outcomes
}

TEST(CliSweep, CityRecipesLoad) {
  // The demo recipe is the README's main command; the Bad Hersfeld recipe
  // reads ../shared/data. A bad key in a recipe is a clear error.
  auto dir = scratch_dir("recipes");
  const std::string bh = (source_dir() / "datasets/badhersfeld/city.toml").string();
  if (fs::exists(shared_data() / "dlr-sumo-scenarios-badhersfeld/osm_edited.net.xml.gz")) {
    // A typo in an otherwise valid copy is caught before any stage runs.
    std::string text = read_text(bh);
    const std::string from = "../../../shared/data", to = shared_data().string();
    for (auto p = text.find(from); p != std::string::npos; p = text.find(from, p + to.size())) text.replace(p, from.size(), to);
    write_text(dir / "bh.toml", text + "\n[sweep.extra]\n");
    auto r = run_raysweep("run " + (dir / "bh.toml").string() + " --out " + (dir / "out").string());
    EXPECT_EQ(r.exit_code, 2) << r.output;
    EXPECT_NE(r.output.find("bh.toml"), std::string::npos) << r.output;
  }
  write_text(dir / "demo.toml", read_text(source_dir() / "datasets/demo/city.toml") + "[traffic.oops]\n");
  auto r = run_raysweep("run " + (dir / "demo.toml").string() + " --out " + (dir / "o").string());
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_FALSE(fs::exists(dir / "o"));
}
