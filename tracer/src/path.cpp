#include "tracer/path.hpp"

#include "tracer/em/constants.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace raysweep::tracer {

const char* interaction_name(InteractionType t) {
  switch (t) {
    case InteractionType::specular: return "specular";
    case InteractionType::refraction: return "refraction";
    case InteractionType::diffuse: return "diffuse";
    case InteractionType::diffraction: return "diffraction";
  }
  return "unknown";  // codes read back from a dataset may be out of range
}

const char* los_class_name(LosClass c) {
  switch (c) {
    case LosClass::LOS: return "LOS";
    case LosClass::NLOSV: return "NLOSV";
    case LosClass::NLOS: return "NLOS";
  }
  return "unknown";
}

double to_db(double linear_power) {
  if (linear_power == 0) return -std::numeric_limits<double>::infinity();
  return 10.0 * std::log10(linear_power);
}

Path diffuse_record(double power, double tau_sum, const Vec3& departure_sum, const Vec3& arrival_sum,
                    double doppler_sum, double wavelength) {
  Path path;
  const double w = 1.0 / power;
  path.tau_s = tau_sum * w;
  const double phase = -2 * kPi * std::fmod(path.tau_s * kSpeedOfLight / wavelength, 1.0);
  path.a = std::polar(std::sqrt(power), phase);
  const Vec3 dep = normalize(departure_sum), arr = normalize(arrival_sum);
  path.theta_t = zenith(dep);
  path.phi_t = azimuth(dep);
  path.theta_r = zenith(arr);
  path.phi_r = azimuth(arr);
  path.doppler_hz = doppler_sum * w;
  return path;
}

PathStats path_stats(const std::vector<Path>& paths) {
  PathStats s;
  s.n_paths = paths.size();
  if (paths.empty()) return s;

  std::complex<double> sum{0, 0};
  double first = paths.front().tau_s;
  for (const Path& p : paths) {
    sum += p.a;
    s.gain_incoherent += std::norm(p.a);
    first = std::min(first, p.tau_s);
  }
  s.gain_coherent = std::norm(sum);
  s.first_delay_s = first;
  s.mean_delay_s = first;
  if (s.gain_incoherent <= 0) return s;  // all-zero gains: no weighting possible

  // Absolute delays can be ~1e-3 s while spreads are ~1e-8 s; squaring the
  // absolute values would lose the spread to cancellation, so work with
  // excess delays over the first arrival.
  double m1 = 0, m2 = 0;
  for (const Path& p : paths) {
    const double w = std::norm(p.a), d = p.tau_s - first;
    m1 += w * d;
    m2 += w * d * d;
  }
  m1 /= s.gain_incoherent;
  m2 /= s.gain_incoherent;
  s.mean_delay_s = first + m1;
  s.rms_delay_spread_s = std::sqrt(std::max(0.0, m2 - m1 * m1));
  return s;
}

}  // namespace raysweep::tracer
