#include "shoot/beam_marks.hpp"

#include <algorithm>

namespace raysweep::tracer {

BeamMarks::BeamMarks(const ImageFaces* faces, const std::vector<Node>& nodes, std::uint32_t src, double spacing,
                     std::vector<BeamVehicle>* beams, std::vector<BeamPair>* beam_pairs,
                     std::vector<BeamVehicle>* bundle_marks)
    : beam_faces_(faces),
      nodes_(nodes),
      src_(src),
      spacing_(spacing),
      beams_(beams),
      beam_pairs_(beam_pairs),
      bundle_marks_(bundle_marks) {}

void BeamMarks::note_beams(const RayState& st, const std::vector<Link>& chain, double seg_end) {
  // After one reflection on a static face: the vehicles this ray passes
  // are in that face's beam (BeamVehicle).
  if (beams_ && st.n == 1 && chain[st.last].face.instance == 0 &&
      !std::binary_search(beam_faces_->ground.begin(), beam_faces_->ground.end(), chain[st.last].face.face)) {
    const auto& spheres = beam_faces_->vehicle_spheres;
    for (std::uint32_t v = 0; v < spheres.size(); ++v)
      if (passes(st, seg_end, spheres[v].centre, spheres[v].radius))
        beams_->push_back({chain[st.last].face.face, v});
  }
  // After two reflections, the first on a static face: their pair's beam
  // is lit (BeamPair); after one, so is the pair with a small static face
  // the ray passes.
  if (beam_pairs_ && st.n == 2 && chain[chain[st.last].parent].face.instance == 0) {
    // The second face may be a vehicle's (a wall's echo off a car onto a
    // wall): its index among ImageFaces' faces.
    const FaceRef& f2 = chain[st.last].face;
    beam_pairs_->push_back({chain[chain[st.last].parent].face.face,
                            f2.instance == 0 ? f2.face : beam_faces_->vehicle_begin[f2.instance - 1] + f2.face});
  }
  if (beam_pairs_ && st.n == 1 && chain[st.last].face.instance == 0) {
    const std::uint32_t f1 = chain[st.last].face.face;
    for (const std::uint32_t f2 : beam_faces_->small)
      if (f2 != f1 && passes(st, seg_end, beam_faces_->spheres[f2].centre,
                             beam_faces_->spheres[f2].radius + beam_faces_->tol[f2]))
        beam_pairs_->push_back({f1, f2});
  }
}

void BeamMarks::note_bundle_marks(const RayState& st, const std::vector<Link>& chain, double seg_end,
                                  double bundle_spacing) {
  if (st.n != 1 || chain[st.last].face.instance == 0) return;
  const FaceRef& f = chain[st.last].face;
  const std::uint32_t from = f.instance - 1, face = beam_faces_->vehicle_begin[from] + f.face;
  const auto& spheres = beam_faces_->vehicle_spheres;
  for (std::uint32_t v = 0; v < spheres.size(); ++v)
    if (v != from && static_cast<int>(v) != nodes_[src_].vehicle &&
        passes(st, seg_end, spheres[v].centre, spheres[v].radius, bundle_spacing))
      bundle_marks_->push_back({face, v});
}

void BeamMarks::finish() {
  if (beams_) {
    std::sort(beams_->begin(), beams_->end());
    beams_->erase(std::unique(beams_->begin(), beams_->end()), beams_->end());
  }
  if (beam_pairs_) {
    std::sort(beam_pairs_->begin(), beam_pairs_->end());
    beam_pairs_->erase(std::unique(beam_pairs_->begin(), beam_pairs_->end()), beam_pairs_->end());
  }
}

}  // namespace raysweep::tracer
