// Radio material names (ITU-R P.2040 table 3 plus the ground types of P.527 as
// Sionna RT names them). meshkit only names materials; their electromagnetic
// parameters live in the tracer.
#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace raysweep::meshkit {

// The P.2040 material names, without the "itu_" prefix.
const std::vector<std::string>& itu_material_names();
bool is_itu_material(std::string_view name);

// "mat-itu_concrete" / "itu_concrete" / "concrete" -> "concrete"; nullopt when
// the name is not an ITU material (callers must treat that as an error).
std::optional<std::string> itu_material_from_id(std::string_view id);

// OSM building:material / building:facade:material values -> P.2040 name.
// nullopt for values with no sensible mapping (the caller warns and falls back).
std::optional<std::string> itu_material_from_osm(std::string_view osm_value);

}  // namespace raysweep::meshkit
