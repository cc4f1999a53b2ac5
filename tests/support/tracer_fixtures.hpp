// Hand-built scenes for the tracer tests: quads (ground, walls) and boxes
// with known planes, materials and object names. The vehicle library's models
// are in vehicle_fixtures.hpp.
#pragma once

#include <string>

#include "meshkit/scene.hpp"
#include "scene_fixtures.hpp"
#include "tracer/tracer.hpp"

namespace raysweep::test {

// The next unused planar-face id of a scene.
inline std::uint32_t next_face_id(const meshkit::Scene& scene) {
  std::uint32_t face = 0;
  for (const auto& mesh : scene.meshes)
    for (auto f : mesh.triangle_face) face = std::max(face, f + 1);
  return face;
}

// A planar quad a-b-c-d (counter-clockwise seen from the side its normal
// points to) as one object and one planar face.
inline void add_quad(meshkit::Scene& scene, const std::string& material, const std::string& object,
                     meshkit::Vec3 a, meshkit::Vec3 b, meshkit::Vec3 c, meshkit::Vec3 d) {
  auto& m = scene.mesh_for(material, "test");
  const auto obj = scene.add_object("mesh", object);
  const std::uint32_t face = next_face_id(scene);
  const auto base = static_cast<std::uint32_t>(m.vertices.size());
  m.vertices.insert(m.vertices.end(), {a, b, c, d});
  m.triangles.push_back({base, base + 1, base + 2});
  m.triangles.push_back({base, base + 2, base + 3});
  m.triangle_object.insert(m.triangle_object.end(), 2, obj);
  m.triangle_face.insert(m.triangle_face.end(), 2, face);
}

// Ground plane z = z0 over [-half, half]^2 around (cx, cy).
inline void add_ground(meshkit::Scene& s, double half, const std::string& material = "medium_dry_ground",
                       double cx = 0, double cy = 0, double z0 = 0) {
  add_quad(s, material, "ground", {cx - half, cy - half, z0}, {cx + half, cy - half, z0}, {cx + half, cy + half, z0},
           {cx - half, cy + half, z0});
}

// Vertical wall x = x0 (normal -x) spanning y, z in [-half, half].
inline void add_wall_x(meshkit::Scene& s, double x0, double half, const std::string& material,
                       const std::string& name) {
  add_quad(s, material, name, {x0, -half, -half}, {x0, -half, half}, {x0, half, half}, {x0, half, -half});
}

// Vertical wall y = y0 spanning x, z in [-half, half].
inline void add_wall_y(meshkit::Scene& s, double y0, double half, const std::string& material,
                       const std::string& name) {
  add_quad(s, material, name, {-half, y0, -half}, {half, y0, -half}, {half, y0, half}, {-half, y0, half});
}

// Closed axis-aligned box (a building) as six faces of one object.
inline void add_box_object(meshkit::Scene& s, meshkit::Vec3 lo, meshkit::Vec3 hi, const std::string& material,
                           const std::string& name) {
  std::uint32_t face = next_face_id(s);
  auto& m = s.mesh_for(material, "test");
  add_box(m, lo, hi, s.add_object("building", name), face);
}

inline tracer::Node node(const std::string& id, meshkit::Vec3 p, meshkit::Vec3 v = {0, 0, 0}) {
  return tracer::Node{id, p, v, {1, 0, 0}, -1};
}

}  // namespace raysweep::test
