#include "generators/sinr/phy.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

namespace raysweep::generators::sinr {

namespace {

struct Mcs {
  int qm;
  int r1024;  // code rate x 1024
};
// TS 38.214 Table 5.1.3.1-1 (MCS index table 1 for PDSCH/PSSCH, up to 64QAM).
constexpr Mcs kMcsTable[] = {{2, 120}, {2, 157}, {2, 193}, {2, 251}, {2, 308}, {2, 379}, {2, 449}, {2, 526},
                             {2, 602}, {2, 679}, {4, 340}, {4, 378}, {4, 434}, {4, 490}, {4, 553}, {4, 616},
                             {4, 658}, {6, 438}, {6, 466}, {6, 517}, {6, 567}, {6, 616}, {6, 666}, {6, 719},
                             {6, 772}, {6, 822}, {6, 873}, {6, 910}, {6, 948}};

// TS 38.101-1 Table 5.3.2-1: N_RB per channel bandwidth (MHz) and SCS; 0 = not defined.
struct RbRow {
  int mhz;
  int rb[3];  // 15, 30, 60 kHz
};
constexpr RbRow kRbTable[] = {{5, {25, 11, 0}},    {10, {52, 24, 11}},   {15, {79, 38, 18}},
                              {20, {106, 51, 24}}, {25, {133, 65, 31}},  {30, {160, 78, 38}},
                              {40, {216, 106, 51}}, {50, {270, 133, 65}}};

}  // namespace

void WifiPhy::check() const {
  (void)data_bits_per_symbol();
  if (!(carrier_hz > 0)) throw std::invalid_argument("802.11p carrier must be positive");
}

int WifiPhy::data_bits_per_symbol() const {
  // 10 MHz OFDM: 8 us symbols, so N_DBPS = rate x 8 us.
  const double n = data_rate_bps * kSymbolS;
  const int rounded = static_cast<int>(std::lround(n));
  for (int ok : {24, 36, 48, 72, 96, 144, 192, 216})
    if (rounded == ok && std::abs(n - ok) < 1e-6) return ok;
  throw std::invalid_argument("802.11p data rate " + std::to_string(data_rate_bps / 1e6) +
                              " Mb/s is not one of 3, 4.5, 6, 9, 12, 18, 24, 27 Mb/s");
}

double WifiPhy::frame_duration_s(std::uint32_t psdu_bytes) const {
  const int ndbps = data_bits_per_symbol();
  const std::uint64_t bits = 16 + 8 * std::uint64_t{psdu_bytes} + 6;  // SERVICE + PSDU + tail
  const std::uint64_t symbols = (bits + ndbps - 1) / ndbps;
  return kPreambleS + kSignalS + static_cast<double>(symbols) * kSymbolS;
}

void NrPhy::check() const {
  if (numerology < 0 || numerology > 2)
    throw std::invalid_argument("NR numerology " + std::to_string(numerology) + " not in 0..2 (FR1 sidelink)");
  if (mcs < 0 || mcs >= static_cast<int>(std::size(kMcsTable)))
    throw std::invalid_argument("NR MCS " + std::to_string(mcs) + " not in 0..28");
  if (data_symbols < 1 || data_symbols > 12)
    throw std::invalid_argument("NR data symbols per slot " + std::to_string(data_symbols) + " not in 1..12");
  if (subchannel_rbs < 10 || subchannel_rbs > 100)
    throw std::invalid_argument("NR subchannel size " + std::to_string(subchannel_rbs) +
                                " RBs not in 10..100 (TS 38.331 sl-SubchannelSize)");
  if (rbs() == 0)
    throw std::invalid_argument("NR bandwidth " + std::to_string(bandwidth_hz / 1e6) +
                                " MHz is not defined for numerology " + std::to_string(numerology) +
                                " (TS 38.101-1 Table 5.3.2-1)");
  if (subchannels() < 1)
    throw std::invalid_argument("NR bandwidth " + std::to_string(bandwidth_hz / 1e6) + " MHz has " +
                                std::to_string(rbs()) + " RBs, fewer than one subchannel of " +
                                std::to_string(subchannel_rbs));
}

double NrPhy::subcarrier_spacing_hz() const { return 15e3 * std::ldexp(1.0, numerology); }
double NrPhy::slot_s() const { return 1e-3 / std::ldexp(1.0, numerology); }

int NrPhy::rbs() const {
  if (numerology < 0 || numerology > 2) return 0;
  for (const auto& row : kRbTable)
    if (std::abs(bandwidth_hz - row.mhz * 1e6) < 1.0) return row.rb[numerology];
  return 0;
}

int NrPhy::subchannels() const { return subchannel_rbs > 0 ? rbs() / subchannel_rbs : 0; }

double NrPhy::bits_per_rb() const {
  const Mcs m = kMcsTable[mcs];
  return 12.0 * data_symbols * m.qm * m.r1024 / 1024.0;
}

int NrPhy::subchannels_for(std::uint32_t bytes) const {
  const double bits = 8.0 * bytes + 24.0;  // transport block + CRC
  const int rbs_needed = static_cast<int>(std::ceil(bits / bits_per_rb() - 1e-9));
  return (rbs_needed + subchannel_rbs - 1) / subchannel_rbs;
}

double NrPhy::f_lo_hz(int first_subchannel) const {
  const double grid_lo = carrier_hz - rbs() * rb_bandwidth_hz() / 2;
  return grid_lo + first_subchannel * subchannel_rbs * rb_bandwidth_hz();
}

double NrPhy::f_hi_hz(int first_subchannel, int count) const {
  return f_lo_hz(first_subchannel) + count * subchannel_rbs * rb_bandwidth_hz();
}

double noise_dbm(double bandwidth_hz, double noise_figure_db) {
  return -174.0 + 10.0 * std::log10(bandwidth_hz) + noise_figure_db;
}

}  // namespace raysweep::generators::sinr
