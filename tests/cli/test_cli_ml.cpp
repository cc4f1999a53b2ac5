// `raysweep features` and `raysweep ml` end to end on a small run of the demo
// city: the feature file validates and is rebuilt only when its inputs or
// settings change; the benchmark writes results rows with intervals and its
// report; a missing run is a clear error.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <fstream>
#include <set>

#include "test_util.hpp"

using namespace raysweep::test;
using nlohmann::json;
namespace fs = std::filesystem;

namespace {

fs::path demo() { return source_dir() / "datasets/demo"; }

// The demo network with little traffic, 8 s swept at 10 Hz with SINR outcomes.
fs::path mini_city(const fs::path& dir) {
  write_text(dir / "city.toml", "[city]\nname = \"mini\"\nosm = \"" + (demo() / "kirchberg.osm").string() +
                                    "\"\nnet = \"" + (demo() / "kirchberg.net.xml").string() +
                                    "\"\n[traffic]\nseed = 5\nend_s = 40\nperiod_s = 1\n"
                                    "[sinr]\nactive_vehicles = 6\nmodels = [\"ray\"]\n"
                                    "[sweep]\nbegin_s = 30\nend_s = 37.95\nmax_vehicles = 12\n"
                                    "[tracer]\nrays_per_source = 512\nmax_depth = 1\n"
                                    "[features]\nalong_cells = 16\nacross_cells = 8\n");
  return dir / "city.toml";
}

}  // namespace

TEST(CliMl, FeaturesAndTheBenchmarkRunOnACitysRun) {
  const fs::path dir = scratch_dir("cli_ml");
  const fs::path city = mini_city(dir), out = dir / "out";
  // Before `raysweep run`: an error naming what is missing and what to run.
  auto r = run_raysweep("features " + city.string() + " --city-out " + out.string());
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("dataset.h5"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("raysweep run"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(out / "features.h5"));

  r = run_raysweep("-q run " + city.string() + " --out " + out.string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  r = run_raysweep("features " + city.string() + " --city-out " + out.string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(run_raysweep("validate " + (out / "features.h5").string()).exit_code, 0);
  r = run_raysweep("info --json " + (out / "features.h5").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const json info = json::parse(r.output.substr(r.output.find('{')));
  EXPECT_EQ(info["along_cells"], 16);
  EXPECT_EQ(info["across_cells"], 8);
  EXPECT_GT(info["rows"].get<int>(), 0);

  // The same inputs and settings: nothing to do; another setting: rebuilt.
  r = run_raysweep("features " + city.string() + " --city-out " + out.string());
  EXPECT_NE(r.output.find("up to date"), std::string::npos) << r.output;
  r = run_raysweep("features " + city.string() + " --city-out " + out.string() + " --set features.across_cells=4");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(r.output.find("up to date"), std::string::npos) << r.output;
  r = run_raysweep("info --json " + (out / "features.h5").string());
  EXPECT_EQ(json::parse(r.output.substr(r.output.find('{')))["across_cells"], 4);

  // The benchmark on this one city: time-window splits only.
  r = run_raysweep("ml " + city.string() + " --city-out " + out.string() + " --out " + (dir / "ml").string() +
                   " --max-train-s 20");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  std::ifstream in(dir / "ml/results.json");
  const json rows = json::parse(in);
  ASSERT_TRUE(rows.is_array());
  ASSERT_FALSE(rows.empty());
  std::set<std::string> tasks, models;
  for (const auto& row : rows) {
    for (const char* k : {"task", "model", "split", "metric", "value", "ci_low", "ci_high"})
      EXPECT_TRUE(row.contains(k)) << k << " missing in " << row.dump();
    tasks.insert(row["task"].get<std::string>());
    models.insert(row["model"].get<std::string>());
  }
  EXPECT_GE(tasks.size(), 2u);
  EXPECT_TRUE(models.count("tr37885")) << rows.dump();
  EXPECT_TRUE(fs::exists(dir / "ml/report.md"));
  fs::remove_all(dir);
}

// The benchmark's own checks (tests/python/test_ml.py): the TR 37.885
// formulas at hand-computed distances, metrics on hand-made cases, the frame
// bootstrap, a training step lowering the loss, and the whole pipeline on a
// synthetic run.
TEST(CliMl, PythonBenchmarkChecks) {
  const fs::path src = source_dir();
  auto r = run_command("PYTHONPATH='" + (src / "python").string() + ":" + (src / "tests/python").string() +
                       "' /usr/bin/python3 '" + (src / "tests/python/test_ml.py").string() + "'");
  EXPECT_EQ(r.exit_code, 0) << r.output;
}
