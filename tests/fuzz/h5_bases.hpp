// The valid base files the HDF5 harnesses edit, written by raysweep's own
// writers (small: a handful of nodes, frames and records of every kind).
// Also used by tests/pipeline/test_fuzz_regressions.cpp, so no libFuzzer header here.
#pragma once

#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "generators/dataset/dataset_writer.hpp"
#include "generators/ns3_table/ns3_table.hpp"
#include "generators/sinr/sinr_file.hpp"

namespace raysweep::fuzz {

namespace gen = raysweep::generators;

// Channel dataset: an RSU and two vehicles, three frames, links with 0, 1 and
// 2 paths, interactions on static and vehicle objects, 4-subcarrier CFRs.
inline void write_channel_base(const std::string& path) {
  gen::DatasetHeader h;
  h.raysweep_version = "fuzz";
  h.git_hash = "fuzz";
  h.config = {{"sweep", {{"step_s", 0.1}}}};
  h.inputs = {{"fcd", {{"path", "fcd.xml"}}}};
  h.provenance = {{"command", "fuzz"}};
  h.seed = 1;
  h.carrier_hz = 5.9e9;
  h.bandwidth_hz = 10e6;
  h.cfr_subcarriers = 4;
  h.cfr_subcarrier_spacing_hz = 156250;
  gen::DatasetWriter w(path, h);
  for (int f = 0; f < 3; ++f) {
    gen::FrameRecord r;
    r.time_s = 0.1 * f;
    for (std::uint32_t n = 0; n < (f == 2 ? 2u : 3u); ++n) {
      gen::NodeState s;
      s.node = n;
      s.x = 10.0 * n + f, s.y = 5.0 * n, s.z = n == 0 ? 6 : 0.5;
      s.vx = n == 0 ? 0.f : 10.f;
      s.heading_deg = 90.f;
      r.nodes.push_back(s);
    }
    for (std::uint32_t a = 0; a < r.nodes.size(); ++a)
      for (std::uint32_t b = a + 1; b < r.nodes.size(); ++b) {
        gen::LinkRecord l;
        l.tx = a, l.rx = b;
        l.path_count = (a + b + static_cast<std::uint32_t>(f)) % 3;
        l.los_class = static_cast<std::uint8_t>(l.path_count == 0 ? 2 : a % 2);
        if (l.path_count == 0) {
          l.gain_coherent_db = l.gain_incoherent_db = -std::numeric_limits<float>::infinity();
        } else {
          l.gain_coherent_db = -70.f - static_cast<float>(b);
          l.gain_incoherent_db = -71.f - static_cast<float>(b);
          l.first_delay_s = 1e-7 * (b + 1);
          l.rms_delay_spread_s = 1e-9f;
        }
        r.links.push_back(l);
        for (std::uint32_t p = 0; p < l.path_count; ++p) {
          gen::PathRecord pr;
          pr.a = {1e-4f, -2e-4f * static_cast<float>(p)};
          pr.tau_s = l.first_delay_s + 1e-8 * p;
          pr.interaction_count = static_cast<std::uint8_t>(p);
          r.paths.push_back(pr);
          for (std::uint32_t i = 0; i < p; ++i) {
            gen::InteractionRecord it;
            it.type = static_cast<std::uint8_t>(1 + i % 4);
            it.object = i == 0 ? 0 : 2 + b;  // a building, then a vehicle
            it.x = 1.f, it.y = 2.f, it.z = 3.f;
            r.interactions.push_back(it);
          }
        }
        for (int k = 0; k < 4; ++k) r.cfr.emplace_back(1e-4f * static_cast<float>(k + 1), 0.f);
      }
    w.append(r);
  }
  std::vector<gen::NodeInfo> nodes(3);
  nodes[0].id = "rsu0", nodes[0].kind = gen::NodeKind::rsu;
  nodes[1].id = "veh0", nodes[1].vclass = "passenger", nodes[1].vtype = "DEFAULT_VEHTYPE";
  nodes[1].length_m = 4.5f, nodes[1].width_m = 1.8f, nodes[1].height_m = 1.5f;
  nodes[2].id = "veh1", nodes[2].vclass = "bus", nodes[2].vtype = "bus";
  nodes[2].length_m = 12.f, nodes[2].width_m = 2.5f, nodes[2].height_m = 3.4f;
  w.finish(nodes, {"building/1", "ground", "rsu0", "veh0", "veh1"});
}

// SINR file: an 802.11p RSU, an 802.11p and an NR-V2X vehicle, three
// transmissions, receptions with overlaps, PRR tables.
inline void write_sinr_base(const std::string& path) {
  namespace s = gen::sinr;
  s::SinrHeader h;
  h.raysweep_version = "fuzz";
  h.git_hash = "fuzz";
  h.config = {{"sinr", {{"prr_range_m", 300}}}};
  h.inputs = {{"channels", {{"path", "channels.h5"}}}};
  h.provenance = {{"command", "fuzz"}};
  h.seed = 3;
  h.channel_model = "ray";
  h.carrier_hz = 5.9e9;
  h.sinr_threshold_db = 2;
  h.sensitivity_dbm = -92;
  h.gain_threshold_db = -110;
  h.time_start_s = 0;
  h.time_end_s = 1;
  s::SinrWriter w(path, h);
  auto tx = [](std::uint32_t node, s::Rat rat, std::uint64_t packet, std::uint8_t attempt, double start) {
    s::Transmission t;
    t.node = node, t.rat = rat, t.packet = packet, t.attempt = attempt, t.size_bytes = 300;
    t.start_s = start, t.duration_s = 4e-4;
    t.f_lo_hz = 5.885e9, t.f_hi_hz = 5.895e9, t.power_dbm = 23;
    return t;
  };
  w.add_transmission(tx(0, s::Rat::wifi80211p, 1, 0, 0.0));
  w.add_transmission(tx(2, s::Rat::nr_v2x, 2, 0, 1e-4));
  w.add_transmission(tx(1, s::Rat::wifi80211p, 3, 0, 2e-3));
  auto rec = [](std::uint32_t t, std::uint32_t rx, std::uint16_t interferers, bool decoded) {
    s::Reception r;
    r.transmission = t, r.rx = rx, r.distance_m = 40, r.prx_dbm = -70, r.intra_dbm = -90, r.inter_dbm = -95;
    r.noise_dbm = -95, r.sinr_db = 20, r.interferers = interferers, r.decoded = decoded;
    return r;
  };
  w.add_reception(rec(0, 1, 1, true), {{1, -80.f, -95.f, true, true}});
  w.add_reception(rec(2, 0, 0, false), {{1, -130.f, -140.f, true, false}});
  s::PrrEntry l1{0, 1, s::Rat::wifi80211p, 1, 1, 40.f}, l2{1, 0, s::Rat::wifi80211p, 1, 0, 40.f};
  s::PrrEntry r1{0, 0, s::Rat::wifi80211p, 2, 1, 40.f};
  w.finish({{"rsu0", gen::NodeKind::rsu, s::Rat::wifi80211p},
            {"veh0", gen::NodeKind::vehicle, s::Rat::wifi80211p},
            {"veh1", gen::NodeKind::vehicle, s::Rat::nr_v2x}},
           {l1, l2}, {r1});
}

// ns-3 table: built from the channel base (written next to it) by build_ns3_table (2 bands).
inline void write_ns3_base(const std::string& path) {
  const std::string channels = path + ".channels.h5";
  write_channel_base(channels);
  gen::Ns3TableHeader h;
  h.raysweep_version = "fuzz";
  h.git_hash = "fuzz";
  h.config = nlohmann::json::object();
  h.inputs = nlohmann::json::array();
  h.provenance = {{"command", "fuzz"}};
  gen::build_ns3_table(channels, path, h, 2);
}

}  // namespace raysweep::fuzz
