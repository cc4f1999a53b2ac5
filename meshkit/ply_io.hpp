// PLY polygon soups as Mitsuba/Sionna scenes store them. CGAL does the
// parsing; this header keeps CGAL out of every other translation unit.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "meshkit/scene.hpp"

namespace raysweep::meshkit {

struct PlyMesh {
  std::vector<Vec3> vertices;
  std::vector<Tri> triangles;
  // PLY face each triangle was cut from: fans of one polygon share it, which
  // lets callers keep a polygon as one planar face.
  std::vector<std::uint32_t> triangle_polygon;
};

// Reads ascii or binary PLY; extra vertex/face properties are ignored and
// polygons are split into fans in file order (none is dropped, non-manifold or
// not). Throws InputError naming `path` for unreadable, truncated or malformed
// files, faces with fewer than three corners and out-of-range indices.
PlyMesh read_ply(const std::string& path);

// Walks the data section of a PLY file against its header, without trusting
// any count: every element and list must lie inside the file, list lengths
// must be non-negative and fit their type, and ascii lists must have their
// items. Throws InputError naming `path` and the element ("face 12") that ends
// early or is corrupt. read_ply calls it; so does the OpenMesh importer, since
// both underlying readers use uninitialised or unbounded counts otherwise.
// Files that do not start with "ply" are left to the readers to refuse.
void check_ply_layout(const std::string& path);

// Binary little-endian PLY: float x,y,z and "list uchar int vertex_indices",
// the layout Mitsuba and Sionna RT read. Coordinates are rounded to float.
void write_ply(const std::string& path, const std::vector<Vec3>& vertices,
               const std::vector<Tri>& triangles);

}  // namespace raysweep::meshkit
