// Interpretation of OSM building tags: heights with units, levels, materials.
#pragma once

#include <optional>
#include <string>
#include <string_view>

namespace raysweep::meshkit {

// Parses an OSM length ("12", "12.5 m", "12m", "12,5", "40'", "40 ft",
// "12'6\"") to metres. nullopt when unparsable, negative, or not finite.
std::optional<double> parse_osm_length(std::string_view text);

// Parses a level count ("3", "2.5", " 4 "); lists ("3;4") take the first.
std::optional<double> parse_osm_levels(std::string_view text);

struct HeightRules {
  double level_height_m = 3.0;    // per building:level
  double default_height_m = 9.0;  // no height and no levels
  double max_height_m = 1000.0;   // above this a tag is treated as an error
};

// Where a building's height came from, recorded per building in the manifest.
enum class HeightSource { Height, Levels, Default };
const char* to_string(HeightSource s);

struct BuildingTags {
  const char* height = nullptr;
  const char* min_height = nullptr;
  const char* levels = nullptr;
  const char* min_level = nullptr;
  const char* roof_levels = nullptr;
};

struct ResolvedHeight {
  double base_m = 0;  // from min_height or building:min_level
  double top_m = 0;
  HeightSource source = HeightSource::Default;
  std::string warning;  // non-empty when a tag was present but unusable
};

// height, else (building:levels + roof:levels) x level height, else default;
// base from min_height, else building:min_level x level height.
ResolvedHeight resolve_height(const BuildingTags& tags, const HeightRules& rules);

}  // namespace raysweep::meshkit
