// The geometry of one Embree scene (TraceScene::Shape: the static scene
// or a vehicle model), built once: planar faces with their planes,
// triangles and on-face tests, bounding spheres, a vehicle model's normal
// index and tables; and the Embree ray every query starts from.
#pragma once

#include <embree3/rtcore.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include "meshkit/scene.hpp"
#include "tracer/trace_scene.hpp"

namespace raysweep::tracer {

inline constexpr std::uint32_t kNone = RTC_INVALID_GEOMETRY_ID;

// A ray in Embree's float frame (origin already relative to the scene origin).
inline RTCRayHit make_ray(const Vec3& o, const Vec3& dir, double tnear, double tfar) {
  RTCRayHit rh;
  rh.ray.org_x = static_cast<float>(o[0]);
  rh.ray.org_y = static_cast<float>(o[1]);
  rh.ray.org_z = static_cast<float>(o[2]);
  rh.ray.dir_x = static_cast<float>(dir[0]);
  rh.ray.dir_y = static_cast<float>(dir[1]);
  rh.ray.dir_z = static_cast<float>(dir[2]);
  rh.ray.tnear = static_cast<float>(tnear);
  rh.ray.tfar = tfar > 3e38 ? std::numeric_limits<float>::infinity() : static_cast<float>(tfar);
  rh.ray.time = 0;
  rh.ray.mask = 0xFFFFFFFF;
  rh.ray.id = 0;
  rh.ray.flags = 0;
  rh.hit.geomID = kNone;
  rh.hit.instID[0] = kNone;
  return rh;
}

// The static scene's triangles sit in the top-level scene itself (no
// instance: one level less for every ray), vehicles are instances 1..n.
inline std::uint32_t instance_of(std::uint32_t inst_id) { return inst_id == kNone ? 0 : inst_id; }

// Octahedral map of unit directions onto a cells x cells grid (the normal
// index: kCells).
inline constexpr int kCells = 32;
inline std::pair<int, int> octa_cell(const Vec3& d, int cells = kCells) {
  const double l1 = std::fabs(d[0]) + std::fabs(d[1]) + std::fabs(d[2]);
  double u = d[0] / l1, v = d[1] / l1;
  if (d[2] < 0) {
    const double uu = (1 - std::fabs(v)) * (u >= 0 ? 1 : -1), vv = (1 - std::fabs(u)) * (v >= 0 ? 1 : -1);
    u = uu;
    v = vv;
  }
  const int i = std::clamp(static_cast<int>((u + 1) / 2 * cells), 0, cells - 1);
  const int j = std::clamp(static_cast<int>((v + 1) / 2 * cells), 0, cells - 1);
  return {i, j};
}
inline Vec3 octa_dir(double u, double v) {  // u, v in [-1, 1]
  Vec3 d{u, v, 1 - std::fabs(u) - std::fabs(v)};
  if (d[2] < 0) {
    d[0] = (1 - std::fabs(v)) * (u >= 0 ? 1 : -1);
    d[1] = (1 - std::fabs(u)) * (v >= 0 ? 1 : -1);
  }
  return normalize(d);
}

// Faces of a shape listed by normal direction: for each angular level
// delta and each cell of the octahedral map, the faces whose normal (either
// sign) lies within delta + the cell's angular radius of the cell centre.
struct NormalIndex {
  static constexpr double kLevels[] = {0.02, 0.05, 0.1, 0.2, 0.4};  // radians
  std::vector<std::vector<std::uint32_t>> lists;  // [level][cell]
  std::vector<std::uint32_t> all;
  const std::vector<std::uint32_t>& query(const Vec3& dir, double delta) const {
    int level = 0;
    while (level < 5 && kLevels[level] < delta) ++level;
    if (level == 5 || lists.empty()) return all;
    const auto [i, j] = octa_cell(dir);
    return lists[(level * kCells + i) * kCells + j];
  }
};

struct TraceScene::Shape {
  std::string name;
  std::vector<Vec3> vertices;  // shape frame: world for the static scene, library frame for a model
  std::vector<meshkit::Tri> triangles;
  std::vector<std::uint32_t> tri_face;  // dense face index
  std::vector<Plane> face_plane;
  std::vector<double> face_flatness;
  std::vector<std::uint16_t> face_material;
  std::vector<std::uint32_t> face_object;
  // Triangles of each face (CSR) with their in-plane edge constraints:
  // p is inside triangle t when dot(edge_normal[3t + k], p) >= edge_offset[3t + k] for k = 0..2.
  std::vector<std::uint32_t> face_tri_begin, face_tris;
  std::vector<Vec3> edge_normal;
  std::vector<double> edge_offset;
  std::vector<Sphere> face_sphere;
  Sphere bounds;  // of all vertices (shape frame)
  NormalIndex normals;  // vehicle models only (empty for the city: nothing looks its faces up by normal)
  Vec3 antenna{0, 0, 0};
  std::string content_key;  // vehicle models: geometry, materials, Embree version (precompute.hpp)
  std::vector<std::uint32_t> seen_from_mount;  // vehicle models: faces the antenna mount sees
  std::vector<Edge> model_edges;               // vehicle models: wedges in the model frame
  // Vehicle models: multi-bounce sequences and, per arrival direction cell
  // (kBounceCells^2 octahedral cells), the ids of those seen there; built
  // on first use (vehicle_bounce_sequences).
  mutable std::once_flag bounce_once;
  mutable std::vector<TraceScene::BounceSequence> bounce_seq;
  mutable std::vector<std::vector<std::uint32_t>> bounce_near;  // [level][cell]: see build_bounce_table
  mutable std::vector<std::uint32_t> bounce_all;
  RTCScene scene = nullptr;
};

// The normal index of a vehicle model's faces (NormalIndex), once per model.
void build_normal_index(TraceScene::Shape& s);

// Attaches a shape's triangles (float, relative to `origin`) to `scene` as
// geometry 0.
void attach_triangles(RTCDevice device, const TraceScene::Shape& s, const Vec3& origin, RTCScene scene);

// Builds per-face planes and geometry tables from a meshkit scene (its
// Embree geometry: attach_triangles, into the top-level scene for the city
// and into a scene of its own for a vehicle model).
void build_shape(TraceScene::Shape& s, const meshkit::Scene& scene,
                 const std::function<std::uint16_t(const std::string&)>& material_index, std::uint32_t object_base);

}  // namespace raysweep::tracer
