// Channel models of the SINR generator, one interface: the ray-traced channel
// of a dataset, and the 3GPP stochastic baselines it is compared with.
//
//   ray             wideband gain and LoS class of the traced link (no shadowing:
//                   the tracer resolves what shadowing models statistically)
//   tr36885         3GPP TR 36.885 A.1.4 V2V urban: WINNER+ B1 path loss with
//                   effective antenna heights h - 1 m, LoS probability
//                   min(18/d, 1)(1 - e^(-d/36)) + e^(-d/36); log-normal shadowing
//                   3 dB (LOS) / 4 dB (NLOS) (what ms-van3t uses for 802.11p)
//   tr37885-urban   3GPP TR 37.885 6.2.1 V2V urban: LOS / NLOSV / NLOS path loss,
//   tr37885-highway highway; LOS / NLOSV / NLOS probabilities, vehicle blockage
//                   loss for NLOSV, shadowing (what ns-3 3.37 implements)
//
// Stochastic state is spatially consistent: per unordered node pair, Gaussian
// processes (LoS draw, shadowing, blockage) evolve frame to frame as AR(1) with
// correlation exp(-dd / decorrelation) where dd is the relative displacement of
// the two nodes since the previous frame. Every draw is a hash of (seed, pair,
// frame, process), so a result depends neither on query order nor on threads.
// With los_from_ray the LoS class comes from the traced link instead (the
// VaN3Twin paper's fair comparison); path loss and shadowing stay stochastic.
#pragma once

#include <cstdint>
#include <memory>
#include <string>

#include "generators/sinr/channel_trace.hpp"

namespace raysweep::generators::sinr {

enum class ChannelModelKind { ray, tr36885, tr37885_urban, tr37885_highway };
const char* channel_model_name(ChannelModelKind k);           // "ray", "tr36885", "tr37885-urban", "tr37885-highway"
ChannelModelKind parse_channel_model(const std::string& name);  // throws std::invalid_argument listing the names

// One channel model of a comparison, as a config or the command line names it:
// "ray", "tr36885", "tr37885-urban", "tr37885-highway", each 3GPP one
// optionally with "+los-from-ray".
struct SinrModel {
  ChannelModelKind kind = ChannelModelKind::ray;
  bool los_from_ray = false;
  std::string label() const;  // e.g. "tr37885-urban+los-from-ray"
};
SinrModel parse_sinr_model(const std::string& s);  // throws std::invalid_argument

struct StochasticOptions {
  std::uint64_t seed = 1;
  bool los_from_ray = false;
  bool shadowing = true;
  double antenna_height_m = 1.5;    // both ends (TR 36.885 / 37.885 vehicle antenna)
  double blocker_height_m = 1.6;    // TR 37.885 NLOSV blockage (vehicle height)
  double decorrelation_m = 10.0;    // shadowing and LoS-state correlation distance
  double min_distance_m = 3.0;      // formulas are evaluated at >= this distance
};

struct LinkState {
  double gain_db = 0;         // -path loss - shadowing (- blockage); -inf when no channel
  std::uint8_t los_class = 2; // 0 LOS, 1 NLOSV, 2 NLOS
  double distance_m = 0;      // 3D distance of the node positions
};

class ChannelModel {
 public:
  virtual ~ChannelModel() = default;
  // Channel between nodes a and b (reciprocal: link(f, a, b) == link(f, b, a)) in a
  // frame of the trace. Both nodes must be present in the frame (else gain -inf,
  // NLOS). Thread-safe.
  virtual LinkState link(std::size_t frame, std::uint32_t a, std::uint32_t b) const = 0;
  virtual ChannelModelKind kind() const = 0;
};

// The trace must outlive the model. carrier from trace.carrier_hz().
std::unique_ptr<ChannelModel> make_channel_model(ChannelModelKind kind, const ChannelTrace& trace,
                                                 const StochasticOptions& options);

// Closed forms (distances in m, fc in Hz; losses in dB, positive).
namespace formulas {
double tr36885_p_los(double d2d_m);
double tr36885_pathloss_db(bool los, double d3d_m, double fc_hz, double h_tx_m, double h_rx_m);
enum class Tr37885Scenario { urban, highway };
double tr37885_p_los(Tr37885Scenario s, double d2d_m);
double tr37885_p_nlos(Tr37885Scenario s, double d2d_m);  // building NLOS; 0 on highways
double tr37885_pathloss_db(Tr37885Scenario s, std::uint8_t los_class, double d3d_m, double fc_hz);
struct Blockage { double mean_db, sigma_db; };
Blockage tr37885_nlosv_blockage(double d3d_m, double h_tx_m, double h_rx_m, double h_blocker_m);
double shadowing_sigma_db(ChannelModelKind k, std::uint8_t los_class);
}  // namespace formulas

}  // namespace raysweep::generators::sinr
