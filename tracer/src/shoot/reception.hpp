// The reception spheres of one source's rays: a node that a segment passes
// within the sphere (radius: the angular ray spacing times the unfolded
// length) gets the ray's face sequence proposed for the pair (source,
// node), once per task.
#pragma once

#include <cstdint>
#include <unordered_set>
#include <vector>

#include "shoot/ray.hpp"
#include "shoot/shoot.hpp"

namespace raysweep::tracer {

class Reception {
 public:
  Reception(const std::vector<Node>& nodes, std::uint32_t src, std::vector<CandidateKey>& out);
  // The nodes segment st (to tseg) passes, at angular spacing `spacing`.
  void propose(const RayState& st, const std::vector<Link>& chain, double tseg, double spacing);

 private:
  const std::uint32_t src_;
  const Vec3 ref_;
  std::vector<float> nx_, ny_, nz_;  // the nodes relative to the source
  std::vector<unsigned char> inside_;
  std::unordered_set<CandidateKey, CandidateHash> seen_;
  CandidateKey key_;
  std::vector<CandidateKey>& out_;
};

}  // namespace raysweep::tracer
