// Scene geometry shared by every stage: indexed triangle meshes grouped by radio
// material, with per-triangle object and planar-face ids so the tracer can name
// what a ray hit and avoid counting coplanar triangles twice.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace raysweep::meshkit {

using Vec3 = std::array<double, 3>;
using Tri = std::array<std::uint32_t, 3>;

struct Bounds {
  Vec3 min{0, 0, 0};
  Vec3 max{0, 0, 0};
  bool empty() const { return min[0] > max[0]; }
  void extend(const Vec3& p);
  static Bounds none();
};

// What a triangle belongs to: a building (OSM way/relation), the ground, or an
// imported mesh. `source_id` is stable and human readable ("way/123",
// "relation/45", "ground", "mesh-Foo").
struct SceneObject {
  std::string kind;       // "building", "ground", "mesh"
  std::string source_id;
};

// One mesh per radio material. Coordinates are metres in the scene frame (SUMO
// network x/y, z up).
struct Mesh {
  std::string name;      // e.g. "buildings-itu_concrete"
  std::string material;  // ITU-R P.2040 name without prefix, e.g. "concrete"
  std::vector<Vec3> vertices;
  std::vector<Tri> triangles;
  std::vector<std::uint32_t> triangle_object;  // index into Scene::objects
  std::vector<std::uint32_t> triangle_face;    // planar face id, unique in the scene

  // Appends another mesh's geometry (object/face ids are kept as they are).
  void append(const Mesh& other);
  Bounds bounds() const;
};

struct Scene {
  std::vector<Mesh> meshes;
  std::vector<SceneObject> objects;

  Bounds bounds() const;
  std::size_t triangle_count() const;
  // Mesh for `material`, created (named `<prefix>-itu_<material>`) if absent.
  Mesh& mesh_for(const std::string& material, const std::string& prefix);
  std::uint32_t add_object(std::string kind, std::string source_id);
};

// Topology checks used by tests and by the scene stage's self-check.
struct EdgeReport {
  std::size_t edges = 0;
  std::size_t boundary_edges = 0;      // used by one triangle
  std::size_t nonmanifold_edges = 0;   // used by more than two triangles
  std::size_t inconsistent_edges = 0;  // two triangles traverse it the same way
  bool watertight() const {
    return boundary_edges == 0 && nonmanifold_edges == 0 && inconsistent_edges == 0;
  }
};

// Edge report over the triangles of `mesh` selected by `object` (all when
// object == UINT32_MAX). Vertices are matched by index.
EdgeReport edge_report(const Mesh& mesh, std::uint32_t object = UINT32_MAX);

// Signed volume of a closed, consistently oriented triangle set (positive when
// the normals point outward).
double signed_volume(const Mesh& mesh, std::uint32_t object = UINT32_MAX);

Vec3 triangle_normal(const Mesh& mesh, std::size_t tri);  // unit, right-handed
double triangle_area(const Mesh& mesh, std::size_t tri);

}  // namespace raysweep::meshkit
