// First-Fresnel-zone obstruction of the direct path: the LoS label's
// criterion. An antenna 5 cm above a car roof sees over every car of the
// same height geometrically, yet cars in line fill the first Fresnel zone
// (radius ~0.8 m at 50 m, 5.9 GHz) and cost several dB each.
//
// Clearance of an obstacle: h / r1, with h its distance from the direct line
// and r1 = sqrt(lambda d1 d2 / d) the first Fresnel radius where it is
// closest. An obstacle the line crosses has negative clearance: minus its
// penetration (the shortest shift of the line, across it, that clears the
// obstacle's outline seen along the line; the outline is taken convex) over
// r1. The knife-edge parameter is v = -sqrt(2) h / r1.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

#include "tracer/path.hpp"
#include "tracer/trace_scene.hpp"

namespace raysweep::tracer {

// The vehicles' knife-edge loss on the direct path (P.526 single knife edge
// J(v) per edge; Deygout's construction for several: the edge with the
// largest v over the whole path, then the largest on each side of it over
// the sub-path from that end to the main edge; losses in dB add).
struct KnifeEdges {
  double loss_db = 0;   // 0: no vehicle has v > -0.78 (clearance above 0.55 r1)
  int edges = 0;        // edges with a loss (0..3)
  double v_main = 0;    // the main edge's v = -sqrt(2) h / r1
  int main_vehicle = -1;
};

// ITU-R P.526's single knife-edge loss J(v) in dB, 0 for v <= kKnifeEdgeOnset.
constexpr double kKnifeEdgeOnset = -0.78;
double knife_edge_loss_db(double v);

// An obstacle obstructs the zone when its clearance is below this fraction
// of the first Fresnel radius (the usual 0.6 F1 criterion).
constexpr double kFresnelZoneFraction = 0.6;

struct FresnelObstruction {
  double clearance = 1;          // worst obstacle's h / r1, capped at 1 (1: clear of the whole first zone)
  double vehicle_clearance = 1;  // the worst vehicle's
  double static_clearance = 1;   // the worst static object's (ground excluded)
};

// Where a line of length d sits in the path whose first zone counts: it
// starts `before` along a path of length `total` (a leg of a reflected
// path, unfolded; the direct line is {0, d}). r1 at t along the line is
// sqrt(lambda s (total - s) / total), s = before + t, clamped 1e-3 total
// from the path's ends.
struct FresnelZone {
  double before = 0, total = 0;
  double r1(double t, double lambda) const {
    t = std::clamp(before + t, 1e-3 * total, total - 1e-3 * total);
    return std::sqrt(lambda * t * (total - t) / total);
  }
  // The point of [lo, hi] (line coordinates) nearest the path's middle,
  // where r1 is largest.
  double widest(double lo, double hi) const { return std::clamp(0.5 * total - before, lo, hi); }
};

// The obstacles of one frame in world coordinates, built once per snapshot:
// every vehicle (index v = vehicle) and every static object but the ground
// (large horizontal faces: the ground's reflection is a path, not an
// obstruction), each with its bounding sphere and triangles.
class FresnelObstacles {
 public:
  explicit FresnelObstacles(const TraceScene& scene);
  // The obstruction of the line a -> b; `skip_a` / `skip_b`: the antennas'
  // own vehicles (-1: none), which carry them rather than obstruct.
  FresnelObstruction between(const Vec3& a, const Vec3& b, double lambda, int skip_a = -1, int skip_b = -1) const;
  // The multiple knife-edge loss of the vehicles (static objects aside) on
  // the line a -> b; each vehicle is one knife edge, at the point its
  // outline must be cleared (tracer/src/fresnel_zone.cpp).
  KnifeEdges vehicle_knife_edges(const Vec3& a, const Vec3& b, double lambda, int skip_a = -1,
                                 int skip_b = -1) const;

  // Vehicle v's clearance of the line a -> b alone (h / r1, capped at 1).
  double vehicle_clearance(const Vec3& a, const Vec3& b, double lambda, int v) const;

  // The same along a path of several legs, points[0] the source to
  // points.back() the receiver (the reflection points between): each leg's
  // vehicles against the whole path's first zone (r1 from the distances
  // along the path: the zone of the path unfolded through its mirrors), and
  // Deygout's sub-paths taken along the path. host[m] is the vehicle that
  // carries points[m] (a reflection on it, -1: none), left out on the two
  // legs that touch it; skip_a / skip_b on every leg.
  KnifeEdges path_knife_edges(const std::vector<Vec3>& points, const std::vector<int>& host, double lambda,
                              int skip_a = -1, int skip_b = -1) const;
  // A face of an obstacle near a line's first zone, with a lower bound of
  // its clearance (negative when the line may cross it).
  struct NearFace {
    double bound;
    std::uint32_t face;
  };

 private:
  struct Obstacle {
    TraceScene::Sphere sphere;
    std::vector<std::array<Vec3, 3>> triangles;
    std::vector<TraceScene::Sphere> face_spheres;  // per face: its triangles are [face_begin[f], face_begin[f + 1])
    std::vector<std::uint32_t> face_begin;
    bool vehicle = false;
  };
  // The faces of o whose spheres come within the first zone of the line
  // a + t u, t in [0, d], by ascending bound; false when none.
  bool near_faces(const Obstacle& o, const Vec3& a, const Vec3& u, double d, double lambda, const FresnelZone& zone,
                  std::vector<NearFace>& near) const;
  std::vector<Obstacle> obstacles_;  // vehicles first (index = vehicle), then static objects
};

// One line, obstacles built on the spot (tests, single queries).
FresnelObstruction fresnel_obstruction(const TraceScene& scene, const Vec3& a, const Vec3& b, double lambda,
                                       int skip_a = -1, int skip_b = -1);

// The label: NLOS when a static object blocks the direct ray or intrudes
// into 0.6 F1; else NLOSV when a vehicle blocks it or intrudes; else LOS.
LosClass fresnel_class(LosClass geometric, const FresnelObstruction& f);

}  // namespace raysweep::tracer
