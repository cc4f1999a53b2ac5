// The base of the candidate searches that run per source: the source, its
// receivers, the on-face test and the counters (SourceSearch); for the image
// search's own stages also the slab bounds and the receivers above the
// source (CappedSearch).
#pragma once

#include <algorithm>
#include <cstdint>
#include <limits>
#include <vector>

#include "search/face_index.hpp"
#include "search/image_search.hpp"
#include "search/receiver_kernel.hpp"
#include "search/visibility.hpp"

namespace raysweep::tracer {

// What one source's searches share: the source, its receivers relative to it
// (the vectorised passes' form), the on-face test and the counters.
class SourceSearch {
 public:
  SourceSearch(const TraceScene& scene, const ImageFaces& faces, const std::vector<Node>& nodes, std::uint32_t src,
               const std::vector<std::uint32_t>& receivers, std::vector<ImageCandidate>& out)
      : scene(scene), faces(faces), nodes(nodes), receivers(receivers), out(out), xs(nodes[src].position) {
    for (auto r : receivers) rx.push(nodes[r].position - xs);
    scratch.n = rx.size();
    scratch.pad();
  }
  void add_stats(ImageSearchStats* stats) const {
    if (stats) {
      stats->image_sources += local.image_sources;
      stats->tests += local.tests;
    }
  }

 protected:
  const TraceScene& scene;
  const ImageFaces& faces;
  const std::vector<Node>& nodes;
  const std::vector<std::uint32_t>& receivers;
  std::vector<ImageCandidate>& out;
  const Vec3 xs;
  // Everything relative to the source: the source is the origin.
  Receivers rx, scratch;
  ImageSearchStats local;

  Vec3 receiver(std::size_t r) const { return Vec3{rx.x[r], rx.y[r], rx.z[r]} + xs; }

  // Inlined at every call (as the lambda it replaces was): it runs per
  // candidate point, and a call costs as much as its sphere test.
  [[gnu::always_inline]] inline bool on_face(std::size_t f, const Vec3& p) const {
    const Vec3 w = p - faces.spheres[f].centre;
    const double rr = faces.spheres[f].radius + faces.tol[f];
    return dot(w, w) <= rr * rr && scene.face_contains(faces.refs[f], p, faces.tol[f]);
  }
};

// The image search's stages: sequences that are their own reverse's
// counterpart are searched towards the receivers above the source only,
// and static sequences whose legs the slab bounds put over their cap are
// skipped.
class CappedSearch : public SourceSearch {
 public:
  CappedSearch(const TraceScene& scene, const ImageFaces& faces, const std::vector<Node>& nodes, std::uint32_t src,
               const std::vector<std::uint32_t>& receivers, std::vector<ImageCandidate>& out, const SlabBounds* slabs)
      : SourceSearch(scene, faces, nodes, src, receivers, out),
        src(src),
        slabs(slabs),
        higher_from(
            static_cast<std::size_t>(std::upper_bound(receivers.begin(), receivers.end(), src) - receivers.begin())) {}

 protected:
  const std::uint32_t src;
  const SlabBounds* slabs;        // null: no slab bounds
  const std::size_t higher_from;  // the first receiver above the source

  // Whether a first leg from the source to static face f1 (and a last leg
  // from static face fl to receiver r) cross more slabs than the cap.
  bool over_cap(std::uint32_t f1) const { return slabs && slabs->at(src, f1) > slabs->cap; }
  bool over_cap(std::uint32_t f1, std::size_t r, std::uint32_t fl) const {
    return slabs && slabs->at(src, f1) + slabs->at(receivers[r], fl) > slabs->cap;
  }

  // The fewest slabs a last leg from a static face to any receiver from
  // `first` on crosses (the bounds' minimum over them), per face and per
  // node of the static tree (the minimum below it): a last face over the
  // budget a first leg leaves (last_leg_budget) ends no path, and a tree
  // node over it holds none that does. In a town most faces a wide beam
  // reaches lie behind buildings from every receiver. Without slab bounds
  // nothing is over any budget.
  void last_leg_bounds(std::size_t first) {
    if (!slabs) return;
    face_last_leg.assign(faces.static_count, std::numeric_limits<std::uint8_t>::max());
    for (std::size_t r = first; r < receivers.size(); ++r)
      for (std::uint32_t f = 0; f < faces.static_count; ++f)
        face_last_leg[f] = std::min(face_last_leg[f], static_cast<std::uint8_t>(slabs->at(receivers[r], f)));
    // Children follow their parent in the depth-first layout: bottom-up is
    // from the back.
    const auto& tree = faces.static_tree;
    node_last_leg.assign(tree.size(), 0);
    for (std::size_t at = tree.size(); at-- > 0;) {
      const auto& node = tree[at];
      std::uint8_t m = std::numeric_limits<std::uint8_t>::max();
      if (node.count > 0) {
        for (std::uint32_t k = node.begin; k < node.begin + node.count; ++k)
          m = std::min(m, face_last_leg[faces.static_order[k]]);
      } else {
        m = std::min(node_last_leg[at + 1], node_last_leg[node.right]);
      }
      node_last_leg[at] = m;
    }
  }
  // The slabs left to the last leg after a first leg to static face f1.
  int last_leg_budget(std::uint32_t f1) const { return slabs ? slabs->cap - slabs->at(src, f1) : 0; }
  bool last_face_over(std::uint32_t f, int budget) const { return slabs && face_last_leg[f] > budget; }
  bool last_node_over(std::uint32_t node, int budget) const { return slabs && node_last_leg[node] > budget; }

 private:
  std::vector<std::uint8_t> face_last_leg, node_last_leg;
};

// image_candidates' sequences of two or more static faces (order 2, and
// with `ground3` order 3 through the ground): search/static_pairs.cpp.
void static_pair_candidates(const TraceScene& scene, const ImageFaces& faces, const std::vector<Node>& nodes,
                            std::uint32_t src, const std::vector<std::uint32_t>& receivers, const SlabBounds* slabs,
                            bool ground3, std::vector<ImageCandidate>& out, ImageSearchStats* stats);

}  // namespace raysweep::tracer
