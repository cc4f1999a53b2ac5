// A channel dataset with CFRs known in closed form and an ns-3 table header,
// shared by the ns-3 table tests (tests/generators/test_ns3_table.cpp) and the
// ns3-table command's (tests/cli/test_cli_ns3_table.cpp).
#pragma once

#include <cmath>
#include <complex>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <string>
#include <vector>

#include "generators/dataset/dataset_writer.hpp"
#include "generators/ns3_table/ns3_table.hpp"

namespace raysweep::test::ns3 {

inline constexpr std::uint32_t kK = 8;  // subcarriers
inline constexpr double kSpacing = 156250, kCarrier = 5.9e9;

// |H_k| = amp(a, b, f) * (1 + k / 8): mean |H|^2 and band means in closed form.
inline double amp(std::uint32_t a, std::uint32_t b, std::size_t f) { return 1e-3 * (1 + a + 2 * b + 0.1 * f); }
inline double hk(std::uint32_t a, std::uint32_t b, std::size_t f, std::uint32_t k) {
  return amp(a, b, f) * (1 + k / 8.0);
}

// 3 nodes, 4 frames; node 2 only in frames 2 and 3; link (0, 1) of frame 1 has no path.
inline std::filesystem::path write_dataset(const std::filesystem::path& dir, bool with_cfr) {
  generators::DatasetHeader h;
  h.raysweep_version = "test";
  h.git_hash = "test";
  h.config = nlohmann::json::object();
  h.inputs = nlohmann::json::array();
  h.provenance = nlohmann::json::object();
  h.carrier_hz = kCarrier;
  h.bandwidth_hz = 10e6;
  h.cfr_subcarriers = with_cfr ? kK : 0;
  h.cfr_subcarrier_spacing_hz = with_cfr ? kSpacing : 0;
  const std::filesystem::path file = dir / (with_cfr ? "cfr.h5" : "plain.h5");
  generators::DatasetWriter w(file, h);
  for (std::size_t f = 0; f < 4; ++f) {
    generators::FrameRecord fr;
    fr.time_s = 5.0 + 0.1 * f;
    const std::uint32_t n = f >= 2 ? 3 : 2;
    for (std::uint32_t i = 0; i < n; ++i) {
      generators::NodeState s;
      s.node = i;
      s.x = 10.0 * i + f;
      s.y = -2.0 * i;
      s.z = 0.3;
      s.vx = 10;
      s.vy = static_cast<float>(i);
      fr.nodes.push_back(s);
    }
    for (std::uint32_t a = 0; a < n; ++a)
      for (std::uint32_t b = a + 1; b < n; ++b) {
        generators::LinkRecord l;
        l.tx = a;
        l.rx = b;
        l.los_class = static_cast<std::uint8_t>((a + b + f) % 3);
        const bool no_path = f == 1 && a == 0 && b == 1;
        const double g = no_path ? -std::numeric_limits<double>::infinity() : 20 * std::log10(amp(a, b, f)) - 3;
        l.gain_coherent_db = l.gain_incoherent_db = static_cast<float>(g);
        l.path_count = 0;
        fr.links.push_back(l);
        if (with_cfr)
          for (std::uint32_t k = 0; k < kK; ++k)
            fr.cfr.emplace_back(no_path ? 0.0f : static_cast<float>(hk(a, b, f, k)), 0.0f);
      }
    w.append(fr);
  }
  std::vector<generators::NodeInfo> nodes(3);
  for (std::uint32_t i = 0; i < 3; ++i) nodes[i].id = "veh" + std::to_string(i);
  w.finish(nodes, {});
  return file;
}

inline generators::Ns3TableHeader header() {
  generators::Ns3TableHeader h;
  h.raysweep_version = "test";
  h.git_hash = "test";
  h.config = nlohmann::json::object();
  h.inputs = nlohmann::json::array();
  h.provenance = {{"stage", "test"}};
  return h;
}

}  // namespace raysweep::test::ns3
