#include "meshkit/material_colors.hpp"

#include <string>
#include <unordered_map>

namespace raysweep::meshkit {

std::array<double, 3> material_display_color(std::string_view material) {
  // Roughly what the surfaces look like, so a glance at a render tells
  // concrete facades from brick or glass.
  static const std::unordered_map<std::string, std::array<double, 3>> colors = {
      {"concrete", {0.54, 0.54, 0.52}},       {"brick", {0.60, 0.24, 0.16}},
      {"plasterboard", {0.88, 0.86, 0.80}},   {"wood", {0.52, 0.35, 0.18}},
      {"glass", {0.55, 0.75, 0.85}},          {"ceiling_board", {0.92, 0.92, 0.90}},
      {"chipboard", {0.76, 0.62, 0.42}},      {"floorboard", {0.62, 0.45, 0.26}},
      {"metal", {0.30, 0.32, 0.36}},          {"very_dry_ground", {0.76, 0.68, 0.50}},
      {"medium_dry_ground", {0.50, 0.42, 0.28}}, {"wet_ground", {0.30, 0.26, 0.18}},
      {"plastic", {0.85, 0.45, 0.10}},        {"rubber", {0.08, 0.08, 0.08}},
      {"textile", {0.70, 0.62, 0.48}},        {"human", {0.85, 0.65, 0.55}},
  };
  if (auto it = colors.find(std::string(material)); it != colors.end()) return it->second;
  return {0.5, 0.5, 0.5};
}

}  // namespace raysweep::meshkit
