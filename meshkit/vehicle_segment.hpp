// Radio materials for vehicle parts. A rules table (ordered, first match
// wins, configurable) maps part and source-material names to materials;
// models without usable names are segmented geometrically (OpenMesh:
// connected components for wheels, normals and a height band for windows).
#pragma once

#include <string>
#include <vector>

#include "meshkit/vehicle_model.hpp"

namespace raysweep::meshkit {

struct SegmentationRule {
  std::string field;     // "part", "material" or "any"
  std::string pattern;   // ECMAScript regex, case-insensitive, searched in the name
  std::string material;  // radio material
};

struct SegmentationRules {
  std::vector<SegmentationRule> rules;
  std::string default_material = "metal";  // parts no rule matches (warned)
  double window_band_low = 0.55;   // geometric fallback: window line, fraction of height
  double window_band_high = 0.95;
};

// paint/body/chrome/rim -> metal, glass/window/light -> glass, rubber/tyre ->
// rubber, plastic/bumper/plate -> plastic, tissue/seat/canvas -> textile...
SegmentationRules default_segmentation_rules();

struct SegmentReport {
  std::size_t by_rule = 0, by_default = 0;
  bool geometric = false;  // the model had no usable names
};

// Sets material and rule of every part. Throws std::invalid_argument for a
// rule naming an unknown material or an invalid regex.
SegmentReport segment(VehicleModel& model, const SegmentationRules& rules);

// The geometric fallback on its own: replaces the parts by "body" (metal),
// "windows" (glass) and "wheels" (rubber).
void segment_geometric(VehicleModel& model, const SegmentationRules& rules);

}  // namespace raysweep::meshkit
