#include "tracer/channel.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <stdexcept>
#include <string>

namespace raysweep::tracer {

OfdmGrid ofdm_80211p(double carrier_hz) { return OfdmGrid{carrier_hz, 156250.0, 64}; }

namespace {
void check_nr(int numerology, int n_rb) {
  if (numerology < 0 || numerology > 4)
    throw std::invalid_argument("ofdm_nr: numerology must be 0..4, got " + std::to_string(numerology));
  if (n_rb < 1) throw std::invalid_argument("ofdm_nr: n_rb must be >= 1, got " + std::to_string(n_rb));
}
}  // namespace

OfdmGrid ofdm_nr(int numerology, int n_rb, double carrier_hz) {
  check_nr(numerology, n_rb);
  return OfdmGrid{carrier_hz, 15e3 * double(1 << numerology), 12 * n_rb};
}

OfdmGridSpec parse_ofdm_grid_spec(const std::string& spec, const std::string& what) {
  OfdmGridSpec g{spec};
  if (spec == "80211p") return g;
  char tail = 0;
  if (std::sscanf(spec.c_str(), "nr:%d:%d%c", &g.numerology, &g.n_rb, &tail) != 2)
    throw std::invalid_argument(what + " '" + spec + "': expected 80211p or nr:NUMEROLOGY:N_RB (e.g. nr:2:10)");
  check_nr(g.numerology, g.n_rb);
  g.nr = true;
  return g;
}

OfdmGrid ofdm_grid(const OfdmGridSpec& spec, double carrier_hz) {
  return spec.nr ? ofdm_nr(spec.numerology, spec.n_rb, carrier_hz) : ofdm_80211p(carrier_hz);
}

// A path's phasor steps by the same rotation from one subcarrier to the
// next, so one sine and cosine per run of kRun subcarriers (re-anchored at
// each run's start, which keeps the recurrence's rounding to a few ulp)
// replaces one per subcarrier: the sweep's CFR cost was nearly all trig.
std::vector<std::complex<double>> frequency_response(const std::vector<Path>& paths, const OfdmGrid& grid) {
  constexpr int kRun = 16;
  const int n = std::max(grid.n_subcarriers, 0);
  std::vector<std::complex<double>> h(n, {0, 0});
  for (const Path& p : paths) {
    const double w = -2 * std::numbers::pi * p.tau_s;
    const std::complex<double> step = std::polar(1.0, w * grid.subcarrier_spacing_hz);
    for (int k0 = 0; k0 < n; k0 += kRun) {
      std::complex<double> ph = p.a * std::polar(1.0, w * grid.offset_hz(k0));
      double re = ph.real(), im = ph.imag();
      for (int k = k0; k < std::min(n, k0 + kRun); ++k) {
        h[k] += std::complex<double>(re, im);
        const double r = re * step.real() - im * step.imag();  // no NaN recovery: finite inputs
        im = re * step.imag() + im * step.real();
        re = r;
      }
    }
  }
  return h;
}

namespace {
double sinc(double x) {
  if (x == 0) return 1.0;
  const double px = std::numbers::pi * x;
  return std::sin(px) / px;
}
}  // namespace

ImpulseResponse impulse_response(const std::vector<Path>& paths, double bandwidth_hz, double sample_rate_hz,
                                 int n_taps, double lead_s) {
  if (!(bandwidth_hz > 0)) throw std::invalid_argument("impulse_response: bandwidth must be positive");
  if (!(sample_rate_hz > 0)) throw std::invalid_argument("impulse_response: sample rate must be positive");
  if (n_taps < 1) throw std::invalid_argument("impulse_response: n_taps must be >= 1");

  ImpulseResponse ir;
  ir.sample_period_s = 1.0 / sample_rate_hz;
  ir.taps.assign(n_taps, {0, 0});
  if (paths.empty()) return ir;

  double first = paths.front().tau_s;
  for (const Path& p : paths) first = std::min(first, p.tau_s);
  ir.t0_s = first - lead_s;

  for (const Path& p : paths) {
    // Relative delay first: t0 and tau may both be large absolute values.
    const double rel = p.tau_s - ir.t0_s;
    for (int n = 0; n < n_taps; ++n) ir.taps[n] += p.a * sinc(bandwidth_hz * (n * ir.sample_period_s - rel));
  }
  return ir;
}

}  // namespace raysweep::tracer
