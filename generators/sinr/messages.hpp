// Application messages of each vehicle: CAMs by the ETSI EN 302 637-2 generation
// rules applied to the traced kinematics, and optional periodic CPMs.
#pragma once

#include <cstdint>
#include <vector>

#include "generators/sinr/channel_trace.hpp"
#include "generators/sinr/sinr_config.hpp"
#include "generators/sinr/types.hpp"

namespace raysweep::generators::sinr {

struct Kinematics {
  double t = 0;
  double x = 0, y = 0;
  double speed_mps = 0;
  double heading_deg = 0;
};

// One vehicle's CAM trigger state (EN 302 637-2 6.1.3). check() is called every
// T_CheckCamGen with the current kinematics; it returns true when a CAM is due.
//  1. dynamics: time since the last CAM >= T_GenCamMin and heading changed by more
//     than 4 deg, or position by more than 4 m, or speed by more than 0.5 m/s;
//     T_GenCam becomes the time since the last CAM;
//  2. time: time since the last CAM >= T_GenCam; after N_GenCam consecutive CAMs
//     by this rule T_GenCam returns to T_GenCamMax.
// The first check always generates a CAM.
class CamTrigger {
 public:
  explicit CamTrigger(const CamConfig& c) : c_(c), t_gen_cam_(c.t_gen_max_s) {}
  bool check(const Kinematics& k);
  // Whether the CAM just generated carries the low-frequency container (first CAM,
  // then when 500 ms have passed since the last one that did).
  bool low_frequency_due() const { return lf_due_; }
  double t_gen_cam() const { return t_gen_cam_; }

 private:
  CamConfig c_;
  bool first_ = true, lf_due_ = false, has_lf_ = false;
  Kinematics last_{};
  double t_gen_cam_;
  double last_lf_ = 0;
  int time_triggered_ = 0;
};

struct GeneratedMessage {
  double t = 0;
  std::uint32_t node = 0;
  Message message = Message::cam;
  std::uint32_t bytes = 0;
};

// Messages of every node with a RAT over [begin, end), sorted by (t, node).
// Each node checks at its own phase (a uniform offset in [0, T_CheckCamGen) drawn
// from the seed) so vehicles sampled at the same FCD instants do not all send at
// once; kinematics are those of the frame in force (sample and hold). A node
// absent from the frame in force sends nothing and restarts its trigger when it
// comes back.
std::vector<GeneratedMessage> generate_messages(const ChannelTrace& trace, const std::vector<Rat>& rats,
                                                const SinrConfig& config, double begin_s, double end_s);

// Deterministic uniform in [0, 1) from integers (counter-based, order independent).
double hash_uniform(std::uint64_t seed, std::uint64_t a, std::uint64_t b = 0, std::uint64_t c = 0);

}  // namespace raysweep::generators::sinr
