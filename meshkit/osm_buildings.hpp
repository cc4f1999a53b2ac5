// Building outlines from an OSM extract (XML, .gz, .bz2, PBF via libosmium):
// closed ways and multipolygon relations tagged building=* or building:part=*,
// projected to scene coordinates. Rings are raw here (as mapped); footprint.hpp
// repairs them.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "meshkit/projection.hpp"

namespace raysweep::meshkit {

struct OsmBuilding {
  std::string source_id;  // "way/123" or "relation/45"
  bool is_part = false;   // building:part
  std::vector<std::vector<Vec2>> outers;
  std::vector<std::vector<Vec2>> inners;
  // Tag values that shape the building (empty when absent).
  std::string height, min_height, levels, min_level, roof_levels;
  std::string material, facade_material;
};

// An OSM element that could not become a building, with the reason code
// (stable, used as manifest key) and a human-readable detail.
struct OsmSkip {
  std::string source_id;
  std::string reason;
  std::string detail;
};

struct OsmBuildings {
  std::vector<OsmBuilding> buildings;
  std::vector<OsmSkip> skipped;
  std::size_t nodes = 0, ways = 0, relations = 0;
  double min_lon = 0, min_lat = 0, max_lon = 0, max_lat = 0;  // of the nodes read
};

using Projector = std::function<Vec2(double lon, double lat)>;

// Throws InputError naming the file (and line for malformed XML).
OsmBuildings read_osm_buildings(const std::string& path, const Projector& project);

}  // namespace raysweep::meshkit
