#include "meshkit/planar_faces.hpp"

#include <cmath>
#include <map>
#include <numeric>
#include <unordered_map>

namespace raysweep::meshkit {

namespace {

class DisjointSets {
 public:
  explicit DisjointSets(std::size_t n) : parent_(n) { std::iota(parent_.begin(), parent_.end(), 0); }
  std::size_t find(std::size_t x) {
    while (parent_[x] != x) x = parent_[x] = parent_[parent_[x]];
    return x;
  }
  void unite(std::size_t a, std::size_t b) {
    a = find(a);
    b = find(b);
    if (a != b) parent_[std::max(a, b)] = std::min(a, b);
  }

 private:
  std::vector<std::size_t> parent_;
};

Vec3 unit_normal(const Vec3& p, const Vec3& q, const Vec3& r) {
  const double ux = q[0] - p[0], uy = q[1] - p[1], uz = q[2] - p[2];
  const double vx = r[0] - p[0], vy = r[1] - p[1], vz = r[2] - p[2];
  Vec3 n{uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx};
  const double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
  if (len == 0) return {0, 0, 0};
  return {n[0] / len, n[1] / len, n[2] / len};
}

}  // namespace

std::vector<std::uint32_t> group_planar_faces(const std::vector<Vec3>& vertices,
                                              const std::vector<Tri>& triangles,
                                              std::uint32_t first_id,
                                              const std::vector<std::uint32_t>& seed) {
  // Float32 storage puts about 1e-4 rad of noise on the normals of metre-sized
  // triangles kilometres from the origin; real creases are far coarser.
  constexpr double kCosTolerance = 1.0 - 1e-6;

  // Exporters duplicate vertices along UV seams, so adjacency goes by position.
  std::map<Vec3, std::uint32_t> canonical;
  std::vector<std::uint32_t> canon(vertices.size());
  for (std::size_t v = 0; v < vertices.size(); ++v)
    canon[v] = canonical.emplace(vertices[v], static_cast<std::uint32_t>(canonical.size())).first->second;

  std::vector<Vec3> normal(triangles.size());
  for (std::size_t t = 0; t < triangles.size(); ++t)
    normal[t] = unit_normal(vertices[triangles[t][0]], vertices[triangles[t][1]], vertices[triangles[t][2]]);

  DisjointSets sets(triangles.size());
  if (!seed.empty()) {
    std::unordered_map<std::uint32_t, std::size_t> first_of_seed;
    for (std::size_t t = 0; t < triangles.size() && t < seed.size(); ++t) {
      auto [it, fresh] = first_of_seed.emplace(seed[t], t);
      if (!fresh) sets.unite(it->second, t);
    }
  }

  std::unordered_map<std::uint64_t, std::vector<std::uint32_t>> edge_users;
  for (std::size_t t = 0; t < triangles.size(); ++t) {
    for (int k = 0; k < 3; ++k) {
      std::uint64_t a = canon[triangles[t][k]], b = canon[triangles[t][(k + 1) % 3]];
      if (a == b) continue;
      if (a > b) std::swap(a, b);
      edge_users[(a << 32) | b].push_back(static_cast<std::uint32_t>(t));
    }
  }
  for (const auto& [edge, users] : edge_users) {
    for (std::size_t i = 0; i < users.size(); ++i)
      for (std::size_t j = i + 1; j < users.size(); ++j) {
        const Vec3& n = normal[users[i]];
        const Vec3& m = normal[users[j]];
        if (n[0] * m[0] + n[1] * m[1] + n[2] * m[2] > kCosTolerance) sets.unite(users[i], users[j]);
      }
  }

  std::vector<std::uint32_t> ids(triangles.size());
  std::unordered_map<std::size_t, std::uint32_t> id_of_root;
  for (std::size_t t = 0; t < triangles.size(); ++t) {
    auto [it, fresh] =
        id_of_root.emplace(sets.find(t), first_id + static_cast<std::uint32_t>(id_of_root.size()));
    ids[t] = it->second;
  }
  return ids;
}

}  // namespace raysweep::meshkit
