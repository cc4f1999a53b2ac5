// The vehicle library the tracer instances at vehicle poses: a
// `raysweep vehicles` folder (manifest.json and one GLB per entry and LOD) or
// the built-in parametric models.
#pragma once

#include <map>
#include <string>
#include <vector>

#include "meshkit/vehicle_model.hpp"

namespace raysweep::meshkit {

// Vehicle models by library entry name or SUMO class.
class VehicleLibrary {
 public:
  // dir empty: the built-in parametric model of each class. lod < 0: each
  // entry's default LOD.
  explicit VehicleLibrary(const std::string& dir = "", int lod = -1);
  // The model for a pose's class (entry name first, then vclass); throws
  // std::invalid_argument when neither exists.
  const VehicleModel& model(const std::string& vclass);
  std::vector<std::string> files() const;  // library files read so far (for provenance)

 private:
  std::string dir_;
  int lod_;
  std::map<std::string, VehicleModel> cache_;
  std::vector<std::string> files_;
};

}  // namespace raysweep::meshkit
