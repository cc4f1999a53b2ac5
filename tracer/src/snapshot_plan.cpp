#include "snapshot_plan.hpp"

#include <algorithm>
#include <stdexcept>
#include <string>

namespace raysweep::tracer {

SnapshotPlan::SnapshotPlan(const TraceScene& scene_, const std::vector<Node>& nodes_, const PairList& pairs_,
                           const TracerConfig& cfg_, const RadioConfig& radio_, const Electromagnetics& em_)
    : scene(scene_),
      nodes(nodes_),
      pairs(pairs_),
      cfg(cfg_),
      radio(radio_),
      em(em_),
      n(static_cast<std::uint32_t>(nodes_.size())),
      range(max_range_m(cfg_, radio_)),
      lambda(em_.wavelength()),
      obstacles(scene_) {
  const bool reflect = cfg.specular && cfg.max_depth > 0;
  image_search = reflect && n > 1 && cfg.candidates == CandidateSearch::image;
  sbr_specular = reflect && cfg.candidates != CandidateSearch::exhaustive;
  const bool diffuse = cfg.diffuse && cfg.max_depth > 0;
  ray_diffuse = diffuse && cfg.diffuse_integration != DiffuseIntegration::tiles;
  tile_diffuse = diffuse && cfg.diffuse_integration != DiffuseIntegration::rays;

  slot.reserve(pairs.size());
  in_range.assign(pairs.size(), 1);
  is_source.assign(n, 0);
  partners.resize(n);
  for (std::size_t p = 0; p < pairs.size(); ++p) {
    auto [i, j] = pairs[p];
    if (i >= j || j >= n) throw std::invalid_argument("trace_pairs: pair (" + std::to_string(i) + ", " +
                                                      std::to_string(j) + ") is not i < j < node count");
    if (!slot.emplace(key(i, j), p).second)
      throw std::invalid_argument("trace_pairs: pair (" + std::to_string(i) + ", " + std::to_string(j) + ") twice");
    if (norm(nodes[j].position - nodes[i].position) > range) {
      in_range[p] = 0;  // labelled, never traced
      continue;
    }
    partners[i].push_back(j);
    partners[j].push_back(i);
    for (auto e : {i, j}) {
      if (is_source[e]) continue;
      is_source[e] = 1;
      sources.push_back(e);
    }
  }
  for (auto& v : partners) std::sort(v.begin(), v.end());
  std::sort(sources.begin(), sources.end());
}

const ImageFaces& SnapshotPlan::faces() const {
  if (!faces_) faces_ = std::make_unique<ImageFaces>(image_faces(scene));
  return *faces_;
}

const SlabBounds& SnapshotPlan::slab_bounds() const {
  if (!slabs_) {
    const std::vector<char> wanted(is_source.begin(), is_source.end());
    const int cap = cfg.refraction ? cfg.max_transmissions : 0;
    slabs_ = std::make_unique<SlabBounds>(tracer::slab_bounds(scene, faces(), nodes, wanted, cap));
  }
  return *slabs_;
}

ShootPass& SnapshotPlan::shoot() {
  if (!shoot_) {
    shoot_ = std::make_unique<ShootPass>(run_shoot_pass(*this));
    search_rays += shoot_->rays;
  }
  return *shoot_;
}

}  // namespace raysweep::tracer
