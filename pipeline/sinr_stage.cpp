#include "pipeline/sinr_stage.hpp"

#include <spdlog/spdlog.h>
#include <toml++/toml.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "generators/dataset_schema.hpp"
#include "generators/sinr/channel_trace.hpp"
#include "generators/sinr/outcomes.hpp"
#include "generators/sinr/sinr_file.hpp"
#include "meshkit/errors.hpp"
#include "pipeline/config.hpp"
#include "pipeline/preview.hpp"
#include "pipeline/provenance.hpp"
#include "pipeline/toml_fields.hpp"
#include "pipeline/version.hpp"

namespace raysweep::pipeline {

namespace fs = std::filesystem;
using json = nlohmann::json;
using namespace toml_fields;
namespace gs = generators::sinr;

std::string SinrModel::label() const {
  return std::string(gs::channel_model_name(kind)) + (los_from_ray ? "+los-from-ray" : "");
}

SinrModel parse_sinr_model(const std::string& s) {
  SinrModel m;
  std::string name = s;
  const std::string suffix = "+los-from-ray";
  if (name.size() > suffix.size() && name.compare(name.size() - suffix.size(), suffix.size(), suffix) == 0) {
    m.los_from_ray = true;
    name.resize(name.size() - suffix.size());
  }
  m.kind = gs::parse_channel_model(name);
  if (m.los_from_ray && m.kind == gs::ChannelModelKind::ray)
    throw std::invalid_argument("'ray+los-from-ray' makes no sense: the ray model is the traced channel");
  return m;
}

namespace {

std::vector<std::pair<double, double>> curve(const std::string& path, const std::string& key, const toml::node& n) {
  const toml::array* a = n.as_array();
  if (!a) throw ConfigError(where(path, key, n) + ": expected [[sinr_db, bler], ...]");
  std::vector<std::pair<double, double>> out;
  for (const auto& e : *a) {
    const toml::array* p = e.as_array();
    if (!p || p->size() != 2) throw ConfigError(where(path, key, e) + ": expected a [sinr_db, bler] pair");
    out.emplace_back(number(path, key, *p->get(0)), number(path, key, *p->get(1)));
  }
  return out;
}

json curve_json(const std::vector<std::pair<double, double>>& c) {
  json j = json::array();
  for (const auto& [x, y] : c) j.push_back({x, y});
  return j;
}

}  // namespace

json SinrSettings::to_json() const {
  const auto& c = config;
  json rat_by_vtype = json::object();
  for (const auto& [k, v] : c.rats.by_vtype) rat_by_vtype[k] = gs::rat_name(v);
  json models_j = json::array();
  for (const auto& m : models) models_j.push_back(m.label());
  return {
      {"seed", c.seed},
      {"begin_s", c.begin_s},
      {"end_s", c.end_s},
      {"nr_fraction", c.rats.nr_fraction},
      {"rat_by_vtype", rat_by_vtype},
      {"nr_ids", c.rats.nr_ids},
      {"wifi_ids", c.rats.wifi_ids},
      {"silent_ids", c.rats.silent_ids},
      {"active_vehicles", c.rats.active_vehicles},
      {"rats_enabled", c.rats.enabled},
      {"cam", c.cam.enabled},
      {"cam_bytes", c.cam.bytes},
      {"cam_low_frequency_bytes", c.cam.low_frequency_bytes},
      {"cam_t_gen_min_s", c.cam.t_gen_min_s},
      {"cam_t_gen_max_s", c.cam.t_gen_max_s},
      {"cam_check_period_s", c.cam.check_period_s},
      {"cpm", c.cpm.enabled},
      {"cpm_period_s", c.cpm.period_s},
      {"cpm_bytes", c.cpm.bytes},
      {"wifi_data_rate_bps", c.wifi.data_rate_bps},
      {"wifi_access_category", c.wifi_mac.access_category},
      {"wifi_cca_signal_dbm", c.wifi_mac.cca_signal_dbm},
      {"wifi_cca_energy_dbm", c.wifi_mac.cca_energy_dbm},
      {"nr_bandwidth_hz", c.nr.bandwidth_hz},
      {"nr_numerology", c.nr.numerology},
      {"nr_subchannel_rbs", c.nr.subchannel_rbs},
      {"nr_mcs", c.nr.mcs},
      {"nr_data_symbols", c.nr.data_symbols},
      {"nr_reservation_period_s", c.nr_mac.reservation_period_s},
      {"nr_selection", c.nr_mac.sensing ? "sensing" : "random"},
      {"nr_sensing_threshold_dbm", c.nr_mac.sensing_threshold_dbm},
      {"nr_keep_probability", c.nr_mac.keep_probability},
      {"nr_retransmissions", c.nr_mac.retransmissions},
      {"tx_power_dbm", c.tx_power_dbm},
      {"sensitivity_dbm", c.sensitivity_dbm},
      {"sinr_threshold_db", c.sinr_threshold_db},
      {"noise_figure_db", c.noise_figure_db},
      {"gain_threshold_db", c.gain_threshold_db},
      {"wifi_bler", curve_json(c.wifi_bler)},
      {"nr_bler", curve_json(c.nr_bler)},
      {"prr_range_m", c.prr_range_m},
      {"max_receiver_distance_m", c.max_receiver_distance_m},
      {"shadowing", stochastic.shadowing},
      {"antenna_height_m", stochastic.antenna_height_m},
      {"blocker_height_m", stochastic.blocker_height_m},
      {"decorrelation_m", stochastic.decorrelation_m},
      {"models", models_j},
      {"schedule", shared_schedule ? "shared" : "own"},
      {"isolated_runs", isolated_runs},
  };
}

SinrSettings load_sinr_settings(const std::string& path) {
  SinrSettings s;
  if (path.empty()) return s;
  load_scene_config(path);  // validates the file and its top-level sections
  const toml::table root = toml::parse_file(path);
  const toml::table* t = root["sinr"].as_table();
  if (!t) return s;
  s.present = true;
  auto& c = s.config;
  for (auto&& entry : *t) {  // no structured binding: clang < 16 cannot capture one in the lambdas
    const toml::node& node = entry.second;
    const std::string key(entry.first.str()), full = "sinr." + key;
    auto num = [&] { return number(path, full, node); };
    auto positive = [&] {
      const double v = num();
      if (!(v > 0)) throw ConfigError(where(path, full, node) + ": must be > 0");
      return v;
    };
    auto count = [&] {
      const int v = integer(path, full, node);
      if (v < 0) throw ConfigError(where(path, full, node) + ": must be >= 0");
      return v;
    };
    auto rat = [&](const toml::node& n) {
      try {
        return gs::parse_rat(text(path, full, n));
      } catch (const std::invalid_argument& e) {
        throw ConfigError(where(path, full, n) + ": " + e.what());
      }
    };
    if (key == "enabled") s.enabled = boolean(path, full, node);
    else if (key == "seed") c.seed = static_cast<std::uint64_t>(count());
    else if (key == "begin_s") c.begin_s = num();
    else if (key == "end_s") c.end_s = num();
    else if (key == "nr_fraction") c.rats.nr_fraction = num();
    else if (key == "rat_by_vtype") {
      const toml::table* m = node.as_table();
      if (!m) throw ConfigError(where(path, full, node) + ": expected a table { vtype = \"nrv2x\" | \"80211p\" | \"none\" }");
      for (auto&& [vt, r] : *m) c.rats.by_vtype[std::string(vt.str())] = rat(r);
    } else if (key == "nr_ids") c.rats.nr_ids = strings(path, full, node);
    else if (key == "wifi_ids") c.rats.wifi_ids = strings(path, full, node);
    else if (key == "silent_ids") c.rats.silent_ids = strings(path, full, node);
    else if (key == "active_vehicles") c.rats.active_vehicles = static_cast<std::uint32_t>(count());
    else if (key == "rats_enabled") c.rats.enabled = text(path, full, node);
    else if (key == "cam") c.cam.enabled = boolean(path, full, node);
    else if (key == "cam_bytes") c.cam.bytes = static_cast<std::uint32_t>(count());
    else if (key == "cam_low_frequency_bytes") c.cam.low_frequency_bytes = static_cast<std::uint32_t>(count());
    else if (key == "cam_t_gen_min_s") c.cam.t_gen_min_s = positive();
    else if (key == "cam_t_gen_max_s") c.cam.t_gen_max_s = positive();
    else if (key == "cam_check_period_s") c.cam.check_period_s = positive();
    else if (key == "cpm") c.cpm.enabled = boolean(path, full, node);
    else if (key == "cpm_period_s") c.cpm.period_s = positive();
    else if (key == "cpm_bytes") c.cpm.bytes = static_cast<std::uint32_t>(count());
    else if (key == "wifi_data_rate_bps") c.wifi.data_rate_bps = positive();
    else if (key == "wifi_access_category") c.wifi_mac.access_category = text(path, full, node);
    else if (key == "wifi_cca_signal_dbm") c.wifi_mac.cca_signal_dbm = num();
    else if (key == "wifi_cca_energy_dbm") c.wifi_mac.cca_energy_dbm = num();
    else if (key == "nr_bandwidth_hz") c.nr.bandwidth_hz = positive();
    else if (key == "nr_numerology") c.nr.numerology = count();
    else if (key == "nr_subchannel_rbs") c.nr.subchannel_rbs = count();
    else if (key == "nr_mcs") c.nr.mcs = count();
    else if (key == "nr_data_symbols") c.nr.data_symbols = count();
    else if (key == "nr_reservation_period_s") c.nr_mac.reservation_period_s = positive();
    else if (key == "nr_selection") {
      const std::string v = text(path, full, node);
      if (v != "random" && v != "sensing") throw ConfigError(where(path, full, node) + ": expected \"random\" or \"sensing\"");
      c.nr_mac.sensing = v == "sensing";
    } else if (key == "nr_sensing_threshold_dbm") c.nr_mac.sensing_threshold_dbm = num();
    else if (key == "nr_keep_probability") c.nr_mac.keep_probability = num();
    else if (key == "nr_retransmissions") c.nr_mac.retransmissions = count();
    else if (key == "tx_power_dbm") c.tx_power_dbm = num();
    else if (key == "sensitivity_dbm") c.sensitivity_dbm = num();
    else if (key == "sinr_threshold_db") c.sinr_threshold_db = num();
    else if (key == "noise_figure_db") c.noise_figure_db = num();
    else if (key == "gain_threshold_db") c.gain_threshold_db = num();
    else if (key == "wifi_bler") c.wifi_bler = curve(path, full, node);
    else if (key == "nr_bler") c.nr_bler = curve(path, full, node);
    else if (key == "prr_range_m") c.prr_range_m = positive();
    else if (key == "max_receiver_distance_m") c.max_receiver_distance_m = num();
    else if (key == "shadowing") s.stochastic.shadowing = boolean(path, full, node);
    else if (key == "antenna_height_m") s.stochastic.antenna_height_m = positive();
    else if (key == "blocker_height_m") s.stochastic.blocker_height_m = positive();
    else if (key == "decorrelation_m") s.stochastic.decorrelation_m = positive();
    else if (key == "models") {
      s.models.clear();
      for (const auto& m : strings(path, full, node)) {
        try {
          s.models.push_back(parse_sinr_model(m));
        } catch (const std::invalid_argument& e) {
          throw ConfigError(where(path, full, node) + ": " + e.what());
        }
      }
      if (s.models.empty()) throw ConfigError(where(path, full, node) + ": needs at least one model");
    } else if (key == "schedule") {
      const std::string v = text(path, full, node);
      if (v != "shared" && v != "own") throw ConfigError(where(path, full, node) + ": expected \"shared\" or \"own\"");
      s.shared_schedule = v == "shared";
    } else if (key == "isolated_runs") s.isolated_runs = boolean(path, full, node);
    else
      throw ConfigError(where(path, full, node) + ": unknown key");
  }
  try {
    c.check();
  } catch (const std::invalid_argument& e) {
    throw ConfigError(path + ": [sinr]: " + e.what());
  }
  return s;
}

json run_sinr_stage(const SinrArgs& args, const std::vector<std::string>& argv) {
  const auto t_start = std::chrono::steady_clock::now();
  SinrSettings settings = load_sinr_settings(args.config);
  const SinrModel model = parse_sinr_model(args.channel_model + (args.los_from_ray ? "+los-from-ray" : ""));
  gs::SinrConfig cfg = settings.config;
  if (args.seed) cfg.seed = *args.seed;
  if (!args.rats_enabled.empty()) cfg.rats.enabled = args.rats_enabled;
  settings.config = cfg;
  cfg.check();
  settings.stochastic.seed = cfg.seed;
  settings.stochastic.los_from_ray = model.los_from_ray;

  spdlog::info("sinr: loading {}", args.channels);
  const gs::ChannelTrace trace = gs::ChannelTrace::load(args.channels);
  cfg.wifi.carrier_hz = trace.carrier_hz();
  cfg.nr.carrier_hz = trace.carrier_hz();
  const auto channel = gs::make_channel_model(model.kind, trace, settings.stochastic);

  std::vector<gs::Rat> rats;
  std::vector<gs::Transmission> reused;
  if (!args.schedule_from.empty()) {
    auto sched = gs::read_sinr_schedule(args.schedule_from);
    if (sched.nodes.size() != trace.nodes().size())
      throw meshkit::InputError(args.schedule_from, "/nodes",
                                std::to_string(sched.nodes.size()) + " nodes but " + args.channels + " has " +
                                    std::to_string(trace.nodes().size()) + " (a schedule from another dataset?)");
    for (std::size_t n = 0; n < sched.nodes.size(); ++n) {
      if (sched.nodes[n].id != trace.nodes()[n].id)
        throw meshkit::InputError(args.schedule_from, "/nodes/id",
                                  "node " + std::to_string(n) + " is '" + sched.nodes[n].id + "' but '" +
                                      trace.nodes()[n].id + "' in " + args.channels);
      rats.push_back(sched.nodes[n].rat);
    }
    reused = std::move(sched.transmissions);
  } else {
    rats = gs::assign_rats(trace, cfg.rats, cfg.seed);
  }

  json config = settings.to_json();
  config["channel_model"] = model.label();
  std::vector<InputFile> inputs{{"channels", args.channels}};
  if (!args.config.empty()) inputs.push_back({"config", args.config});
  if (!args.schedule_from.empty()) inputs.push_back({"schedule", args.schedule_from});
  const json prov = provenance("sinr", inputs, config, recorded_command(argv));

  gs::SinrHeader header;
  stamp_header(header, kVersion, kGitHash, config, prov);
  header.seed = cfg.seed;
  header.channel_model = gs::channel_model_name(model.kind);
  header.los_from_ray = model.los_from_ray;
  header.carrier_hz = trace.carrier_hz();
  header.sinr_threshold_db = cfg.sinr_threshold_db;
  header.sensitivity_dbm = cfg.sensitivity_dbm;
  header.gain_threshold_db = cfg.gain_threshold_db;
  std::tie(header.time_start_s, header.time_end_s) = gs::sinr_window(trace, cfg);

  const fs::path out(args.out);
  if (out.has_parent_path()) fs::create_directories(out.parent_path());
  const fs::path tmp = out.string() + ".tmp";
  gs::SinrRunStats stats;
  try {
    gs::SinrWriter writer(tmp, header);
    auto progress_at = std::chrono::steady_clock::now();
    stats = gs::run_sinr(trace, *channel, cfg, rats, args.schedule_from.empty() ? nullptr : &reused, writer,
                         [&](const gs::SinrRunProgress& p) {
                           const auto now = std::chrono::steady_clock::now();
                           if (now - progress_at < std::chrono::seconds(2)) return;
                           progress_at = now;
                           spdlog::info("sinr {}: {}/{} transmissions evaluated ({:.0f}%)", model.label(), p.done,
                                        p.total, 100.0 * static_cast<double>(p.done) / std::max<double>(1, p.total));
                         });
  } catch (...) {
    std::error_code ec;
    fs::remove(tmp, ec);
    throw;
  }
  fs::rename(tmp, out);

  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  json summary = {{"out", args.out},
                  {"channel_model", model.label()},
                  {"packets", stats.packets},
                  {"transmissions", stats.transmissions},
                  {"receptions", stats.receptions},
                  {"decoded", stats.decoded},
                  {"wifi_dropped", stats.wifi_dropped},
                  {"nr_dropped", stats.nr_dropped},
                  {"nr_mean_latency_ms", stats.nr_mean_latency_s * 1e3},
                  {"wifi_mean_latency_ms", stats.wifi_mean_latency_s * 1e3},
                  {"time_start_s", stats.time_start_s},
                  {"time_end_s", stats.time_end_s},
                  {"wall_seconds", wall},
                  {"bytes", fs::file_size(out)}};
  json prr = json::object();
  for (const auto& p : stats.prr_rats)
    prr[gs::rat_name(p.rat)] = {{"packets", p.packets}, {"received", p.received},
                                {"prr", p.packets ? static_cast<double>(p.received) / p.packets : 0.0}};
  summary["prr"] = prr;
  std::string prr_text;
  for (const auto& [rat, v] : prr.items())
    prr_text += fmt::format(", PRR {} {:.1f}%", rat, 100 * v["prr"].get<double>());
  spdlog::info("sinr {}: {} packets, {} transmissions, {} reception attempts ({} decoded){} in {:.1f} s -> {}",
               model.label(), stats.packets, stats.transmissions, stats.receptions, stats.decoded, prr_text, wall,
               args.out);
  return summary;
}

json run_report_stage(const ReportArgs& args) {
  if (args.sinr.empty()) throw std::invalid_argument("report: no SINR file given (--sinr FILE.h5 ...)");
  for (const auto& f : args.sinr)
    if (!fs::exists(f)) throw meshkit::InputError(f, "", "no such file");
  std::vector<std::string> py{args.out};
  py.insert(py.end(), args.sinr.begin(), args.sinr.end());
  if (!args.labels.empty()) py.insert(py.end(), {"--labels", args.labels});
  if (!run_python_script("sinr_report.py", py))
    throw std::runtime_error("report: python/sinr_report.py failed (needs /usr/bin/python3 with h5py, numpy, "
                             "matplotlib: apt-get install python3-h5py python3-matplotlib)");
  json r = {{"out", args.out}};
  json pngs = json::array();
  for (const char* name : {"sinr_pdf.png", "prr_distance.png"})
    if (fs::exists(fs::path(args.out) / name)) pngs.push_back((fs::path(args.out) / name).string());
  r["pngs"] = pngs;
  std::ifstream in(fs::path(args.out) / "report.md");
  std::stringstream ss;
  ss << in.rdbuf();
  r["table"] = ss.str();
  return r;
}

}  // namespace raysweep::pipeline
