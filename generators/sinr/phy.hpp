// Physical-layer arithmetic of the two RATs sharing the 5.9 GHz channel: how
// long an IEEE 802.11p frame lasts, which band it occupies, how many NR-V2X
// sidelink subchannels a packet needs and where they sit, and thermal noise.
#pragma once

#include <cstdint>

namespace raysweep::generators::sinr {

// IEEE 802.11p (IEEE 802.11-2016 clause 17, 10 MHz channel spacing).
struct WifiPhy {
  double carrier_hz = 5.9e9;
  double data_rate_bps = 3e6;  // 3, 4.5, 6, 9, 12, 18, 24 or 27 Mb/s
  static constexpr double kSymbolS = 8e-6;        // OFDM symbol incl. 1.6 us guard interval
  static constexpr double kPreambleS = 32e-6;     // short + long training fields
  static constexpr double kSignalS = 8e-6;        // SIGNAL field (one symbol)
  static constexpr double kSubcarrierHz = 156.25e3;
  static constexpr int kUsedSubcarriers = 52;     // 48 data + 4 pilots

  // Throws std::invalid_argument for a rate 802.11p does not have.
  void check() const;
  int data_bits_per_symbol() const;  // N_DBPS = rate x 4 us... (24 at 3 Mb/s)
  // PPDU duration of a PSDU of `bytes`: preamble + SIGNAL + ceil((16 + 8 bytes + 6) / N_DBPS) symbols.
  double frame_duration_s(std::uint32_t psdu_bytes) const;
  double f_lo_hz() const { return carrier_hz - kUsedSubcarriers / 2 * kSubcarrierHz; }
  double f_hi_hz() const { return carrier_hz + kUsedSubcarriers / 2 * kSubcarrierHz; }
  int resource_units() const { return kUsedSubcarriers; }  // SINR is resolved per subcarrier
};

// NR-V2X sidelink (TS 38.211 numerology, TS 38.101-1 RB counts, TS 38.214 MCS table).
struct NrPhy {
  double carrier_hz = 5.9e9;
  double bandwidth_hz = 10e6;
  int numerology = 2;         // mu: subcarrier spacing 15 kHz x 2^mu
  int subchannel_rbs = 10;
  int mcs = 14;               // index into TS 38.214 Table 5.1.3.1-1 (64QAM table)
  int data_symbols = 10;      // PSSCH symbols per slot carrying data: 14 - AGC - guard - 2 DMRS

  // Throws std::invalid_argument for unsupported numerology/bandwidth/MCS/subchannel size.
  void check() const;
  double subcarrier_spacing_hz() const;
  double rb_bandwidth_hz() const { return 12 * subcarrier_spacing_hz(); }
  double slot_s() const;                    // 1 ms / 2^mu
  int rbs() const;                          // transmission bandwidth configuration N_RB (TS 38.101-1 Table 5.3.2-1)
  int subchannels() const;                  // floor(rbs / subchannel_rbs)
  double bits_per_rb() const;               // 12 x data_symbols x Qm x R
  // Subchannels a packet of `bytes` needs (payload + 24-bit CRC at the MCS);
  // may exceed subchannels() (the caller decides what to do).
  int subchannels_for(std::uint32_t bytes) const;
  // Band of subchannels [first, first + count): the RB grid is centred on the carrier.
  double f_lo_hz(int first_subchannel) const;
  double f_hi_hz(int first_subchannel, int count) const;
};

// Thermal noise power in a band: -174 dBm/Hz + 10 log10(bandwidth) + noise figure.
double noise_dbm(double bandwidth_hz, double noise_figure_db);

// Length of the overlap of [a0, a1) and [b0, b1) (0 when disjoint).
inline double overlap(double a0, double a1, double b0, double b1) {
  const double lo = a0 > b0 ? a0 : b0, hi = a1 < b1 ? a1 : b1;
  return hi > lo ? hi - lo : 0.0;
}

}  // namespace raysweep::generators::sinr
