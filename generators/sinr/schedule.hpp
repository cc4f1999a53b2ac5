// Medium access of the two RATs on the shared channel: which transmissions the
// generated messages become.
//  - NR-V2X sidelink Mode 2 semi-persistent scheduling (TS 38.321 5.22.1.1, TS
//    38.214 8.1.4): a grant of one slot and subchannels every reservation period,
//    a reselection counter, random or sensing-based selection, blind retransmissions.
//    NR does not listen to 802.11p, so its schedule is computed first.
//  - IEEE 802.11p EDCA for broadcast frames: CCA (preamble and energy detection,
//    NR transmissions count as energy), AIFS, backoff frozen while busy, no ACKs.
// The channel model supplies the received powers both need (sensing, CCA); every
// transmission carries its channel gains to all nodes at its start, which the
// SINR evaluation reuses.
#pragma once

#include <cstdint>
#include <vector>

#include "generators/sinr/channel_models.hpp"
#include "generators/sinr/messages.hpp"
#include "generators/sinr/sinr_config.hpp"
#include "generators/sinr/types.hpp"

namespace raysweep::generators::sinr {

struct Schedule {
  std::vector<Transmission> transmissions;  // sorted by (start, node, packet, attempt)
  std::uint32_t nodes = 0;
  // Channel gain (dB) from each transmission's sender to every node at the
  // transmission's start: gain_db[row * nodes + node]; -inf for absent nodes and
  // for the sender itself.
  std::vector<float> gain_db;
  std::uint64_t packets = 0;          // messages handed to the MACs
  std::uint64_t wifi_dropped = 0;     // 802.11p frames replaced in the queue by a newer message
  std::uint64_t nr_dropped = 0;       // NR packets that found no resource (larger than the channel)
  double nr_mean_latency_s = 0, wifi_mean_latency_s = 0;  // generation to first transmission
  float gain(std::size_t row, std::uint32_t node) const { return gain_db[row * nodes + node]; }
};

// Messages must be sorted by time (generate_messages()); packet id = message index.
Schedule schedule_transmissions(const ChannelTrace& trace, const ChannelModel& channel, const std::vector<Rat>& rats,
                                const std::vector<GeneratedMessage>& messages, const SinrConfig& config);

// The channel gains of given transmissions (an earlier run's schedule reused with
// another channel model).
Schedule schedule_from(const ChannelTrace& trace, const ChannelModel& channel, std::vector<Transmission> transmissions);

// EDCA parameters of an access category for OCB (IEEE 802.11-2016 Table 10-27 with
// aCWmin 15, aCWmax 1023): AIFSN, CWmin, CWmax. Throws std::invalid_argument.
struct EdcaParams {
  int aifsn, cw_min, cw_max;
};
EdcaParams edca_params(const std::string& access_category);

// Reselection counter range of TS 38.321 5.22.1.1 for a reservation period:
// [5 m, 15 m] with m = ceil(100 ms / max(20 ms, period)).
std::pair<int, int> sps_counter_range(double reservation_period_s);

}  // namespace raysweep::generators::sinr
