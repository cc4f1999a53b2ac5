// SINR outcomes of a traffic run: messages -> medium access -> one reception
// attempt per transmission and receiver of the same RAT, decided by the
// coexistence SINR, with PRR per link and per RAT. Written to a raysweep-sinr file.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "generators/sinr/channel_models.hpp"
#include "generators/sinr/sinr_config.hpp"
#include "generators/sinr/sinr_file.hpp"

namespace raysweep::generators::sinr {

// The RAT of every node of the trace (RatAssignment rules). Throws
// std::invalid_argument naming an id of the lists that is not in the trace.
std::vector<Rat> assign_rats(const ChannelTrace& trace, const RatAssignment& a, std::uint64_t seed);

struct SinrRunStats {
  std::uint64_t packets = 0, transmissions = 0, receptions = 0, decoded = 0, interferers = 0;
  std::uint64_t wifi_dropped = 0, nr_dropped = 0;
  double nr_mean_latency_s = 0, wifi_mean_latency_s = 0;
  double time_start_s = 0, time_end_s = 0;
  std::vector<PrrEntry> prr_rats;  // per RAT
};

struct SinrRunProgress {
  std::uint64_t done = 0, total = 0;  // transmissions evaluated
};

// Runs the whole generator into `writer` (which receives header-independent rows
// and finish()). `reuse`: transmissions of an earlier run to evaluate instead of
// scheduling anew (the same packets under another channel model); then `rats`
// must be those of that run.
SinrRunStats run_sinr(const ChannelTrace& trace, const ChannelModel& channel, const SinrConfig& config,
                      const std::vector<Rat>& rats, const std::vector<Transmission>* reuse, SinrWriter& writer,
                      const std::function<void(const SinrRunProgress&)>& progress = {});

// The simulated window: config begin/end clipped to the trace ([first frame, last
// frame + frame step) when unset).
std::pair<double, double> sinr_window(const ChannelTrace& trace, const SinrConfig& config);

}  // namespace raysweep::generators::sinr
