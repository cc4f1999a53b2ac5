#include "shoot/reception.hpp"

#include <algorithm>

namespace raysweep::tracer {

Reception::Reception(const std::vector<Node>& nodes, std::uint32_t src, std::vector<CandidateKey>& out)
    : src_(src), ref_(nodes[src].position), out_(out) {
  nx_.resize(nodes.size());
  ny_.resize(nodes.size());
  nz_.resize(nodes.size());
  for (std::size_t j = 0; j < nodes.size(); ++j) {
    nx_[j] = static_cast<float>(nodes[j].position[0] - ref_[0]);
    ny_[j] = static_cast<float>(nodes[j].position[1] - ref_[1]);
    nz_[j] = static_cast<float>(nodes[j].position[2] - ref_[2]);
  }
  inside_.resize(nodes.size());
}

// The nodes this segment passes within the reception sphere propose the
// ray's face sequence to the pair (src, node).
void Reception::propose(const RayState& st, const std::vector<Link>& chain, double tseg, double spacing) {
  // Branch-free pass over all nodes first (vectorises), keys only for hits.
  const std::size_t nn = nx_.size();
  // Single precision relative to the source (city-sized offsets keep
  // millimetres): a candidate test only, the exact path is recomputed
  // in double; float doubles the SIMD width of this hot loop.
  const float ox = static_cast<float>(st.o[0] - ref_[0]), oy = static_cast<float>(st.o[1] - ref_[1]),
              oz = static_cast<float>(st.o[2] - ref_[2]);
  const float dx = static_cast<float>(st.d[0]), dy = static_cast<float>(st.d[1]), dz = static_cast<float>(st.d[2]);
  const float len = static_cast<float>(st.len), sp = static_cast<float>(spacing);
  const float tmax = static_cast<float>(std::min(tseg, 1e30));
  const float* nx = nx_.data();
  const float* ny = ny_.data();
  const float* nz = nz_.data();
  unsigned char* inside = inside_.data();
  unsigned any = 0;
  for (std::size_t j = 0; j < nn; ++j) {
    const float wx = nx[j] - ox, wy = ny[j] - oy, wz = nz[j] - oz;
    const float s = wx * dx + wy * dy + wz * dz;
    const float r = sp * (len + s);
    const unsigned in = (s > 0) & (s <= tmax) & (wx * wx + wy * wy + wz * wz - s * s <= r * r);
    inside[j] = static_cast<unsigned char>(in);
    any |= in;
  }
  for (std::uint32_t j = 0; any && j < nn; ++j) {
    if (!inside[j] || j == src_) continue;
    key_.other = j;
    key_.faces.resize(st.n);
    unwind(chain, st, key_.faces.data(), nullptr);
    if (seen_.insert(key_).second) out_.push_back(key_);
  }
}

}  // namespace raysweep::tracer
