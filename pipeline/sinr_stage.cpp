#include "pipeline/sinr_stage.hpp"

#include <spdlog/spdlog.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "generators/sinr/channel_trace.hpp"
#include "generators/sinr/outcomes.hpp"
#include "generators/sinr/sinr_file.hpp"
#include "meshkit/errors.hpp"
#include "pipeline/preview.hpp"
#include "pipeline/provenance.hpp"
#include "pipeline/staged_output.hpp"
#include "pipeline/version.hpp"

namespace raysweep::pipeline {

namespace fs = std::filesystem;
using json = nlohmann::json;
namespace gs = generators::sinr;

using gs::SinrModel;

namespace {

// Each node's RAT and, with --schedule-from, the transmissions to evaluate
// again (empty: the run schedules its own).
struct SinrSchedule {
  std::vector<gs::Rat> rats;
  std::vector<gs::Transmission> reused;
};

SinrSchedule sinr_schedule(const SinrArgs& args, const gs::ChannelTrace& trace, const gs::SinrConfig& cfg) {
  SinrSchedule s;
  if (args.schedule_from.empty()) {
    s.rats = gs::assign_rats(trace, cfg.rats, cfg.seed);
    return s;
  }
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
    s.rats.push_back(sched.nodes[n].rat);
  }
  s.reused = std::move(sched.transmissions);
  return s;
}

gs::SinrHeader sinr_header(const SinrArgs& args, const Settings& all, const SinrSettings& settings, const SinrModel& model,
                           const gs::SinrConfig& cfg, const gs::ChannelTrace& trace,
                           const std::vector<std::string>& argv) {
  json config = settings.to_json();
  config["channel_model"] = model.label();
  std::vector<InputFile> inputs{{"channels", args.channels}};
  if (!all.file.empty()) inputs.push_back({"config", all.file});
  if (!args.schedule_from.empty()) inputs.push_back({"schedule", args.schedule_from});
  json prov = provenance("sinr", inputs, config, recorded_command(argv));
  all.record_sets(prov);

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
  return header;
}

json sinr_summary(const SinrArgs& args, const SinrModel& model, const gs::SinrRunStats& stats, double wall) {
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
                  {"bytes", fs::file_size(args.out)}};
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

}  // namespace

json run_sinr_stage(const SinrArgs& args, const Settings& all, const std::vector<std::string>& argv) {
  const auto t_start = std::chrono::steady_clock::now();
  SinrSettings settings = all.sinr;
  const SinrModel model = gs::parse_sinr_model(args.channel_model + (args.los_from_ray ? "+los-from-ray" : ""));
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
  const SinrSchedule schedule = sinr_schedule(args, trace, cfg);
  const gs::SinrHeader header = sinr_header(args, all, settings, model, cfg, trace, argv);

  StagedFile staged{fs::path(args.out)};
  gs::SinrRunStats stats;
  {
    gs::SinrWriter writer(staged.path(), header);
    auto progress_at = std::chrono::steady_clock::now();
    stats = gs::run_sinr(trace, *channel, cfg, schedule.rats, args.schedule_from.empty() ? nullptr : &schedule.reused,
                         writer, [&](const gs::SinrRunProgress& p) {
                           const auto now = std::chrono::steady_clock::now();
                           if (now - progress_at < std::chrono::seconds(2)) return;
                           progress_at = now;
                           spdlog::info("sinr {}: {}/{} transmissions evaluated ({:.0f}%)", model.label(), p.done,
                                        p.total, 100.0 * static_cast<double>(p.done) / std::max<double>(1, p.total));
                         });
  }
  staged.commit();
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  return sinr_summary(args, model, stats, wall);
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
