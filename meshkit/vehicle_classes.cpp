#include "meshkit/vehicle_classes.hpp"

namespace raysweep::meshkit {

const std::vector<VehicleClassInfo>& vehicle_classes() {
  // length, width, height in metres.
  static const std::vector<VehicleClassInfo> classes = {
      {"passenger", {5.0, 1.8, 1.5}, "car"},      {"taxi", {5.0, 1.8, 1.5}, "car"},
      {"evehicle", {5.0, 1.8, 1.5}, "car"},       {"private", {5.0, 1.8, 1.5}, "car"},
      {"delivery", {6.5, 2.16, 2.86}, "van"},     {"emergency", {6.5, 2.16, 2.86}, "van"},
      {"truck", {7.1, 2.4, 2.4}, "truck"},        {"trailer", {16.5, 2.55, 4.0}, "semitrailer"},
      {"bus", {12.0, 2.5, 3.4}, "bus"},           {"coach", {14.0, 2.6, 4.0}, "bus"},
      {"motorcycle", {2.2, 0.9, 1.5}, "motorcycle"}, {"moped", {2.1, 0.8, 1.7}, "motorcycle"},
      {"bicycle", {1.6, 0.65, 1.7}, "bicycle"},
  };
  return classes;
}

const VehicleClassInfo* find_vehicle_class(const std::string& vclass) {
  for (const auto& c : vehicle_classes())
    if (c.vclass == vclass) return &c;
  return nullptr;
}

}  // namespace raysweep::meshkit
