#include "meshkit/vehicle_library.hpp"

#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>
#include <stdexcept>

#include "meshkit/gltf_io.hpp"
#include "meshkit/vehicle_classes.hpp"
#include "meshkit/vehicle_parametric.hpp"

namespace raysweep::meshkit {

namespace fs = std::filesystem;

VehicleLibrary::VehicleLibrary(const std::string& dir, int lod) : dir_(dir), lod_(lod) {
  if (!dir_.empty() && !fs::exists(fs::path(dir_) / "manifest.json"))
    throw std::invalid_argument(dir_ + ": not a vehicle library (no manifest.json; run `raysweep vehicles`)");
}

const VehicleModel& VehicleLibrary::model(const std::string& vclass) {
  if (auto it = cache_.find(vclass); it != cache_.end()) return it->second;
  if (dir_.empty()) {
    // What `raysweep vehicles` builds for the class without a model file and
    // with its default settings (antenna offset included).
    const VehicleClassInfo* info = find_vehicle_class(vclass);
    if (!info) throw std::invalid_argument("vehicle class '" + vclass + "' has no built-in model");
    return cache_.emplace(vclass, parametric_vehicle(vclass, vclass, info->archetype, info->dims)).first->second;
  }
  const fs::path manifest_path = fs::path(dir_) / "manifest.json";
  std::ifstream in(manifest_path);
  const auto manifest = nlohmann::json::parse(in);
  const nlohmann::json* entry = nullptr;
  for (const auto& v : manifest.at("vehicles"))
    if (v.at("name") == vclass) entry = &v;
  if (!entry)
    for (const auto& v : manifest.at("vehicles"))
      if (v.value("vclass", "") == vclass) {
        entry = &v;
        break;
      }
  if (!entry) throw std::invalid_argument(manifest_path.string() + ": no entry for vehicle class '" + vclass + "'");
  const int lod = lod_ >= 0 ? lod_ : entry->value("default_lod", 0);
  std::string file;
  for (const auto& l : entry->at("lods"))
    if (l.at("lod") == lod) file = l.at("file");
  if (file.empty())
    throw std::invalid_argument(manifest_path.string() + ": entry '" + entry->at("name").get<std::string>() +
                                "' has no LOD " + std::to_string(lod));
  const std::string path = (fs::path(dir_) / file).string();
  auto model = from_scene(read_glb(path), entry->at("name"));
  model.vclass = entry->value("vclass", vclass);
  const auto& a = entry->at("antenna");
  model.antenna = {a.at(0).get<double>(), a.at(1).get<double>(), a.at(2).get<double>()};
  files_.push_back(path);
  return cache_.emplace(vclass, std::move(model)).first->second;
}

std::vector<std::string> VehicleLibrary::files() const { return files_; }

}  // namespace raysweep::meshkit
