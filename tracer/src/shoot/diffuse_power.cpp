// One source's diffuse power at many receivers (radio maps): the rays'
// gathering alone, as trace_pairs' shoot stage runs it.
#include <tbb/parallel_for.h>

#include <algorithm>
#include <stdexcept>
#include <unordered_map>
#include <utility>

#include "shoot/shoot.hpp"

namespace raysweep::tracer {

std::vector<double> diffuse_power(const TraceScene& scene, const std::vector<Node>& nodes, std::uint32_t src,
                                  const std::vector<std::uint32_t>& receivers, const TracerConfig& cfg,
                                  const RadioConfig& radio) {
  validate(cfg, radio);
  std::vector<double> out(receivers.size(), 0.0);
  if (!cfg.diffuse || cfg.max_depth <= 0 || cfg.diffuse_integration == DiffuseIntegration::tiles) return out;
  if (src >= nodes.size()) throw std::invalid_argument("diffuse_power: source index out of range");
  const Electromagnetics em(scene.material_names(), radio, cfg.materials, cfg.diffuse);
  const double range = max_range_m(cfg, radio);
  DiffuseTargets targets;
  targets.bin_s = 1.0 / radio.bandwidth_hz;
  targets.roulette = roulette_power(cfg, radio);
  std::unordered_map<std::uint32_t, std::size_t> slot;
  for (std::size_t k = 0; k < receivers.size(); ++k) {
    const auto r = receivers[k];
    if (r >= nodes.size()) throw std::invalid_argument("diffuse_power: receiver index out of range");
    if (r == src || norm(nodes[r].position - nodes[src].position) > range) continue;
    if (slot.emplace(r, k).second) targets.rx.push_back(r);
  }
  std::sort(targets.rx.begin(), targets.rx.end());
  if (targets.rx.empty()) return out;
  // The same rays, chunks and merge order as trace_pairs' shoot stage.
  TracerConfig local = cfg;
  local.specular = cfg.specular && cfg.candidates != CandidateSearch::exhaustive;
  const auto lattice = fibonacci_sphere(cfg.rays_per_source, cfg.lattice_turn);
  const std::size_t chunk = kShootChunk, chunks = (lattice.size() + chunk - 1) / chunk;
  std::vector<DiffuseBins> bins(chunks);
  tbb::parallel_for(std::size_t{0}, chunks, [&](std::size_t c) {
    ShootFinds finds;
    shoot_from({scene, em, local, nodes}, src, lattice, c * chunk, std::min(lattice.size(), (c + 1) * chunk),
               {.diffuse = &targets}, finds);
    bins[c] = std::move(finds.bins);
  });
  for (const auto& b : bins)
    for (const auto& [dk, acc] : b) out[slot.at(dk.rx)] += acc.power;
  return out;
}

}  // namespace raysweep::tracer
