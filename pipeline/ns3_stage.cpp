#include "pipeline/ns3_stage.hpp"

#include <spdlog/spdlog.h>
#include <toml++/toml.h>

#include <chrono>
#include <filesystem>

#include "generators/ns3_table.hpp"
#include "pipeline/config.hpp"
#include "pipeline/provenance.hpp"
#include "pipeline/toml_fields.hpp"
#include "pipeline/version.hpp"

namespace raysweep::pipeline {

namespace fs = std::filesystem;
using json = nlohmann::json;
using namespace toml_fields;

json Ns3Settings::to_json() const { return {{"subcarriers_per_band", subcarriers_per_band}}; }

Ns3Settings load_ns3_settings(const std::string& path) {
  Ns3Settings s;
  if (path.empty()) return s;
  load_scene_config(path);  // validates the file and its top-level sections
  const toml::table root = toml::parse_file(path);
  const toml::table* t = root["ns3"].as_table();
  if (!t) return s;
  s.present = true;
  for (auto&& [k, node] : *t) {
    const std::string key(k.str()), full = "ns3." + key;
    if (key == "enabled") {
      s.enabled = boolean(path, full, node);
    } else if (key == "subcarriers_per_band") {
      const int v = integer(path, full, node);
      if (v < 0) throw ConfigError(where(path, full, node) + ": must be >= 0");
      s.subcarriers_per_band = static_cast<std::uint32_t>(v);
    } else {
      throw ConfigError(where(path, full, node) + ": unknown key");
    }
  }
  return s;
}

json run_ns3_table_stage(const Ns3TableArgs& args, const std::vector<std::string>& argv) {
  const auto t_start = std::chrono::steady_clock::now();
  const Ns3Settings settings = load_ns3_settings(args.config);
  const json config = settings.to_json();
  std::vector<InputFile> inputs{{"channels", args.channels}};
  if (!args.config.empty()) inputs.push_back({"config", args.config});
  const json prov = provenance("ns3-table", inputs, config, recorded_command(argv));

  generators::Ns3TableHeader header;
  stamp_header(header, kVersion, kGitHash, config, prov);

  spdlog::info("ns3-table: {} -> {}", args.channels, args.out);
  const fs::path out(args.out);
  if (out.has_parent_path()) fs::create_directories(out.parent_path());
  const fs::path tmp = out.string() + ".tmp";
  generators::Ns3TableBuildStats stats;
  try {
    stats = generators::build_ns3_table(args.channels, tmp, header, settings.subcarriers_per_band);
  } catch (...) {
    std::error_code ec;
    fs::remove(tmp, ec);
    throw;
  }
  fs::rename(tmp, out);
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  const auto bytes = fs::file_size(out);
  json summary = {{"out", args.out},
                  {"frames", stats.frames},
                  {"pairs", stats.pairs},
                  {"nodes", stats.nodes},
                  {"bands", stats.bands},
                  {"gain_source", generators::gain_source_name(stats.gain_source)},
                  {"bytes", bytes},
                  {"bytes_per_pair_frame", stats.pairs ? static_cast<double>(bytes) / static_cast<double>(stats.pairs) : 0.0},
                  {"wall_seconds", wall}};
  spdlog::info("ns3-table: {} frames, {} pair-frames, {} nodes, {} bands, gain from {}, {} bytes ({:.2f} per pair-frame) "
               "in {:.1f} s -> {}",
               stats.frames, stats.pairs, stats.nodes, stats.bands, generators::gain_source_name(stats.gain_source),
               bytes, summary["bytes_per_pair_frame"].get<double>(), wall, args.out);
  return summary;
}

}  // namespace raysweep::pipeline
