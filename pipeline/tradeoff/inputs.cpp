#include "pipeline/tradeoff/inputs.hpp"

#include <stdexcept>

#include "pipeline/city_run.hpp"

namespace raysweep::pipeline {

namespace fs = std::filesystem;

TradeoffInputs resolve_inputs(const TradeoffArgs& args, const Settings& settings) {
  TradeoffInputs in{args.scene, args.vehicles, args.fcd, args.config, args.rsus, args.out, "", args.vtypes, {}};
  if (!args.city.empty()) {
    if (!args.scene.empty() || !args.fcd.empty() || !args.vehicles.empty() || !args.config.empty() ||
        !args.rsus.empty() || !args.vtypes.empty())
      throw std::invalid_argument("tradeoff: give either a city file or --scene/--fcd/--vehicles/--config, not both");
    const CityOutputs o = city_outputs(settings, args.city_out);
    in.scene_dir = o.scene;
    in.vehicles_dir = o.vehicles;
    in.fcd = o.fcd;
    in.rsus_file = o.rsus;
    in.vtype_files = o.vtypes;
    in.config = args.city;
    if (in.out.empty()) in.out = (fs::path(o.out) / "tradeoff").string();
    in.title = settings.city.name;
  } else {
    if (!args.city_out.empty()) throw std::invalid_argument("tradeoff: --city-out needs a city file");
    if (in.scene_dir.empty() || in.fcd.empty())
      throw std::invalid_argument("tradeoff: give a city file (after `raysweep run CITY.toml`) or --scene and --fcd");
    if (in.out.empty()) throw std::invalid_argument("tradeoff: --out DIR is required with --scene/--fcd");
    in.title = fs::path(in.scene_dir).filename().string();
  }
  in.scene_file = fs::path(in.scene_dir) / "scene.glb";
  if (!fs::exists(in.scene_file))
    throw std::invalid_argument(in.scene_dir + ": no scene.glb (run `raysweep scene` first)");
  if (!fs::exists(in.fcd)) throw std::invalid_argument(in.fcd + ": FCD file not found");
  if (!in.vehicles_dir.empty() && !fs::exists(fs::path(in.vehicles_dir) / "manifest.json"))
    throw std::invalid_argument(in.vehicles_dir +
                                ": not a vehicle library (no manifest.json; run `raysweep vehicles`)");
  if (!in.rsus_file.empty() && !fs::exists(in.rsus_file))
    throw std::invalid_argument(in.rsus_file + ": RSU file not found");
  if (fs::exists(in.out) && !fs::is_directory(in.out))
    throw std::invalid_argument(in.out + ": exists and is not a folder");
  return in;
}

}  // namespace raysweep::pipeline
