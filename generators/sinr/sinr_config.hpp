// Settings of the SINR generator ([sinr] table of a city config; defaults from
// the VaN3Twin paper's tables where it gives them).
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "generators/sinr/phy.hpp"
#include "generators/sinr/types.hpp"

namespace raysweep::generators::sinr {

// Which vehicles use which RAT. Precedence: ids lists, then per-vType, then the
// NR fraction over the remaining vehicles (an exact split, drawn with the seed).
// RSUs are silent unless listed.
struct RatAssignment {
  double nr_fraction = 0.5;
  std::map<std::string, Rat> by_vtype;
  std::vector<std::string> nr_ids, wifi_ids, silent_ids;
  // Only the first `active_vehicles` vehicles in order of appearance take part
  // (0: all); the others are present in the channel (they block and reflect) but silent.
  std::uint32_t active_vehicles = 0;
  // "both", "80211p-only" or "nrv2x-only": silences the other RAT after the
  // assignment, so the same vehicles keep their RAT (the paper's no-coexistence run).
  std::string enabled = "both";
};

// ETSI EN 302 637-2 CAM generation (no DCC: T_GenCam_Dcc = T_GenCamMin).
struct CamConfig {
  bool enabled = true;
  double t_gen_min_s = 0.1, t_gen_max_s = 1.0;
  double check_period_s = 0.1;  // T_CheckCamGen
  double heading_deg = 4, position_m = 4, speed_mps = 0.5;
  int n_gen_cam = 3;
  std::uint32_t bytes = 300;            // PSDU / transport block of a CAM
  std::uint32_t low_frequency_bytes = 0; // added when the low-frequency container is due (every 500 ms)
};

struct CpmConfig {
  bool enabled = false;
  double period_s = 0.1;
  std::uint32_t bytes = 800;
};

// IEEE 802.11p EDCA for broadcast (no ACK, CW stays at CWmin).
struct WifiMacConfig {
  std::string access_category = "BE";  // BK, BE, VI, VO (IEEE 802.11-2016 OCB defaults)
  double cca_signal_dbm = -85;   // an 802.11p preamble received above this makes the medium busy
  double cca_energy_dbm = -65;   // any in-band energy above this makes the medium busy (NR included)
  static constexpr double kSlotS = 13e-6, kSifsS = 32e-6;
};

// NR-V2X sidelink Mode 2 semi-persistent scheduling.
struct NrMacConfig {
  double reservation_period_s = 0.02;
  bool sensing = false;                 // false: random selection (the paper); true: TS 38.214 8.1.4 exclusion
  double sensing_threshold_dbm = -110;  // RSRP per resource element above which a reserved resource is excluded
  double sensing_window_s = 1.0;        // reservations of UEs heard within this window are known
  double min_candidate_ratio = 0.2;     // raise the threshold by 3 dB until this share of candidates remains
  double keep_probability = 0.0;        // sl-ProbResourceKeep
  int retransmissions = 0;              // blind retransmissions per packet (within 32 slots)
  int t1_slots = 1;                     // selection window [n + T1, n + T2]
  int t2_slots = 0;                     // 0: the reservation period
};

struct SinrConfig {
  RatAssignment rats;
  CamConfig cam;
  CpmConfig cpm;
  WifiPhy wifi;
  NrPhy nr;
  WifiMacConfig wifi_mac;
  NrMacConfig nr_mac;
  double tx_power_dbm = 30;
  double sensitivity_dbm = -93;
  double sinr_threshold_db = 10;
  double noise_figure_db = 9;
  double gain_threshold_db = -120;  // inter-RAT interferers count only above this channel gain
  // Optional BLER-vs-SINR curves replacing the threshold: points (sinr_db, bler),
  // increasing SINR, interpolated linearly in SINR and clamped at the ends.
  std::vector<std::pair<double, double>> wifi_bler, nr_bler;
  double prr_range_m = 150;       // receivers within this distance count in PRR
  double max_receiver_distance_m = 0;  // 0: every present receiver of the RAT gets a row
  double begin_s = -1, end_s = -1;  // simulated window within the channel dataset (-1: all of it)
  std::uint64_t seed = 1;

  // Throws std::invalid_argument naming the setting when something is out of range.
  void check() const;
};

}  // namespace raysweep::generators::sinr
