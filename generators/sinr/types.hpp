// Shared vocabulary of the SINR generator (VaN3Twin coexistence):
// radio access technologies, transmissions on the shared channel, and the
// outcome of one reception attempt. Codes are part of the SINR file schema
// (schemas/raysweep_sinr.schema.json) and must not be renumbered.
#pragma once

#include <cstdint>
#include <string>

namespace raysweep::generators::sinr {

// Radio access technology of a vehicle. `none`: the vehicle is present (it can
// block and reflect) but sends and receives nothing.
enum class Rat : std::uint8_t { none = 0, wifi80211p = 1, nr_v2x = 2 };

// Kind of application message.
enum class Message : std::uint8_t { cam = 0, cpm = 1 };

const char* rat_name(Rat r);          // "none", "80211p", "nrv2x"
Rat parse_rat(const std::string& s);  // inverse of rat_name; throws std::invalid_argument
const char* message_name(Message m);  // "cam", "cpm"

// One transmission on the shared channel: a packet (or one of its blind
// retransmissions) occupying [start, start + duration) x [f_lo, f_hi) with a
// flat power spectral density power / (f_hi - f_lo).
struct Transmission {
  std::uint32_t node = 0;     // channel-dataset node index of the sender
  Rat rat = Rat::none;
  Message message = Message::cam;
  std::uint64_t packet = 0;   // packet id, unique over the run
  std::uint8_t attempt = 0;   // 0: first transmission; k: k-th blind retransmission
  std::uint32_t size_bytes = 0;
  double start_s = 0, duration_s = 0;
  double f_lo_hz = 0, f_hi_hz = 0;  // occupied band (absolute frequency)
  double power_dbm = 0;             // total transmit power over the band
  double end_s() const { return start_s + duration_s; }
};

// Outcome of one reception attempt (one transmission at one receiver of the same RAT).
struct Reception {
  std::uint32_t transmission = 0;  // row of the transmissions table
  std::uint32_t rx = 0;            // receiver node
  float distance_m = 0;            // tx-rx distance at the start of the transmission
  float prx_dbm = 0;               // received signal power over the signal's band
  float intra_dbm = 0;             // time-averaged interference power from the same RAT, in the signal's band
  float inter_dbm = 0;             // ... from the other RAT (only interferers above the gain threshold)
  float noise_dbm = 0;             // thermal noise (+ noise figure) in the signal's band
  float sinr_db = 0;               // bandwidth-weighted average SINR over the resource blocks
  std::uint8_t los_class = 0;      // channel model's LoS state (0 LOS, 1 NLOSV, 2 NLOS)
  std::uint16_t interferers = 0;   // transmissions counted as interference (intra + inter)
  bool decoded = false;            // sinr_db >= threshold and prx_dbm >= sensitivity
};

// A transmission that overlapped a reception in time and frequency.
struct Interferer {
  std::uint32_t transmission = 0;  // row of the transmissions table
  float gain_db = 0;               // channel gain interferer -> receiver (dB, -inf when no path)
  float power_dbm = 0;             // time-averaged interference power it adds in the signal's band
  bool inter_rat = false;          // of the other RAT
  bool counted = false;            // intra-RAT: always; inter-RAT: gain_db >= the gain threshold
};

// Packet reception ratio of one directed link (tx -> rx) or of a whole RAT: a
// packet counts as received when any of its attempts was decoded.
struct PrrEntry {
  std::uint32_t tx = 0, rx = 0;  // node indices (both 0 in a per-RAT entry)
  Rat rat = Rat::none;
  std::uint64_t packets = 0;     // packets sent while the receiver was present and within the PRR range
  std::uint64_t received = 0;
  float mean_distance_m = 0;     // mean tx-rx distance over those packets
};

}  // namespace raysweep::generators::sinr
