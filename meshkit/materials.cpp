#include "meshkit/materials.hpp"

#include <algorithm>
#include <cctype>
#include <unordered_map>

namespace raysweep::meshkit {

const std::vector<std::string>& itu_material_names() {
  static const std::vector<std::string> names = {
      "concrete",   "brick",        "plasterboard",  "wood",           "glass",
      "ceiling_board", "chipboard", "floorboard",    "metal",          "very_dry_ground",
      "medium_dry_ground", "wet_ground"};
  return names;
}

bool is_itu_material(std::string_view name) {
  const auto& n = itu_material_names();
  return std::find(n.begin(), n.end(), name) != n.end();
}

std::optional<std::string> itu_material_from_id(std::string_view id) {
  if (id.rfind("mat-", 0) == 0) id.remove_prefix(4);
  if (id.rfind("itu_", 0) == 0) id.remove_prefix(4);
  if (is_itu_material(id)) return std::string(id);
  return std::nullopt;
}

const std::vector<CustomMaterial>& custom_materials() {
  // eps'' = sigma / (2 pi f eps0): at 5.9 GHz, sigma = 0.328 S/m x eps''.
  static const std::vector<CustomMaterial> table = {
      {"plastic", 2.8, 0.0092, 0.003,
       "automotive polymers (PP, PC, ABS) eps_r 2.5-3.2, loss tangent ~0.01 in the 1-10 GHz band; "
       "sigma = 2 pi f eps0 eps_r tan(delta) at 5.9 GHz; 3 mm bumper/lamp-lens wall"},
      {"rubber", 10.0, 0.98, 0.012,
       "carbon-black-filled tyre rubber: eps' ~8-15, eps'' ~2-5 at a few GHz; eps''=3 -> sigma 0.98 S/m; "
       "12 mm tread"},
      {"textile", 1.7, 0.011, 0.002,
       "seat fabric, convertible-top canvas: eps_r 1.5-2, loss tangent ~0.02; 2 mm"},
      {"human", 33.0, 3.3, 0.3,
       "riders (motorcycle, bicycle): 2/3-muscle-equivalent tissue at 5.8 GHz (muscle eps_r ~49, sigma ~5 S/m, "
       "Gabriel et al. 1996 tissue data), scaled by 2/3; lossy enough that the slab thickness hardly matters"},
  };
  return table;
}

const CustomMaterial* find_custom_material(std::string_view name) {
  for (const auto& m : custom_materials())
    if (m.name == name) return &m;
  return nullptr;
}

bool is_radio_material(std::string_view name) { return is_itu_material(name) || find_custom_material(name); }

std::string radio_material_id(std::string_view material) {
  if (is_itu_material(material)) return "itu_" + std::string(material);
  return std::string(material);
}

std::optional<std::string> radio_material_from_id(std::string_view id) {
  if (id.rfind("mat-", 0) == 0) id.remove_prefix(4);
  // "raysweep_<name>": a material written with its own parameters (peer export).
  if (id.rfind("raysweep_", 0) == 0) id.remove_prefix(9);
  if (auto itu = itu_material_from_id(id)) return itu;
  if (find_custom_material(id)) return std::string(id);
  return std::nullopt;
}

std::optional<std::string> itu_material_from_osm(std::string_view osm_value) {
  std::string v(osm_value);
  std::transform(v.begin(), v.end(), v.begin(), [](unsigned char c) { return std::tolower(c); });
  // OSM allows "a;b" lists; the first entry is the dominant material.
  if (auto semi = v.find(';'); semi != std::string::npos) v.resize(semi);
  while (!v.empty() && std::isspace(static_cast<unsigned char>(v.back()))) v.pop_back();
  while (!v.empty() && std::isspace(static_cast<unsigned char>(v.front()))) v.erase(v.begin());
  // Facades of stone and blocks are closest to concrete electrically
  // (eps_r 5.2-5.3 at 1-10 GHz); plaster is applied over masonry but its thin
  // layer is best approximated by plasterboard.
  static const std::unordered_map<std::string, std::string> table = {
      {"concrete", "concrete"},       {"reinforced_concrete", "concrete"},
      {"cement_block", "concrete"},   {"stone", "concrete"},
      {"sandstone", "concrete"},      {"limestone", "concrete"},
      {"granite", "concrete"},        {"masonry", "brick"},
      {"brick", "brick"},             {"bricks", "brick"},
      {"clay", "brick"},              {"glass", "glass"},
      {"mirror", "glass"},            {"wood", "wood"},
      {"timber", "wood"},             {"timber_framing", "wood"},
      {"log", "wood"},                {"bamboo", "wood"},
      {"metal", "metal"},             {"steel", "metal"},
      {"metal_plates", "metal"},      {"aluminium", "metal"},
      {"aluminum", "metal"},          {"copper", "metal"},
      {"tin", "metal"},               {"plaster", "plasterboard"},
      {"plasterboard", "plasterboard"}, {"stucco", "plasterboard"},
  };
  if (auto it = table.find(v); it != table.end()) return it->second;
  if (is_itu_material(v)) return v;
  return std::nullopt;
}

}  // namespace raysweep::meshkit
