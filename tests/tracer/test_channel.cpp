// Path statistics and summaries, OFDM grids, frequency and impulse responses against
// hand-computed values and analytic properties (notch spacing, Parseval,
// sinc energy, DTFT of the taps).
#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <limits>
#include <numbers>
#include <stdexcept>

#include "tracer/channel.hpp"
#include "tracer/channel_summary.hpp"
#include "tracer/path.hpp"

using namespace raysweep::tracer;
using cd = std::complex<double>;

namespace {
constexpr double kPi = std::numbers::pi;

Path make_path(cd a, double tau) {
  Path p;
  p.a = a;
  p.tau_s = tau;
  return p;
}

double energy(const std::vector<cd>& v) {
  double e = 0;
  for (const cd& x : v) e += std::norm(x);
  return e;
}
}  // namespace

TEST(PathNames, InteractionAndLos) {
  EXPECT_STREQ(interaction_name(InteractionType::specular), "specular");
  EXPECT_STREQ(interaction_name(InteractionType::refraction), "refraction");
  EXPECT_STREQ(interaction_name(InteractionType::diffuse), "diffuse");
  EXPECT_STREQ(interaction_name(InteractionType::diffraction), "diffraction");
  EXPECT_STREQ(los_class_name(LosClass::LOS), "LOS");
  EXPECT_STREQ(los_class_name(LosClass::NLOSV), "NLOSV");
  EXPECT_STREQ(los_class_name(LosClass::NLOS), "NLOS");
}

TEST(PathStats, ToDb) {
  EXPECT_DOUBLE_EQ(to_db(100.0), 20.0);
  EXPECT_DOUBLE_EQ(to_db(1e-9), -90.0);
  EXPECT_NEAR(to_db(0.5), -3.0103, 1e-4);
  EXPECT_EQ(to_db(0.0), -std::numeric_limits<double>::infinity());
}

TEST(PathStats, EmptyIsAllZero) {
  const PathStats s = path_stats({});
  EXPECT_EQ(s.n_paths, 0u);
  EXPECT_EQ(s.gain_coherent, 0);
  EXPECT_EQ(s.gain_incoherent, 0);
  EXPECT_EQ(s.first_delay_s, 0);
  EXPECT_EQ(s.mean_delay_s, 0);
  EXPECT_EQ(s.rms_delay_spread_s, 0);
}

TEST(PathStats, TwoPathsByHand) {
  // a = 2 @ 10 ns, 1 @ 40 ns.  Powers 4 and 1, P = 5.
  // coherent |2 + 1|^2 = 9, incoherent 5.
  // mean = (4*10 + 1*40) / 5 = 16 ns; E[tau^2] = (4*100 + 1*1600) / 5 = 400 ns^2;
  // spread = sqrt(400 - 256) = 12 ns.
  const PathStats s = path_stats({make_path(1.0, 40e-9), make_path(2.0, 10e-9)});
  EXPECT_EQ(s.n_paths, 2u);
  EXPECT_NEAR(s.gain_coherent, 9.0, 1e-12);
  EXPECT_NEAR(s.gain_incoherent, 5.0, 1e-12);
  EXPECT_DOUBLE_EQ(s.first_delay_s, 10e-9);
  EXPECT_NEAR(s.mean_delay_s, 16e-9, 1e-18);
  EXPECT_NEAR(s.rms_delay_spread_s, 12e-9, 1e-18);
}

TEST(PathStats, ThreePathsByHand) {
  // a = 1 @ 1 us, 0.5 @ 2 us, -0.5j @ 4 us (given out of order).
  // Powers 1, 0.25, 0.25; P = 1.5.  sum a = 1.5 - 0.5j -> coherent 2.25 + 0.25 = 2.5.
  // mean = (1*1 + 0.25*2 + 0.25*4) / 1.5 = 5/3 us.
  // E[tau^2] = (1*1 + 0.25*4 + 0.25*16) / 1.5 = 4 us^2; var = 4 - 25/9 = 11/9 us^2;
  // spread = sqrt(11)/3 us = 1.10554 us.
  const PathStats s =
      path_stats({make_path(0.5, 2e-6), make_path(cd(0, -0.5), 4e-6), make_path(1.0, 1e-6)});
  EXPECT_EQ(s.n_paths, 3u);
  EXPECT_NEAR(s.gain_coherent, 2.5, 1e-12);
  EXPECT_NEAR(s.gain_incoherent, 1.5, 1e-12);
  EXPECT_DOUBLE_EQ(s.first_delay_s, 1e-6);
  EXPECT_NEAR(s.mean_delay_s, 5.0 / 3.0 * 1e-6, 1e-15);
  EXPECT_NEAR(s.rms_delay_spread_s, std::sqrt(11.0) / 3.0 * 1e-6, 1e-15);
}

TEST(PathStats, CoherentVersusIncoherent) {
  const PathStats in_phase = path_stats({make_path(1.0, 1e-7), make_path(1.0, 2e-7)});
  EXPECT_NEAR(in_phase.gain_coherent, 4.0, 1e-12);
  EXPECT_NEAR(in_phase.gain_incoherent, 2.0, 1e-12);

  const PathStats anti = path_stats({make_path(1.0, 1e-7), make_path(-1.0, 2e-7)});
  EXPECT_NEAR(anti.gain_coherent, 0.0, 1e-12);
  EXPECT_NEAR(anti.gain_incoherent, 2.0, 1e-12);
}

TEST(PathStats, EqualPowerSpreadIsHalfSeparation) {
  const double dt = 300e-9;
  // Phases differ: only the powers weight the delays.
  const PathStats s = path_stats({make_path(std::polar(0.7, 0.3), 2e-6), make_path(std::polar(0.7, 2.1), 2e-6 + dt)});
  EXPECT_NEAR(s.rms_delay_spread_s, dt / 2, 1e-15);
  EXPECT_NEAR(s.mean_delay_s, 2e-6 + dt / 2, 1e-15);
}

TEST(PathStats, SinglePathHasNoSpread) {
  const PathStats s = path_stats({make_path(cd(0.1, -0.2), 3.3e-6)});
  EXPECT_EQ(s.rms_delay_spread_s, 0);
  EXPECT_DOUBLE_EQ(s.mean_delay_s, 3.3e-6);
  EXPECT_DOUBLE_EQ(s.first_delay_s, 3.3e-6);
  EXPECT_NEAR(s.gain_coherent, 0.05, 1e-15);
}

TEST(PathStats, SpreadIsStableAtLargeAbsoluteDelay) {
  // 1 ms absolute delay (300 km) with a 100 ns separation: E[tau^2] - E[tau]^2
  // on absolute delays would cancel ~1e-6 against ~2.5e-15.
  const PathStats s = path_stats({make_path(1.0, 1e-3), make_path(1.0, 1e-3 + 100e-9)});
  EXPECT_NEAR(s.rms_delay_spread_s, 50e-9, 1e-12);
  EXPECT_NEAR(s.mean_delay_s, 1e-3 + 50e-9, 1e-12);
}

TEST(OfdmGrid, Ieee80211p) {
  const OfdmGrid g = ofdm_80211p(5.9e9);
  EXPECT_EQ(g.n_subcarriers, 64);
  EXPECT_DOUBLE_EQ(g.subcarrier_spacing_hz, 156250.0);
  EXPECT_DOUBLE_EQ(g.carrier_hz, 5.9e9);
  EXPECT_DOUBLE_EQ(g.n_subcarriers * g.subcarrier_spacing_hz, 10e6);
  EXPECT_DOUBLE_EQ(g.offset_hz(32), 0.0);
  EXPECT_DOUBLE_EQ(g.offset_hz(0), -5e6);
  EXPECT_DOUBLE_EQ(g.offset_hz(63), 5e6 - 156250.0);
}

TEST(OfdmGrid, NrNumerologies) {
  const OfdmGrid g = ofdm_nr(2, 10, 3.5e9);
  EXPECT_EQ(g.n_subcarriers, 120);
  EXPECT_DOUBLE_EQ(g.subcarrier_spacing_hz, 60e3);
  EXPECT_DOUBLE_EQ(g.carrier_hz, 3.5e9);
  EXPECT_DOUBLE_EQ(ofdm_nr(0, 1).subcarrier_spacing_hz, 15e3);
  EXPECT_DOUBLE_EQ(ofdm_nr(4, 1).subcarrier_spacing_hz, 240e3);
  EXPECT_EQ(ofdm_nr(1, 51).n_subcarriers, 612);

  EXPECT_THROW(ofdm_nr(-1, 10), std::invalid_argument);
  EXPECT_THROW(ofdm_nr(5, 10), std::invalid_argument);
  EXPECT_THROW(ofdm_nr(1, 0), std::invalid_argument);
}

TEST(FrequencyResponse, EmptyIsZero) {
  const auto h = frequency_response({}, ofdm_80211p());
  ASSERT_EQ(h.size(), 64u);
  EXPECT_EQ(energy(h), 0);
}

TEST(FrequencyResponse, SinglePathFlatMagnitudeLinearPhase) {
  const cd a = std::polar(0.3, 0.7);
  const double tau = 250e-9;
  const OfdmGrid g = ofdm_80211p();
  const auto h = frequency_response({make_path(a, tau)}, g);
  ASSERT_EQ(h.size(), 64u);
  EXPECT_NEAR(std::abs(h[32] - a), 0, 1e-15);
  const double step = -2 * kPi * g.subcarrier_spacing_hz * tau;  // -0.245 rad: no wrapping
  for (int k = 0; k < 64; ++k) {
    EXPECT_NEAR(std::abs(h[k]), 0.3, 1e-14) << k;
    if (k > 0) {
      EXPECT_NEAR(std::arg(h[k] / h[k - 1]), step, 1e-12) << k;
    }
  }
}

TEST(FrequencyResponse, CarrierIsCoherentSum) {
  const std::vector<Path> paths{make_path(cd(0.2, 0.1), 1e-6), make_path(cd(-0.05, 0.3), 1.7e-6),
                                make_path(cd(0.01, -0.02), 5e-6)};
  const auto h = frequency_response(paths, ofdm_nr(1, 20));
  EXPECT_NEAR(std::abs(h[120] - cd(0.16, 0.38)), 0, 1e-15);
  EXPECT_NEAR(std::norm(h[120]), path_stats(paths).gain_coherent, 1e-15);
}

TEST(FrequencyResponse, TwoPathNotchesSpacedByInverseDelay) {
  // H = 1 + exp(-j 2 pi f dt) vanishes at f = (m + 1/2) / dt. With dt = 1 us and
  // a 10 kHz grid over +-10 MHz the notches land on subcarriers every 1 MHz.
  const double dt = 1e-6, t1 = 3e-6;
  OfdmGrid g{5.9e9, 10e3, 2000};
  const auto h = frequency_response({make_path(1.0, t1), make_path(1.0, t1 + dt)}, g);
  std::vector<double> minima;
  for (int k = 1; k + 1 < g.n_subcarriers; ++k)
    if (std::abs(h[k]) < std::abs(h[k - 1]) && std::abs(h[k]) < std::abs(h[k + 1])) {
      minima.push_back(g.offset_hz(k));
      EXPECT_LT(std::abs(h[k]), 1e-9);
    }
  ASSERT_EQ(minima.size(), 20u);  // -9.5 ... +9.5 MHz
  for (std::size_t i = 0; i < minima.size(); ++i) {
    EXPECT_NEAR(minima[i], (-9.5 + double(i)) * 1e6, 1.0);
    if (i > 0) {
      EXPECT_NEAR(minima[i] - minima[i - 1], 1.0 / dt, 1.0);
    }
  }
}

TEST(FrequencyResponse, WidebandAverageIsIncoherentPower) {
  // Cross terms a_i a_j* exp(-j 2 pi f (tau_i - tau_j)) average out over a span
  // much wider than 1 / (smallest delay difference) = 1 / 137 ns.
  const std::vector<Path> paths{make_path(std::polar(1.0, 0.2), 1e-6), make_path(std::polar(0.8, 2.0), 1.137e-6),
                                make_path(std::polar(0.5, -1.1), 1.412e-6), make_path(std::polar(0.6, 0.9), 1.9e-6)};
  const OfdmGrid g{5.9e9, 156250.0, 1024};  // 160 MHz
  const auto h = frequency_response(paths, g);
  const double mean = energy(h) / double(h.size());
  const double incoherent = path_stats(paths).gain_incoherent;
  EXPECT_NEAR(mean / incoherent, 1.0, 0.03);
}

TEST(ImpulseResponse, InvalidArguments) {
  const std::vector<Path> p{make_path(1.0, 1e-6)};
  EXPECT_THROW(impulse_response(p, 0, 10e6, 16), std::invalid_argument);
  EXPECT_THROW(impulse_response(p, -1, 10e6, 16), std::invalid_argument);
  EXPECT_THROW(impulse_response(p, 10e6, 0, 16), std::invalid_argument);
  EXPECT_THROW(impulse_response(p, 10e6, 10e6, 0), std::invalid_argument);
}

TEST(ImpulseResponse, EmptyPathsGiveZeroTaps) {
  const ImpulseResponse ir = impulse_response({}, 10e6, 20e6, 8);
  EXPECT_EQ(ir.t0_s, 0);
  EXPECT_DOUBLE_EQ(ir.sample_period_s, 50e-9);
  ASSERT_EQ(ir.taps.size(), 8u);
  EXPECT_EQ(energy(ir.taps), 0);
}

TEST(ImpulseResponse, OnSamplePathIsOneTap) {
  const cd a = std::polar(0.4, -1.2);
  const double T = 100e-9;
  // lead of 3 samples puts the path on tap 3; with B = 1/T every other tap
  // sits on a zero of the sinc.
  const ImpulseResponse ir = impulse_response({make_path(a, 2e-6)}, 10e6, 10e6, 16, 3 * T);
  EXPECT_NEAR(ir.t0_s, 2e-6 - 3 * T, 1e-18);
  EXPECT_DOUBLE_EQ(ir.sample_period_s, T);
  ASSERT_EQ(ir.taps.size(), 16u);
  for (int n = 0; n < 16; ++n) {
    if (n == 3)
      EXPECT_NEAR(std::abs(ir.taps[n] - a), 0, 1e-12);
    else
      EXPECT_LT(std::abs(ir.taps[n]), 1e-12) << n;
  }
}

TEST(ImpulseResponse, OffSampleEnergyIsPreserved) {
  // sum_n sinc^2(n - x) = 1 for any x; the truncation tail of N centred taps
  // is about 4 / (pi^2 N) = 0.6 % for N = 64.
  const cd a = std::polar(0.9, 2.5);
  const double T = 100e-9;
  const int n_taps = 64;
  const ImpulseResponse ir = impulse_response({make_path(a, 1e-6)}, 10e6, 10e6, n_taps, 31.37 * T);
  EXPECT_NEAR(energy(ir.taps) / std::norm(a), 1.0, 0.02);
  EXPECT_LE(energy(ir.taps), std::norm(a) * (1 + 1e-12));
}

TEST(ImpulseResponse, TapsDtftMatchesFrequencyResponse) {
  // With fs >= B the band-limited sampling does not alias, so for |f| < B/2:
  //   H(f) = T B exp(-j 2 pi f t0) sum_n h[n] exp(-j 2 pi f n T).
  // B = 20 MHz, fs = 40 MHz; the 10 MHz 802.11p grid sits well inside the band,
  // away from the rect edges where truncation rings. The sinc tails decay as
  // 1/n, so the truncation error falls as 1/n_taps: ~0.5 % worst case here.
  const std::vector<Path> paths{make_path(std::polar(1.0, 0.4), 2e-6), make_path(std::polar(0.6, -2.0), 2.0312e-6),
                                make_path(std::polar(0.3, 1.3), 2.4567e-6)};
  const double B = 20e6, fs = 40e6, T = 1 / fs;
  const int n_taps = 2048;
  const ImpulseResponse ir = impulse_response(paths, B, fs, n_taps, 1000 * T);
  const OfdmGrid g = ofdm_80211p();
  const auto h = frequency_response(paths, g);
  for (int k = 0; k < g.n_subcarriers; ++k) {
    const double f = g.offset_hz(k);
    cd dtft{0, 0};
    for (int n = 0; n < n_taps; ++n) dtft += ir.taps[n] * std::polar(1.0, -2 * kPi * f * n * ir.sample_period_s);
    const cd est = T * B * std::polar(1.0, -2 * kPi * f * ir.t0_s) * dtft;
    EXPECT_LT(std::abs(est - h[k]) / std::abs(h[k]), 1e-2) << "k=" << k << " f=" << f;
  }
}

// The response by its definition, one phasor per path and subcarrier.
TEST(Channel, FrequencyResponseMatchesTheDirectSumOnWideGridsAndLongDelays) {
  std::vector<Path> paths;
  for (int i = 0; i < 40; ++i)
    paths.push_back(make_path(std::polar(1e-4 / (1 + i), 0.37 * i), 2e-7 + 2.5e-7 * i));  // up to 10 us
  for (const OfdmGrid& g : {ofdm_80211p(), ofdm_nr(1, 273), ofdm_nr(0, 1)}) {
    const auto h = frequency_response(paths, g);
    ASSERT_EQ(h.size(), static_cast<std::size_t>(g.n_subcarriers));
    double worst = 0, scale = 0;
    for (int k = 0; k < g.n_subcarriers; ++k) {
      cd direct{0, 0};
      for (const Path& p : paths) direct += p.a * std::polar(1.0, -2 * kPi * g.offset_hz(k) * p.tau_s);
      worst = std::max(worst, std::abs(h[k] - direct));
      scale = std::max(scale, std::abs(direct));
    }
    EXPECT_LT(worst, 1e-11 * scale) << g.n_subcarriers << " subcarriers";
  }
}

// --- Channel summaries (tracer/channel_summary.hpp) ----------------------------

namespace {
Path angled(double amplitude, double tau, double theta, double phi, double doppler) {
  Path p = make_path(cd(amplitude, 0), tau);
  p.theta_t = p.theta_r = theta;
  p.phi_t = phi;
  p.phi_r = -phi;
  p.doppler_hz = doppler;
  return p;
}
}  // namespace

TEST(ChannelSummary, HandComputedTwoPaths) {
  // Powers 4 (at 2 us) and 1 (at 1 us, the first): K = 4; the strongest is the later one.
  const std::vector<Path> paths = {angled(1, 1e-6, 1.2, -0.3, -100), angled(2, 2e-6, 1.0, 0.3, 100)};
  const ChannelSummary s = channel_summary(paths);
  EXPECT_DOUBLE_EQ(s.k_factor, 4.0);
  EXPECT_EQ(s.strongest_delay_s, 2e-6);
  EXPECT_EQ(s.strongest_theta_t, 1.0);
  EXPECT_EQ(s.strongest_phi_t, 0.3);
  EXPECT_EQ(s.strongest_phi_r, -0.3);
  // Doppler: mean (400 - 100) / 5 = 60, variance (4 * 40^2 + 160^2) / 5 = 6400.
  EXPECT_NEAR(s.rms_doppler_spread_hz, 80.0, 1e-9);
  // Zenith: weights 4 at 1.0 and 1 at 1.2: mean 1.04, variance (4 * 0.04^2 + 0.16^2) / 5 = 0.0064.
  EXPECT_NEAR(s.zenith_spread_t, 0.08, 1e-12);
  EXPECT_NEAR(s.zenith_spread_r, 0.08, 1e-12);
  // Azimuth: |4 e^{0.3j} + e^{-0.3j}| / 5 = sqrt(16 + 1 + 8 cos 0.6) / 5.
  const double r = std::sqrt(17 + 8 * std::cos(0.6)) / 5;
  EXPECT_NEAR(s.azimuth_spread_t, std::sqrt(-2 * std::log(r)), 1e-12);
  EXPECT_NEAR(s.azimuth_spread_r, s.azimuth_spread_t, 1e-12);
  EXPECT_EQ(s.diffuse_gain, 0.0);
}

TEST(ChannelSummary, AzimuthSpreadIgnoresTheWrap) {
  // Equal powers just either side of phi = pi: the same spread as either side of 0
  // (sqrt(-2 ln cos 0.1) ~ 0.1), where an RMS of the raw angles would give ~pi.
  const std::vector<Path> near_pi = {angled(1, 1e-6, 1, kPi - 0.1, 0), angled(1, 2e-6, 1, -kPi + 0.1, 0)};
  const std::vector<Path> near_0 = {angled(1, 1e-6, 1, 0.1, 0), angled(1, 2e-6, 1, -0.1, 0)};
  const double expect = std::sqrt(-2 * std::log(std::cos(0.1)));
  EXPECT_NEAR(channel_summary(near_pi).azimuth_spread_t, expect, 1e-9);
  EXPECT_NEAR(channel_summary(near_0).azimuth_spread_t, expect, 1e-9);
  EXPECT_LT(expect, 0.101);
  // Equal powers: the first of them is the strongest, and K = 1.
  EXPECT_EQ(channel_summary(near_0).strongest_delay_s, 1e-6);
  EXPECT_DOUBLE_EQ(channel_summary(near_0).k_factor, 1.0);
}

TEST(ChannelSummary, DiffusePowerAndDegenerateSets) {
  Path diffuse = angled(3, 5e-6, 1, 0, 0);
  diffuse.interactions.push_back({InteractionType::specular, 0, 0, {0, 0, 0}});
  diffuse.interactions.push_back({InteractionType::diffuse, 1, 0, {1, 0, 0}});
  Path specular = angled(1, 4e-6, 1, 0, 0);
  specular.interactions.push_back({InteractionType::specular, 0, 0, {0, 0, 0}});
  EXPECT_DOUBLE_EQ(channel_summary({specular, diffuse}).diffuse_gain, 9.0);
  // One path: K infinite, no spread; none: all zero.
  const ChannelSummary one = channel_summary({specular});
  EXPECT_TRUE(std::isinf(one.k_factor) && one.k_factor > 0);
  EXPECT_EQ(one.azimuth_spread_t, 0.0);
  EXPECT_EQ(one.rms_doppler_spread_hz, 0.0);
  const ChannelSummary none = channel_summary({});
  EXPECT_EQ(none.k_factor, 0.0);
  EXPECT_EQ(none.strongest_delay_s, 0.0);
  // Opposite azimuths of equal power cancel: the circular spread grows without bound
  // (rounding leaves a resultant of ~1e-16, sqrt(-2 ln 1e-16) ~ 8.6).
  EXPECT_GT(channel_summary({angled(1, 1e-6, 1, 0.5, 0), angled(1, 2e-6, 1, 0.5 - kPi, 0)}).azimuth_spread_t, 5.0);
}
