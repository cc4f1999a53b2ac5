#include "mechanisms/mechanism.hpp"

namespace raysweep::tracer {

Mechanisms make_mechanisms(const TracerConfig& cfg) {
  Mechanisms out;
  for (auto make : {make_direct, make_specular, make_diffraction, make_diffuse})
    if (auto m = make(cfg)) out.push_back(std::move(m));
  return out;
}

}  // namespace raysweep::tracer
