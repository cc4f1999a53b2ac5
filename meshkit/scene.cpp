#include "meshkit/scene.hpp"

#include "meshkit/materials.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <utility>

namespace raysweep::meshkit {

Bounds Bounds::none() {
  constexpr double inf = std::numeric_limits<double>::infinity();
  return Bounds{{inf, inf, inf}, {-inf, -inf, -inf}};
}

void Bounds::extend(const Vec3& p) {
  for (int k = 0; k < 3; ++k) {
    min[k] = std::min(min[k], p[k]);
    max[k] = std::max(max[k], p[k]);
  }
}

void Mesh::append(const Mesh& other) {
  const auto base = static_cast<std::uint32_t>(vertices.size());
  vertices.insert(vertices.end(), other.vertices.begin(), other.vertices.end());
  for (const Tri& t : other.triangles) triangles.push_back({t[0] + base, t[1] + base, t[2] + base});
  triangle_object.insert(triangle_object.end(), other.triangle_object.begin(), other.triangle_object.end());
  triangle_face.insert(triangle_face.end(), other.triangle_face.begin(), other.triangle_face.end());
}

Bounds Mesh::bounds() const {
  Bounds b = Bounds::none();
  for (const Tri& t : triangles)
    for (auto v : t) b.extend(vertices[v]);
  return b;
}

Bounds Scene::bounds() const {
  Bounds b = Bounds::none();
  for (const Mesh& m : meshes) {
    if (m.triangles.empty()) continue;
    Bounds mb = m.bounds();
    b.extend(mb.min);
    b.extend(mb.max);
  }
  return b;
}

std::size_t Scene::triangle_count() const {
  std::size_t n = 0;
  for (const Mesh& m : meshes) n += m.triangles.size();
  return n;
}

Mesh& Scene::mesh_for(const std::string& material, const std::string& prefix) {
  const std::string name = prefix + "-" + radio_material_id(material);
  for (Mesh& m : meshes)
    if (m.name == name) return m;
  meshes.push_back(Mesh{name, material, {}, {}, {}, {}});
  return meshes.back();
}

std::uint32_t Scene::add_object(std::string kind, std::string source_id) {
  objects.push_back({std::move(kind), std::move(source_id)});
  return static_cast<std::uint32_t>(objects.size() - 1);
}

namespace {
bool selected(const Mesh& m, std::size_t t, std::uint32_t object) {
  return object == UINT32_MAX || (t < m.triangle_object.size() && m.triangle_object[t] == object);
}
}  // namespace

EdgeReport edge_report(const Mesh& mesh, std::uint32_t object) {
  // Directed use count per undirected edge: a closed, consistently oriented
  // surface uses every edge exactly once in each direction.
  std::map<std::pair<std::uint32_t, std::uint32_t>, std::pair<int, int>> uses;
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    if (!selected(mesh, t, object)) continue;
    const Tri& tri = mesh.triangles[t];
    for (int k = 0; k < 3; ++k) {
      std::uint32_t a = tri[k], b = tri[(k + 1) % 3];
      if (a < b)
        ++uses[{a, b}].first;
      else
        ++uses[{b, a}].second;
    }
  }
  EdgeReport r;
  r.edges = uses.size();
  for (const auto& [edge, count] : uses) {
    const int total = count.first + count.second;
    if (total == 1)
      ++r.boundary_edges;
    else if (total > 2)
      ++r.nonmanifold_edges;
    else if (count.first != 1)
      ++r.inconsistent_edges;
  }
  return r;
}

double signed_volume(const Mesh& mesh, std::uint32_t object) {
  // Divergence theorem over tetrahedra to a reference point inside the bounds;
  // the reference keeps the sum well conditioned far from the origin.
  Bounds b = mesh.bounds();
  const Vec3 o{(b.min[0] + b.max[0]) / 2, (b.min[1] + b.max[1]) / 2, (b.min[2] + b.max[2]) / 2};
  double v = 0;
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    if (!selected(mesh, t, object)) continue;
    const auto& p = mesh.vertices[mesh.triangles[t][0]];
    const auto& q = mesh.vertices[mesh.triangles[t][1]];
    const auto& r = mesh.vertices[mesh.triangles[t][2]];
    const double ax = p[0] - o[0], ay = p[1] - o[1], az = p[2] - o[2];
    const double bx = q[0] - o[0], by = q[1] - o[1], bz = q[2] - o[2];
    const double cx = r[0] - o[0], cy = r[1] - o[1], cz = r[2] - o[2];
    v += ax * (by * cz - bz * cy) - ay * (bx * cz - bz * cx) + az * (bx * cy - by * cx);
  }
  return v / 6.0;
}

static Vec3 raw_normal(const Mesh& mesh, std::size_t tri) {
  const auto& p = mesh.vertices[mesh.triangles[tri][0]];
  const auto& q = mesh.vertices[mesh.triangles[tri][1]];
  const auto& r = mesh.vertices[mesh.triangles[tri][2]];
  const double ux = q[0] - p[0], uy = q[1] - p[1], uz = q[2] - p[2];
  const double vx = r[0] - p[0], vy = r[1] - p[1], vz = r[2] - p[2];
  return {uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx};
}

Vec3 triangle_normal(const Mesh& mesh, std::size_t tri) {
  Vec3 n = raw_normal(mesh, tri);
  const double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
  if (len == 0) return {0, 0, 0};
  return {n[0] / len, n[1] / len, n[2] / len};
}

double triangle_area(const Mesh& mesh, std::size_t tri) {
  Vec3 n = raw_normal(mesh, tri);
  return 0.5 * std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
}

}  // namespace raysweep::meshkit
