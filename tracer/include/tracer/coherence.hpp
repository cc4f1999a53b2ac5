// Frame-to-frame coherence: a pair's paths of the frame it was last searched
// in, solved again exactly at a later frame's positions, without the
// candidate searches (image search, shoot and bounce, beams, edge views).
//
// A recalled specular or refracted path keeps its face sequence and a
// diffracted path its edge (and reflecting face): the image method and the
// exact visibility decide them anew, so a kept path has exactly the gain,
// phase, delay, angles and Doppler a full trace gives it. The direct path
// and both labels (LoS class, Fresnel zone) are always computed afresh. A
// diffuse record keeps its power and scattering point (moved with its
// vehicle); its delay, phase, angles and Doppler follow its legs
// (tracer/src/coherence.cpp).
//
// A recalled sequence that a vehicle now blocks, and a candidate the search
// found blocked by a vehicle only (a near miss), are tried again every frame:
// traffic taking a reflected path away or giving it back does not change
// what the search would find, only the exact solution does.
//
// What the re-solve cannot see is a path the last search did not find: one
// that appeared since (a reflection point entering its face, a leg coming
// out of a building's shadow, an edge coming into view). resolve_pairs
// therefore reports, per pair, whether the recall is still intact (both
// labels unchanged, every recalled path still there, the range status
// unchanged); the caller searches the pair again when it is not, and at an
// interval and a displacement of its choosing (generators/sweep/sweep.hpp,
// docs/tracer.md).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "tracer/solver.hpp"

namespace raysweep::tracer {

// A face named by its vehicle's id (VehiclePose::id), which stays the same
// from frame to frame while the vehicle's slot does not.
struct RecallFace {
  std::int32_t vehicle = -1;  // index into PairRecall::vehicles; -1: static
  std::uint32_t face = 0;
  bool operator==(const RecallFace&) const = default;
};

// A diffuse record with its interaction points in their hosts' frames.
struct RecallScatter {
  Path record;
  double share = 0;  // of the pair's power when recalled
  std::vector<std::int32_t> host;  // per interaction: index into PairRecall::vehicles, -1 static
  std::vector<Vec3> local;         // per interaction: the point in its host's frame
};

struct PairRecall {
  std::vector<std::string> vehicles;  // ids of the vehicles the faces below name
  std::vector<VehiclePose> poses;     // and their poses when it was made
  struct Sequence {
    std::vector<RecallFace> faces;  // specular / refracted, from the pair's lower end
    double share = 0;               // of the pair's power when recalled
  };
  std::vector<Sequence> sequences;
  std::vector<std::vector<RecallFace>> near_misses;  // sequences only a vehicle blocked (PairResult::near_misses)
  struct Diffracted {
    std::uint32_t edge = 0;  // static edge
    std::vector<RecallFace> face;  // the reflection before or after the edge, if any
    std::int8_t reflected = 0;
    double share = 0;
  };
  std::vector<Diffracted> diffracted;
  std::vector<RecallScatter> diffuse;
  // The ends when it was made (the diffuse records follow their legs).
  Node a, b;
  // Labels of the latest frame the pair was traced or re-solved in.
  LosClass los_class = LosClass::LOS, fresnel_class = LosClass::LOS;
  bool out_of_range = false;
  // False when a path has no recall (a vehicle edge's diffraction): the
  // pair is searched every frame.
  bool complete = true;
  // The power share of the paths a search finds anew as traffic moves
  // (reflections on vehicles, diffuse records, vehicle edges): the sweep
  // re-solves a pair only while it is small (generators/sweep/sweep.hpp).
  double volatile_share = 0;
  // The direct path's share: new paths (a wall's reflection coming out of a
  // building's shadow) are weaker than a strong direct path.
  double direct_share = 0;
};

// What to solve again of a traced pair (`nodes` and the scene's vehicles as
// they were traced).
PairRecall make_recall(const TraceScene& scene, const std::vector<Node>& nodes, const PairResult& res);

// The listed pairs (i < j, each once) from their recalls (one per pair) at
// the scene's current vehicles and `nodes`. intact[p]: pair p's recall still
// holds: both labels and the range status unchanged, and the recalled paths
// that are gone other than by a blocked leg (off their face or edge, on a
// vehicle that left) carried at most `vanish_limit` of its power. The
// labels in each recall are updated to this frame.
Snapshot resolve_pairs(const TraceScene& scene, const std::vector<Node>& nodes,
                       const std::vector<std::pair<std::uint32_t, std::uint32_t>>& pairs,
                       const std::vector<PairRecall*>& recalls, const TracerConfig& config, const RadioConfig& radio,
                       double vanish_limit, std::vector<unsigned char>& intact);

}  // namespace raysweep::tracer
