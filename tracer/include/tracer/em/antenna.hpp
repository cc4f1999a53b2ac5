// Antenna patterns: isotropic and dipole antennas in either polarisation,
// their far-field vector pattern and peak gain.
#pragma once

#include <string>

#include "tracer/vec.hpp"

namespace raysweep::tracer {

enum class AntennaPattern { isotropic, short_dipole, halfwave_dipole };
enum class Polarization { V, H };

struct AntennaSpec {
  AntennaPattern pattern = AntennaPattern::isotropic;
  Polarization polarization = Polarization::V;
};

// Parses "isotropic" | "dipole" (short dipole) | "halfwave"; "V" | "H".
// Throw std::invalid_argument on anything else.
AntennaPattern parse_antenna_pattern(const std::string& s);
Polarization parse_polarization(const std::string& s);

// Far-field vector pattern: a vector perpendicular to `dir` whose length is
// the amplitude gain sqrt(G(dir)) and whose direction is the radiated field's
// polarisation. `dir` is a unit direction in the world frame; the antenna's
// local frame has z up and x along `forward` (unit, horizontal; the vehicle
// heading). Vertical polarisation: isotropic -> theta_hat; dipoles along z
// (short: G = 1.5 sin^2 theta; half-wave: G = 1.64 (cos(pi/2 cos theta)/sin theta)^2),
// field along theta_hat. Horizontal: isotropic -> phi_hat of the local frame;
// dipoles along the local y axis (broadside to the driving direction). At the
// poles of the pattern (where theta_hat/phi_hat are undefined) a deterministic
// perpendicular vector is used.
Vec3 antenna_field(const AntennaSpec& antenna, const Vec3& dir, const Vec3& forward);

// An antenna pattern's peak gain (linear): the free-space reach and the
// diffuse gathering's bounds use it.
double peak_gain(AntennaPattern pattern);

}  // namespace raysweep::tracer
