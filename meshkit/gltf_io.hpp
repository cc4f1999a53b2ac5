// Binary glTF (.glb) scenes for viewers and for exchange, optionally with
// Draco-compressed geometry. The file carries everything a Scene holds:
// per-triangle object and planar-face ids travel as extra accessors that
// viewers ignore, so one file serves both people and the tracer.
//
// Layout written (and expected back):
//   - one root node "raysweep_z_up" whose rotation turns the scene's z-up frame
//     into glTF's y-up frame; vertices stay in scene coordinates beneath it;
//   - per Scene::Mesh one child node and one glTF mesh (same name) with one
//     triangle primitive: POSITION (FLOAT VEC3, min/max), indices
//     (UNSIGNED_INT), material "itu_<material>", and primitive extras
//     {"raysweep_triangle_object": accessor, "raysweep_triangle_face": accessor}
//     naming SCALAR UNSIGNED_INT accessors with one entry per triangle;
//   - scene extras "raysweep_objects": [{"kind": ..., "source_id": ...}, ...].
// With Draco, positions and indices live in a KHR_draco_mesh_compression
// buffer (sequential encoding keeps the triangle order, so the per-triangle
// accessors stay valid); the id accessors remain plain.
#pragma once

#include <string>
#include <vector>

#include "meshkit/scene.hpp"

namespace raysweep::meshkit {

struct GltfOptions {
  bool draco = false;
  // Position quantisation bits (1-30; 0 keeps float32 exactly). Draco snaps
  // each coordinate to a grid over the mesh's bounding cube, so the error per
  // coordinate is at most draco_position_step(bounds, bits) / 2 plus float
  // rounding.
  int draco_position_bits = 16;
};

// Throws std::invalid_argument for scenes it cannot represent faithfully
// (non-ITU material, id vectors not one per triangle, index out of range) and
// std::runtime_error when the file cannot be written. Meshes without
// triangles are left out.
void write_glb(const Scene& scene, const std::string& path, const GltfOptions& options = {});

// Reads files written by write_glb, plain or Draco. glTF files from elsewhere
// load too when their materials are named "itu_<material>": node transforms
// are applied (then the z-up rotation undone), and without raysweep extras
// each mesh becomes one object with faces grouped from coplanar neighbours.
// Throws InputError naming the file (and the mesh, where there is one) for
// broken or truncated files (with tinygltf's or Draco's message), unknown
// materials, non-triangle primitives and ids or indices out of range.
Scene read_glb(const std::string& path);

// Draco and other readers. Without Draco (the default everywhere) the files
// open in tinygltf 2.7 and Blender 3.4 as they are. With Draco they follow
// KHR_draco_mesh_compression (indices and POSITION accessors without a
// bufferView) and open in Draco-capable readers (three.js, upstream Blender
// builds), but Debian 12's tinygltf 2.7 refuses them ("accessor[n] invalid
// bufferView", https://github.com/syoyo/tinygltf/issues/328, fixed upstream
// in 2023) and Debian's Blender 3.4 ships no Draco decoder. Reason for the
// warning the stages print:
extern const char* const kDracoReadersNote;

// The workaround for tinygltf 2.7: drops the `indices` reference of Draco
// primitives from a GLB's JSON chunk (the faces come from the Draco blob, so
// nothing is lost for a reader that decodes Draco). Leaves anything that is
// not a well-formed GLB, or has no Draco primitive, untouched. read_glb uses it.
void tinygltf27_draco_workaround(std::vector<unsigned char>& glb);

// Draco's quantisation grid spacing for a mesh with these bounds: the largest
// extent divided by 2^bits - 1.
double draco_position_step(const Bounds& bounds, int bits);

}  // namespace raysweep::meshkit
