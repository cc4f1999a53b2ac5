// The scene the tracer shoots rays into. Static geometry (city, ground) is
// one Embree scene built once; each vehicle model is its own Embree scene,
// placed by instances whose transforms change per frame, so moving vehicles
// re-commits only the small top-level scene (never the city BVH).
//
// Embree intersects in float relative to a local origin (the centre of the
// static bounds), so coordinates far from zero keep their precision; every
// quantity derived from a hit is recomputed in double from the planar face it
// names (FaceRef), which is also what the image method reflects in.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "meshkit/scene.hpp"
#include "tracer/path.hpp"
#include "tracer/precompute.hpp"
#include "tracer/vec.hpp"

namespace raysweep::tracer {

// A planar face of a placed shape (FaceRef, tracer/path.hpp) groups
// coplanar, connected triangles (meshkit planar face ids), so a wall split
// into triangles is one reflector and a ray through a shared edge names one
// face.
struct Plane {
  Vec3 normal{0, 0, 1};  // unit
  double offset = 0;     // normal . x = offset
};

struct Hit {
  double t = 0;  // distance along the (unit) ray direction
  FaceRef face;
};

// A diffracting edge of the static scene: a wedge where two planar faces
// meet at a convex angle (building corners, roof edges), or the free border
// of a face (a thin screen, n = 2). Exterior angle n pi, 1 < n <= 2. Frame:
// t0 lies in face 0, perpendicular to the edge, pointing from the edge into
// the face; n0 is face 0's outward normal; the edge direction e = t0 x n0
// runs from a to b. Angles around the edge are measured from t0 towards n0,
// so the exterior is phi in [0, n pi] and face n lies at phi = n pi.
struct Edge {
  Vec3 a{0, 0, 0}, b{0, 0, 0};
  Vec3 e{0, 0, 1}, t0{1, 0, 0}, n0{0, 1, 0};
  double n = 1.5;
  FaceRef face0, face_n;  // face_n == face0 for a free border
  std::uint32_t object = 0;
  std::uint16_t material0 = 0, material_n = 0;
};

// Where a vehicle is in the current frame.
struct VehiclePose {
  std::string id;
  std::uint32_t model = 0;      // index returned by add_vehicle_model
  Vec3 position{0, 0, 0};       // front-bumper centre on the ground (SUMO's FCD point)
  double yaw_rad = 0;           // direction of the front, counter-clockwise from +x
  Vec3 velocity{0, 0, 0};       // m/s
};

class TraceScene {
 public:
  // Static geometry: every mesh's triangles with their material, object and
  // planar-face ids. Object names come from scene.objects (source_id).
  explicit TraceScene(const meshkit::Scene& static_scene);
  ~TraceScene();
  TraceScene(const TraceScene&) = delete;
  TraceScene& operator=(const TraceScene&) = delete;

  // A vehicle model in the library frame (meshkit::to_scene output) with its
  // antenna mount; returns the model index. Models are built once.
  std::uint32_t add_vehicle_model(const std::string& name, const meshkit::Scene& model, const Vec3& antenna);
  // Where models' precomputed tables are kept between processes (see
  // precompute.hpp); set before add_vehicle_model. Without one, every table
  // is built in this process.
  void set_precompute_store(std::shared_ptr<const PrecomputeStore> store);
  std::size_t model_count() const;
  const std::string& model_name(std::uint32_t model) const;

  // Places the vehicles of a frame: instance transforms + one top-level commit.
  void set_vehicles(const std::vector<VehiclePose>& vehicles);
  const std::vector<VehiclePose>& vehicles() const { return vehicles_; }
  // World position of vehicle v's antenna and its forward unit vector.
  Vec3 vehicle_antenna(std::size_t v) const;
  Vec3 vehicle_forward(std::size_t v) const;

  // Closest hit along origin + t dir, t in (tnear, tfar); dir unit. A hit on
  // `skip` (the face a ray leaves) is stepped over. False when nothing is hit.
  bool closest_hit(const Vec3& origin, const Vec3& dir, double tnear, double tfar, Hit& hit,
                   const FaceRef* skip = nullptr) const;
  // Every face crossed by origin + t dir for t in (tnear, tfar), sorted by t;
  // each face at most once per crossing. Stops after `max_hits` hits
  // (returns false then).
  bool all_hits(const Vec3& origin, const Vec3& dir, double tnear, double tfar, std::vector<Hit>& hits,
                std::size_t max_hits, const FaceRef* skip = nullptr) const;
  // Whether anything but the faces `ignore0` / `ignore1` lies on origin +
  // t dir for t in (tnear, tfar): a shadow ray, ended by the first hit found.
  bool occluded(const Vec3& origin, const Vec3& dir, double tnear, double tfar, const FaceRef* ignore0 = nullptr,
                const FaceRef* ignore1 = nullptr) const;

  // Distance that absorbs Embree's float rounding for a hit at distance t
  // from p: Embree's frame is centred on the scene, so it depends on p's
  // distance from that centre, not from the world origin.
  double slack(const Vec3& p, double t) const;

  // Face data in world coordinates (double precision).
  Plane plane(const FaceRef& f) const;
  std::uint16_t material(const FaceRef& f) const;
  std::uint32_t object(const FaceRef& f) const;  // index into object_names()
  // Max distance of the face's vertices from its plane (bent "planar" faces).
  double flatness(const FaceRef& f) const;
  bool is_vehicle(const FaceRef& f) const { return f.instance > 0; }
  Vec3 velocity(const FaceRef& f) const;  // of the surface point (vehicle translation)
  std::size_t face_count(std::uint32_t instance) const;

  // Face shape for the exact image search (tracer/src/search/): whether a
  // point near the face's plane projects inside one of its triangles, with
  // `tol` metres to spare at the borders (so the test never rejects a point
  // that the exact path's ray test would accept), and a bounding sphere.
  bool face_contains(const FaceRef& f, const Vec3& p, double tol) const;
  struct Sphere {
    Vec3 centre{0, 0, 0};
    double radius = 0;
  };
  Sphere face_sphere(const FaceRef& f) const;  // world frame
  // World vertices of face f's triangles, appended to `out`.
  void face_triangles(const FaceRef& f, std::vector<std::array<Vec3, 3>>& out) const;
  // Static faces that are ground: horizontal (|n_z| > 0.999) with a
  // bounding radius >= 25 m (the ground, large squares). Their reflection is
  // a path; they do not obstruct (tracer/src/fresnel_zone.hpp) and pair with every
  // vehicle in the image search.
  bool is_ground(std::uint32_t static_face) const;
  // Bounding sphere of vehicle v's model, in the world.
  Sphere vehicle_sphere(std::size_t v) const;
  // Faces of vehicle v whose normal (either sign) may lie within `delta`
  // radians of the unit world direction `dir`: a superset from a table of
  // normal directions built once per model (callers test each face).
  const std::vector<std::uint32_t>& vehicle_faces_near_normal(std::size_t v, const Vec3& dir, double delta) const;
  // Faces of vehicle v that its own antenna mount sees (2^16 rays from the
  // mount against the model alone, once per model), or nullptr when `node`
  // is not at the mount (then any face may be seen).
  const std::vector<std::uint32_t>* faces_seen_from_mount(std::size_t v, const Vec3& node) const;

  // Face sequences of order 2 and 3 on one vehicle (its concave parts: hood
  // and windscreen, mirrors, a truck's cab and box) that a wave arriving at
  // vehicle v along the unit world direction `dir` (from the source towards
  // the vehicle) may follow, for arrival directions within `spread` radians
  // of it. A superset from a table built once per model, on first use:
  // bundles of parallel rays from 16 x 16 direction cells (four directions
  // each) against the model alone, up to three reflections. Faces are the
  // model's face indices (FaceRef{v + 1, face}); `order` of them are used.
  struct BounceSequence {
    std::array<std::uint32_t, 3> faces{};
    int order = 0;
    // Bit k set: face k is met from the side its normal points to (the
    // ray, and so the image before that reflection, on the normal's side).
    unsigned front = 0;
  };
  struct BounceQuery {
    const std::vector<BounceSequence>* table;  // the model's sequences
    const std::vector<std::uint32_t>* ids;     // those to try (sorted)
  };
  BounceQuery vehicle_bounce_sequences(std::size_t v, const Vec3& dir, double spread) const;

  // Tables the path records index: materials by name ("concrete", "glass"...),
  // objects: static objects first ("way/123", "ground"), then one per vehicle
  // of the current frame ("vehicle/<id>").
  const std::vector<std::string>& material_names() const { return materials_; }
  std::vector<std::string> object_names() const;
  std::uint32_t static_object_count() const;
  std::uint32_t vehicle_object(std::size_t v) const { return static_object_count() + static_cast<std::uint32_t>(v); }
  // The static object whose closed surface holds p (a building an antenna
  // stands inside: a SUMO lane through an OSM footprint), or -1: a ray
  // straight up crosses its faces an odd number of times, and so do rays in
  // two or more of the four horizontal directions (a roof alone, or the
  // ground, is not crossed sideways). Vehicles are not counted.
  std::int64_t enclosing_object(const Vec3& p) const;

  // The static scene's diffracting edges, extracted once when the scene is
  // built: edges between planar faces that turn by at least 10 degrees
  // (collinear pieces merged), and free borders of faces; edges touching a
  // downward-facing face (building floors) and ground borders are left out.
  const std::vector<Edge>& edges() const;
  // Vehicle v's diffracting edges in the world, appended to `out`: the
  // model's convex wedges (faces turning by at least 10 degrees, extracted
  // once per model; free borders and edges touching a face that lies on
  // the ground left out, the underside above it kept), placed at v's pose; faces FaceRef{v + 1, .}, object
  // vehicle_object(v).
  void vehicle_edges(std::size_t v, std::vector<Edge>& out) const;

  meshkit::Bounds static_bounds() const;
  std::size_t static_triangle_count() const;
  // Shoots `directions.size()` rays from `origin` (closest hit), for measuring
  // Embree's raw throughput on this scene; returns how many hit.
  std::size_t shoot_raw(const Vec3& origin, const std::vector<Vec3>& directions, double tfar) const;

  // Data derived from the static scene alone (it never moves), built by
  // `make` on the first request for `key` and kept for every later frame:
  // e.g. the diffuse tile tree. Thread-safe; `make` runs under a lock.
  std::shared_ptr<const void> static_memo(const std::string& key,
                                          const std::function<std::shared_ptr<const void>()>& make) const;

  struct Shape;  // geometry of one Embree scene (static or a vehicle model)

 private:
  std::uint16_t material_index(const std::string& name);

  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::vector<std::string> materials_;
  std::vector<VehiclePose> vehicles_;
};

}  // namespace raysweep::tracer
