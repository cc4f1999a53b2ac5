// The diffuse gathering of one source's rays (effective roughness, rays
// integration): at every hit on a rough surface, the power it scatters
// towards each target receiver whose shadow ray is clear, binned per
// receiver, object and delay (shoot/diffuse_bins.hpp).
#pragma once

#include <cstdint>
#include <unordered_map>
#include <vector>

#include "shoot/diffuse_bins.hpp"
#include "shoot/ray.hpp"
#include "shoot/shoot.hpp"

namespace raysweep::tracer {

class DiffuseGathering {
 public:
  // Into `out`; the shadow rays counted in `rays`; `chain`: the shooter's
  // (the samples' paths before their scattering).
  // `salt`: ShootFeeds::sample_salt.
  DiffuseGathering(const ShootContext& world, std::uint32_t src, const std::vector<Vec3>& lattice,
                   const DiffuseTargets& targets, DiffuseBins& out, std::uint64_t& rays,
                   const std::vector<Link>& chain, std::uint64_t salt);
  const DiffuseTargets& targets() const { return *diffuse_; }
  // At hit `hit_no` (the roulette's sample identity) of lattice ray r.
  void at_hit(const RayState& st, const HitField& h, std::size_t r, std::uint64_t hit_no);

 private:
  class AtHit;

  const TraceScene& scene_;
  const Electromagnetics& em_;
  const std::vector<Node>& nodes_;
  const std::uint32_t src_;
  const std::vector<Vec3>& lattice_;
  const DiffuseTargets* diffuse_;
  DiffuseBins* diffuse_out_;
  std::uint64_t& rays_;
  const std::vector<Link>& chain_;
  const double d_omega_, lambda_, rx_peak_gain_;
  const std::uint64_t salt_;
  std::unordered_map<DiffuseKey, std::size_t, DiffuseKeyHash> bin_index_;
  std::size_t r_ = 0;         // the lattice ray
  std::uint64_t hit_no_ = 0;  // the ray's hits so far
};

}  // namespace raysweep::tracer
