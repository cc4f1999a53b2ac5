// The city scene: OSM buildings -> repaired footprints -> extruded prisms,
// clipped to the area the network needs, plus a ground plane. Everything
// kept, repaired, simplified or dropped is counted with its reason.
#pragma once

#include <array>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "meshkit/footprint.hpp"
#include "meshkit/osm_buildings.hpp"
#include "meshkit/osm_tags.hpp"
#include "meshkit/scene.hpp"

namespace raysweep::meshkit {

struct CityOptions {
  HeightRules heights;
  FootprintOptions footprint;
  std::string default_material = "concrete";
  // Extra OSM material value -> P.2040 name mappings (override the built-in table).
  std::map<std::string, std::string> material_map;
  bool ground = true;
  std::string ground_material = "medium_dry_ground";
  double ground_margin_m = 50;
  // Keep buildings within this distance of a network lane (<= 0: keep all).
  double clip_distance_m = 150;
  // Or keep buildings that intersect this box (scene x/y: xmin, ymin, xmax, ymax).
  std::optional<std::array<double, 4>> clip_bbox;
  // An outline with building:part inside is drawn by its parts (Simple 3D Buildings).
  bool outlines_yield_to_parts = true;
};

struct BuildingRecord {
  std::string id;
  bool part = false;
  double base_m = 0, top_m = 0;
  std::string height_source;
  std::string material, material_source;
  double area_m2 = 0;
  Vec2 centroid{0, 0};
  std::vector<std::string> repairs;
  bool simplified = false;
  std::size_t triangles = 0;
};

struct CityReport {
  std::size_t candidates = 0;  // building ways/relations found in the extract
  std::vector<BuildingRecord> kept;
  std::map<std::string, std::vector<std::string>> skipped;  // reason -> OSM ids
  std::map<std::string, std::size_t> repairs;               // repair kind -> count
  std::size_t simplified = 0, simplification_undone = 0;
  std::size_t vertices_in = 0, vertices_out = 0;
  std::size_t wall_faces = 0;
  std::map<std::string, std::size_t> triangles_by_material;
  std::vector<std::string> warnings;  // each names the OSM element
};

struct CityScene {
  Scene scene;
  CityReport report;
};

using Progress = std::function<void(std::size_t done, std::size_t total)>;

// `lanes`: the network's lane centre lines (may be empty: then no distance clip).
CityScene build_city(const OsmBuildings& osm, const std::vector<std::vector<Vec2>>& lanes,
                     const CityOptions& options, const Progress& progress = {});

nlohmann::json to_json(const CityReport& report);

}  // namespace raysweep::meshkit
