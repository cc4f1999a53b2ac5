#include "pipeline/config.hpp"

#include "pipeline/config_tables.hpp"

namespace raysweep::pipeline {

SceneConfig load_scene_config(const std::string& path) {
  SceneConfig cfg;
  if (path.empty()) return cfg;
  ConfigFile(path).read(scene_table(), cfg);
  return cfg;
}

nlohmann::json SceneConfig::to_json() const { return scene_table().write(*this); }

}  // namespace raysweep::pipeline
