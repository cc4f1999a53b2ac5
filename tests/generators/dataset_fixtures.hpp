// Channel dataset records shared by the dataset and frame block tests: three
// frames of an RSU and two vehicles with every kind of link, path and
// interaction, and scratch files.
#pragma once

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <bit>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "generators/dataset/dataset.hpp"
#include "generators/dataset/dataset_writer.hpp"
#include "test_util.hpp"

namespace raysweep::generators::fixtures {

inline constexpr float kNoGain = -std::numeric_limits<float>::infinity();
inline constexpr std::uint32_t kK = 4;  // subcarriers
inline constexpr std::uint32_t kStaticObjects = 3;

inline std::filesystem::path tmp_dir(const std::string& name) {
  return raysweep::test::scratch_dir(name + "-" + std::to_string(::getpid()));
}

// ---------------------------------------------------------------------------
// Test records: 1 RSU (node 0) and 2 vehicles (nodes 1, 2), three frames, links
// with 1, 3 and 0 paths (one out of range with -inf gains), interactions, CFR.

struct Builder {
  std::uint32_t path_counter = 0, interaction_counter = 0, link_counter = 0;

  NodeState state(std::uint32_t node, double t) {
    NodeState s;
    s.node = node;
    s.x = 10.0 + 25.0 * node + 12.5 * t;
    s.y = 20.0 - 3.0 * node;
    s.z = node == 0 ? 6.0 : 0.25;
    s.vx = node == 0 ? 0.f : 12.5f;
    s.vy = node == 2 ? -1.5f : 0.f;
    s.vz = 0.f;
    s.heading_deg = node == 0 ? 0.f : 90.f + static_cast<float>(node);
    return s;
  }

  // Adds a link with paths whose interaction counts and objects are given.
  void link(FrameRecord& f, std::uint32_t tx, std::uint32_t rx, std::uint8_t los, std::uint8_t flags,
            const std::vector<std::vector<std::uint32_t>>& path_objects) {
    LinkRecord l;
    l.tx = tx;
    l.rx = rx;
    l.los_class = los;
    l.flags = flags;
    l.blocker_count = static_cast<std::uint16_t>(los == 0 ? 0 : los + 1);
    l.path_count = static_cast<std::uint32_t>(path_objects.size());
    const std::uint32_t li = link_counter++;
    l.paths_below_threshold = (flags & kLinkOutOfRange) ? 0 : 7 * li + 1;
    l.los_class_fresnel = static_cast<std::uint8_t>(std::max<int>(los, li % 3));
    l.fresnel_clearance = 1.0f - 0.37f * static_cast<float>(li);
    l.vehicle_loss_db = 2.5f * static_cast<float>(li % 4);
    // Summaries: any values (the writer stores them as given).
    l.diffuse_gain_db = li % 2 ? -70.5f - static_cast<float>(li) : kNoGain;
    l.k_factor_db = path_objects.size() == 1 ? std::numeric_limits<float>::infinity() : 3.25f * static_cast<float>(li);
    l.rms_doppler_spread_hz = 1.5f * static_cast<float>(li);
    l.aod_spread[0] = 0.01f * static_cast<float>(li), l.aod_spread[1] = 0.02f * static_cast<float>(li);
    l.aoa_spread[0] = 0.03f * static_cast<float>(li), l.aoa_spread[1] = 0.04f * static_cast<float>(li);
    l.strongest_excess_delay_s = 1e-8f * static_cast<float>(li % 3);
    l.strongest_aod[0] = 1.25f, l.strongest_aod[1] = -0.5f * static_cast<float>(li);
    l.strongest_aoa[0] = 1.75f, l.strongest_aoa[1] = 0.5f * static_cast<float>(li);
    if (path_objects.empty()) {
      l.gain_coherent_db = kNoGain;
      l.gain_incoherent_db = kNoGain;
      l.first_delay_s = 0;
      l.rms_delay_spread_s = 0;
    } else {
      l.gain_coherent_db = -60.5f - static_cast<float>(li);
      l.gain_incoherent_db = -61.25f - static_cast<float>(li);
      l.first_delay_s = 1e-7 * (li + 1);
      l.rms_delay_spread_s = 2.5e-9f * static_cast<float>(li);
    }
    f.links.push_back(l);
    for (std::size_t p = 0; p < path_objects.size(); ++p) {
      const std::uint32_t j = path_counter++;
      PathRecord r;
      r.a = {1e-3f * static_cast<float>(j + 1), -5e-4f * static_cast<float>(j)};
      r.tau_s = l.first_delay_s + 1e-8 * static_cast<double>(p);
      r.theta_t = 0.1f * static_cast<float>(j), r.phi_t = -0.2f * static_cast<float>(j);
      r.theta_r = 1.5f - 0.05f * static_cast<float>(j), r.phi_r = 3.0f - 0.1f * static_cast<float>(j);
      r.doppler_hz = 10.f * static_cast<float>(j) - 30.f;
      r.interaction_count = static_cast<std::uint8_t>(path_objects[p].size());
      f.paths.push_back(r);
      for (std::uint32_t obj : path_objects[p]) {
        const std::uint32_t m = interaction_counter++;
        InteractionRecord it;
        it.type = static_cast<std::uint8_t>(1 + m % 4);
        it.object = obj;
        it.x = static_cast<float>(m), it.y = 2.f * static_cast<float>(m), it.z = 0.5f * static_cast<float>(m);
        f.interactions.push_back(it);
      }
    }
    for (std::uint32_t k = 0; k < kK; ++k)
      f.cfr.emplace_back(static_cast<float>(li * 10 + k), -0.5f * static_cast<float>(k));
  }

  std::vector<FrameRecord> frames() {
    std::vector<FrameRecord> out(3);
    out[0].time_s = 0.0;
    out[1].time_s = 0.1;
    out[2].time_s = 0.2;
    for (std::uint32_t n : {0u, 1u, 2u}) out[0].nodes.push_back(state(n, 0.0));
    link(out[0], 0, 1, 0, 0, {{}});                 // LOS, 1 direct path
    link(out[0], 0, 2, 2, 0, {{0}, {1, 2}, {}});    // NLOS, 3 paths
    link(out[0], 1, 2, 1, kLinkOutOfRange, {});     // out of range: no paths
    for (std::uint32_t n : {0u, 1u, 2u}) out[1].nodes.push_back(state(n, 0.1));
    link(out[1], 0, 1, 0, kLinkCached, {{kStaticObjects + 1}});
    link(out[1], 1, 2, 1, 0, {{kStaticObjects + 2, 0}, {}, {2}});
    for (std::uint32_t n : {0u, 2u}) out[2].nodes.push_back(state(n, 0.2));  // vehicle 1 has left
    link(out[2], 0, 2, 2, 0, {{0, 1, 2}});
    return out;
  }
};

// A value's bits (floats compared bit for bit: NaN payloads, -0 and -inf included).
template <class T>
auto bits(T v) {
  if constexpr (std::is_same_v<T, float>)
    return std::bit_cast<std::uint32_t>(v);
  else if constexpr (std::is_same_v<T, double>)
    return std::bit_cast<std::uint64_t>(v);
  else
    return v;
}

// Every link column but the path counts, bit for bit.
inline void expect_same_link_columns(const LinkRecord& p, const LinkRecord& q) {
  EXPECT_EQ(std::pair(p.tx, p.rx), std::pair(q.tx, q.rx));
  EXPECT_EQ(p.los_class, q.los_class);
  EXPECT_EQ(p.flags, q.flags);
  EXPECT_EQ(p.blocker_count, q.blocker_count);
  EXPECT_EQ(bits(p.gain_coherent_db), bits(q.gain_coherent_db));
  EXPECT_EQ(bits(p.gain_incoherent_db), bits(q.gain_incoherent_db));
  EXPECT_EQ(bits(p.first_delay_s), bits(q.first_delay_s));
  EXPECT_EQ(bits(p.rms_delay_spread_s), bits(q.rms_delay_spread_s));
  EXPECT_EQ(p.paths_below_threshold, q.paths_below_threshold);
  EXPECT_EQ(p.los_class_fresnel, q.los_class_fresnel);
  EXPECT_EQ(bits(p.fresnel_clearance), bits(q.fresnel_clearance));
  EXPECT_EQ(bits(p.vehicle_loss_db), bits(q.vehicle_loss_db));
  EXPECT_EQ(bits(p.diffuse_gain_db), bits(q.diffuse_gain_db));
  EXPECT_EQ(bits(p.k_factor_db), bits(q.k_factor_db));
  EXPECT_EQ(bits(p.rms_doppler_spread_hz), bits(q.rms_doppler_spread_hz));
  EXPECT_EQ(bits(p.strongest_excess_delay_s), bits(q.strongest_excess_delay_s));
  for (int k = 0; k < 2; ++k) {
    EXPECT_EQ(bits(p.aod_spread[k]), bits(q.aod_spread[k]));
    EXPECT_EQ(bits(p.aoa_spread[k]), bits(q.aoa_spread[k]));
    EXPECT_EQ(bits(p.strongest_aod[k]), bits(q.strongest_aod[k]));
    EXPECT_EQ(bits(p.strongest_aoa[k]), bits(q.strongest_aoa[k]));
  }
}

// The node and object tables and the header of the records above.
inline std::vector<NodeInfo> test_nodes() {
  std::vector<NodeInfo> n(3);
  n[0].id = "rsu0";
  n[0].kind = NodeKind::rsu;
  n[1].id = "veh.a";
  n[1].vclass = "passenger";
  n[1].vtype = "DEFAULT_VEHTYPE";
  n[1].length_m = 4.5f, n[1].width_m = 1.8f, n[1].height_m = 1.5f;
  n[2].id = "veh.b";
  n[2].vclass = "truck";
  n[2].vtype = "lorry";
  n[2].length_m = 12.f, n[2].width_m = 2.5f, n[2].height_m = 3.75f;
  return n;
}

inline std::vector<std::string> test_objects() { return {"building/1", "building/2", "ground", "rsu0", "veh.a", "veh.b"}; }

inline DatasetHeader test_header() {
  DatasetHeader h;
  h.raysweep_version = "0.1.0-test";
  h.git_hash = "0123456789ab";
  h.config = {{"sweep", {{"step_s", 0.1}}}};
  h.inputs = {{"fcd", {{"path", "fcd.xml"}, {"sha256", "ab"}}}};
  h.provenance = {{"command", "raysweep sweep"}};
  h.seed = 42;
  h.carrier_hz = 5.9e9;
  h.bandwidth_hz = 10e6;
  h.cfr_subcarriers = kK;
  h.cfr_subcarrier_spacing_hz = 156250;
  return h;
}

inline void write_bytes(const std::filesystem::path& p, const std::string& bytes) {
  std::ofstream out(p, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

}  // namespace raysweep::generators::fixtures
