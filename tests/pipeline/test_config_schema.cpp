// The declared config schema (pipeline/settings/tables*.cpp): its errors per value
// type, defaults, the recipes. docs/config.md and the provenance it feeds,
// through the CLI: tests/cli/test_cli_config.cpp.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <fstream>
#include <functional>
#include <regex>

#include "pipeline/city_run.hpp"
#include "pipeline/settings/config_file.hpp"
#include "pipeline/settings/settings.hpp"
#include "pipeline/settings/tables.hpp"
#include "pipeline/ns3_stage.hpp"
#include "pipeline/radiomap_stage.hpp"
#include "pipeline/sinr_stage.hpp"
#include "pipeline/sweep_stage.hpp"
#include "pipeline/traffic_stage.hpp"
#include "pipeline/vehicles_stage.hpp"
#include "test_util.hpp"

using namespace raysweep::pipeline;
using namespace raysweep::test;
using json = nlohmann::json;

namespace {

// The ConfigError that reading `toml` gives, "" when it reads fine.
std::string error_of(const std::string& toml) {
  const fs::path dir = scratch_dir("cfg");
  write_text(dir / "c.toml", toml);
  try {
    effective_config((dir / "c.toml").string());
  } catch (const ConfigError& e) {
    const std::string msg = e.what();
    const std::string prefix = (dir / "c.toml").string();
    // Errors start with the file; the rest is compared whole below.
    EXPECT_EQ(msg.rfind(prefix, 0), 0u) << msg;
    return msg.substr(prefix.size());
  }
  return "";
}

}  // namespace

TEST(ConfigSchema, IntegerErrors) {
  EXPECT_EQ(error_of("[tracer]\nrays_per_source = -3\n"),
            ":2: tracer.rays_per_source: expected an integer >= 1, got -3");
  EXPECT_EQ(error_of("[tracer]\n\nmax_depth = 17\n"), ":3: tracer.max_depth: expected an integer in [0, 16], got 17");
  EXPECT_EQ(error_of("[tracer]\nmax_depth = \"3\"\n"), ":2: tracer.max_depth: expected an integer in [0, 16], got \"3\"");
  EXPECT_EQ(error_of("[tracer]\nmax_depth = 2.5\n"), ":2: tracer.max_depth: expected an integer in [0, 16], got 2.5");
  EXPECT_EQ(error_of("[tracer]\nmax_depth = true\n"), ":2: tracer.max_depth: expected an integer in [0, 16], got true");
  // Unsigned fields reject negatives and values beyond their type, never wrap.
  EXPECT_EQ(error_of("[sweep]\nblock_frames = 4294967296\n"),
            ":2: sweep.block_frames: expected an integer >= 1, got 4294967296");
  EXPECT_EQ(error_of("[sinr]\nseed = -1\n"), ":2: sinr.seed: expected an integer >= 0, got -1");
  // An integral float is an integer, as TOML readers commonly take it; a huge
  // one is no integer (and no undefined cast on the way).
  EXPECT_EQ(error_of("[tracer]\nmax_depth = 2.0\n"), "");
  EXPECT_EQ(error_of("[sinr]\nseed = 1e30\n"), ":2: sinr.seed: expected an integer >= 0, got 1e+30");
  EXPECT_EQ(error_of("[sinr]\nseed = -inf\n"), ":2: sinr.seed: expected an integer >= 0, got -inf");
}

TEST(ConfigSchema, NumberErrors) {
  EXPECT_EQ(error_of("[radio]\nfrequency_hz = \"5.9 GHz\"\n"),
            ":2: radio.frequency_hz: expected a finite number > 0, got \"5.9 GHz\"");
  EXPECT_EQ(error_of("[radio]\nfrequency_hz = 0\n"), ":2: radio.frequency_hz: expected a finite number > 0, got 0");
  EXPECT_EQ(error_of("[radio]\ntx_power_dbm = nan\n"), ":2: radio.tx_power_dbm: expected a finite number, got nan");
  EXPECT_EQ(error_of("[radio]\ntx_power_dbm = inf\n"), ":2: radio.tx_power_dbm: expected a finite number, got inf");
  EXPECT_EQ(error_of("[sinr]\nnr_fraction = 1.5\n"), ":2: sinr.nr_fraction: expected a finite number in [0, 1], got 1.5");
  EXPECT_EQ(error_of("[vehicles]\nlod_ratios = [1.0, 0]\n"),
            ":2: vehicles.lod_ratios: expected a finite number in (0, 1], got 0");
  EXPECT_EQ(error_of("[radio]\nfrequency_hz = 6\n"), "");  // integers are numbers
}

TEST(ConfigSchema, BooleanAndStringErrors) {
  EXPECT_EQ(error_of("[scene]\nground = 1\n"), ":2: scene.ground: expected true or false, got 1");
  EXPECT_EQ(error_of("[scene]\nground = \"yes\"\n"), ":2: scene.ground: expected true or false, got \"yes\"");
  EXPECT_EQ(error_of("[sweep]\nexclude_objects = 3\n"), ":2: sweep.exclude_objects: expected a string, got 3");
  EXPECT_EQ(error_of("[city]\nname = [\"a\"]\nnet = \"n.xml\"\n"), ":2: city.name: expected a string, got an array of 1 value");
}

TEST(ConfigSchema, EnumErrorsSuggestTheClosestValue) {
  EXPECT_EQ(error_of("[tracer]\ncandidates = \"imag\"\n"),
            ":2: tracer.candidates: expected \"image\", \"sbr\" or \"exhaustive\", got \"imag\" (did you mean \"image\"?)");
  EXPECT_EQ(error_of("[tracer]\ndiffuse_integration = \"voxels\"\n"),
            ":2: tracer.diffuse_integration: expected \"tiles\", \"rays\" or \"hybrid\", got \"voxels\"");
  EXPECT_EQ(error_of("[sweep]\noutside = 1\n"), ":2: sweep.outside: expected \"error\" or \"drop\", got 1");
  EXPECT_EQ(error_of("[sinr]\nrat_by_vtype = { bus = \"lte\" }\n"),
            ":2: sinr.rat_by_vtype.bus: expected \"80211p\", \"nrv2x\" or \"none\", got \"lte\"");
  // Names checked by a parser: materials, classes, models, OFDM grids.
  EXPECT_EQ(error_of("[scene]\nground_material = \"concrte\"\n"),
            ":2: scene.ground_material: unknown ITU-R P.2040 material 'concrte' (did you mean 'concrete'?)");
  EXPECT_EQ(error_of("[vehicles]\nclasses = [\"bus\", \"buss\"]\n"),
            ":2: vehicles.classes: unknown vehicle class 'buss' (did you mean 'bus'?)");
  EXPECT_NE(error_of("[sinr]\nmodels = [\"winner\"]\n").find(":2: sinr.models: unknown channel model 'winner'"),
            std::string::npos);
  EXPECT_NE(error_of("[sweep]\ncfr = \"nr:9:1\"\n").find(":2: sweep.cfr: "), std::string::npos);
}

TEST(ConfigSchema, ArrayMapAndTableErrors) {
  EXPECT_EQ(error_of("[sweep]\nids = [\"a\", 2]\n"), ":2: sweep.ids: expected a string, got 2");
  EXPECT_EQ(error_of("[sweep]\nids = \"a\"\n"), ":2: sweep.ids: expected an array of strings, got \"a\"");
  EXPECT_EQ(error_of("[sweep]\narea = [0, 0, 10]\n"),
            ":2: sweep.area: expected an array of 4 numbers, got an array of 3 values");
  EXPECT_EQ(error_of("[sweep]\narea = [10, 0, 0, 10]\n"),
            ":2: sweep.area: expected [xmin, ymin, xmax, ymax] with xmin < xmax and ymin < ymax, got an array of 4 values");
  EXPECT_EQ(error_of("[sinr]\nmodels = []\n"),
            ":2: sinr.models: expected an array of strings (at least 1), got an empty array");
  EXPECT_EQ(error_of("[sinr]\nwifi_bler = [[0, 1], [5]]\n"),
            ":2: sinr.wifi_bler: expected an array of 2 numbers, got an array of 1 value");
  EXPECT_EQ(error_of("[traffic]\nclasses = { bus = \"many\" }\n"),
            ":2: traffic.classes.bus: expected a finite number >= 0, got \"many\"");
  EXPECT_EQ(error_of("[scene]\nmaterial_map = 3\n"),
            ":2: scene.material_map: expected a table of OSM value = string, got 3");
  EXPECT_EQ(error_of("[vehicles.class.bus]\nlenght = 12\n"),
            ":2: vehicles.class.bus.lenght: unknown key (did you mean 'length'?)");
  EXPECT_EQ(error_of("[vehicles.class.bus]\nantenna = [0, 1]\n"),
            ":2: vehicles.class.bus.antenna: expected an array of 3 numbers, got an array of 2 values");
  EXPECT_EQ(error_of("[[vehicles.rules]]\npattern = \"x\"\n"), ":1: vehicles.rules: missing key 'material'");
  EXPECT_EQ(error_of("[[vehicles.rules]]\nfield = \"name\"\nmaterial = \"glass\"\n"),
            ":2: vehicles.rules.field: expected \"part\", \"material\" or \"any\", got \"name\"");
  EXPECT_EQ(error_of("[materials.concrete]\nthickness_m = \"thick\"\n"),
            ":2: materials.concrete.thickness_m: expected a finite number >= 0, got \"thick\"");
  EXPECT_EQ(error_of("[materials.concrte]\neps_r = 4\n"),
            ":1: materials.concrte: unknown material 'concrte' (did you mean 'concrete'?)");
  EXPECT_EQ(error_of("[city]\nosm = \"a.osm\"\n"), ":1: city: missing key 'name'");
  EXPECT_EQ(error_of("[city]\nname = \"\"\nnet = \"n.xml\"\n"), ":2: city.name: expected a non-empty string, got \"\"");
}

TEST(ConfigSchema, UnknownKeysAndTablesSuggestTheClosestName) {
  EXPECT_EQ(error_of("[sinr]\nseed = 1\nnr_fractoin = 0.5\n"),
            ":3: sinr.nr_fractoin: unknown key (did you mean 'nr_fraction'?)");
  EXPECT_EQ(error_of("[tracer]\nmax_dept = 3\n"), ":2: tracer.max_dept: unknown key (did you mean 'max_depth'?)");
  EXPECT_EQ(error_of("[tracer]\ncompletely_else = 3\n"), ":2: tracer.completely_else: unknown key");
  EXPECT_EQ(error_of("[radiomap]\nvoxel = 1\n"), ":2: radiomap.voxel: unknown key (did you mean 'voxel_m'?)");
  EXPECT_EQ(error_of("[scnee]\n"), ":1: unknown table [scnee] (did you mean [scene]?)");
  EXPECT_EQ(error_of("[report]\n"), ":1: unknown table [report]");
  EXPECT_EQ(error_of("[sweep.extra]\n"), ":1: sweep.extra: unknown key");
  EXPECT_EQ(error_of("sweep = 3\n"), ":1: sweep: expected a table [sweep], got 3");
  EXPECT_EQ(error_of("[scene\n"), ":1: Error while parsing table header: expected ']', saw '\\n'");
}

TEST(ConfigSchema, EveryTableIsCheckedByEveryLoader) {
  // A typo in [radiomap] fails `raysweep scene` too, before any work is done.
  const fs::path dir = scratch_dir("cfg");
  write_text(dir / "c.toml", "[scene]\nground = true\n[radiomap]\nvoxl_m = 1\n");
  try {
    load_settings((dir / "c.toml").string());
    FAIL() << "no error";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find(":4: radiomap.voxl_m: unknown key (did you mean 'voxel_m'?)"), std::string::npos)
        << e.what();
  }
}

TEST(ConfigSchema, ErrorsAcrossKeysNameTheLineToo) {
  const fs::path dir = scratch_dir("cfg");
  const std::string c = (dir / "c.toml").string();
  auto error = [&](const std::function<void()>& load) {
    try {
      load();
    } catch (const ConfigError& e) {
      return std::string(e.what()).substr(c.size());
    }
    return std::string();
  };
  write_text(c, "[sweep]\nbegin_s = 10\nend_s = 5\n");
  EXPECT_EQ(error([&] { load_settings(c); }), ":3: sweep.end_s: must not be before sweep.begin_s");
  write_text(dir / "n.xml", "");
  write_text(c, "[city]\nname = \"x\"\nnet = \"n.xml\"\nosm = \"n.xml\"\nmitsuba = \"n.xml\"\n");
  EXPECT_EQ(error([&] { load_city_settings(c); }), ":5: city.mitsuba: give exactly one of city.osm and city.mitsuba");
  write_text(c, "[city]\nname = \"x\"\nnet = \"n.xml\"\n");
  EXPECT_EQ(error([&] { load_city_settings(c); }), ":1: city.osm: give exactly one of city.osm and city.mitsuba");
}

TEST(ConfigSchema, DefaultsAreFilledIn) {
  const fs::path dir = scratch_dir("cfg");
  write_text(dir / "c.toml", "[tracer]\nmax_depth = 2\n[materials.glass]\nthickness_m = 0.004\n[scene]\n");
  const json eff = effective_config((dir / "c.toml").string());
  const json defaults = effective_config("");
  // Every table and every declared key, given or not.
  for (const auto* t : config_tables()) {
    ASSERT_TRUE(eff.contains(t->name())) << t->name();
    if (t->name() == "materials") continue;  // its keys are names
    for (const auto& k : t->docs()) EXPECT_TRUE(eff[t->name()].contains(k.key)) << t->name() << "." << k.key;
  }
  EXPECT_EQ(eff["tracer"]["max_depth"], 2);
  EXPECT_EQ(eff["tracer"]["rays_per_source"], 6144);
  EXPECT_EQ(eff["scene"], defaults["scene"]);
  EXPECT_EQ(eff["materials"]["glass"]["thickness_m"], 0.004);
  EXPECT_TRUE(eff["materials"]["glass"]["eps_r"].is_null());  // the built-in value at the carrier
  EXPECT_EQ(defaults["sweep"]["block_frames"], 50);
  EXPECT_EQ(defaults["sinr"]["models"], json::array({"ray"}));
  // The loaders' structs hold the same values.
  const TraceSettings s = load_settings((dir / "c.toml").string()).trace;
  EXPECT_EQ(s.tracer.max_depth, 2);
  EXPECT_EQ(s.tracer.rays_per_source, 6144);
  ASSERT_TRUE(s.tracer.materials.at("glass").thickness_m.has_value());
  EXPECT_EQ(*s.tracer.materials.at("glass").thickness_m, 0.004);
}

TEST(ConfigSchema, EffectiveConfigIsWhatTheLoadersRead) {
  // What each stage records in its provenance (to_json) is the schema's
  // writing of the struct it loaded: the same tables, keys and values as
  // `raysweep config` prints.
  const std::string demo = (source_dir() / "datasets/demo/city.toml").string();
  const json eff = effective_config(demo);
  EXPECT_EQ(load_settings(demo).scene.to_json(), eff["scene"]);
  EXPECT_EQ(load_settings(demo).vehicles.to_json(), eff["vehicles"]);
  EXPECT_EQ(load_settings(demo).sweep.to_json(), eff["sweep"]);
  const json trace = load_settings(demo).trace.to_json();
  for (const char* t : {"radio", "tracer", "materials"}) EXPECT_EQ(trace[t], eff[t]) << t;
  EXPECT_EQ(load_settings(demo).sinr.to_json(), eff["sinr"]);
  EXPECT_EQ(load_settings(demo).ns3.to_json(), eff["ns3"]);
  EXPECT_EQ(load_settings(demo).radiomap.to_json(), eff["radiomap"]);
  // The recipe's values arrive in the structs.
  EXPECT_EQ(load_settings(demo).sweep.begin_s, 60);
  EXPECT_EQ(load_settings(demo).sweep.options.block_frames, 50u);
  EXPECT_EQ(load_settings(demo).trace.radio.antenna.pattern, raysweep::tracer::AntennaPattern::short_dipole);
  EXPECT_EQ(load_settings(demo).sinr.models.size(), 4u);
  EXPECT_EQ(load_settings(demo).radiomap.tx.at(0).id, "rsu1");
  EXPECT_EQ(load_city_settings(demo).city.name, "demo");
  EXPECT_EQ(eff["traffic"]["seed"], 42);
  EXPECT_EQ(eff["traffic"]["classes"]["passenger"], 8.0);
}

TEST(ConfigSchema, EveryRecipeParses) {
  std::vector<fs::path> files = {source_dir() / "docs/ns3_compare.toml"};
  for (const auto& e : fs::directory_iterator(source_dir() / "datasets"))
    if (fs::exists(e.path() / "city.toml")) files.push_back(e.path() / "city.toml");
  ASSERT_GE(files.size(), 4u);
  for (const auto& f : files) {
    SCOPED_TRACE(f.string());
    const json eff = effective_config(f.string());
    EXPECT_EQ(eff.size(), config_tables().size());
    EXPECT_NO_THROW(load_settings(f.string()));  // every stage table
  }
}

TEST(ConfigSchema, NoStageReadsTomlByHand) {
  // Only the schema touches toml++: a stage reading a key itself would
  // bypass the checks, the docs and the provenance.
  const std::regex toml_use(R"(toml::|toml\+\+)");
  for (const auto& e : fs::directory_iterator(source_dir() / "pipeline")) {
    const std::string name = e.path().filename().string();
    if (name.rfind("config_schema.", 0) == 0 || name.rfind("config_tables.", 0) == 0) continue;
    if (e.path().extension() != ".cpp" && e.path().extension() != ".hpp") continue;
    EXPECT_FALSE(std::regex_search(read_text(e.path()), toml_use)) << name << " uses toml++ directly";
  }
}

TEST(ConfigSchema, SetChangesTheParsedFileAndIsCheckedLikeIt) {
  const fs::path dir = scratch_dir("cfg");
  const std::string c = (dir / "c.toml").string();
  write_text(c, "[tracer]\nmax_depth = 2\n[sweep]\nbegin_s = 10\n");
  // Values are TOML; a word that is not is a string; a later option wins.
  const std::vector<std::string> sets = {"tracer.max_depth=3",       "tracer.diffuse=false", "radio.antenna=halfwave",
                                         "sweep.ids=[\"a\", \"b\"]", "sweep.end_s=40",       "tracer.max_depth = 4",
                                         "materials.glass.eps_r=5.5", "sweep.cfr=nr:2:10"};
  const Settings s = load_settings(c, sets);
  EXPECT_EQ(s.trace.tracer.max_depth, 4);
  EXPECT_FALSE(s.trace.tracer.diffuse);
  EXPECT_EQ(s.trace.radio.antenna.pattern, raysweep::tracer::AntennaPattern::halfwave_dipole);
  EXPECT_EQ(s.sweep.ids, (std::vector<std::string>{"a", "b"}));
  EXPECT_EQ(s.sweep.begin_s, 10);  // the file's other keys stay
  EXPECT_EQ(s.sweep.end_s, 40);
  ASSERT_TRUE(s.trace.tracer.materials.at("glass").eps_r.has_value());
  EXPECT_EQ(*s.trace.tracer.materials.at("glass").eps_r, 5.5);
  ASSERT_TRUE(s.sweep.cfr.has_value());
  EXPECT_EQ(s.sweep.cfr->n_rb, 10);
  // The effective config holds them (with or without a file); provenance records the options too.
  EXPECT_EQ(s.effective["tracer"]["max_depth"], 4);
  EXPECT_EQ(s.effective["sweep"]["cfr"], "nr:2:10");
  EXPECT_EQ(effective_config(c, {"sweep.end_s=40"})["sweep"]["begin_s"], 10);
  EXPECT_EQ(effective_config("", {"sweep.end_s=40"})["sweep"]["end_s"], 40);
  EXPECT_EQ(load_settings("", {"ns3.subcarriers_per_band=2"}).ns3.subcarriers_per_band, 2u);
  json prov = json::object();
  s.record_sets(prov);
  EXPECT_EQ(prov["set"], json(sets));
  // Errors name the option where a file names its line.
  auto error = [&](const std::vector<std::string>& bad) {
    try {
      load_settings(c, bad);
    } catch (const ConfigError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_EQ(error({"tracer.max_depth=17"}),
            "--set tracer.max_depth: tracer.max_depth: expected an integer in [0, 16], got 17");
  EXPECT_EQ(error({"tracer.max_dept=3"}),
            "--set tracer.max_dept: tracer.max_dept: unknown key (did you mean 'max_depth'?)");
  EXPECT_EQ(error({"tracr.max_depth=3"}), "--set tracr.max_depth: unknown table [tracr] (did you mean [tracer]?)");
  EXPECT_EQ(error({"tracer.diffuse=maybe"}), "--set tracer.diffuse: tracer.diffuse: expected true or false, got \"maybe\"");
  EXPECT_EQ(error({"sweep.end_s=5"}), "--set sweep.end_s: sweep.end_s: must not be before sweep.begin_s");
  EXPECT_EQ(error({"tracer"}), "--set tracer: expected TABLE.KEY=VALUE");
  EXPECT_EQ(error({"max_depth=3"}), "--set max_depth=3: expected TABLE.KEY=VALUE");
}
