// In-memory records of a channel dataset: what the sweep produces per frame
// and what the HDF5 writer (dataset_writer.hpp) stores. The layout and the
// meaning of every field and code are specified in schemas/.
//
// Nodes are the antennas of the dataset: road-side units first (known up
// front), then vehicles in order of first appearance in the traffic. Their
// index is stable over the whole dataset; links name nodes by it. Objects
// are the static scene objects (buildings, ground) followed by one object
// per node, so an interaction on vehicle node n has object
// static_object_count + n.
#pragma once

#include <complex>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

namespace raysweep::generators {

enum class NodeKind : std::uint8_t { vehicle = 0, rsu = 1 };

struct NodeInfo {
  std::string id;      // SUMO vehicle id or RSU id
  NodeKind kind = NodeKind::vehicle;
  std::string vclass;  // library class ("" for RSUs)
  std::string vtype;   // SUMO vType ("" when unknown or an RSU)
  float length_m = 0, width_m = 0, height_m = 0;  // 0 for RSUs
};

// A node's state in one frame. Position: vehicles' front-bumper centre on the
// road (SUMO convention) with z the road height; RSUs' antenna position.
struct NodeState {
  std::uint32_t node = 0;
  double x = 0, y = 0, z = 0;
  float vx = 0, vy = 0, vz = 0;  // m/s
  float heading_deg = 0;         // clockwise from north (SUMO)
};

// Link flags (bit field).
enum LinkFlags : std::uint8_t {
  kLinkCached = 1,      // channel reused from an earlier frame (path cache / update rule)
  kLinkOutOfRange = 2,  // beyond free-space reach of the sensitivity: not traced, no paths
  kLinkEnclosed = 4,    // an end's antenna stands inside a building's closed volume (channels through walls)
};

struct LinkRecord {
  std::uint32_t tx = 0, rx = 0;  // node indices, tx < rx
  std::uint8_t los_class = 0;    // tracer::LosClass: 0 LOS, 1 NLOSV, 2 NLOS
  std::uint8_t flags = 0;        // LinkFlags
  std::uint16_t blocker_count = 0;
  float gain_coherent_db = 0;    // 10 log10 |sum a|^2; -inf when no path
  float gain_incoherent_db = 0;  // 10 log10 sum |a|^2; -inf when no path
  double first_delay_s = 0;      // 0 when no path
  float rms_delay_spread_s = 0;
  std::uint32_t path_count = 0;  // this link's paths follow the previous links' paths in FrameRecord::paths
  std::uint32_t paths_below_threshold = 0;  // found but dropped: tracer.path_threshold_db below the strongest
  std::uint8_t los_class_fresnel = 0;  // the label by the first Fresnel zone (tracer/src/fresnel_zone.hpp)
  float fresnel_clearance = 1;         // worst obstacle's h / r1 (negative: crossed), capped at 1
  float vehicle_loss_db = 0;           // vehicles' knife-edge loss on the direct path (>= 0)
  // Summaries of every path (tracer/channel_summary.hpp), kept at every store level.
  std::uint32_t paths_beyond_top_k = 0;  // in the gains but not stored (paths_top_k); not in path_count
  // 10 log10 sum |a|^2 of the paths with a diffuse interaction
  float diffuse_gain_db = -std::numeric_limits<float>::infinity();
  // The strongest path's power over the others' (+inf: one path)
  float k_factor_db = -std::numeric_limits<float>::infinity();
  float rms_doppler_spread_hz = 0;
  float aod_spread[2] = {0, 0};  // zenith (RMS), azimuth (circular) spreads at departure, rad
  float aoa_spread[2] = {0, 0};  // and at arrival
  // The strongest path's delay less first_delay_s, and its directions (theta,
  // phi); 0 without paths.
  float strongest_excess_delay_s = 0;
  float strongest_aod[2] = {0, 0};
  float strongest_aoa[2] = {0, 0};
};

struct PathRecord {
  std::complex<float> a;  // baseband gain at the carrier incl. exp(-j 2 pi f tau)
  double tau_s = 0;
  float theta_t = 0, phi_t = 0;  // departure (rad, zenith from +z, azimuth from +x CCW)
  float theta_r = 0, phi_r = 0;  // arrival, pointing from rx towards the incoming wave
  float doppler_hz = 0;
  std::uint8_t interaction_count = 0;  // this path's interactions follow the previous paths' ones
};

struct InteractionRecord {
  std::uint8_t type = 0;     // tracer::InteractionType: 1 specular, 2 refraction, 3 diffuse, 4 diffraction
  std::uint32_t object = 0;  // index into the dataset's object table
  float x = 0, y = 0, z = 0; // interaction point (scene frame, m); NaN where the level stores none
};

// What a dataset stores, cumulatively (schemas/README.md, "Store levels"):
// links: every link column; cfr: + the frequency responses; paths: + the
// paths and their interactions' types and objects; full: + the interaction
// points. Link columns and CFR are computed from every path whatever the level.
enum class StoreLevel : std::uint8_t { links = 0, cfr = 1, paths = 2, full = 3 };

// One traced frame. Links are sorted by (tx, rx); paths by link then delay.
// Below the paths level `paths` and `interactions` are empty and a link's
// path_count counts the paths its gains sum; below cfr, `cfr` is empty.
struct FrameRecord {
  double time_s = 0;
  std::vector<NodeState> nodes;  // nodes present in this frame, sorted by node index
  std::vector<LinkRecord> links;
  std::vector<PathRecord> paths;
  std::vector<InteractionRecord> interactions;
  // Optional frequency responses: links.size() x subcarriers, row-major
  // (empty when the dataset stores none).
  std::vector<std::complex<float>> cfr;
};

}  // namespace raysweep::generators
