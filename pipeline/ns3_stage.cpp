#include "pipeline/ns3_stage.hpp"

#include <spdlog/spdlog.h>

#include <chrono>
#include <filesystem>

#include "generators/ns3_table/ns3_table.hpp"
#include "pipeline/provenance.hpp"
#include "pipeline/staged_output.hpp"
#include "pipeline/version.hpp"

namespace raysweep::pipeline {

namespace fs = std::filesystem;
using json = nlohmann::json;

json run_ns3_table_stage(const Ns3TableArgs& args, const Settings& all, const std::vector<std::string>& argv) {
  const auto t_start = std::chrono::steady_clock::now();
  const Ns3Settings& settings = all.ns3;
  const json config = settings.to_json();
  std::vector<InputFile> inputs{{"channels", args.channels}};
  if (!all.file.empty()) inputs.push_back({"config", all.file});
  json prov = provenance("ns3-table", inputs, config, recorded_command(argv));
  all.record_sets(prov);

  generators::Ns3TableHeader header;
  stamp_header(header, kVersion, kGitHash, config, prov);

  spdlog::info("ns3-table: {} -> {}", args.channels, args.out);
  const fs::path out(args.out);
  StagedFile staged(out);
  const generators::Ns3TableBuildStats stats =
      generators::build_ns3_table(args.channels, staged.path(), header, settings.subcarriers_per_band);
  staged.commit();
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
