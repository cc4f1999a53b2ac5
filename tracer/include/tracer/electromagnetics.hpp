// The radio materials of one scene at one carrier: P.2040 slab
// coefficients per material, which ones are opaque, and the rough surfaces'
// specular share.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "tracer/config.hpp"
#include "tracer/em.hpp"

namespace raysweep::tracer {

// Materials evaluated at the carrier for one scene (errors for materials
// used by the scene whose P.2040 range excludes the carrier).
class Electromagnetics {
 public:
  // `rough`: diffuse scattering is traced, so specular reflections keep
  // sqrt(1 - S^2) of their field (specular_keep), in reflected and
  // diffracted paths alike.
  Electromagnetics(const std::vector<std::string>& material_names, const RadioConfig& radio,
                   const std::map<std::string, MaterialOverride>& overrides, bool rough = false);
  const RadioMaterial& material(std::uint16_t i) const { return materials_.at(i); }
  SlabCoefficients coefficients(std::uint16_t i, double cos_theta) const;
  TeTm reflection(std::uint16_t i, double cos_theta) const;  // coefficients(i, cos_theta).r, bit for bit
  // Half spaces and good conductors: nothing gets through.
  bool opaque(std::uint16_t i) const { return opaque_.at(i); }
  // Loss of the stronger polarisation through the slab at normal incidence (dB).
  double normal_transmission_loss_db(std::uint16_t i) const { return normal_loss_db_.at(i); }
  double wavelength() const { return kSpeedOfLight / radio_.frequency_hz; }
  double specular_keep(std::uint16_t i) const { return keep_.at(i); }
  const RadioConfig& radio() const { return radio_; }

 private:
  RadioConfig radio_;
  std::vector<RadioMaterial> materials_;
  std::vector<bool> opaque_;
  std::vector<double> normal_loss_db_;
  std::vector<double> keep_;
};

// An antenna pattern's peak gain (linear): the free-space reach and the
// diffuse gathering's bounds use it.
double peak_gain(AntennaPattern pattern);

}  // namespace raysweep::tracer
