// Propagation paths and per-pair results: what the tracer hands to the
// generators. Object and material ids index the tables of the traced scene
// (TraceScene::object_names(), TraceScene::material_names()).
#pragma once

#include <compare>
#include <complex>
#include <cstdint>
#include <string>
#include <vector>

#include "tracer/vec.hpp"

namespace raysweep::tracer {

// Codes are stable: datasets store them.
enum class InteractionType : std::uint8_t { specular = 1, refraction = 2, diffuse = 3, diffraction = 4 };
const char* interaction_name(InteractionType t);

enum class LosClass : std::uint8_t { LOS = 0, NLOSV = 1, NLOS = 2 };
const char* los_class_name(LosClass c);

struct Interaction {
  InteractionType type;
  std::uint32_t object;    // scene object (building, ground, vehicle)
  std::uint16_t material;  // index into the scene's material table
  Vec3 point;              // where it happens (scene frame, metres)
};

// A face of the traced scene: instance 0 is the static scene, instance v + 1
// the current frame's vehicle v.
struct FaceRef {
  std::uint32_t instance = 0;
  std::uint32_t face = 0;
  auto operator<=>(const FaceRef&) const = default;
};

// What produced a path, so that a later frame can solve the same path again
// at new positions (a coherent sweep's carried sequences) without searching
// for it.
struct PathOrigin {
  enum class Kind : std::uint8_t { unknown, direct, sequence, diffraction, vehicle_edge, diffuse };
  Kind kind = Kind::unknown;
  // sequence: the faces from tx; diffraction: the face reflected on before
  // (reflected < 0) or after (reflected > 0) the edge, if any.
  std::vector<FaceRef> faces;
  std::uint32_t edge = 0;  // diffraction: index into TraceScene::edges()
  std::int8_t reflected = 0;
};

struct Path {
  std::complex<double> a;  // baseband gain at the carrier, incl. exp(-j 2 pi f tau)
  double tau_s = 0;        // delay
  double theta_t = 0, phi_t = 0;  // departure direction at tx (radians)
  double theta_r = 0, phi_r = 0;  // arrival direction, pointing from rx to where the wave comes from
  double doppler_hz = 0;
  std::vector<Interaction> interactions;  // in order from tx to rx
  PathOrigin origin;
};

// Aggregates over a set of paths (all in linear units / seconds).
struct PathStats {
  double gain_coherent = 0;    // |sum a|^2
  double gain_incoherent = 0;  // sum |a|^2
  double first_delay_s = 0;    // min tau (0 when no path)
  double mean_delay_s = 0;     // power-weighted
  double rms_delay_spread_s = 0;
  std::size_t n_paths = 0;
};
PathStats path_stats(const std::vector<Path>& paths);

// A diffuse record from power-weighted sums of its contributions (power,
// power x delay, x departure and arrival directions, x Doppler): delay,
// angles and Doppler are their means, the amplitude sqrt(power) with the
// mean delay's carrier phase (diffuse phases are random in nature; a fixed
// rule keeps runs reproducible). No interactions yet.
Path diffuse_record(double power, double tau_sum, const Vec3& departure_sum, const Vec3& arrival_sum,
                    double doppler_sum, double wavelength);

// 10 log10(x), with -inf kept for zero.
double to_db(double linear_power);

}  // namespace raysweep::tracer
