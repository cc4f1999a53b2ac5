// raysweep: scene preparation and V2X channel dataset generation.
#include <CLI/CLI.hpp>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <functional>
#include <iostream>
#include <map>
#include <memory>
#include <optional>
#include <sstream>

#include <tbb/global_control.h>

#include "generators/dataset/dataset_writer.hpp"
#include "generators/formats.hpp"
#include "meshkit/errors.hpp"
#include "pipeline/city_run.hpp"
#include "pipeline/cli/docs.hpp"
#include "pipeline/settings/config_file.hpp"
#include "pipeline/settings/settings.hpp"
#include "pipeline/settings/tables.hpp"
#include "pipeline/merge_stage.hpp"
#include "pipeline/mpi_run.hpp"
#include "pipeline/radiomap_stage.hpp"
#include "pipeline/render_stage.hpp"
#include "pipeline/scene_stage.hpp"
#include "pipeline/features_stage.hpp"
#include "pipeline/ns3_stage.hpp"
#include "pipeline/sinr_stage.hpp"
#include "pipeline/staged_output.hpp"
#include "pipeline/sweep_stage.hpp"
#include "pipeline/tradeoff/stage.hpp"
#include "pipeline/traffic_stage.hpp"
#include "pipeline/trace_inputs.hpp"
#include "pipeline/trace_stage.hpp"
#include "pipeline/vehicles_stage.hpp"
#include "pipeline/version.hpp"

namespace {

std::optional<raysweep::meshkit::Vec2> parse_offset(const std::string& s) {
  if (s.empty()) return std::nullopt;
  std::istringstream in(s);
  double x, y;
  char comma;
  if (!(in >> x >> comma >> y) || comma != ',') throw CLI::ValidationError("--net-offset", "expected X,Y");
  return raysweep::meshkit::Vec2{x, y};
}

// "passenger:8,truck:1,bus" -> {passenger: 8, truck: 1, bus: 1}.
std::map<std::string, double> parse_class_mix(const std::string& s) {
  std::map<std::string, double> mix;
  std::istringstream in(s);
  std::string item;
  while (std::getline(in, item, ',')) {
    const auto colon = item.find(':');
    mix[item.substr(0, colon)] = colon == std::string::npos ? 1.0 : std::stod(item.substr(colon + 1));
  }
  return mix;
}

namespace rp = raysweep::pipeline;
using Argv = std::vector<std::string>;

// `--set TABLE.KEY=VALUE` (settings/overrides.hpp), on the commands that trace.
void add_set_option(CLI::App* app, std::vector<std::string>& sets) {
  app->add_option("--set", sets, "TABLE.KEY=VALUE: change one setting of the config, checked like the file (repeatable)")
      ->allow_extra_args(false);
}

// One subcommand: its options, registered on the app, and what runs when it
// is the one given (returns the exit status). The options live in a
// shared_ptr the run function holds, so CLI11 can write into them.
struct Subcommand {
  CLI::App* app = nullptr;
  std::function<int(const Argv&)> run;
};

Subcommand scene_command(CLI::App& app) {
  struct Options {
    rp::SceneArgs scene;
    std::string config, offset;
    bool draco = false, no_draco = false, no_preview = false;
  };
  auto o = std::make_shared<Options>();
  auto* sc = app.add_subcommand("scene", "build a 3D radio scene from OSM + SUMO network, or import a Mitsuba scene");
  sc->add_option("--osm", o->scene.osm, "OSM extract (.osm, .osm.gz, .osm.bz2, .osm.pbf)");
  sc->add_option("--net", o->scene.net, "SUMO network (.net.xml[.gz]): projection and clipping area");
  sc->add_option("--proj", o->scene.proj, "explicit PROJ string instead of --net");
  sc->add_option("--net-offset", o->offset, "X,Y offset added after projection (with --proj)");
  sc->add_option("--from-mitsuba", o->scene.from_mitsuba, "import a Sionna RT / Mitsuba scene.xml");
  sc->add_option("--out", o->scene.out, "output scene folder")->required();
  sc->add_option("--config", o->config, "TOML config ([scene] table)");
  sc->add_flag("--draco", o->draco, "Draco-compress the glTF geometry");
  sc->add_flag("--no-draco", o->no_draco, "do not compress (overrides the config)");
  sc->add_flag("--no-preview", o->no_preview, "skip preview.png");
  return {sc, [o](const Argv& args) {
            auto& scene = o->scene;
            scene.net_offset = parse_offset(o->offset);
            if (o->draco) scene.draco = true;
            if (o->no_draco) scene.draco = false;
            scene.preview = !o->no_preview;
            const auto manifest = rp::run_scene_stage(scene, rp::load_settings(o->config), args);
            std::cout << scene.out << ": " << manifest["triangle_count"] << " triangles";
            if (manifest.contains("buildings"))
              std::cout << ", buildings kept " << manifest["buildings"]["kept"] << " / repaired "
                        << manifest["buildings"]["repaired"] << " / skipped " << manifest["buildings"]["skipped"];
            std::cout << "\n";
            return 0;
          }};
}

Subcommand vehicles_command(CLI::App& app) {
  struct Options {
    rp::VehiclesArgs vehicles;
    std::string config;
    bool no_preview = false;
  };
  auto o = std::make_shared<Options>();
  auto* vc = app.add_subcommand("vehicles", "build the vehicle library: one GLB per class and LOD + manifest");
  vc->add_option("--out", o->vehicles.out, "output library folder")->required();
  vc->add_option("--model", o->vehicles.models, "CLASS=FILE: use a glTF/GLB/OBJ/PLY/OFF model for a class");
  vc->add_option("--model-unit", o->vehicles.model_units,
                 "[CLASS=]UNIT: a model file's length unit (m, dm, cm, mm, in, ft); glTF is metres, OBJ/PLY/OFF "
                 "are guessed from the size otherwise");
  vc->add_option("--vtypes", o->vehicles.vtypes, "SUMO file with <vType> elements: one entry per vType");
  vc->add_option("--config", o->config, "TOML config ([vehicles] table)");
  vc->add_flag("--no-preview", o->no_preview, "skip preview.png");
  return {vc, [o](const Argv& args) {
            o->vehicles.preview = !o->no_preview;
            const auto manifest = rp::run_vehicles_stage(o->vehicles, rp::load_settings(o->config), args);
            std::cout << o->vehicles.out << ": " << manifest["vehicles"].size() << " vehicle models\n";
            return 0;
          }};
}

Subcommand trace_command(CLI::App& app) {
  auto trace = std::make_shared<rp::TraceArgs>();
  auto config = std::make_shared<std::string>();
  auto sets = std::make_shared<std::vector<std::string>>();
  auto* tc = app.add_subcommand("trace", "trace one snapshot: every antenna pair's paths, gains and LoS class");
  tc->add_option("--scene", trace->scene, "scene folder (from `raysweep scene`)")->required();
  tc->add_option("--vehicles", trace->vehicles, "vehicle library folder (default: built-in parametric models)");
  tc->add_option("--poses", trace->poses, "vehicle poses CSV: id,class,x,y,heading_deg,speed_mps[,z]");
  tc->add_option("--nodes", trace->nodes, "bare antennas CSV: id,x,y,z");
  tc->add_option("--out", trace->out, "output: .json (trace document) or .h5 (one-frame channel dataset)");
  tc->add_option("--mitsuba", trace->mitsuba,
                 "also write the snapshot for a peer tracer: Mitsuba/Sionna RT 2 scene with raysweep's material "
                 "parameters, every vehicle posed, and peer.json with the antennas (without --out: only that)");
  tc->add_option("--config", *config, "TOML config ([radio], [tracer], [materials.<name>])");
  tc->add_option("--lod", trace->lod, "vehicle LOD (default: each library entry's default)");
  tc->add_option("--exclude-objects", trace->exclude_objects,
                 "regex on static object ids to leave out (e.g. '^mesh-car_' for Sionna's placeholder cars)");
  tc->add_option("--cfr", trace->cfr, "add each pair's frequency response: 80211p or nr:MU:NRB (e.g. nr:2:10)");
  add_set_option(tc, *sets);
  return {tc, [trace, config, sets](const Argv& args) {
            const auto summary = rp::run_trace_stage(*trace, rp::load_settings(*config, *sets), args);
            if (trace->out.empty()) {
              std::cout << trace->mitsuba << ": " << summary["nodes"] << " antennas\n";
              return 0;
            }
            std::cout << trace->out << ": " << summary["pairs"] << " pairs (" << summary["los"] << " LOS, "
                      << summary["nlosv"] << " NLOSV, " << summary["nlos"] << " NLOS), " << summary["paths"]
                      << " paths\n";
            return 0;
          }};
}

Subcommand poses_command(CLI::App& app) {
  struct Options {
    std::string net, out, mix = "passenger";
    int count = 10;
    std::uint64_t seed = 1;
    double gap = 6.0;
  };
  auto o = std::make_shared<Options>();
  auto* pc = app.add_subcommand("poses", "place vehicles along a SUMO network's lanes (a poses CSV for `trace`)");
  pc->add_option("--net", o->net, "SUMO network (.net.xml[.gz])")->required();
  pc->add_option("--count", o->count, "number of vehicles")->check(CLI::PositiveNumber);
  pc->add_option("--seed", o->seed, "random seed (same seed, same poses)");
  pc->add_option("--classes", o->mix, "class mix, e.g. passenger:8,truck:1,bus:1");
  pc->add_option("--min-gap", o->gap, "spacing that sets the footprint margin (m)");
  pc->add_option("--out", o->out, "output CSV")->required();
  return {pc, [o](const Argv&) {
            const auto mix = parse_class_mix(o->mix);
            const auto net = raysweep::meshkit::read_sumo_network(o->net);
            const auto rows = rp::place_on_lanes(net, o->count, o->seed, mix, o->gap);
            rp::write_file_atomic(o->out, rp::poses_csv(rows));
            std::cout << o->out << ": " << rows.size() << " vehicles\n";
            return 0;
          }};
}

Subcommand traffic_command(CLI::App& app) {
  struct Options {
    rp::TrafficArgs traffic;
    std::string classes;
  };
  auto o = std::make_shared<Options>();
  auto& traffic = o->traffic;
  auto* tf = app.add_subcommand("traffic", "run SUMO (real traffic) into an FCD trace: from a .sumocfg or random trips");
  tf->add_option("--net", traffic.net, "SUMO network (.net.xml[.gz])")->required();
  auto* tf_cfg = tf->add_option("--sumocfg", traffic.sumocfg, "SUMO config with the demand (routes)");
  auto* tf_seed = tf->add_option("--trips-seed", traffic.seed, "generate random trips (randomTrips.py) with this seed");
  tf_cfg->excludes(tf_seed);
  tf->add_option("--seed", traffic.seed, "SUMO seed (with --sumocfg)");
  tf->add_option("--begin", traffic.begin_s, "simulation begin (s)");
  tf->add_option("--end", traffic.end_s, "simulation end (s)");
  tf->add_option("--step-length", traffic.step_length_s, "simulation step = FCD sampling (s)");
  tf->add_option("--period", traffic.period_s, "random trips: one trip every PERIOD seconds");
  tf->add_option("--fringe-factor", traffic.fringe_factor, "random trips: weight of trips starting at the fringe");
  tf->add_option("--classes", o->classes, "random trips: class mix, e.g. passenger:8,truck:1,bus:1");
  tf->add_option("--out", traffic.out, "output folder")->required();
  return {tf, [o](const Argv& args) {
            if (!o->classes.empty()) o->traffic.classes = parse_class_mix(o->classes);
            const auto rec = rp::run_traffic_stage(o->traffic, args);
            std::cout << o->traffic.out << ": " << rec["fcd"].get<std::string>() << " (" << rec["fcd_bytes"]
                      << " bytes)\n";
            return 0;
          }};
}

Subcommand sweep_command(CLI::App& app) {
  struct Options {
    rp::SweepArgs sweep;
    std::string config, shard;
    std::vector<std::string> sets;
  };
  auto o = std::make_shared<Options>();
  auto& sweep = o->sweep;
  auto* sw = app.add_subcommand("sweep", "trace an FCD trace frame by frame into an HDF5 channel dataset");
  sw->add_option("--scene", sweep.scene, "scene folder (from `raysweep scene`)")->required();
  sw->add_option("--vehicles", sweep.vehicles, "vehicle library folder (default: built-in parametric models)");
  sw->add_option("--fcd", sweep.fcd, "SUMO FCD trace (.xml or .xml.gz)")->required();
  sw->add_option("--vtypes", sweep.vtypes, ".sumocfg or route/additional files defining the FCD's vehicle types");
  sw->add_option("--rsus", sweep.rsus, "road-side units CSV: id,x,y,z (antenna position)");
  sw->add_option("--out", sweep.out, "output .h5")->required();
  sw->add_option("--config", o->config, "TOML config ([sweep], [radio], [tracer], [materials.<name>])");
  sw->add_flag("--resume", sweep.resume, "continue an interrupted run (keeps its committed blocks)");
  sw->add_option("--shard", o->shard, "I/N: trace only blocks b with b mod N = I into a shard file (raysweep merge)");
  add_set_option(sw, o->sets);
  return {sw, [o](const Argv& args) {
            auto& sweep = o->sweep;
            if (!o->shard.empty()) sweep.shard = rp::parse_shard(o->shard);
            const auto summary = rp::run_sweep_stage(sweep, rp::load_settings(o->config, o->sets), args);
            std::cout << sweep.out << ": " << summary["frames"] << " frames, " << summary["links"]
                      << " pair-channels (" << summary["traced_links"] << " traced), " << summary["bytes"]
                      << " bytes\n";
            return 0;
          }};
}

// What `raysweep run` prints when the city's stages are done; the exit status.
int print_city_summary(const rp::CityRunArgs& city, const nlohmann::json& summary) {
  if (summary.contains("shard")) {
    std::cout << "shard: " << summary["shard"].get<std::string>() << "\n";
    return 0;
  }
  if (!summary.contains("info")) {
    std::cout << "stages up to " << city.until << " done in " << summary["out"].get<std::string>() << "\n";
    return 0;
  }
  std::cout << "dataset: " << summary["dataset"].get<std::string>() << "\n";
  if (summary.contains("png")) std::cout << "picture: " << summary["png"].get<std::string>() << "\n";
  std::cout << raysweep::generators::format_dataset_info(summary["info"])
            << "read it in Python: PYTHONPATH=python /usr/bin/python3 python/example_dataset.py "
            << summary["dataset"].get<std::string>() << "\n";
  if (summary.contains("sinr_report")) {
    std::cout << "SINR outcomes:";
    for (const auto& f : summary["sinr_files"]) std::cout << " " << f.get<std::string>();
    std::cout << "\nSINR report: " << summary["sinr_report"].get<std::string>() << "/report.md (+ PNGs)\n";
  }
  if (summary.contains("ns3_table"))
    std::cout << "ns-3 table: " << summary["ns3_table"].get<std::string>() << " (ns3/README.md)\n";
  return summary["valid"].get<bool>() ? 0 : 1;
}

Subcommand run_command(CLI::App& app) {
  struct Options {
    rp::CityRunArgs city;
    std::string shard;
    bool mpi = false;
  };
  auto o = std::make_shared<Options>();
  auto& city = o->city;
  auto* rc = app.add_subcommand("run", "one city: scene -> vehicles -> traffic -> sweep (skips up-to-date stages)");
  rc->add_option("city", city.city, "city config (e.g. datasets/demo/city.toml)")->required();
  rc->add_option("--out", city.out, "output folder (default: [city] out or out/<name>)");
  rc->add_flag("--resume", city.resume, "continue an interrupted sweep");
  rc->add_flag("--force", city.force, "run every stage even when up to date");
  add_set_option(rc, city.set);
  rc->add_option("--until", city.until, "stop after this stage: scene, vehicles, traffic or sweep");
  rc->add_option("--shard", o->shard, "I/N: trace shard I of N into <out>/shards/dataset.I-of-N.h5 and stop");
  rc->add_flag("--merge", city.merge, "merge <out>/shards/ into <out>/dataset.h5, then run the later stages");
  rc->add_flag("--virtual", city.virtual_dataset, "with --merge or --mpi: an HDF5 virtual dataset over the shards");
  rc->add_flag("--mpi", o->mpi, "under mpirun: rank r traces shard r/N, rank 0 merges and runs the later stages");
  return {rc, [o](const Argv& args) {
            auto& city = o->city;
            if (!o->shard.empty()) city.shard = rp::parse_shard(o->shard);
            if (city.virtual_dataset && !city.merge && !o->mpi)
              throw std::invalid_argument("--virtual goes with --merge or --mpi");
            std::optional<nlohmann::json> result;
            if (o->mpi) {
              result = rp::run_city_mpi(city, args);
              if (!result) return 0;  // ranks other than 0: their shard is done
            } else {
              result = rp::run_city(city, args);
            }
            return print_city_summary(city, *result);
          }};
}

Subcommand merge_command(CLI::App& app) {
  auto merge = std::make_shared<rp::MergeArgs>();
  auto* mg = app.add_subcommand("merge", "merge the shard files of a sweep (--shard I/N) into one dataset");
  mg->add_option("shards", merge->shards, "shard files (every shard of the sweep once)")->required();
  mg->add_option("--out", merge->out, "output .h5")->required();
  mg->add_flag("--virtual", merge->virtual_dataset, "an HDF5 virtual dataset over the shard files instead of a copy");
  return {mg, [merge](const Argv&) {
            const auto summary = rp::run_merge_stage(*merge);
            std::cout << merge->out << ": " << summary["frames"] << " frames from " << summary["shards"]
                      << " shards (" << summary["blocks"] << " blocks)"
                      << (merge->virtual_dataset ? ", virtual dataset" : "") << ", " << summary["bytes"] << " bytes\n";
            return 0;
          }};
}

Subcommand sinr_command(CLI::App& app) {
  struct Options {
    rp::SinrArgs sinr;
    std::string config;
    std::uint64_t seed = 0;
    CLI::Option* seed_option = nullptr;
  };
  auto o = std::make_shared<Options>();
  auto& sinr = o->sinr;
  auto* sn = app.add_subcommand("sinr", "SINR outcomes of 802.11p and NR-V2X sharing one channel (HDF5)");
  sn->add_option("--channels", sinr.channels, "channel dataset .h5 (from `raysweep sweep`)")->required();
  sn->add_option("--out", sinr.out, "output SINR .h5")->required();
  sn->add_option("--channel-model", sinr.channel_model, "ray | tr36885 | tr37885-urban | tr37885-highway")
      ->capture_default_str();
  sn->add_flag("--los-from-ray", sinr.los_from_ray, "baselines: take the LoS class from the traced link");
  sn->add_option("--config", o->config, "TOML config ([sinr] table)");
  sn->add_option("--schedule-from", sinr.schedule_from,
                 "evaluate the transmissions of an earlier SINR file (same packets, another channel model)");
  sn->add_option("--rats-enabled", sinr.rats_enabled, "both | 80211p-only | nrv2x-only (overrides the config)");
  o->seed_option = sn->add_option("--seed", o->seed, "random seed (overrides the config)");
  return {sn, [o](const Argv& args) {
            auto& sinr = o->sinr;
            if (o->seed_option->count()) sinr.seed = o->seed;
            const auto summary = rp::run_sinr_stage(sinr, rp::load_settings(o->config), args);
            std::cout << sinr.out << ": " << summary["transmissions"] << " transmissions, " << summary["receptions"]
                      << " reception attempts (" << summary["decoded"] << " decoded)";
            for (const auto& [rat, v] : summary["prr"].items())
              std::cout << ", PRR " << rat << " " << v["prr"].get<double>();
            std::cout << "\n";
            return 0;
          }};
}

Subcommand ns3_table_command(CLI::App& app) {
  auto ns3 = std::make_shared<rp::Ns3TableArgs>();
  auto config = std::make_shared<std::string>();
  auto* nt = app.add_subcommand("ns3-table", "lookup table for ns-3's Raysweep models (HDF5) from a channel dataset");
  nt->add_option("--channels", ns3->channels, "channel dataset .h5 (from `raysweep sweep`)")->required();
  nt->add_option("--out", ns3->out, "output table .h5")->required();
  nt->add_option("--config", *config, "TOML config ([ns3] table)");
  return {nt, [ns3, config](const Argv& args) {
            const auto summary = rp::run_ns3_table_stage(*ns3, rp::load_settings(*config), args);
            std::cout << ns3->out << ": " << summary["frames"] << " frames, " << summary["pairs"] << " pair-frames, "
                      << summary["bytes"] << " bytes\n";
            return 0;
          }};
}

Subcommand features_command(CLI::App& app) {
  auto f = std::make_shared<rp::FeaturesArgs>();
  auto* fe = app.add_subcommand("features",
                                "per-link context for learning (the map along the link, the vehicles near it) from "
                                "the scene and the traffic, never from the tracer -> features.h5");
  fe->add_option("city", f->city, "city config (uses the outputs of `raysweep run CITY.toml`)");
  fe->add_option("--city-out", f->city_out, "the output folder of that run, when it ran with --out");
  fe->add_option("--dataset", f->dataset, "channel dataset .h5 (default: <city out>/dataset.h5)");
  fe->add_option("--scene", f->scene, "scene folder with scene.glb (default: <city out>/scene)");
  fe->add_option("--config", f->config, "TOML config ([features], [sweep] exclude_objects) without a city file");
  fe->add_option("--out", f->out, "output .h5 (default: features.h5 beside the dataset)");
  fe->add_flag("--force", f->force, "rebuild even when up to date");
  add_set_option(fe, f->set);
  return {fe, [f](const Argv& args) {
            const auto s = rp::run_features_stage(*f, args);
            std::cout << s["out"].get<std::string>() << ": "
                      << (s["up_to_date"].get<bool>() ? std::string("up to date")
                                                      : std::to_string(s["rows"].get<std::uint64_t>()) + " rows")
                      << "\n";
            return 0;
          }};
}

Subcommand ml_command(CLI::App& app) {
  auto m = std::make_shared<rp::MlArgs>();
  auto* ml = app.add_subcommand("ml",
                                "learning benchmark on the cities' runs: LoS class, path gain and packet tasks, "
                                "3GPP TR 37.885 baselines against learned models, held-out cities (python/ml)");
  ml->add_option("cities", m->cities, "city configs, after `raysweep run` of each")->required();
  ml->add_option("--city-out", m->city_outs, "a city's run folder when it ran with --out (once per city, in order)");
  ml->add_option("--out", m->out, "output folder: results.json, report.md, PNGs")->required();
  ml->add_option("--seed", m->seed, "seed of the models and the bootstrap")->capture_default_str();
  ml->add_option("--max-train-s", m->max_train_s, "wall-clock budget of the neural model's training, all splits")
      ->capture_default_str();
  ml->add_option("--max-links", m->max_links, "training links kept per city and split (evenly spaced)")
      ->capture_default_str();
  add_set_option(ml, m->set);
  return {ml, [m](const Argv& args) { return rp::run_ml_stage(*m, args); }};
}

Subcommand report_command(CLI::App& app) {
  auto report = std::make_shared<rp::ReportArgs>();
  auto* rp_app =
      app.add_subcommand("report", "SINR report: PNGs (SINR densities, PRR vs distance) and a comparison table");
  rp_app->add_option("--sinr", report->sinr, "SINR files; the first is the reference of the disagreement ratios")
      ->required();
  rp_app->add_option("--out", report->out, "output folder")->required();
  rp_app->add_option("--labels", report->labels, "comma-separated labels (default: the channel models)");
  return {rp_app, [report](const Argv&) {
            const auto r = rp::run_report_stage(*report);
            std::cout << r["table"].get<std::string>();
            for (const auto& png : r["pngs"]) std::cout << "picture: " << png.get<std::string>() << "\n";
            return 0;
          }};
}

Subcommand tradeoff_command(CLI::App& app) {
  struct Options {
    rp::TradeoffArgs tradeoff;
    bool no_chart = false;
  };
  auto o = std::make_shared<Options>();
  auto& tradeoff = o->tradeoff;
  auto* to = app.add_subcommand("tradeoff",
                                "tracer accuracy against cost: a grid of settings vs a high-effort reference "
                                "(CSV, JSON, PNG with the Pareto front)");
  to->add_option("city", tradeoff.city, "city config (uses the outputs of `raysweep run CITY.toml`)");
  to->add_option("--city-out", tradeoff.city_out, "the output folder of that run, when it ran with --out");
  to->add_option("--scene", tradeoff.scene, "scene folder (instead of a city file)");
  to->add_option("--vehicles", tradeoff.vehicles, "vehicle library folder (default: built-in parametric models)");
  to->add_option("--fcd", tradeoff.fcd, "SUMO FCD trace (instead of a city file)");
  to->add_option("--vtypes", tradeoff.vtypes, ".sumocfg or route/additional files defining the FCD's vehicle types");
  to->add_option("--rsus", tradeoff.rsus, "road-side units CSV: id,x,y,z");
  to->add_option("--config", tradeoff.config, "TOML config ([sweep], [radio], [tracer], [materials.<name>]): the base");
  to->add_option("--out", tradeoff.out, "output folder (default with a city: <city out>/tradeoff)");
  to->add_option("--snapshots", tradeoff.snapshots, "frames evenly spaced over the trace (default 4; --quick 2)")
      ->check(CLI::PositiveNumber);
  to->add_option("--rays", tradeoff.rays, "rays per source of the grid (default 1024,4096,16384)");
  to->add_option("--depths", tradeoff.depths, "maximum depths of the grid (default 1,2,3)");
  to->add_option("--simplify", tradeoff.simplify, "static simplification errors in metres (default 0.5,2)");
  to->add_option("--reference-rays", tradeoff.reference_rays, "reference rays per source (default 4 x the largest)")
      ->check(CLI::PositiveNumber);
  to->add_option("--reference-depth", tradeoff.reference_depth, "reference depth (default largest + 1, at most 5)")
      ->check(CLI::NonNegativeNumber);
  to->add_option("--repeats", tradeoff.repeats, "trace everything N times; a snapshot's time is its fastest (default 1)")
      ->check(CLI::PositiveNumber);
  to->add_option("--target-p95", tradeoff.target_p95_db,
                 "suggest the cheapest setting within this 95th-percentile gain error (dB)")
      ->capture_default_str();
  to->add_option("--coherence-window", tradeoff.coherence_window,
                 "frames swept with [sweep] coherence off and on, from the first with two vehicles (default 20; "
                 "--quick 4; 0: none)")
      ->check(CLI::Range(0, 1000));
  to->add_option("--lattice-frames", tradeoff.lattice_frames,
                 "the coherence window's [sweep] lattice_frames axis, e.g. 1,4 (default 1,2,4,8; --quick 1,4)");
  to->add_flag("--quick", tradeoff.quick, "a tiny grid: rays 256,1024, depths 1,2, simplify 2 m, 2 snapshots");
  to->add_flag("--no-chart", o->no_chart, "skip tradeoff.png");
  add_set_option(to, tradeoff.set);
  return {to, [o](const Argv& args) {
            auto& tradeoff = o->tradeoff;
            tradeoff.chart = !o->no_chart;
            const auto settings = tradeoff.city.empty() ? rp::load_settings(tradeoff.config, tradeoff.set)
                                                        : rp::load_city_settings(tradeoff.city, tradeoff.set);
            const auto r = rp::run_tradeoff_stage(tradeoff, settings, args);
            std::cout << r["table"].get<std::string>();
            std::cout << "tradeoff: " << r["csv"].get<std::string>() << ", " << r["json"].get<std::string>();
            if (r.contains("png")) std::cout << "\npicture: " << r["png"].get<std::string>();
            std::cout << "\nsuggested (cheapest with p95 gain error <= " << r["target_p95_db"].get<double>()
                      << " dB and LoS agreement >= 99%): "
                      << (r["suggested"].is_null() ? std::string("none") : r["suggested"].get<std::string>()) << "\n";
            return 0;
          }};
}

// Radio maps (OpenVDB) and Blender pictures: docs/radiomap.md.
Subcommand radiomap_command(CLI::App& app) {
  auto radiomap = std::make_shared<rp::RadioMapArgs>();
  auto config = std::make_shared<std::string>();
  auto* rm = app.add_subcommand("radiomap", "path gain from transmitters at every street voxel (OpenVDB)");
  rm->add_option("--scene", radiomap->scene, "scene folder (from `raysweep scene`)")->required();
  rm->add_option("--vehicles", radiomap->vehicles, "vehicle library folder (default: built-in parametric models)");
  rm->add_option("--poses", radiomap->poses, "vehicle poses CSV: id,class,x,y,heading_deg,speed_mps[,z]");
  rm->add_option("--net", radiomap->net, "SUMO network for region \"streets\" (default: the scene's)");
  rm->add_option("--tx", radiomap->tx, "transmitter ID,X,Y,Z[,POWER_DBM] (repeatable)");
  rm->add_option("--out", radiomap->out, "output .vdb")->required();
  rm->add_option("--config", *config, "TOML config ([radiomap], [radio], [tracer], [materials.<name>])");
  rm->add_option("--png", radiomap->png, "horizontal slice at antenna height (.png)");
  rm->add_option("--check", radiomap->check, "trace N voxels with the per-point tracer and report the agreement")
      ->check(CLI::NonNegativeNumber);
  return {rm, [radiomap, config](const Argv& args) {
            const auto r = rp::run_radiomap_stage(*radiomap, rp::load_settings(*config), args);
            std::cout << radiomap->out << ": " << r["voxels"] << " voxels (" << r["region"].get<std::string>()
                      << "), " << r["tx"].size() << " transmitter(s) in " << r["solve_s"].get<double>() << " s\n";
            if (!r["check"].is_null())
              std::cout << "vs trace at " << r["check"]["voxels"] << " voxels: |diff| median "
                        << r["check"]["median_abs_db"].get<double>() << " dB, p90 "
                        << r["check"]["p90_abs_db"].get<double>() << " dB\n";
            if (r.contains("png")) std::cout << "picture: " << r["png"].get<std::string>() << "\n";
            return 0;
          }};
}

Subcommand render_command(CLI::App& app) {
  auto render = std::make_shared<rp::RenderArgs>();
  auto* rn = app.add_subcommand("render", "render the scene, vehicles, paths and a radio map with Blender (PNG)");
  rn->add_option("--scene", render->scene, "scene folder (from `raysweep scene`)")->required();
  rn->add_option("--vehicles", render->vehicles, "vehicle library folder (default: built-in parametric models)");
  rn->add_option("--poses", render->poses, "vehicle poses CSV");
  rn->add_option("--paths", render->paths, "paths to draw: a `raysweep trace` JSON");
  rn->add_option("--radiomap", render->radiomap, "radio map to draw (.vdb from `raysweep radiomap`)");
  rn->add_option("--out", render->out, "output .png")->required();
  rn->add_option("--camera", render->camera, "top | oblique | X,Y,Z:TX,TY,TZ")->capture_default_str();
  rn->add_option("--size", render->size, "W,H in pixels")->capture_default_str();
  rn->add_option("--samples", render->samples, "Cycles samples per pixel")->check(CLI::PositiveNumber)
      ->capture_default_str();
  return {rn, [render](const Argv& args) {
            const auto r = rp::run_render_stage(*render, args);
            std::cout << render->out << ": rendered in " << r["seconds"].get<double>() << " s\n";
            return 0;
          }};
}

// The declared schema of city.toml (pipeline/settings/tables.hpp).
Subcommand config_command(CLI::App& app) {
  struct Options {
    std::string file;
    std::vector<std::string> sets;
    bool docs = false;
  };
  auto o = std::make_shared<Options>();
  auto* cf = app.add_subcommand("config", "check a city/stage config and print its effective settings (JSON)");
  cf->add_option("file", o->file, "city.toml or stage config (none: the defaults)");
  cf->add_flag("--docs", o->docs, "print the schema as Markdown (docs/config.md)");
  add_set_option(cf, o->sets);
  return {cf, [o](const Argv&) {
            if (o->docs) std::cout << rp::config_docs();
            else std::cout << rp::effective_config(o->file, o->sets).dump(2) << "\n";
            return 0;
          }};
}

Subcommand validate_command(CLI::App& app) {
  auto file = std::make_shared<std::string>();
  auto* vd = app.add_subcommand("validate", "check an HDF5 dataset against the schema (schemas/)");
  vd->add_option("file", *file, "dataset .h5")->required();
  return {vd, [file](const Argv&) {
            const std::string& check_file = *file;
            const auto problems = raysweep::generators::validate_dataset(check_file);
            for (const auto& p : problems) std::cout << check_file << ": " << p << "\n";
            if (!problems.empty()) {
              std::cout << check_file << ": INVALID (" << problems.size() << " problems)\n";
              return 1;
            }
            const auto info = raysweep::generators::dataset_info(check_file);
            std::cout << check_file << ": valid (" << info.value("format", std::string()) << " schema "
                      << info.value("schema_version", std::string()) << ")\n";
            return 0;
          }};
}

Subcommand info_command(CLI::App& app) {
  struct Options {
    std::string file;
    bool json = false;
  };
  auto o = std::make_shared<Options>();
  auto* inf = app.add_subcommand("info", "summarise an HDF5 dataset");
  inf->add_option("file", o->file, "dataset .h5")->required();
  inf->add_flag("--json", o->json, "print the summary as JSON");
  return {inf, [o](const Argv&) {
            const auto info = raysweep::generators::dataset_info(o->file);
            if (o->json) std::cout << info.dump(1) << "\n";
            else std::cout << raysweep::generators::format_dataset_info(info);
            return 0;
          }};
}

// `raysweep help`: every subcommand's options; with --docs docs/cli.md.
Subcommand help_command(CLI::App& app) {
  auto docs = std::make_shared<bool>(false);
  auto* hp = app.add_subcommand("help", "every subcommand's options, or the command-line reference (docs/cli.md)");
  hp->add_flag("--docs", *docs, "print the command-line reference as Markdown (docs/cli.md is this)");
  return {hp, [docs, &app](const Argv&) {
            // app.help() would answer for the subcommand parsed: this one.
            std::cout << (*docs ? rp::cli_docs(app)
                                : app.get_formatter()->make_help(&app, app.get_name(), CLI::AppFormatMode::All));
            return 0;
          }};
}

// In the order `raysweep --help` and docs/cli.md list them: a city's run,
// its stages in order, the tools around them.
using MakeSubcommand = Subcommand (*)(CLI::App&);
constexpr MakeSubcommand kSubcommands[] = {
    run_command,      scene_command,    vehicles_command, traffic_command,   sweep_command,    merge_command,
    trace_command,    poses_command,    sinr_command,     report_command,    ns3_table_command, radiomap_command,
    render_command,   tradeoff_command, features_command, ml_command,        config_command,   validate_command,
    info_command,     help_command};

// Bad input (files, configs, arguments) exits 2, any other failure 1.
int run_reporting_errors(const Subcommand& command, const Argv& args) {
  try {
    return command.run(args);
  } catch (const raysweep::meshkit::InputError& e) {
    spdlog::error("{}", e.what());
    return 2;
  } catch (const raysweep::pipeline::ConfigError& e) {
    spdlog::error("{}", e.what());
    return 2;
  } catch (const std::invalid_argument& e) {
    spdlog::error("{}", e.what());
    return 2;
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return 1;
  }
}

}  // namespace

int main(int argc, char** argv) {
  // Logs go to stderr so stdout stays clean for summaries a script may parse.
  spdlog::set_default_logger(spdlog::stderr_color_mt("raysweep"));
  spdlog::set_pattern("[%H:%M:%S] %^%l%$ %v");
  const Argv args(argv, argv + argc);

  CLI::App app{"raysweep: city-scale V2X ray-tracing datasets"};
  app.set_version_flag("--version", std::string(raysweep::kVersion) + " (" + raysweep::kGitHash + ")");
  app.require_subcommand(1);
  bool quiet = false;
  app.add_flag("-q,--quiet", quiet, "only warnings and errors");
  int threads = 0;
  app.add_option("-j,--threads", threads, "worker threads (default: all cores; results do not depend on it)")
      ->check(CLI::NonNegativeNumber);
  std::vector<Subcommand> commands;
  for (const MakeSubcommand make : kSubcommands) commands.push_back(make(app));

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // --help and --version exit 0; usage errors (unknown option, bad value) 2, like any bad input.
    return app.exit(e) == 0 ? 0 : 2;
  }
  if (quiet) spdlog::set_level(spdlog::level::warn);
  std::optional<tbb::global_control> thread_limit;
  if (threads > 0) thread_limit.emplace(tbb::global_control::max_allowed_parallelism, threads);

  for (const auto& command : commands)
    if (command.app->parsed()) return run_reporting_errors(command, args);
  return 0;
}
