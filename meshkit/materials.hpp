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

// Dielectrics that P.2040 does not list but vehicles are made of. Their
// parameters are estimates for the 5.9 GHz band, documented in materials.cpp.
struct CustomMaterial {
  std::string name;
  double eps_r;          // relative permittivity (real part)
  double sigma_s_per_m;  // conductivity at 5.9 GHz
  double thickness_m;    // default slab thickness
  std::string basis;     // where the numbers come from
};
const std::vector<CustomMaterial>& custom_materials();
const CustomMaterial* find_custom_material(std::string_view name);

// ITU or custom: every triangle of a scene carries one of these.
bool is_radio_material(std::string_view name);
// Names as files carry them: "itu_concrete" for ITU materials, the plain
// name ("plastic") for custom ones.
std::string radio_material_id(std::string_view material);
// Inverse of radio_material_id, also accepting a "mat-" prefix (Mitsuba ids)
// and "raysweep_<name>" (materials written with explicit parameters).
std::optional<std::string> radio_material_from_id(std::string_view id);

// OSM building:material / building:facade:material values -> P.2040 name.
// nullopt for values with no sensible mapping (the caller warns and falls back).
std::optional<std::string> itu_material_from_osm(std::string_view osm_value);

}  // namespace raysweep::meshkit
