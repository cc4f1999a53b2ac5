// Channel helpers on traced paths: frequency response on an OFDM grid and a
// sampled (band-limited) impulse response.
#pragma once

#include <complex>
#include <string>
#include <vector>

#include "tracer/path.hpp"

namespace raysweep::tracer {

// Subcarrier k of n has the baseband offset (k - n/2) * spacing from the
// carrier (k = n/2 is the carrier itself), the FFT-shifted order.
struct OfdmGrid {
  double carrier_hz = 5.9e9;
  double subcarrier_spacing_hz = 156250;
  int n_subcarriers = 64;
  double offset_hz(int k) const { return (k - n_subcarriers / 2) * subcarrier_spacing_hz; }
};

// IEEE 802.11p: 10 MHz channel, 64 subcarriers of 156.25 kHz.
OfdmGrid ofdm_80211p(double carrier_hz = 5.9e9);
// NR: numerology mu (0..4, spacing 15 kHz * 2^mu) with n_rb resource blocks of
// 12 subcarriers. Throws std::invalid_argument for mu outside 0..4 or n_rb < 1.
OfdmGrid ofdm_nr(int numerology, int n_rb, double carrier_hz = 5.9e9);

// An OFDM grid as a setting names it, "80211p" or "nr:MU:NRB", before the
// carrier is known: the spec is checked when read, the grid made once the
// radio's carrier is (the grid's shape does not depend on it).
struct OfdmGridSpec {
  std::string text;  // as given, for the records
  bool nr = false;   // else IEEE 802.11p
  int numerology = 0, n_rb = 0;
};
// Throws std::invalid_argument naming `what` (the option or key) and the spec.
OfdmGridSpec parse_ofdm_grid_spec(const std::string& spec, const std::string& what);
OfdmGrid ofdm_grid(const OfdmGridSpec& spec, double carrier_hz);

// H(f_c + df_k) = sum_i a_i exp(-j 2 pi df_k tau_i): a_i already carries the
// carrier phase, so H at df = 0 is the coherent narrowband channel.
std::vector<std::complex<double>> frequency_response(const std::vector<Path>& paths, const OfdmGrid& grid);

// Band-limited baseband impulse response sampled at `sample_rate_hz`:
// h[n] = sum_i a_i sinc(B (n T - (tau_i - t0))), T = 1 / sample_rate, B = bandwidth,
// t0 = the first-arrival delay minus `lead_s` (so taps start just before the
// first path). n_taps samples.
struct ImpulseResponse {
  double t0_s = 0;
  double sample_period_s = 0;
  std::vector<std::complex<double>> taps;
};
ImpulseResponse impulse_response(const std::vector<Path>& paths, double bandwidth_hz, double sample_rate_hz,
                                 int n_taps, double lead_s = 0);

}  // namespace raysweep::tracer
