// The coexistence SINR of the VaN3Twin paper (Algorithm 1) on a global
// time-frequency grid spanning both RATs. The signal's band is cut into the
// receiving RAT's resource blocks (NR: 12-subcarrier RBs; 802.11p: its 52
// subcarriers); every overlapping transmission adds, per block, its power
// spectral density times the block's overlap with its band, weighted by the
// share of the signal's duration it overlaps. Per block
//   SINR = P_rx / (N0 + intra-RAT interference + inter-RAT interference),
// where an interferer of the other RAT counts only when its channel gain to the
// receiver is at least the gain threshold (VaN3Twin ignores 802.11p interferers
// beyond 120 dB path loss). The packet SINR is the bandwidth-weighted average of
// the blocks' linear SINR.
#pragma once

#include <cstdint>
#include <vector>

#include "generators/sinr/sinr_config.hpp"
#include "generators/sinr/types.hpp"

namespace raysweep::generators::sinr {

struct OverlapInput {
  std::uint32_t row = 0;                // transmissions-table row of the interferer
  const Transmission* tx = nullptr;
  double gain_db = 0;                   // channel gain interferer -> receiver
};

struct SinrBreakdown {
  double prx_dbm = 0, intra_dbm = 0, inter_dbm = 0, noise_dbm = 0, sinr_db = 0;
  std::uint16_t counted = 0;
  std::vector<Interferer> overlaps;  // one per input overlap, in input order
};

// Resource blocks the receiver resolves in the signal's band.
int resource_blocks(const Transmission& signal, const SinrConfig& c);

SinrBreakdown coexistence_sinr(const Transmission& signal, double signal_gain_db,
                               const std::vector<OverlapInput>& overlaps, const SinrConfig& c);

// Decoding rule: P_rx >= sensitivity and SINR >= threshold, or, with a BLER
// curve for the RAT, u >= BLER(SINR) for a uniform u of the attempt.
bool decodable(Rat rat, double sinr_db, double prx_dbm, const SinrConfig& c, double u);

}  // namespace raysweep::generators::sinr
