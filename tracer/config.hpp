// Radio and tracer settings ([radio], [tracer] and [materials.<name>] in the
// TOML config; the pipeline parses them, the tracer only consumes them).
#pragma once

#include <map>
#include <string>

#include "tracer/em.hpp"

namespace raysweep::tracer {

struct RadioConfig {
  double frequency_hz = 5.9e9;
  double bandwidth_hz = 10e6;
  double tx_power_dbm = 30;  // recorded for the generators; path gains do not depend on it
  AntennaSpec antenna;       // the same pattern at every node (vertical isotropic by default)
};

enum class CandidateSearch {
  sbr,        // shoot-and-bounce from every node over a Fibonacci lattice (default)
  exhaustive  // every face sequence up to max_depth: small scenes and tests only
};

struct TracerConfig {
  int max_depth = 3;  // specular reflections per path (0..kMaxDepth)
  bool los = true;
  bool specular = true;
  bool refraction = true;  // transmission through slabs (without bending)
  int rays_per_source = 4096;
  // Reception sphere radius = factor * angular ray spacing * unfolded length.
  // Candidates are refined exactly, so a generous sphere only costs time.
  double reception_radius_factor = 1.0;
  CandidateSearch candidates = CandidateSearch::sbr;
  // A path crossing more slabs than this is dropped and counted in the pair
  // record (never silently).
  int max_transmissions = 8;
  // Shoot-and-bounce rays continue through a slab losing at most this much at
  // normal incidence (glass, plastic), at most sbr_max_transmissions times,
  // so reflections behind windows are found; the exact path keeps every slab.
  double sbr_transmission_loss_db = 15;
  int sbr_max_transmissions = 2;
  std::map<std::string, MaterialOverride> materials;
};

constexpr int kMaxDepth = 16;

// Throws std::invalid_argument naming the offending setting.
void validate(const TracerConfig& tracer, const RadioConfig& radio);

}  // namespace raysweep::tracer
