// Loading third-party vehicle models as named parts: glTF/GLB (tinygltf, full
// node hierarchy) and OBJ/PLY/OFF (OpenMesh). Output is in a z-up frame, with
// every part keeping its node/mesh name and source material name, so the
// segmentation rules can map them to radio materials.
//
// Frames. glTF is y-up with the model's front facing +Z; raysweep is z-up and
// right-handed with the front along +x, so a point is mapped as
// (x, y, z)_raysweep = (z, x, y)_glTF, a proper rotation (nothing mirrored).
// OBJ/PLY/OFF are taken as already z-up and left as they are.
//
// Parts. glTF: one part per (node with a mesh, material), named after the
// node, else its mesh, else "part<node index>"; a node whose primitives use k > 1
// materials gives "<name>#0" .. "<name>#<k-1>" in order of first use. Points and
// lines are skipped with a warning. OBJ: one part per (o/g name, usemtl), named
// after the group (else the object, else the file stem). PLY/OFF: one part
// named after the file stem. A name already taken gets ".2", ".3", ...
//
// Repairs, each counted per part in `repairs`: degenerate triangles (repeated
// vertex, or zero area: |cross| <= 1e-12 * longest edge^2) are dropped, and
// parts left without triangles are dropped with a warning. Non-finite
// coordinates are an InputError naming the part. Mirroring node transforms
// (negative determinant) have their triangles' winding flipped so normals stay
// outward. Non-manifold faces are kept with their shared vertices: OpenMesh's
// parsers feed a polygon soup here, not an OpenMesh TriMesh (which detaches
// "complex edge" faces and drops faces with repeated or invalid indices).
//
// Units. The model's own unit is asked first: a unit given by the caller
// (ImportOptions::unit: --model-unit, model_unit in the vehicles config) wins;
// glTF is metres by specification and is never rescaled otherwise; OBJ/PLY/OFF
// carry no unit, so it is guessed: of metres, centimetres and millimetres, the
// one that brings the largest bounding-box extent (after all transforms)
// closest by ratio to the class length when it is known, else into the 1 to
// 25 m of any vehicle (ties keep the larger unit, so a 2.5 m game-scale car
// stays in metres). A rescale is noted in `repairs`; a result outside a factor
// of 3 of the class length (else outside 1 to 25 m) is a warning that names
// the unit and how to set it. Below 0.05 m the model is an InputError
// ("zero-size model").
//
// Thread safety: OBJ/PLY/OFF go through OpenMesh's reader singletons and are
// serialised by a mutex; glTF import is reentrant.
#pragma once

#include <cstddef>
#include <string>
#include <utility>
#include <vector>

#include "meshkit/scene.hpp"

namespace raysweep::meshkit {

struct ImportedPart {
  std::string name;      // node name (else mesh name, else "part<N>")
  std::string material;  // source material name ("" when the file has none)
  std::vector<Vec3> vertices;  // z-up, in the file's units times `unit_scale`
  std::vector<Tri> triangles;
  std::string source;    // where in the file it came from, for messages ("node 12 'X', mesh 3 'Y'")
};

struct ImportedModel {
  std::string path;
  std::vector<ImportedPart> parts;
  double unit_scale = 1.0;        // applied to reach metres (0.01 for a centimetre model)
  std::string unit_source;        // "given", "glTF (metres by specification)" or "guessed from the size"
  std::string up_axis = "z";      // axis the file used as up before conversion ("y" for glTF)
  std::vector<std::string> repairs;   // counted, documented repairs ("dropped 12 degenerate triangles in part X")
  std::vector<std::string> warnings;  // each names the part

  Bounds bounds() const;  // over all parts' triangles (Bounds::none() when empty)
  std::size_t triangle_count() const;
};

// Length units a model file may be in, as metres per unit: m, dm, cm, mm, in, ft.
const std::vector<std::pair<std::string, double>>& model_units();
// Metres per unit for one of model_units()' names; 0 for an unknown name.
double parse_model_unit(const std::string& name);

struct ImportOptions {
  double unit = 0;          // metres per file unit; 0: the file's own (glTF) or guessed (OBJ/PLY/OFF)
  std::string vclass;       // for messages ("a bus")
  double class_length = 0;  // metres; 0: unknown (plausible range 1 to 25 m)
};

// Throws InputError (file + element) for unreadable, truncated or malformed
// files, missing buffers, and models with no triangles or zero size.
ImportedModel import_model(const std::string& path, const ImportOptions& options = {});

}  // namespace raysweep::meshkit
