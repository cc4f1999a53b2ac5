#include "tracer/trace_scene.hpp"

#include <embree3/rtcore.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <limits>
#include <map>
#include <mutex>
#include <stdexcept>

#include "meshkit/planar_faces.hpp"
#include "tracer/em/constants.hpp"

namespace raysweep::tracer {

namespace {

constexpr std::uint32_t kNone = RTC_INVALID_GEOMETRY_ID;

void check_device(RTCDevice device, const char* what) {
  const RTCError e = rtcGetDeviceError(device);
  if (e != RTC_ERROR_NONE) throw std::runtime_error(std::string("Embree error ") + std::to_string(e) + " in " + what);
}

// A ray in Embree's float frame (origin already relative to the scene origin).
RTCRayHit make_ray(const Vec3& o, const Vec3& dir, double tnear, double tfar) {
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
std::uint32_t instance_of(std::uint32_t inst_id) { return inst_id == kNone ? 0 : inst_id; }

}  // namespace

namespace {

// Octahedral map of unit directions onto a cells x cells grid (the normal
// index: kCells).
constexpr int kCells = 32;
std::pair<int, int> octa_cell(const Vec3& d, int cells = kCells) {
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
Vec3 octa_dir(double u, double v) {  // u, v in [-1, 1]
  Vec3 d{u, v, 1 - std::fabs(u) - std::fabs(v)};
  if (d[2] < 0) {
    d[0] = (1 - std::fabs(v)) * (u >= 0 ? 1 : -1);
    d[1] = (1 - std::fabs(u)) * (v >= 0 ? 1 : -1);
  }
  return normalize(d);
}

}  // namespace

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

struct TraceScene::Impl {
  RTCDevice device = nullptr;
  Vec3 origin{0, 0, 0};  // Embree's float frame is relative to this point
  meshkit::Bounds bounds = meshkit::Bounds::none();
  std::vector<std::string> static_objects;
  Shape world;
  std::vector<std::unique_ptr<Shape>> models;
  RTCScene top = nullptr;
  std::vector<RTCGeometry> slots;  // vehicle instance v lives at top-level geometry id v + 1
  std::vector<bool> slot_enabled;
  std::vector<double> cos_yaw, sin_yaw;
  std::vector<Edge> edges;
  std::vector<char> ground;  // per static face: is_ground
  // Bit g of row 2 f + (side < 0): static face g reaches that side of f
  // (a bitset: a list per face and side grows as faces squared in ints).
  std::vector<std::uint64_t> reaching;
  std::size_t reaching_words = 0;
  std::shared_ptr<const PrecomputeStore> store;
  mutable std::mutex memo_mutex;
  mutable std::map<std::string, std::shared_ptr<const void>> memo;

  const Shape& shape_of(const FaceRef& f, const std::vector<VehiclePose>& vehicles) const {
    return f.instance == 0 ? world : *models[vehicles[f.instance - 1].model];
  }
  // Step that clears float rounding of a point at distance `t` along a ray
  // whose origin is `o_local` away from the Embree origin.
  static double step(double o_local, double t) { return std::max(1e-4, 4e-7 * (o_local + t)); }

  // One traversal instead of one per crossing: an intersection-context
  // filter sees every candidate hit. It either records it and rejects it
  // (all_hits: the traversal goes on to tfar), or rejects only the faces a
  // query ignores (occluded: the first other hit ends the traversal).
  struct RawHit {
    float t;
    FaceRef face;
  };
  struct FilterContext {
    RTCIntersectContext ctx;  // first member: Embree hands back its address
    const Impl* impl = nullptr;
    const std::vector<VehiclePose>* vehicles = nullptr;
    std::vector<RawHit>* collect = nullptr;
    const FaceRef* ignore[2] = {nullptr, nullptr};
  };
  static void filter(const RTCFilterFunctionNArguments* args) {
    auto* fc = reinterpret_cast<FilterContext*>(args->context);
    for (unsigned i = 0; i < args->N; ++i) {
      if (args->valid[i] != -1) continue;
      const std::uint32_t inst = instance_of(RTCHitN_instID(args->hit, args->N, i, 0));
      const std::uint32_t prim = RTCHitN_primID(args->hit, args->N, i);
      const Shape& s = inst == 0 ? fc->impl->world : *fc->impl->models[(*fc->vehicles)[inst - 1].model];
      const FaceRef face{inst, s.tri_face[prim]};
      if (fc->collect) {
        fc->collect->push_back(RawHit{RTCRayN_tfar(args->ray, args->N, i), face});
        args->valid[i] = 0;
      } else if ((fc->ignore[0] && face == *fc->ignore[0]) || (fc->ignore[1] && face == *fc->ignore[1])) {
        args->valid[i] = 0;
      }
    }
  }
};

static void build_normal_index(TraceScene::Shape& s) {
  NormalIndex& ix = s.normals;
  const auto nf = static_cast<std::uint32_t>(s.face_plane.size());
  ix.all.resize(nf);
  for (std::uint32_t f = 0; f < nf; ++f) ix.all[f] = f;
  ix.lists.assign(5 * kCells * kCells, {});
  // Rows of cells on every core: each cell's lists are its own.
  tbb::parallel_for(0, kCells, [&](int i) {
    for (int j = 0; j < kCells; ++j) {
      const double u0 = -1 + 2.0 * i / kCells, v0 = -1 + 2.0 * j / kCells, h = 2.0 / kCells;
      const Vec3 c = octa_dir(u0 + h / 2, v0 + h / 2);
      // Angular radius of the cell: the farthest of a 9 x 9 grid over it
      // (with margin: the map is smooth within a cell); acos decreases, so
      // one acos of the smallest cosine.
      double min_cos = 1;
      for (int a = 0; a <= 8; ++a)
        for (int b = 0; b <= 8; ++b) min_cos = std::min(min_cos, dot(c, octa_dir(u0 + h * a / 8, v0 + h * b / 8)));
      const double radius = std::acos(std::clamp(min_cos, -1.0, 1.0)) * 1.25 + 1e-3;
      for (int level = 0; level < 5; ++level) {
        const double cos_max = std::cos(std::min(kPi / 2, NormalIndex::kLevels[level] + radius));
        auto& list = ix.lists[(level * kCells + i) * kCells + j];
        for (std::uint32_t f = 0; f < nf; ++f)
          if (std::fabs(dot(s.face_plane[f].normal, c)) >= cos_max) list.push_back(f);
      }
    }
  });
}

// Attaches a shape's triangles (float, relative to `origin`) to `scene` as
// geometry 0.
static void attach_triangles(RTCDevice device, const TraceScene::Shape& s, const Vec3& origin, RTCScene scene) {
  RTCGeometry g = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
  auto* vb = static_cast<float*>(
      rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), s.vertices.size()));
  for (std::size_t i = 0; i < s.vertices.size(); ++i)
    for (int k = 0; k < 3; ++k) vb[3 * i + k] = static_cast<float>(s.vertices[i][k] - origin[k]);
  auto* ib = static_cast<unsigned*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                            3 * sizeof(unsigned), s.triangles.size()));
  for (std::size_t i = 0; i < s.triangles.size(); ++i)
    for (int k = 0; k < 3; ++k) ib[3 * i + k] = s.triangles[i][k];
  rtcSetGeometryBuildQuality(g, RTC_BUILD_QUALITY_HIGH);
  rtcCommitGeometry(g);
  rtcAttachGeometryByID(scene, g, 0);
  rtcReleaseGeometry(g);
}

// Builds per-face planes and geometry tables from a meshkit scene (its
// Embree geometry: attach_triangles, into the top-level scene for the city
// and into a scene of its own for a vehicle model).
static void build_shape(TraceScene::Shape& s, const meshkit::Scene& scene,
                        const std::function<std::uint16_t(const std::string&)>& material_index,
                        std::uint32_t object_base) {
  std::map<std::pair<std::size_t, std::uint32_t>, std::uint32_t> face_index;
  for (std::size_t mi = 0; mi < scene.meshes.size(); ++mi) {
    const auto& m = scene.meshes[mi];
    // A non-finite vertex would make the bounds, hence Embree's origin and
    // every tolerance, infinite and lose every path without a word.
    for (std::size_t v = 0; v < m.vertices.size(); ++v)
      for (double c : m.vertices[v])
        if (!std::isfinite(c))
          throw std::invalid_argument(s.name + ": mesh '" + m.name + "' (material " + m.material + "): vertex " +
                                      std::to_string(v) + " is not finite");
    const std::uint16_t mat = material_index(m.material);
    std::vector<std::uint32_t> faces = m.triangle_face;
    if (faces.size() != m.triangles.size()) faces = meshkit::group_planar_faces(m.vertices, m.triangles, 0);
    const auto base = static_cast<std::uint32_t>(s.vertices.size());
    s.vertices.insert(s.vertices.end(), m.vertices.begin(), m.vertices.end());
    for (std::size_t t = 0; t < m.triangles.size(); ++t) {
      const auto& tri = m.triangles[t];
      s.triangles.push_back({tri[0] + base, tri[1] + base, tri[2] + base});
      auto [it, inserted] = face_index.try_emplace({mi, faces[t]}, static_cast<std::uint32_t>(s.face_material.size()));
      if (inserted) {
        s.face_material.push_back(mat);
        const std::uint32_t obj = t < m.triangle_object.size() ? m.triangle_object[t] : 0;
        s.face_object.push_back(object_base + obj);
      }
      s.tri_face.push_back(it->second);
    }
  }
  // Planes: area-weighted normal through the area-weighted centroid.
  const std::size_t nf = s.face_material.size();
  std::vector<Vec3> nsum(nf, Vec3{0, 0, 0}), csum(nf, Vec3{0, 0, 0});
  std::vector<double> asum(nf, 0);
  for (std::size_t t = 0; t < s.triangles.size(); ++t) {
    const auto& tri = s.triangles[t];
    const Vec3 &a = s.vertices[tri[0]], &b = s.vertices[tri[1]], &c = s.vertices[tri[2]];
    const Vec3 n2 = cross(b - a, c - a);
    const double area2 = norm(n2);
    const auto f = s.tri_face[t];
    nsum[f] = nsum[f] + n2;
    csum[f] = csum[f] + (area2 / 3.0) * (a + b + c);
    asum[f] += area2;
  }
  s.face_plane.resize(nf);
  s.face_flatness.assign(nf, 0);
  for (std::size_t f = 0; f < nf; ++f) {
    const Vec3 n = normalize(nsum[f]);
    const Vec3 c = asum[f] > 0 ? (1.0 / asum[f]) * csum[f] : Vec3{0, 0, 0};
    s.face_plane[f] = Plane{n, dot(n, c)};
  }
  for (std::size_t t = 0; t < s.triangles.size(); ++t) {
    const auto f = s.tri_face[t];
    for (auto vi : s.triangles[t])
      s.face_flatness[f] =
          std::max(s.face_flatness[f], std::fabs(dot(s.face_plane[f].normal, s.vertices[vi]) - s.face_plane[f].offset));
  }

  // Triangle membership and edge constraints for face_contains.
  s.face_tri_begin.assign(nf + 1, 0);
  for (auto f : s.tri_face) ++s.face_tri_begin[f + 1];
  for (std::size_t f = 0; f < nf; ++f) s.face_tri_begin[f + 1] += s.face_tri_begin[f];
  s.face_tris.resize(s.triangles.size());
  {
    std::vector<std::uint32_t> fill(s.face_tri_begin.begin(), s.face_tri_begin.end() - 1);
    for (std::uint32_t t = 0; t < s.triangles.size(); ++t) s.face_tris[fill[s.tri_face[t]]++] = t;
  }
  s.edge_normal.assign(3 * s.triangles.size(), Vec3{0, 0, 0});
  s.edge_offset.assign(3 * s.triangles.size(), 1e300);  // degenerate triangles contain nothing
  for (std::size_t t = 0; t < s.triangles.size(); ++t) {
    const auto& tri = s.triangles[t];
    const Vec3 n = s.face_plane[s.tri_face[t]].normal;
    const Vec3 a = s.vertices[tri[0]], b = s.vertices[tri[1]], c = s.vertices[tri[2]];
    const double orient = dot(cross(b - a, c - a), n) >= 0 ? 1.0 : -1.0;
    const Vec3 pts[3] = {a, b, c};
    bool degenerate = false;
    Vec3 en[3];
    for (int k = 0; k < 3; ++k) {
      en[k] = orient * cross(n, pts[(k + 1) % 3] - pts[k]);  // points into the triangle
      if (norm(en[k]) < 1e-12) degenerate = true;
      en[k] = normalize(en[k]);
    }
    if (degenerate) continue;
    for (int k = 0; k < 3; ++k) {
      s.edge_normal[3 * t + k] = en[k];
      s.edge_offset[3 * t + k] = dot(en[k], pts[k]);
    }
  }
  s.face_sphere.assign(nf, TraceScene::Sphere{});
  {
    std::vector<Vec3> lo(nf, Vec3{1e300, 1e300, 1e300}), hi(nf, Vec3{-1e300, -1e300, -1e300});
    for (std::size_t t = 0; t < s.triangles.size(); ++t)
      for (auto vi : s.triangles[t])
        for (int k = 0; k < 3; ++k) {
          lo[s.tri_face[t]][k] = std::min(lo[s.tri_face[t]][k], s.vertices[vi][k]);
          hi[s.tri_face[t]][k] = std::max(hi[s.tri_face[t]][k], s.vertices[vi][k]);
        }
    for (std::size_t f = 0; f < nf; ++f) {
      s.face_sphere[f].centre = 0.5 * (lo[f] + hi[f]);
      s.face_sphere[f].radius = 0.5 * norm(hi[f] - lo[f]);
    }
  }

  {
    Vec3 lo{1e300, 1e300, 1e300}, hi{-1e300, -1e300, -1e300};
    for (const auto& v : s.vertices)
      for (int k = 0; k < 3; ++k) {
        lo[k] = std::min(lo[k], v[k]);
        hi[k] = std::max(hi[k], v[k]);
      }
    if (!s.vertices.empty()) s.bounds = TraceScene::Sphere{0.5 * (lo + hi), 0.5 * norm(hi - lo)};
  }
}

namespace {

// Diffracting edges of a shape: triangle edges (matched by position, so
// meshes with duplicated vertices still connect) between two planar faces
// that turn convexly by at least kMinTurn, and free borders of faces.
constexpr double kMinTurn = 10.0 * kPi / 180.0;

// `floor_on_ground`: a downward face is a floor only at z = 0 (a vehicle
// model's underside is a face of its body above the ground, whose edges
// diffract; a building's floor lies on the ground).
std::vector<Edge> extract_edges(const TraceScene::Shape& s, const std::vector<std::string>& object_names,
                                bool floor_on_ground = false) {
  // Vertex ids by position on a 0.1 mm grid.
  std::map<std::array<long long, 3>, std::uint32_t> grid;
  std::vector<std::uint32_t> canon(s.vertices.size());
  for (std::size_t i = 0; i < s.vertices.size(); ++i) {
    std::array<long long, 3> key;
    for (int k = 0; k < 3; ++k) key[k] = std::llround(s.vertices[i][k] * 1e4);
    canon[i] = grid.try_emplace(key, static_cast<std::uint32_t>(i)).first->second;
  }
  struct Side {
    std::uint32_t tri;
    std::uint32_t face;
    std::uint32_t third;  // vertex opposite the edge
  };
  std::map<std::pair<std::uint32_t, std::uint32_t>, std::vector<Side>> sides;
  for (std::uint32_t t = 0; t < s.triangles.size(); ++t) {
    const auto& tri = s.triangles[t];
    for (int k = 0; k < 3; ++k) {
      std::uint32_t u = canon[tri[k]], v = canon[tri[(k + 1) % 3]];
      if (u == v) continue;
      if (u > v) std::swap(u, v);
      sides[{u, v}].push_back(Side{t, s.tri_face[t], tri[(k + 2) % 3]});
    }
  }
  auto is_floor = [&](std::uint32_t f) {
    const Plane& pl = s.face_plane[f];
    return pl.normal[2] < -0.9 && (!floor_on_ground || pl.offset / pl.normal[2] < 0.02);
  };
  auto is_ground = [&](std::uint32_t f) {
    const auto o = s.face_object[f];
    return o < object_names.size() && object_names[o] == "ground";
  };
  // Direction from the edge into the face of `side`, perpendicular to the edge.
  auto inward = [&](const Vec3& p, const Vec3& dir, const Side& side) {
    const Vec3 w = s.vertices[side.third] - p;
    return normalize(w - dot(w, dir) * dir);
  };
  std::vector<Edge> pieces;
  for (const auto& [uv, list] : sides) {
    const Vec3 p = s.vertices[uv.first], q = s.vertices[uv.second];
    if (norm(q - p) < 1e-6) continue;
    const Vec3 dir = normalize(q - p);
    Edge e;
    if (list.size() == 1) {
      const std::uint32_t f = list[0].face;
      if (is_ground(f) || is_floor(f)) continue;
      e.face0 = e.face_n = FaceRef{0, f};
      e.t0 = inward(p, dir, list[0]);
      e.n0 = s.face_plane[f].normal;
      e.n = 2;
    } else if (list.size() == 2 && list[0].face != list[1].face) {
      const Side &A = list[0], &B = list[1];
      if (is_floor(A.face) || is_floor(B.face) || is_ground(A.face) || is_ground(B.face)) continue;
      const Vec3 ta = inward(p, dir, A), tb = inward(p, dir, B);
      const Vec3 na = s.face_plane[A.face].normal, nb = s.face_plane[B.face].normal;
      double ext = std::atan2(dot(tb, na), dot(tb, ta));
      if (ext <= 0) ext += 2 * kPi;
      if (ext < kPi + kMinTurn || ext > 2 * kPi - 1e-9) continue;  // concave, flat or a fold
      // Face n's normal must point into the exterior (at angle ext - pi/2):
      // meshes whose windings disagree have no well-defined outside here.
      const Vec3 expect = std::cos(ext - kPi / 2) * ta + std::sin(ext - kPi / 2) * na;
      if (dot(nb, expect) < 0.5) continue;
      e.face0 = FaceRef{0, A.face};
      e.face_n = FaceRef{0, B.face};
      e.t0 = ta;
      e.n0 = na;
      e.n = ext / kPi;
    } else {
      continue;  // inside a planar face, or non-manifold
    }
    e.e = normalize(cross(e.t0, e.n0));
    const bool forward = dot(e.e, dir) > 0;
    e.a = forward ? p : q;
    e.b = forward ? q : p;
    e.object = s.face_object[e.face0.face];
    e.material0 = s.face_material[e.face0.face];
    e.material_n = s.face_material[e.face_n.face];
    pieces.push_back(e);
  }
  // Merge collinear pieces of the same face pair, so a diffraction point on
  // the seam of two triangles is found once.
  std::sort(pieces.begin(), pieces.end(), [](const Edge& x, const Edge& y) {
    if (x.face0 != y.face0) return x.face0 < y.face0;
    if (x.face_n != y.face_n) return x.face_n < y.face_n;
    return dot(x.a, x.e) < dot(y.a, y.e);
  });
  std::vector<Edge> edges;
  for (const auto& e : pieces) {
    if (!edges.empty()) {
      Edge& last = edges.back();
      const Vec3 w = e.a - last.a;
      const double off = norm(w - dot(w, last.e) * last.e);
      if (last.face0 == e.face0 && last.face_n == e.face_n && dot(e.e, last.e) > 1 - 1e-9 && off < 1e-4 &&
          dot(e.a - last.b, last.e) < 1e-4) {
        if (dot(e.b - last.b, last.e) > 0) last.b = e.b;
        continue;
      }
    }
    edges.push_back(e);
  }
  return edges;
}

// Whether x lies inside a static solid: the nearest face straight up is
// seen from behind (a building's roof from inside). Not down or sideways:
// floors lie on the ground plane and touching buildings' walls coincide, so
// the nearest face there is either of two. A roofless mesh reads as outside.
bool inside_solid(const TraceScene& scene, const Vec3& x) {
  const Vec3 up{0, 0, 1};
  Hit hit;
  return scene.closest_hit(x, up, 0, std::numeric_limits<double>::infinity(), hit) &&
         dot(scene.plane(hit.face).normal, up) > 0;
}

// A point of an edge is buried when another solid fills part of the
// exterior wedge next to it: two buildings that touch (row houses, OSM
// footprints sharing a wall) keep each other's corners inside the block,
// where the meshes still carry them as wedges (a corner where the fronts are
// flush, a lower roof's edge along its taller neighbour's wall). Probes
// across the exterior wedge, kProbeReach from the edge.
constexpr int kProbes = 6;
constexpr double kProbeReach = 0.05;
bool buried(const TraceScene& scene, const Edge& e, const Vec3& p) {
  for (int k = 0; k < kProbes; ++k) {
    const double phi = (k + 0.5) / kProbes * e.n * kPi;
    if (inside_solid(scene, p + kProbeReach * (std::cos(phi) * e.t0 + std::sin(phi) * e.n0))) return true;
  }
  return false;
}

// The parts of `edges` that are not buried: each edge is probed every
// kProbeSpacing (at least twice) and cut where the state changes, the cut
// found by bisection to kCutTolerance. Order kept (deterministic).
constexpr double kProbeSpacing = 0.5;
constexpr double kCutTolerance = 1e-3;
std::vector<Edge> exposed_parts(const TraceScene& scene, const std::vector<Edge>& edges) {
  std::vector<std::vector<Edge>> parts(edges.size());
  tbb::parallel_for(std::size_t{0}, edges.size(), [&](std::size_t i) {
    const Edge& e = edges[i];
    const double len = norm(e.b - e.a);
    const int n = std::clamp(static_cast<int>(std::ceil(len / kProbeSpacing)), 2, 4096);
    auto at = [&](double z) { return e.a + z * e.e; };
    auto z_of = [&](int k) { return (k + 0.5) * len / n; };
    std::vector<char> hidden(n);
    bool any = false;
    for (int k = 0; k < n; ++k) any |= (hidden[k] = buried(scene, e, at(z_of(k))));
    if (!any) {
      parts[i].push_back(e);
      return;
    }
    auto emit = [&](double z0, double z1) {
      if (z1 - z0 < kCutTolerance) return;
      Edge piece = e;
      piece.a = at(z0);
      piece.b = at(z1);
      parts[i].push_back(piece);
    };
    double start = 0;
    for (int k = 1; k < n; ++k) {
      if (hidden[k] == hidden[k - 1]) continue;
      double lo = z_of(k - 1), hi = z_of(k);  // lo has hidden[k - 1]'s state
      while (hi - lo > kCutTolerance) {
        const double mid = 0.5 * (lo + hi);
        (buried(scene, e, at(mid)) == static_cast<bool>(hidden[k - 1]) ? lo : hi) = mid;
      }
      const double cut = 0.5 * (lo + hi);
      if (hidden[k - 1]) start = cut;
      else emit(start, cut);
    }
    if (!hidden[n - 1]) emit(start, len);
  });
  std::vector<Edge> out;
  for (auto& p : parts) out.insert(out.end(), p.begin(), p.end());
  return out;
}

// The ground: large horizontal faces (a bounding radius of 25 m or more) at
// the scene's lowest level of such faces, within kGroundBand. A large flat
// roof is above that band: it stays a reflector and an obstacle like any
// other face, and does not multiply the ground's order-3 search (a town of
// 633 buildings had 71 such faces).
std::vector<char> ground_faces(const TraceScene::Shape& w) {
  constexpr double kGroundBand = 2.0;  // m: curbs, gentle slopes, ground split into patches
  const std::size_t nf = w.face_plane.size();
  std::vector<char> out(nf, 0);
  auto large_flat = [&](std::size_t f) {
    return std::fabs(w.face_plane[f].normal[2]) > 0.999 && w.face_sphere[f].radius >= 25;
  };
  auto height = [&](std::size_t f) { return w.face_plane[f].offset / w.face_plane[f].normal[2]; };
  double lowest = std::numeric_limits<double>::infinity();
  for (std::size_t f = 0; f < nf; ++f)
    if (large_flat(f)) lowest = std::min(lowest, height(f));
  for (std::size_t f = 0; f < nf; ++f) out[f] = large_flat(f) && height(f) <= lowest + kGroundBand;
  return out;
}

}  // namespace

TraceScene::TraceScene(const meshkit::Scene& static_scene) : impl_(std::make_unique<Impl>()) {
  auto& d = *impl_;
  d.device = rtcNewDevice("verbose=0");
  if (!d.device) throw std::runtime_error("cannot create an Embree device");
  d.bounds = static_scene.bounds();
  if (!d.bounds.empty())
    for (int k = 0; k < 3; ++k) d.origin[k] = std::round(0.5 * (d.bounds.min[k] + d.bounds.max[k]));
  for (const auto& o : static_scene.objects) d.static_objects.push_back(o.source_id);
  if (d.static_objects.empty()) d.static_objects.push_back("static");
  d.world.name = "static scene";
  build_shape(d.world, static_scene, [this](const std::string& m) { return material_index(m); }, 0);
  for (auto& o : d.world.face_object) o = std::min<std::uint32_t>(o, d.static_objects.size() - 1);
  d.edges = extract_edges(d.world, d.static_objects);
  d.ground = ground_faces(d.world);
  {
    const std::size_t nf = d.world.face_plane.size();
    std::vector<std::vector<std::uint32_t>> verts(nf);
    for (std::size_t t = 0; t < d.world.triangles.size(); ++t)
      for (auto vi : d.world.triangles[t]) verts[d.world.tri_face[t]].push_back(vi);
    for (auto& v : verts) {
      std::sort(v.begin(), v.end());
      v.erase(std::unique(v.begin(), v.end()), v.end());
    }
    d.reaching_words = (nf + 63) / 64;
    d.reaching.assign(2 * nf * d.reaching_words, 0);
    for (std::uint32_t f = 0; f < nf; ++f) {
      const Plane& p = d.world.face_plane[f];
      const double eps = 1e-9 + d.world.face_flatness[f];
      for (std::uint32_t g = 0; g < nf; ++g) {
        if (g == f) continue;
        bool front = false, back = false;
        for (auto vi : verts[g]) {
          const double h = dot(p.normal, d.world.vertices[vi]) - p.offset;
          front = front || h > eps;
          back = back || h < -eps;
        }
        const std::uint64_t bit = std::uint64_t{1} << (g % 64);
        if (front) d.reaching[(2 * std::size_t{f}) * d.reaching_words + g / 64] |= bit;
        if (back) d.reaching[(2 * std::size_t{f} + 1) * d.reaching_words + g / 64] |= bit;
      }
    }
  }

  d.top = rtcNewScene(d.device);
  rtcSetSceneFlags(d.top, static_cast<RTCSceneFlags>(RTC_SCENE_FLAG_DYNAMIC | RTC_SCENE_FLAG_ROBUST |
                                                     RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION));
  rtcSetSceneBuildQuality(d.top, RTC_BUILD_QUALITY_LOW);
  // The static scene's triangles directly in the top-level scene, not as
  // an instance of the world's own scene: every ray then walks one BVH for
  // them (Embree's raw closest-hit rays 15-30 % faster on the bench scenes).
  if (!d.world.triangles.empty()) attach_triangles(d.device, d.world, d.origin, d.top);
  rtcCommitScene(d.top);
  check_device(d.device, "top-level scene");
  d.edges = exposed_parts(*this, d.edges);
}

TraceScene::~TraceScene() {
  auto& d = *impl_;
  for (auto g : d.slots) rtcReleaseGeometry(g);
  if (d.top) rtcReleaseScene(d.top);
  for (auto& m : d.models) rtcReleaseScene(m->scene);
  rtcReleaseDevice(d.device);
}

std::uint16_t TraceScene::material_index(const std::string& name) {
  for (std::size_t i = 0; i < materials_.size(); ++i)
    if (materials_[i] == name) return static_cast<std::uint16_t>(i);
  materials_.push_back(name);
  return static_cast<std::uint16_t>(materials_.size() - 1);
}

namespace {

// What a model's tables depend on: its triangles, faces and materials, and
// the Embree that traces them (its float traversal decides grazing hits).
std::string model_content_key(const TraceScene::Shape& s, const std::vector<std::string>& materials,
                              long embree_version) {
  ContentKey k;
  k.add("raysweep vehicle model tables").add_u64(static_cast<std::uint64_t>(embree_version));
  k.add_vector(s.vertices).add_vector(s.triangles).add_vector(s.tri_face);
  for (auto m : s.face_material) k.add(materials.at(m));
  return k.hex();
}

// Faces the antenna sees on its own vehicle (through its windows too: rays
// continue through every face until they leave the model).
std::vector<std::uint32_t> faces_seen_from(const TraceScene::Shape& s, const Vec3& antenna) {
  std::vector<char> seen(s.face_plane.size(), 0);
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  for (const Vec3& dir : fibonacci_sphere(1 << 16)) {
    float tnear = 0;
    for (int hop = 0; hop < 64; ++hop) {
      RTCRayHit rh = make_ray(antenna, dir, tnear, 1e3);
      rtcIntersect1(s.scene, &ctx, &rh);
      if (rh.hit.geomID == kNone) break;
      seen[s.tri_face[rh.hit.primID]] = 1;
      tnear = rh.ray.tfar + 1e-4f;
    }
  }
  std::vector<std::uint32_t> out;
  for (std::uint32_t f = 0; f < seen.size(); ++f)
    if (seen[f]) out.push_back(f);
  return out;
}

// Face ids, strictly increasing, each below `faces`.
bool decode_increasing(const std::vector<std::uint32_t>& w, std::uint32_t faces, std::vector<std::uint32_t>& out) {
  for (std::size_t i = 0; i < w.size(); ++i)
    if (w[i] >= faces || (i > 0 && w[i] <= w[i - 1])) return false;
  out = w;
  return true;
}

// Table `key` from the store when it unframes and decodes (decode fills the
// outputs), else built here (build fills them) and stored (encode).
template <class Decode, class Build, class Encode>
void cached_table(const PrecomputeStore* store, const std::string& key, Decode&& decode, Build&& build,
                              Encode&& encode) {
  if (store) {
    if (auto bytes = store->load(key)) {
      std::string why;
      if (auto words = unframe_table(*bytes, why)) {
        if (decode(*words)) return;
        why = "contents do not fit the model";
      }
      store->rejected(key, why);
    }
  }
  build();
  if (store) store->save(key, frame_table(encode()));
}

}  // namespace

std::uint32_t TraceScene::add_vehicle_model(const std::string& name, const meshkit::Scene& model,
                                            const Vec3& antenna) {
  auto& d = *impl_;
  auto s = std::make_unique<Shape>();
  s->name = "vehicle model " + name;
  s->antenna = antenna;
  build_shape(*s, model, [this](const std::string& m) { return material_index(m); }, 0);
  // Only vehicles' faces are looked up by normal (vehicle_faces_near_normal):
  // the city's index would cost a process a few milliseconds for nothing.
  build_normal_index(*s);
  s->scene = rtcNewScene(d.device);
  rtcSetSceneFlags(s->scene, static_cast<RTCSceneFlags>(RTC_SCENE_FLAG_ROBUST | RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION));
  rtcSetSceneBuildQuality(s->scene, RTC_BUILD_QUALITY_HIGH);
  if (!s->triangles.empty()) attach_triangles(d.device, *s, Vec3{0, 0, 0}, s->scene);
  rtcCommitScene(s->scene);
  check_device(d.device, s->name.c_str());
  s->content_key = model_content_key(*s, materials_, rtcGetDeviceProperty(d.device, RTC_DEVICE_PROPERTY_VERSION));
  const std::uint32_t faces = static_cast<std::uint32_t>(s->face_plane.size());
  cached_table(
      d.store.get(), "mount-" + ContentKey().add(s->content_key).add(&antenna, sizeof antenna).hex(),
      [&](const std::vector<std::uint32_t>& w) { return decode_increasing(w, faces, s->seen_from_mount); },
      [&] { s->seen_from_mount = faces_seen_from(*s, antenna); },
      [&] { return s->seen_from_mount; });
  // Wedges only: a free border of a model's face is a modelling seam (an
  // open panel, a glass pane set into the body), not a thin screen.
  for (const Edge& e : extract_edges(*s, {}, true))
    if (e.face0 != e.face_n) s->model_edges.push_back(e);
  d.models.push_back(std::move(s));
  return static_cast<std::uint32_t>(d.models.size() - 1);
}

void TraceScene::set_precompute_store(std::shared_ptr<const PrecomputeStore> store) {
  impl_->store = std::move(store);
}

std::size_t TraceScene::model_count() const { return impl_->models.size(); }
const std::string& TraceScene::model_name(std::uint32_t model) const { return impl_->models.at(model)->name; }

void TraceScene::set_vehicles(const std::vector<VehiclePose>& vehicles) {
  auto& d = *impl_;
  for (const auto& v : vehicles)
    if (v.model >= d.models.size()) throw std::invalid_argument("vehicle " + v.id + ": unknown model index");
  vehicles_ = vehicles;
  d.cos_yaw.resize(vehicles.size());
  d.sin_yaw.resize(vehicles.size());
  for (std::size_t i = 0; i < vehicles.size(); ++i) {
    const auto& v = vehicles[i];
    d.cos_yaw[i] = std::cos(v.yaw_rad);
    d.sin_yaw[i] = std::sin(v.yaw_rad);
    if (i >= d.slots.size()) {
      RTCGeometry g = rtcNewGeometry(d.device, RTC_GEOMETRY_TYPE_INSTANCE);
      d.slots.push_back(g);
      d.slot_enabled.push_back(true);
      rtcAttachGeometryByID(d.top, g, static_cast<unsigned>(i + 1));
    } else if (!d.slot_enabled[i]) {
      rtcEnableGeometry(d.slots[i]);
      d.slot_enabled[i] = true;
    }
    RTCGeometry g = d.slots[i];
    rtcSetGeometryInstancedScene(g, d.models[v.model]->scene);
    const float c = static_cast<float>(d.cos_yaw[i]), s = static_cast<float>(d.sin_yaw[i]);
    const float xfm[12] = {c, s, 0, -s, c, 0, 0, 0, 1,
                           static_cast<float>(v.position[0] - d.origin[0]),
                           static_cast<float>(v.position[1] - d.origin[1]),
                           static_cast<float>(v.position[2] - d.origin[2])};
    rtcSetGeometryTransform(g, 0, RTC_FORMAT_FLOAT3X4_COLUMN_MAJOR, xfm);
    rtcCommitGeometry(g);
  }
  for (std::size_t i = vehicles.size(); i < d.slots.size(); ++i)
    if (d.slot_enabled[i]) {
      rtcDisableGeometry(d.slots[i]);
      d.slot_enabled[i] = false;
    }
  rtcCommitScene(d.top);
  check_device(d.device, "vehicle update");
}

Vec3 TraceScene::vehicle_antenna(std::size_t v) const {
  const auto& d = *impl_;
  const Vec3& a = d.models[vehicles_[v].model]->antenna;
  const double c = d.cos_yaw[v], s = d.sin_yaw[v];
  return Vec3{c * a[0] - s * a[1], s * a[0] + c * a[1], a[2]} + vehicles_[v].position;
}

Vec3 TraceScene::vehicle_forward(std::size_t v) const { return Vec3{impl_->cos_yaw[v], impl_->sin_yaw[v], 0}; }

bool TraceScene::closest_hit(const Vec3& origin, const Vec3& dir, double tnear, double tfar, Hit& hit,
                             const FaceRef* skip) const {
  const auto& d = *impl_;
  const Vec3 o = origin - d.origin;
  const double olen = norm(o);
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  for (int attempt = 0; attempt < 16; ++attempt) {
    RTCRayHit rh = make_ray(o, dir, tnear, tfar);
    rtcIntersect1(d.top, &ctx, &rh);
    if (rh.hit.geomID == kNone) return false;
    const std::uint32_t inst = instance_of(rh.hit.instID[0]);
    const Shape& s = inst == 0 ? d.world : *d.models[vehicles_[inst - 1].model];
    hit.t = rh.ray.tfar;
    hit.face = FaceRef{inst, s.tri_face[rh.hit.primID]};
    if (skip && hit.face == *skip) {
      tnear = hit.t + Impl::step(olen, hit.t);
      continue;
    }
    return true;
  }
  return false;
}

bool TraceScene::all_hits(const Vec3& origin, const Vec3& dir, double tnear, double tfar, std::vector<Hit>& hits,
                          std::size_t max_hits, const FaceRef* skip) const {
  hits.clear();
  if (!(tnear < tfar)) return true;
  const auto& d = *impl_;
  const Vec3 o = origin - d.origin;
  const double olen = norm(o);
  thread_local std::vector<Impl::RawHit> raw;
  raw.clear();
  Impl::FilterContext fc;
  rtcInitIntersectContext(&fc.ctx);
  fc.ctx.filter = &Impl::filter;
  fc.impl = &d;
  fc.vehicles = &vehicles_;
  fc.collect = &raw;
  RTCRayHit rh = make_ray(o, dir, tnear, tfar);
  rtcIntersect1(d.top, &fc.ctx, &rh);
  std::sort(raw.begin(), raw.end(), [](const Impl::RawHit& a, const Impl::RawHit& b) {
    return a.t != b.t ? a.t < b.t : a.face < b.face;
  });
  // Crossings as a walk from hit to hit would list them: a hit within
  // float rounding of the previous one (the same crossing seen on two
  // triangles, or a second face at the same point) is one crossing; the
  // face the ray leaves is stepped over.
  double cursor = tnear;
  for (const auto& r : raw) {
    if (r.t < cursor) continue;
    cursor = r.t + Impl::step(olen, r.t);
    if (skip && r.face == *skip) continue;
    if (hits.size() >= max_hits) return false;
    hits.push_back(Hit{r.t, r.face});
  }
  return true;
}

bool TraceScene::occluded(const Vec3& origin, const Vec3& dir, double tnear, double tfar, const FaceRef* ignore0,
                          const FaceRef* ignore1) const {
  if (!(tnear < tfar)) return false;
  const auto& d = *impl_;
  Impl::FilterContext fc;
  rtcInitIntersectContext(&fc.ctx);
  fc.ctx.filter = (ignore0 || ignore1) ? &Impl::filter : nullptr;
  fc.impl = &d;
  fc.vehicles = &vehicles_;
  fc.ignore[0] = ignore0;
  fc.ignore[1] = ignore1;
  RTCRayHit rh = make_ray(origin - d.origin, dir, tnear, tfar);
  rtcOccluded1(d.top, &fc.ctx, &rh.ray);
  return rh.ray.tfar < 0;
}

double TraceScene::slack(const Vec3& p, double t) const {
  return std::max(1e-3, 1e-6 * (norm(p - impl_->origin) + t));
}

Plane TraceScene::plane(const FaceRef& f) const {
  const auto& d = *impl_;
  if (f.instance == 0) return d.world.face_plane[f.face];
  const std::size_t v = f.instance - 1;
  const Plane& p = d.models[vehicles_[v].model]->face_plane[f.face];
  const double c = d.cos_yaw[v], s = d.sin_yaw[v];
  const Vec3 n{c * p.normal[0] - s * p.normal[1], s * p.normal[0] + c * p.normal[1], p.normal[2]};
  return Plane{n, p.offset + dot(n, vehicles_[v].position)};
}

std::uint16_t TraceScene::material(const FaceRef& f) const {
  return impl_->shape_of(f, vehicles_).face_material[f.face];
}

std::uint32_t TraceScene::object(const FaceRef& f) const {
  if (f.instance == 0) return impl_->world.face_object[f.face];
  return vehicle_object(f.instance - 1);
}

double TraceScene::flatness(const FaceRef& f) const { return impl_->shape_of(f, vehicles_).face_flatness[f.face]; }

Vec3 TraceScene::velocity(const FaceRef& f) const {
  return f.instance == 0 ? Vec3{0, 0, 0} : vehicles_[f.instance - 1].velocity;
}

std::size_t TraceScene::face_count(std::uint32_t instance) const {
  if (instance == 0) return impl_->world.face_plane.size();
  return impl_->models[vehicles_.at(instance - 1).model]->face_plane.size();
}

bool TraceScene::face_contains(const FaceRef& f, const Vec3& p, double tol) const {
  const auto& d = *impl_;
  const Shape& s = d.shape_of(f, vehicles_);
  Vec3 q = p;
  if (f.instance > 0) {  // into the model frame
    const std::size_t v = f.instance - 1;
    const Vec3 w = p - vehicles_[v].position;
    const double c = d.cos_yaw[v], sn = d.sin_yaw[v];
    q = Vec3{c * w[0] + sn * w[1], -sn * w[0] + c * w[1], w[2]};
  }
  const Sphere& b = s.face_sphere[f.face];
  const Vec3 w = q - b.centre;
  if (dot(w, w) > (b.radius + tol) * (b.radius + tol)) return false;
  for (std::uint32_t k = s.face_tri_begin[f.face]; k < s.face_tri_begin[f.face + 1]; ++k) {
    const std::uint32_t t = s.face_tris[k];
    if (dot(s.edge_normal[3 * t], q) >= s.edge_offset[3 * t] - tol &&
        dot(s.edge_normal[3 * t + 1], q) >= s.edge_offset[3 * t + 1] - tol &&
        dot(s.edge_normal[3 * t + 2], q) >= s.edge_offset[3 * t + 2] - tol)
      return true;
  }
  return false;
}

TraceScene::Sphere TraceScene::face_sphere(const FaceRef& f) const {
  const auto& d = *impl_;
  const Sphere& b = d.shape_of(f, vehicles_).face_sphere[f.face];
  if (f.instance == 0) return b;
  const std::size_t v = f.instance - 1;
  const double c = d.cos_yaw[v], sn = d.sin_yaw[v];
  const Vec3& m = b.centre;
  return Sphere{Vec3{c * m[0] - sn * m[1], sn * m[0] + c * m[1], m[2]} + vehicles_[v].position, b.radius};
}

bool TraceScene::static_face_reaches(std::uint32_t f, int side, std::uint32_t g) const {
  const auto& d = *impl_;
  const std::size_t row = 2 * std::size_t{f} + (side > 0 ? 0 : 1);
  return (d.reaching[row * d.reaching_words + g / 64] >> (g % 64)) & 1u;
}

void TraceScene::face_triangles(const FaceRef& f, std::vector<std::array<Vec3, 3>>& out) const {
  const auto& d = *impl_;
  const Shape& s = d.shape_of(f, vehicles_);
  double c = 1, sn = 0;
  Vec3 t{0, 0, 0};
  if (f.instance > 0) {
    const std::size_t v = f.instance - 1;
    c = d.cos_yaw[v];
    sn = d.sin_yaw[v];
    t = vehicles_[v].position;
  }
  for (std::uint32_t k = s.face_tri_begin[f.face]; k < s.face_tri_begin[f.face + 1]; ++k) {
    std::array<Vec3, 3> tri;
    for (int q = 0; q < 3; ++q) {
      const Vec3& m = s.vertices[s.triangles[s.face_tris[k]][q]];
      tri[q] = Vec3{c * m[0] - sn * m[1], sn * m[0] + c * m[1], m[2]} + t;
    }
    out.push_back(tri);
  }
}

bool TraceScene::is_ground(std::uint32_t f) const { return impl_->ground.at(f) != 0; }

TraceScene::Sphere TraceScene::vehicle_sphere(std::size_t v) const {
  const auto& d = *impl_;
  const Sphere& b = d.models[vehicles_[v].model]->bounds;
  const double c = d.cos_yaw[v], sn = d.sin_yaw[v];
  const Vec3& m = b.centre;
  return Sphere{Vec3{c * m[0] - sn * m[1], sn * m[0] + c * m[1], m[2]} + vehicles_[v].position, b.radius};
}

const std::vector<std::uint32_t>& TraceScene::vehicle_faces_near_normal(std::size_t v, const Vec3& dir,
                                                                        double delta) const {
  const auto& d = *impl_;
  const double c = d.cos_yaw[v], sn = d.sin_yaw[v];
  const Vec3 m{c * dir[0] + sn * dir[1], -sn * dir[0] + c * dir[1], dir[2]};  // into the model frame
  return d.models[vehicles_[v].model]->normals.query(m, delta);
}

const std::vector<std::uint32_t>* TraceScene::faces_seen_from_mount(std::size_t v, const Vec3& node) const {
  if (norm(node - vehicle_antenna(v)) > 1e-6) return nullptr;
  return &impl_->models[vehicles_[v].model]->seen_from_mount;
}

std::vector<std::string> TraceScene::object_names() const {
  std::vector<std::string> names = impl_->static_objects;
  for (const auto& v : vehicles_) names.push_back("vehicle/" + v.id);
  return names;
}

std::uint32_t TraceScene::static_object_count() const {
  return static_cast<std::uint32_t>(impl_->static_objects.size());
}

const std::vector<Edge>& TraceScene::edges() const { return impl_->edges; }

void TraceScene::vehicle_edges(std::size_t v, std::vector<Edge>& out) const {
  const auto& d = *impl_;
  const double c = d.cos_yaw[v], sn = d.sin_yaw[v];
  const Vec3& at = vehicles_[v].position;
  auto turn = [&](const Vec3& x) { return Vec3{c * x[0] - sn * x[1], sn * x[0] + c * x[1], x[2]}; };
  const auto inst = static_cast<std::uint32_t>(v + 1);
  for (Edge e : d.models[vehicles_[v].model]->model_edges) {
    e.a = turn(e.a) + at;
    e.b = turn(e.b) + at;
    e.e = turn(e.e);
    e.t0 = turn(e.t0);
    e.n0 = turn(e.n0);
    e.face0.instance = e.face_n.instance = inst;
    e.object = vehicle_object(v);
    out.push_back(e);
  }
}

meshkit::Bounds TraceScene::static_bounds() const { return impl_->bounds; }
std::size_t TraceScene::static_triangle_count() const { return impl_->world.triangles.size(); }

std::size_t TraceScene::shoot_raw(const Vec3& origin, const std::vector<Vec3>& directions, double tfar) const {
  const auto& d = *impl_;
  const Vec3 o = origin - d.origin;
  return tbb::parallel_reduce(
      tbb::blocked_range<std::size_t>(0, directions.size(), 1024), std::size_t{0},
      [&](const tbb::blocked_range<std::size_t>& r, std::size_t n) {
        RTCIntersectContext ctx;
        rtcInitIntersectContext(&ctx);
        for (std::size_t i = r.begin(); i != r.end(); ++i) {
          RTCRayHit rh = make_ray(o, directions[i], 0, tfar);
          rtcIntersect1(d.top, &ctx, &rh);
          n += rh.hit.geomID != kNone;
        }
        return n;
      },
      std::plus<>());
}

namespace {

constexpr int kBounceCells = 16;
// Angular radius of an octahedral cell (16 x 16: at most ~0.17 rad from its
// centre direction) and the query radii the table is unioned for.
constexpr double kBounceCellRadius = 0.2;
constexpr double kBounceLevels[] = {0.2, 0.4, 0.8};

// Plane waves from every direction cell (2 x 2 directions inside each) as
// bundles of parallel rays over the model's bounding disc (41 x 41 grid),
// followed through up to three specular reflections against the model
// alone, and straight through its low-loss slabs (`see_through` faces:
// glass, plastic, textile), where they branch: a bus's or a car's cabin
// echoes between its windows and roof. Every sequence of two or three
// reflecting faces a ray follows is listed under its cell. Deterministic
// (fixed directions and grid).
void build_bounce_table(const TraceScene::Shape& s, const std::vector<char>& see_through,
                        std::vector<TraceScene::BounceSequence>& seqs, std::vector<std::vector<std::uint32_t>>& cells) {
  using Key = std::array<std::uint32_t, 5>;  // faces, the order, the sides (BounceSequence::front)
  const Vec3 c = s.bounds.centre;
  const double r = s.bounds.radius;
  constexpr int kHalf = 20, kMaxCrossings = 4, kCellCount = kBounceCells * kBounceCells;
  const double h = r / kHalf;
  std::vector<std::vector<Key>> found(kCellCount);
  tbb::parallel_for(0, kCellCount, [&](int cell) {
    const int i = cell / kBounceCells, j = cell % kBounceCells;
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    struct Ray {
      Vec3 o, d;
      double tnear;
      int n, crossings;
      std::array<std::uint32_t, 3> seq;
      unsigned front;
    };
    std::vector<Ray> stack;
    auto& keys = found[cell];
    for (int sub = 0; sub < 4; ++sub) {
      const double u = -1 + (i + 0.25 + 0.5 * (sub & 1)) * 2.0 / kBounceCells;
      const double v = -1 + (j + 0.25 + 0.5 * (sub >> 1)) * 2.0 / kBounceCells;
      const Vec3 d = octa_dir(u, v);
      const Vec3 e1 = any_perpendicular(d), e2 = cross(d, e1);
      for (int gx = -kHalf; gx <= kHalf; ++gx)
        for (int gy = -kHalf; gy <= kHalf; ++gy) {
          if (gx * gx + gy * gy > kHalf * kHalf) continue;
          stack.push_back({c - (2 * r) * d + (gx * h) * e1 + (gy * h) * e2, d, 0, 0, 0, {}, 0u});
          while (!stack.empty()) {
            Ray ray = stack.back();
            stack.pop_back();
            RTCRayHit rh = make_ray(ray.o, ray.d, ray.tnear, 8 * r);
            rtcIntersect1(s.scene, &ctx, &rh);
            if (rh.hit.geomID == kNone) continue;
            const std::uint32_t f = s.tri_face[rh.hit.primID];
            const Vec3 p = ray.o + static_cast<double>(rh.ray.tfar) * ray.d;
            if (see_through[f] && ray.crossings < kMaxCrossings)
              stack.push_back({p, ray.d, 1e-4, ray.n, ray.crossings + 1, ray.seq, ray.front});
            const Vec3& n = s.face_plane[f].normal;
            Ray next{p, ray.d, 1e-4, ray.n + 1, ray.crossings, ray.seq, ray.front};
            next.seq[ray.n] = f;
            if (dot(ray.d, n) < 0) next.front |= 1u << ray.n;
            if (next.n >= 2)
              keys.push_back({next.seq[0], next.seq[1], next.n == 3 ? next.seq[2] : 0u, static_cast<std::uint32_t>(next.n),
                              next.front});
            if (next.n == 3) continue;
            next.d = ray.d - (2 * dot(ray.d, n)) * n;
            stack.push_back(next);
          }
        }
    }
    std::sort(keys.begin(), keys.end());
    keys.erase(std::unique(keys.begin(), keys.end()), keys.end());
  });
  // Ids in cell order: the same table for any thread count.
  std::map<Key, std::uint32_t> ids;
  std::vector<std::vector<std::uint32_t>> per_cell(kCellCount);
  for (int cell = 0; cell < kCellCount; ++cell)
    for (const Key& k : found[cell]) {
      auto [it, fresh] = ids.try_emplace(k, static_cast<std::uint32_t>(seqs.size()));
      if (fresh) seqs.push_back({{k[0], k[1], k[2]}, static_cast<int>(k[3]), k[4]});
      per_cell[cell].push_back(it->second);
    }
  // Per level and cell, the union over the cells whose centres lie within
  // the level's radius plus two cell radii of this cell's centre: a query
  // from anywhere in the cell with spread + margin <= the level's radius
  // needs no other cell.
  std::vector<Vec3> centre(kCellCount);
  for (int cell = 0; cell < kCellCount; ++cell)
    centre[cell] = octa_dir(-1 + (cell / kBounceCells + 0.5) * 2.0 / kBounceCells,
                            -1 + (cell % kBounceCells + 0.5) * 2.0 / kBounceCells);
  cells.assign(std::size(kBounceLevels) * kCellCount, {});
  for (std::size_t level = 0; level < std::size(kBounceLevels); ++level)
    for (int cell = 0; cell < kCellCount; ++cell) {
      auto& list = cells[level * kCellCount + cell];
      const double cos_r = std::cos(std::min(kPi, kBounceLevels[level] + 2 * kBounceCellRadius));
      for (int other = 0; other < kCellCount; ++other)
        if (dot(centre[cell], centre[other]) >= cos_r) list.insert(list.end(), per_cell[other].begin(), per_cell[other].end());
      std::sort(list.begin(), list.end());
      list.erase(std::unique(list.begin(), list.end()), list.end());
    }
}

// Sequences (faces, order, sides: 5 words each), then each cell list (its
// length, then its ids).
std::vector<std::uint32_t> encode_bounce_table(const std::vector<TraceScene::BounceSequence>& seqs,
                                               const std::vector<std::vector<std::uint32_t>>& cells) {
  std::vector<std::uint32_t> w{static_cast<std::uint32_t>(seqs.size())};
  for (const auto& q : seqs)
    w.insert(w.end(), {q.faces[0], q.faces[1], q.faces[2], static_cast<std::uint32_t>(q.order), q.front});
  w.push_back(static_cast<std::uint32_t>(cells.size()));
  for (const auto& c : cells) {
    w.push_back(static_cast<std::uint32_t>(c.size()));
    w.insert(w.end(), c.begin(), c.end());
  }
  return w;
}

bool decode_bounce_table(const std::vector<std::uint32_t>& w, const TraceScene::Shape& s,
                         std::vector<TraceScene::BounceSequence>& seqs, std::vector<std::vector<std::uint32_t>>& cells) {
  const std::size_t faces = s.face_plane.size(), n_cells = std::size(kBounceLevels) * kBounceCells * kBounceCells;
  std::size_t at = 0;
  auto next = [&](std::uint32_t& v) { return at < w.size() ? (v = w[at++], true) : false; };
  std::uint32_t n = 0;
  if (!next(n) || n > (w.size() - 1) / 5) return false;
  std::vector<TraceScene::BounceSequence> q(n);
  for (auto& b : q) {
    std::uint32_t order = 0;
    if (!(next(b.faces[0]) && next(b.faces[1]) && next(b.faces[2]) && next(order) && next(b.front))) return false;
    b.order = static_cast<int>(order);
    if (order < 1 || order > 3 || b.front >= (1u << order)) return false;
    for (std::uint32_t k = 0; k < order; ++k)
      if (b.faces[k] >= faces) return false;
  }
  std::uint32_t m = 0;
  if (!next(m) || m != n_cells) return false;
  std::vector<std::vector<std::uint32_t>> c(m);
  for (auto& list : c) {
    std::uint32_t len = 0;
    if (!next(len) || len > w.size() - at) return false;
    list.assign(w.begin() + static_cast<std::ptrdiff_t>(at), w.begin() + static_cast<std::ptrdiff_t>(at + len));
    at += len;
    for (std::size_t k = 0; k < list.size(); ++k)
      if (list[k] >= n || (k > 0 && list[k] <= list[k - 1])) return false;
  }
  if (at != w.size()) return false;
  seqs = std::move(q);
  cells = std::move(c);
  return true;
}

}  // namespace

std::shared_ptr<const void> TraceScene::static_memo(const std::string& key,
                                                    const std::function<std::shared_ptr<const void>()>& make) const {
  const auto& d = *impl_;
  const std::lock_guard<std::mutex> lock(d.memo_mutex);
  auto& slot = d.memo[key];
  if (!slot) slot = make();
  return slot;
}

TraceScene::BounceQuery TraceScene::vehicle_bounce_sequences(std::size_t v, const Vec3& dir, double spread) const {
  const auto& d = *impl_;
  const Shape& s = *d.models[vehicles_.at(v).model];
  std::call_once(s.bounce_once, [&] {
    // Low-loss slabs of the vehicle materials (names as in meshkit's
    // material table); metal, rubber and the riders only reflect here.
    std::vector<char> see_through(s.face_material.size());
    for (std::size_t f = 0; f < see_through.size(); ++f) {
      const std::string& m = materials_.at(s.face_material[f]);
      see_through[f] = m == "glass" || m == "plastic" || m == "textile";
    }
    cached_table(
        d.store.get(), "bounce-" + ContentKey().add(s.content_key).add_vector(see_through).hex(),
        [&](const std::vector<std::uint32_t>& w) { return decode_bounce_table(w, s, s.bounce_seq, s.bounce_near); },
        [&] { build_bounce_table(s, see_through, s.bounce_seq, s.bounce_near); },
        [&] { return encode_bounce_table(s.bounce_seq, s.bounce_near); });
    s.bounce_all.resize(s.bounce_seq.size());
    for (std::uint32_t k = 0; k < s.bounce_all.size(); ++k) s.bounce_all[k] = k;
  });
  std::size_t level = 0;
  while (level < std::size(kBounceLevels) && kBounceLevels[level] < spread) ++level;
  if (level == std::size(kBounceLevels)) return {&s.bounce_seq, &s.bounce_all};
  const double c = d.cos_yaw[v], sn = d.sin_yaw[v];
  const auto [i, j] = octa_cell(Vec3{c * dir[0] + sn * dir[1], -sn * dir[0] + c * dir[1], dir[2]}, kBounceCells);
  return {&s.bounce_seq, &s.bounce_near[level * kBounceCells * kBounceCells + i * kBounceCells + j]};
}

}  // namespace raysweep::tracer
