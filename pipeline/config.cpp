#include "pipeline/config.hpp"

#include <toml++/toml.h>

#include <set>

#include "meshkit/materials.hpp"
#include "pipeline/toml_fields.hpp"

namespace raysweep::pipeline {

using namespace toml_fields;

namespace {

// Sections every stage may meet in a city config; keys inside them are
// checked by the stage that owns them.
const std::set<std::string> kKnownSections = {"scene", "vehicles", "traffic", "radio", "tracer",
                                              "materials", "sweep", "sinr", "city", "report", "ns3",
                                              "radiomap"};

std::string get_material(const std::string& path, const std::string& key, const toml::node& n) {
  auto v = n.value<std::string>();
  if (!v) throw ConfigError(where(path, key, n) + ": expected a material name");
  auto m = meshkit::itu_material_from_id(*v);
  if (!m) throw ConfigError(where(path, key, n) + ": '" + *v + "' is not an ITU-R P.2040 material");
  return *m;
}

}  // namespace

SceneConfig load_scene_config(const std::string& path) {
  SceneConfig cfg;
  if (path.empty()) return cfg;
  toml::table root;
  try {
    root = toml::parse_file(path);
  } catch (const toml::parse_error& e) {
    throw ConfigError(path + ": line " + std::to_string(e.source().begin.line) + ": " +
                      std::string(e.description()));
  }
  for (auto&& [key, node] : root) {
    if (!kKnownSections.count(std::string(key.str())))
      throw ConfigError(where(path, std::string(key.str()), node) + ": unknown section");
  }
  const toml::table* scene = root["scene"].as_table();
  if (!scene) return cfg;
  auto& c = cfg.city;
  for (auto&& [k, node] : *scene) {
    const std::string key(k.str());
    const std::string full = "scene." + key;
    if (key == "clip_distance_m") c.clip_distance_m = number(path, full, node);
    else if (key == "clip_bbox") {
      const toml::array* a = node.as_array();
      if (!a || a->size() != 4) throw ConfigError(where(path, full, node) + ": expected [xmin, ymin, xmax, ymax]");
      std::array<double, 4> bb{};
      for (std::size_t i = 0; i < 4; ++i) bb[i] = number(path, full, *a->get(i));
      if (bb[0] >= bb[2] || bb[1] >= bb[3]) throw ConfigError(where(path, full, node) + ": empty box");
      c.clip_bbox = bb;
    } else if (key == "default_material") c.default_material = get_material(path, full, node);
    else if (key == "ground") c.ground = boolean(path, full, node);
    else if (key == "ground_material") c.ground_material = get_material(path, full, node);
    else if (key == "ground_margin_m") c.ground_margin_m = number(path, full, node);
    else if (key == "level_height_m") c.heights.level_height_m = number(path, full, node);
    else if (key == "default_height_m") c.heights.default_height_m = number(path, full, node);
    else if (key == "max_height_m") c.heights.max_height_m = number(path, full, node);
    else if (key == "simplify_tolerance_m") c.footprint.simplify_tolerance_m = number(path, full, node);
    else if (key == "max_area_change") c.footprint.max_area_change = number(path, full, node);
    else if (key == "max_centroid_shift_m") c.footprint.max_centroid_shift_m = number(path, full, node);
    else if (key == "min_area_m2") c.footprint.min_area_m2 = number(path, full, node);
    else if (key == "outlines_yield_to_parts") c.outlines_yield_to_parts = boolean(path, full, node);
    else if (key == "draco") cfg.draco = boolean(path, full, node);
    else if (key == "draco_position_bits") {
      const double bits = number(path, full, node);
      if (bits != 0 && (bits < 8 || bits > 30))
        throw ConfigError(where(path, full, node) + ": must be 0 (lossless) or 8..30");
      cfg.draco_position_bits = static_cast<int>(bits);
    } else if (key == "material_map") {
      const toml::table* t = node.as_table();
      if (!t) throw ConfigError(where(path, full, node) + ": expected a table of osm_value = \"material\"");
      for (auto&& [mk, mv] : *t)
        c.material_map[std::string(mk.str())] = get_material(path, full + "." + std::string(mk.str()), mv);
    } else {
      throw ConfigError(where(path, full, node) + ": unknown key");
    }
  }
  if (c.heights.level_height_m <= 0 || c.heights.default_height_m <= 0)
    throw ConfigError(path + ": scene heights must be positive");
  return cfg;
}

nlohmann::json SceneConfig::to_json() const {
  const auto& c = city;
  nlohmann::json j = {
      {"clip_distance_m", c.clip_distance_m},
      {"default_material", c.default_material},
      {"ground", c.ground},
      {"ground_material", c.ground_material},
      {"ground_margin_m", c.ground_margin_m},
      {"level_height_m", c.heights.level_height_m},
      {"default_height_m", c.heights.default_height_m},
      {"max_height_m", c.heights.max_height_m},
      {"simplify_tolerance_m", c.footprint.simplify_tolerance_m},
      {"max_area_change", c.footprint.max_area_change},
      {"max_centroid_shift_m", c.footprint.max_centroid_shift_m},
      {"min_area_m2", c.footprint.min_area_m2},
      {"outlines_yield_to_parts", c.outlines_yield_to_parts},
      {"draco", draco},
      {"draco_position_bits", draco_position_bits},
      {"material_map", c.material_map},
  };
  if (c.clip_bbox) j["clip_bbox"] = *c.clip_bbox;
  return j;
}

}  // namespace raysweep::pipeline
