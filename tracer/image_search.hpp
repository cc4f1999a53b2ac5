// Exact candidate search by the image method (no sampling).
//
// A specular path exists only where every reflection point lies on its face,
// so enumerating image sources and testing where the unfolded line meets each
// face yields a superset of the exact paths of that order; compute_path then
// decides each candidate exactly (occlusion, slabs, the transmission cap).
// Nothing is sampled, so no face is missed for being small or far away:
//   order 1: every face of the scene, static and vehicles;
//   order 2: every pair of static faces (walls, roofs, ground; few and large),
//            pruned by side tests and the beam each first face reflects.
// Order-2 sequences touching a vehicle and orders >= 3 come from
// shoot-and-bounce (solver.cpp), whose candidates are merged with these.
#pragma once

#include <cstdint>
#include <vector>

#include "tracer/solver.hpp"

namespace raysweep::tracer {

struct ImageCandidate {
  std::uint32_t rx = 0;
  std::vector<FaceRef> faces;  // in order from the source
};

struct ImageSearchStats {
  std::uint64_t image_sources = 0;  // images built (order 1 and 2)
  std::uint64_t tests = 0;          // (image, receiver) pairs tested against a face
};

// Every face of the current frame in world coordinates: built once per
// snapshot and shared by all sources.
struct ImageFaces {
  std::vector<FaceRef> refs;  // static faces first (instance 0), then each vehicle's
  std::vector<Plane> planes;
  std::vector<TraceScene::Sphere> spheres;
  std::vector<double> tol;    // border tolerance of the on-face test
  std::uint32_t static_count = 0;
};
ImageFaces image_faces(const TraceScene& scene);

// Face sequences of order 1..max_order (at most 2) from node `src` to each
// node in `receivers` whose reflection points lie on their faces.
// Deterministic: the output order depends only on the scene and the nodes.
void image_candidates(const TraceScene& scene, const ImageFaces& faces, const std::vector<Node>& nodes,
                      std::uint32_t src, const std::vector<std::uint32_t>& receivers, int max_order,
                      std::vector<ImageCandidate>& out, ImageSearchStats* stats = nullptr);

}  // namespace raysweep::tracer
