#include "pipeline/city_run.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <sstream>

#include "generators/formats.hpp"
#include "pipeline/merge_stage.hpp"
#include "pipeline/preview.hpp"
#include "pipeline/radiomap_stage.hpp"
#include "pipeline/provenance.hpp"
#include "pipeline/scene_stage.hpp"
#include "pipeline/ns3_stage.hpp"
#include "pipeline/sinr_stage.hpp"
#include "pipeline/staged_output.hpp"
#include "pipeline/sweep_stage.hpp"
#include "pipeline/traffic_stage.hpp"
#include "pipeline/vehicles_stage.hpp"
#include "pipeline/version.hpp"

namespace raysweep::pipeline {

namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

// The effective tables (schema order, defaults filled in) that configure a
// stage, as text for its stamp: a comment or a key written out at its default
// value does not rerun the stage, a changed value does.
std::string tables_text(const json& effective, const std::vector<std::string>& names) {
  std::string s;
  for (const auto& n : names) s += "[" + n + "]\n" + effective.at(n).dump() + "\n";
  return s;
}

class Stamps {
 public:
  explicit Stamps(fs::path dir) : dir_(std::move(dir)) {}
  bool up_to_date(const std::string& stage, const std::string& key, const fs::path& output) const {
    std::ifstream in(dir_ / (stage + ".json"));
    if (!in || !fs::exists(output)) return false;
    try {
      return json::parse(in).value("key", "") == key;
    } catch (...) {
      return false;
    }
  }
  void mark(const std::string& stage, const std::string& key) const {
    fs::create_directories(dir_);
    write_file_atomic(dir_ / (stage + ".json"), json{{"key", key}}.dump() + "\n");
  }

 private:
  fs::path dir_;
};

}  // namespace

namespace {

// SUMO's run: [traffic] with the city's network and demand (the time span
// was checked by load_city_settings).
TrafficArgs traffic_args(const Settings& s, const std::string& out) {
  TrafficArgs a = s.traffic.sumo;
  a.net = s.city.net;
  a.sumocfg = s.city.sumocfg;
  a.out = out;
  return a;
}

// The FCD and vType files of a traffic stage's folder; returns its end time (< 0 unknown).
double read_traffic_record(const fs::path& traffic_dir, std::string& fcd, std::vector<std::string>& vtype_files) {
  std::ifstream in(traffic_dir / "traffic.json");
  const json rec = json::parse(in);
  fcd = (traffic_dir / rec.at("fcd").get<std::string>()).string();
  for (const auto& f : rec.at("vtype_files")) {
    const fs::path p(f.get<std::string>());
    vtype_files.push_back(p.is_absolute() ? p.string() : (traffic_dir / p).string());
  }
  return rec.value("end_s", -1.0);
}

// The shard files of <out>/shards for a merge: those of `count` shards (0:
// the one count there is), each traced by `run --shard` from the inputs and
// settings the city has now (its stamp).
std::vector<std::string> shard_files(const fs::path& dir, std::uint32_t count, const fs::path& stamp_dir,
                                     const std::string& sweep_key, const std::string& hint) {
  static const std::regex name(R"(dataset\.(\d+)-of-(\d+)\.h5)");
  std::map<std::uint32_t, std::vector<fs::path>> by_count;
  if (fs::is_directory(dir))
    for (const auto& e : fs::directory_iterator(dir)) {
      std::smatch m;
      const std::string f = e.path().filename().string();
      if (std::regex_match(f, m, name)) by_count[static_cast<std::uint32_t>(std::stoul(m[2]))].push_back(e.path());
    }
  if (count == 0 && by_count.size() > 1) {
    std::string counts;
    for (const auto& [n, files] : by_count) counts += (counts.empty() ? "" : ", ") + std::to_string(n);
    throw std::invalid_argument(dir.string() + ": shards of different sweeps split " + counts +
                                " ways; remove the stale ones");
  }
  if (count == 0 && !by_count.empty()) count = by_count.begin()->first;
  auto files = by_count[count];
  if (files.empty())
    throw std::invalid_argument(dir.string() + ": no shard files" +
                                (count ? " of " + std::to_string(count) + " shards" : std::string()) + hint);
  std::sort(files.begin(), files.end());
  const Stamps stamps(stamp_dir);
  std::vector<std::string> out;
  for (const auto& f : files) {
    const std::string stage = "sweep." + f.stem().string().substr(std::string("dataset.").size());
    if (!stamps.up_to_date(stage, sweep_key, f))
      throw std::invalid_argument(f.string() + ": traced from other inputs or settings than the city has now (or not "
                                  "by `raysweep run --shard`); trace that shard again");
    out.push_back(f.string());
  }
  return out;
}

}  // namespace

CityOutputs city_outputs(const Settings& settings, const std::string& out_dir) {
  const CitySettings& city = settings.city;
  const std::string& city_file = settings.file;
  CityOutputs o;
  const fs::path out = out_dir.empty() ? fs::path(city.out) : fs::path(out_dir);
  o.out = out.string();
  o.scene = (out / "scene").string();
  o.vehicles = (out / "vehicles").string();
  o.rsus = city.rsus;
  const std::string hint = "; run `raysweep run " + city_file + (out_dir.empty() ? "" : " --out " + out_dir) + "` first";
  if (!fs::exists(out / "scene" / "scene.glb"))
    throw std::invalid_argument(o.scene + ": no scene.glb (the scene of city " + city.name + ")" + hint);
  if (!fs::exists(out / "vehicles" / "manifest.json"))
    throw std::invalid_argument(o.vehicles + ": no vehicle library (manifest.json)" + hint);
  if (!city.fcd.empty()) {
    o.fcd = city.fcd;
  } else {
    const fs::path traffic = out / "traffic";
    if (!fs::exists(traffic / "traffic.json"))
      throw std::invalid_argument(traffic.string() + ": no traffic (traffic.json)" + hint);
    read_traffic_record(traffic, o.fcd, o.vtypes);
    if (!fs::exists(o.fcd)) throw std::invalid_argument(o.fcd + ": FCD trace not found" + hint);
  }
  if (!city.sumocfg.empty() && o.vtypes.empty()) o.vtypes.push_back(city.sumocfg);
  return o;
}

namespace {

// One `raysweep run`: the city, its checked settings, the stamps of its
// stages, and the summary the stages add to.
struct CityRun {
  CityRun(const CityRunArgs& a, const std::vector<std::string>& v)
      : args(a), argv(v), settings(load_city_settings(a.city, a.set)), city(settings.city), root(settings.effective) {}

  const CityRunArgs& args;
  const std::vector<std::string>& argv;
  Settings settings;  // every table, read once
  CitySettings city;
  fs::path out;
  json root;  // the effective config
  int stages = 4;
  // Shards and the merge share the scene, the vehicle library and the traffic
  // built once before them (`--until traffic`): several processes building
  // them at once into one folder would race, and SUMO need not run N times.
  bool shared_only = false;
  std::string out_opt;  // " --out OUT" when given, for the hints
  Stamps stamps{fs::path()};
  std::string version = std::string(kVersion) + "+" + kGitHash;
  json summary;

  // Whether a stage may be skipped as up to date (shards and the merge never rebuild the shared stages).
  bool reuse() const { return !args.force || shared_only; }

  std::invalid_argument not_built(const std::string& stage, const fs::path& dir) const {
    return std::invalid_argument(dir.string() + ": the " + stage + " stage of city " + city.name +
                                 " is not built or out of date; run `raysweep run " + args.city + out_opt +
                                 " --until traffic` once before the shards and the merge");
  }
};

std::string file_hash(const std::string& p) { return p.empty() ? std::string() : sha256_file(p); }

// Every table is checked before the first stage runs: a typo in [sweep]
// must not surface after an hour of scene building.
CityRun start_city_run(const CityRunArgs& args, const std::vector<std::string>& argv) {
  CityRun r(args, argv);
  r.out = args.out.empty() ? fs::path(r.city.out) : fs::path(args.out);
  const SinrSettings& sinr = r.settings.sinr;
  r.stages = sinr.present && sinr.enabled ? 5 : 4;
  if (args.shard && args.merge) throw std::invalid_argument("--shard and --merge: trace every shard first, then merge once");
  if (!args.until.empty() && (args.shard || args.merge))
    throw std::invalid_argument("--until with --shard or --merge: build the shared stages first, then the shards");
  if (!args.until.empty() && args.until != "scene" && args.until != "vehicles" && args.until != "traffic" &&
      args.until != "sweep")
    throw std::invalid_argument("--until " + args.until + ": expected scene, vehicles, traffic or sweep");
  r.shared_only = args.shard || args.merge;
  r.out_opt = args.out.empty() ? "" : " --out " + args.out;
  r.stamps = Stamps(r.out / ".stamps");
  r.summary = {{"city", r.city.name}, {"out", r.out.string()}};
  return r;
}

void city_scene(CityRun& r, const fs::path& scene_dir) {
  const std::string scene_key = sha256_text(r.version + tables_text(r.root, {"scene"}) + file_hash(r.city.osm) +
                                            file_hash(r.city.net) + file_hash(r.city.mitsuba));
  if (r.reuse() && r.stamps.up_to_date("scene", scene_key, scene_dir / "scene.glb")) {
    spdlog::info("[1/{}] scene: up to date ({})", r.stages, scene_dir.string());
    return;
  }
  if (r.shared_only) throw r.not_built("scene", scene_dir);
  spdlog::info("[1/{}] scene: building {}", r.stages, scene_dir.string());
  SceneArgs s;
  if (r.city.mitsuba.empty()) {
    s.osm = r.city.osm;
    s.net = r.city.net;
  } else {
    s.from_mitsuba = r.city.mitsuba;
  }
  s.out = scene_dir.string();
  run_scene_stage(s, r.settings, r.argv);
  r.stamps.mark("scene", scene_key);
}

void city_vehicles(CityRun& r, const fs::path& vehicles_dir) {
  const std::string vehicles_key = sha256_text(r.version + tables_text(r.root, {"vehicles"}));
  if (r.reuse() && r.stamps.up_to_date("vehicles", vehicles_key, vehicles_dir / "manifest.json")) {
    spdlog::info("[2/{}] vehicles: up to date ({})", r.stages, vehicles_dir.string());
    return;
  }
  if (r.shared_only) throw r.not_built("vehicles", vehicles_dir);
  spdlog::info("[2/{}] vehicles: building {}", r.stages, vehicles_dir.string());
  VehiclesArgs v;
  v.out = vehicles_dir.string();
  run_vehicles_stage(v, r.settings, r.argv);
  r.stamps.mark("vehicles", vehicles_key);
}

// What the sweep reads of the traffic: the FCD trace, its vType files and
// the simulation's end (< 0 unknown).
struct CityTraffic {
  std::string fcd;
  std::vector<std::string> vtype_files;
  double eta_end = -1;
};

CityTraffic city_traffic(CityRun& r, const fs::path& traffic_dir) {
  CityTraffic t{r.city.fcd, {}, -1};
  if (!t.fcd.empty()) {
    spdlog::info("[3/{}] traffic: using the FCD trace {}", r.stages, t.fcd);
  } else {
    const TrafficArgs a = traffic_args(r.settings, traffic_dir.string());
    const std::string traffic_key =
        sha256_text(r.version + tables_text(r.root, {"traffic"}) + file_hash(r.city.net) + file_hash(r.city.sumocfg));
    if (r.reuse() && r.stamps.up_to_date("traffic", traffic_key, traffic_dir / "traffic.json")) {
      spdlog::info("[3/{}] traffic: up to date ({})", r.stages, traffic_dir.string());
    } else {
      if (r.shared_only) throw r.not_built("traffic", traffic_dir);
      spdlog::info("[3/{}] traffic: running SUMO into {}", r.stages, traffic_dir.string());
      run_traffic_stage(a, r.argv);
      r.stamps.mark("traffic", traffic_key);
    }
    t.eta_end = read_traffic_record(traffic_dir, t.fcd, t.vtype_files);
  }
  if (!r.city.sumocfg.empty() && t.vtype_files.empty()) t.vtype_files.push_back(r.city.sumocfg);
  return t;
}

// The sweep into <out>/dataset.h5: traced, merged from the shards, or one
// shard traced (then the run stops: returns false).
bool city_sweep(CityRun& r, const CityTraffic& t, const fs::path& scene_dir, const fs::path& vehicles_dir,
                const fs::path& dataset) {
  std::string sweep_key = r.version + tables_text(r.root, {"sweep", "radio", "tracer", "materials"}) +
                          file_hash(t.fcd) + file_hash(r.city.rsus) + file_hash((scene_dir / "scene.glb").string()) +
                          file_hash((vehicles_dir / "manifest.json").string());
  for (const auto& f : t.vtype_files) sweep_key += file_hash(f);
  sweep_key = sha256_text(sweep_key);
  SweepArgs sweep_args;
  sweep_args.scene = scene_dir.string();
  sweep_args.vehicles = vehicles_dir.string();
  sweep_args.fcd = t.fcd;
  sweep_args.vtypes = t.vtype_files;
  sweep_args.rsus = r.city.rsus;
  sweep_args.out = dataset.string();
  sweep_args.resume = r.args.resume;
  sweep_args.eta_end_s = t.eta_end;
  const auto& args = r.args;
  if (args.shard) {
    // One shard: its blocks into <out>/shards/, stamped on its own so that a
    // rerun (an MPI job restarted with --resume) skips the finished shards.
    const fs::path file = r.out / "shards" / shard_file_name(*args.shard);
    const std::string stage = "sweep." + args.shard->name();
    if (!args.force && r.stamps.up_to_date(stage, sweep_key, file)) {
      spdlog::info("[4/{}] sweep shard {}: up to date ({})", r.stages, args.shard->name(), file.string());
    } else {
      spdlog::info("[4/{}] sweep shard {}: tracing its blocks of {} into {}", r.stages, args.shard->name(), t.fcd,
                   file.string());
      sweep_args.out = file.string();
      sweep_args.shard = args.shard;
      r.summary["sweep"] = run_sweep_stage(sweep_args, r.settings, r.argv);
      r.stamps.mark(stage, sweep_key);
    }
    r.summary["shard"] = file.string();
    return false;
  }
  if (args.merge) {
    const auto files = shard_files(r.out / "shards", args.merge_count, r.out / ".stamps", sweep_key,
                                   "; run `raysweep run " + args.city + r.out_opt + " --shard I/N` for I = 0..N-1 first");
    spdlog::info("[4/{}] sweep: merging {} shard files of {} into {}", r.stages, files.size(),
                 (r.out / "shards").string(), dataset.string());
    MergeArgs m;
    m.shards = files;
    m.out = dataset.string();
    m.virtual_dataset = args.virtual_dataset;
    r.summary["merge"] = run_merge_stage(m);
    r.stamps.mark("sweep", sweep_key);
  } else if (!args.force && r.stamps.up_to_date("sweep", sweep_key, dataset)) {
    spdlog::info("[4/{}] sweep: up to date ({})", r.stages, dataset.string());
  } else {
    spdlog::info("[4/{}] sweep: tracing {} into {}", r.stages, t.fcd, dataset.string());
    r.summary["sweep"] = run_sweep_stage(sweep_args, r.settings, r.argv);
    r.stamps.mark("sweep", sweep_key);
  }
  return true;
}

// The picture people look at first (path gain against distance per LoS
// class), the dataset's summary, and its problems against the schema.
std::vector<std::string> city_dataset(CityRun& r, const fs::path& dataset) {
  const fs::path png = r.out / "dataset.png";
  if (!fs::exists(png) || fs::last_write_time(png) < fs::last_write_time(dataset)) {
    if (run_python_script("example_dataset.py", {dataset.string(), "--png", png.string()}))
      r.summary["png"] = png.string();
    else
      spdlog::warn("{}: no picture (python3 with h5py and matplotlib needed)", png.string());
  } else {
    r.summary["png"] = png.string();
  }
  r.summary["dataset"] = dataset.string();
  r.summary["info"] = generators::dataset_info(dataset.string());
  auto problems = generators::validate_dataset(dataset.string());
  for (const auto& p : problems) spdlog::error("{}: {}", dataset.string(), p);
  return problems;
}

// The reference model first; the others reuse its transmissions (shared
// schedule) so that their disagreement with it is measured on the same packets.
std::vector<std::pair<std::string, SinrArgs>> sinr_runs(const CityRun& r, const fs::path& dataset,
                                                        const fs::path& sinr_dir) {
  const SinrSettings& sinr = r.settings.sinr;
  std::vector<std::pair<std::string, SinrArgs>> runs;
  for (std::size_t i = 0; i < sinr.models.size(); ++i) {
    SinrArgs a;
    a.channels = dataset.string();
    a.channel_model = generators::sinr::channel_model_name(sinr.models[i].kind);
    a.los_from_ray = sinr.models[i].los_from_ray;
    a.out = (sinr_dir / (sinr.models[i].label() + ".h5")).string();
    if (i > 0 && sinr.shared_schedule) a.schedule_from = runs.front().second.out;
    runs.emplace_back(sinr.models[i].label(), a);
  }
  if (sinr.isolated_runs)
    for (const char* only : {"nrv2x-only", "80211p-only"}) {
      SinrArgs a = runs.front().second;
      a.rats_enabled = only;
      a.out = (sinr_dir / (sinr.models.front().label() + "-" + only + ".h5")).string();
      runs.emplace_back(sinr.models.front().label() + "-" + only, a);
    }
  return runs;
}

// SINR outcomes and their report, when the city asks for them.
void city_sinr(CityRun& r, const fs::path& dataset, std::vector<std::string>& problems) {
  const fs::path sinr_dir = r.out / "sinr";
  const fs::path report_dir = sinr_dir / "report";
  const std::string sinr_key = sha256_text(r.version + tables_text(r.root, {"sinr"}) + file_hash(dataset.string()));
  const auto runs = sinr_runs(r, dataset, sinr_dir);
  // Up to date only while every outcome file is there too, not just the report.
  const bool outcomes_present =
      std::all_of(runs.begin(), runs.end(), [](const auto& run) { return fs::exists(run.second.out); });
  if (!r.args.force && outcomes_present && r.stamps.up_to_date("sinr", sinr_key, report_dir / "report.md")) {
    spdlog::info("[5/{}] sinr: up to date ({})", r.stages, sinr_dir.string());
  } else {
    json sinr_summary = json::array();
    for (std::size_t i = 0; i < runs.size(); ++i) {
      spdlog::info("[5/{}] sinr: {} ({}/{})", r.stages, runs[i].first, i + 1, runs.size());
      sinr_summary.push_back(run_sinr_stage(runs[i].second, r.settings, r.argv));
    }
    r.summary["sinr"] = sinr_summary;
    ReportArgs report;
    report.out = report_dir.string();
    std::string labels;
    for (const auto& [label, a] : runs) {
      report.sinr.push_back(a.out);
      labels += (labels.empty() ? "" : ",") + label;
    }
    report.labels = labels;
    run_report_stage(report);
    r.stamps.mark("sinr", sinr_key);
  }
  json files = json::array();
  for (const auto& [label, a] : runs) {
    files.push_back(a.out);
    for (const auto& p : generators::validate_dataset(a.out)) {
      spdlog::error("{}: {}", a.out, p);
      problems.push_back(a.out + ": " + p);
    }
  }
  r.summary["sinr_files"] = files;
  r.summary["sinr_report"] = report_dir.string();
}

// The ns-3 lookup table, when the city asks for it.
void city_ns3(CityRun& r, const fs::path& dataset, std::vector<std::string>& problems) {
  const fs::path table = r.out / "ns3" / "table.h5";
  const std::string ns3_key = sha256_text(r.version + tables_text(r.root, {"ns3"}) + file_hash(dataset.string()));
  if (!r.args.force && r.stamps.up_to_date("ns3", ns3_key, table)) {
    spdlog::info("ns3: up to date ({})", table.string());
  } else {
    run_ns3_table_stage({dataset.string(), table.string()}, r.settings, r.argv);
    r.stamps.mark("ns3", ns3_key);
  }
  for (const auto& p : generators::validate_dataset(table.string())) {
    spdlog::error("{}: {}", table.string(), p);
    problems.push_back(table.string() + ": " + p);
  }
  r.summary["ns3_table"] = table.string();
}

}  // namespace

json run_city(const CityRunArgs& args, const std::vector<std::string>& argv) {
  CityRun r = start_city_run(args, argv);
  const fs::path scene_dir = r.out / "scene", vehicles_dir = r.out / "vehicles";
  city_scene(r, scene_dir);
  if (args.until == "scene") return r.summary;
  city_vehicles(r, vehicles_dir);
  if (args.until == "vehicles") return r.summary;
  const CityTraffic traffic = city_traffic(r, r.out / "traffic");
  if (args.until == "traffic") return r.summary;
  const fs::path dataset = r.out / "dataset.h5";
  if (!city_sweep(r, traffic, scene_dir, vehicles_dir, dataset)) return r.summary;
  if (args.until == "sweep") {
    r.summary["dataset"] = dataset.string();
    return r.summary;
  }
  std::vector<std::string> problems = city_dataset(r, dataset);
  // Radio map ([radiomap]) and the Blender picture: docs/radiomap.md.
  const Settings& s = r.settings;
  if (s.radiomap.present)
    r.summary["radiomap"] = run_city_radiomap(s, r.out.string(), scene_dir.string(), r.city.net, args.force, argv);
  if (s.sinr.present && s.sinr.enabled) city_sinr(r, dataset, problems);
  if (s.ns3.present && s.ns3.enabled) city_ns3(r, dataset, problems);
  r.summary["valid"] = problems.empty();
  return r.summary;
}

}  // namespace raysweep::pipeline
