#include "pipeline/features_stage.hpp"

#include <fmt/ranges.h>
#include <spdlog/spdlog.h>

#include <chrono>
#include <filesystem>

#include "generators/sweep/context_features.hpp"
#include "meshkit/gltf_io.hpp"
#include "pipeline/preview.hpp"
#include "pipeline/provenance.hpp"
#include "pipeline/scene_cache.hpp"
#include "pipeline/staged_output.hpp"
#include "pipeline/trace_inputs.hpp"
#include "pipeline/version.hpp"
#include "tracer/trace_scene.hpp"

namespace raysweep::pipeline {

namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

struct FeaturesInputs {
  Settings settings;
  fs::path dataset, scene_glb, out;
};

FeaturesInputs resolve(const FeaturesArgs& a) {
  FeaturesInputs in;
  if (!a.city.empty()) {
    if (!a.config.empty()) throw std::invalid_argument("features: give a city file or --config, not both");
    if (!fs::exists(a.city)) throw std::invalid_argument(a.city + ": city file not found");
    in.settings = load_city_settings(a.city, a.set);
    const fs::path run(a.city_out.empty() ? in.settings.city.out : a.city_out);
    const std::string hint = "; run `raysweep run " + a.city + (a.city_out.empty() ? "" : " --out " + a.city_out) + "` first";
    in.dataset = a.dataset.empty() ? run / "dataset.h5" : fs::path(a.dataset);
    in.scene_glb = (a.scene.empty() ? run / "scene" : fs::path(a.scene)) / "scene.glb";
    if (!fs::exists(in.dataset)) throw std::invalid_argument(in.dataset.string() + ": no channel dataset" + hint);
    if (!fs::exists(in.scene_glb)) throw std::invalid_argument(in.scene_glb.string() + ": no scene" + hint);
  } else {
    if (!a.city_out.empty()) throw std::invalid_argument("features: --city-out needs a city file");
    if (a.dataset.empty() || a.scene.empty())
      throw std::invalid_argument("features: give a city file (after `raysweep run CITY.toml`) or --dataset and --scene");
    in.settings = load_settings(a.config, a.set);
    in.dataset = a.dataset;
    in.scene_glb = fs::path(a.scene) / "scene.glb";
    if (!fs::exists(in.dataset)) throw std::invalid_argument(in.dataset.string() + ": channel dataset not found");
    if (!fs::exists(in.scene_glb)) throw std::invalid_argument(in.scene_glb.string() + ": no scene.glb (run `raysweep scene`)");
  }
  in.out = a.out.empty() ? in.dataset.parent_path() / "features.h5" : fs::path(a.out);
  if (in.out.extension() != ".h5") throw std::invalid_argument(in.out.string() + ": the feature file must end in .h5");
  return in;
}

// What decides the file's content: the features' settings, the objects left
// out of the scene, and the inputs' hashes.
json content_key(const FeaturesInputs& in, const json& inputs) {
  json key = {{"features", in.settings.features.to_json()},
              {"exclude_objects", in.settings.sweep.exclude_objects},
              {"version", kVersion},
              {"schema", generators::kFeaturesSchemaVersion}};
  for (const auto& f : inputs) key["sha256"].push_back(f.at("sha256"));
  return key;
}

// Whether `out` holds a finished feature file with the same content key.
bool up_to_date(const fs::path& out, const json& key) {
  const auto prov = generators::finished_features_provenance(out);
  return prov && prov->value("content_key", json()) == key;
}

generators::HeightMap height_map(const FeaturesInputs& in) {
  const auto t0 = std::chrono::steady_clock::now();
  const meshkit::Scene scene = exclude_objects(read_scene_glb(in.scene_glb.parent_path()), in.settings.sweep.exclude_objects);
  const tracer::TraceScene traced(scene);
  auto map = generators::HeightMap::build(traced, scene.bounds(), in.settings.features.grid.map_resolution_m);
  spdlog::info("features: height map of {} cells ({:.2f} m) in {:.1f} s", map.cells(),
               in.settings.features.grid.map_resolution_m,
               std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  return map;
}

}  // namespace

json run_features_stage(const FeaturesArgs& args, const std::vector<std::string>& argv) {
  const FeaturesInputs in = resolve(args);
  const json config = in.settings.features.to_json();
  std::vector<InputFile> files{{"channels", in.dataset.string()}, {"scene", in.scene_glb.string()}};
  if (!in.settings.file.empty()) files.push_back({"config", in.settings.file});
  json prov = provenance("features", files, config, recorded_command(argv));
  in.settings.record_sets(prov);
  json inputs_for_key = json::array();
  for (std::size_t i = 0; i < 2; ++i) inputs_for_key.push_back(prov["inputs"][i]);
  prov["content_key"] = content_key(in, inputs_for_key);
  if (!args.force && up_to_date(in.out, prov["content_key"])) {
    spdlog::info("features: up to date ({})", in.out.string());
    return {{"out", in.out.string()}, {"city", in.settings.city.name}, {"up_to_date", true}};
  }
  spdlog::info("features: {} + {} -> {}", in.dataset.string(), in.scene_glb.string(), in.out.string());
  const generators::HeightMap map = height_map(in);
  generators::FeaturesHeader header;
  stamp_header(header, kVersion, kGitHash, config, prov);
  StagedFile staged(in.out);
  const auto stats = generators::write_features(
      in.settings.features.grid, map, in.dataset, staged.path(), header, [](std::uint64_t done, std::uint64_t total) {
        spdlog::info("features: frame {} of {}", done, total);
      });
  staged.commit();
  const auto bytes = fs::file_size(in.out);
  spdlog::info("features: {} rows of {} frames, {} bytes ({:.0f} a row) in {:.1f} s -> {}", stats.rows, stats.frames,
               bytes, stats.rows ? static_cast<double>(bytes) / static_cast<double>(stats.rows) : 0.0, stats.seconds,
               in.out.string());
  return {{"out", in.out.string()}, {"city", in.settings.city.name}, {"rows", stats.rows},
          {"frames", stats.frames},  {"bytes", bytes}, {"seconds", stats.seconds}, {"up_to_date", false}};
}

int run_ml_stage(const MlArgs& args, const std::vector<std::string>& argv) {
  if (args.cities.empty()) throw std::invalid_argument("ml: give at least one city file");
  if (args.city_outs.size() > args.cities.size())
    throw std::invalid_argument("ml: more --city-out than city files (one per city, in order)");
  if (args.out.empty()) throw std::invalid_argument("ml: --out DIR is required");
  std::vector<std::string> py{"--out", args.out, "--seed", std::to_string(args.seed), "--max-train-s",
                              fmt::format("{}", args.max_train_s), "--max-links", std::to_string(args.max_links)};
  for (std::size_t i = 0; i < args.cities.size(); ++i) {
    FeaturesArgs f;
    f.city = args.cities[i];
    f.city_out = i < args.city_outs.size() ? args.city_outs[i] : "";
    f.set = args.set;
    const json s = run_features_stage(f, argv);
    const std::string name = s["city"].get<std::string>();
    const fs::path run = fs::path(s["out"].get<std::string>()).parent_path();
    if (!fs::exists(run / "sinr" / "ray.h5"))
      spdlog::warn("ml: {}: no sinr/ray.h5 (the city file has no [sinr] table): no packet task for {}", run.string(),
                   name);
    py.push_back("--city");
    py.push_back(name + "=" + run.string());
  }
  fs::create_directories(args.out);
  spdlog::info("ml: python3 -m ml {}", fmt::join(py, " "));
  const int rc = run_python_module("ml", py);
  if (rc != 0) spdlog::error("ml: the benchmark (python/ml) exited with status {}", rc);
  return rc;
}

}  // namespace raysweep::pipeline
