// A vehicle model for the tracer: named parts, each with one radio material,
// in the library frame: metres, z up, front along +x, origin at the centre of
// the front bumper on the ground (SUMO's FCD position), so the body extends
// over x in [-length, 0], y in [-width/2, width/2], z in [0, height].
#pragma once

#include <map>
#include <string>
#include <vector>

#include "meshkit/scene.hpp"

namespace raysweep::meshkit {

struct VehiclePart {
  std::string name;
  std::string source_material;  // material name in the input file ("" for built-in models)
  std::string material;         // radio material (ITU-R P.2040 or custom)
  std::string rule;             // which segmentation rule chose it ("" until segmented)
  std::vector<Vec3> vertices;
  std::vector<Tri> triangles;
};

struct VehicleDims {
  double length = 0, width = 0, height = 0;
};

struct VehicleModel {
  std::string name;    // library entry: a SUMO vClass or a vType id
  std::string vclass;  // SUMO vehicle class
  std::string source;  // "parametric" or the input file
  std::vector<VehiclePart> parts;
  Vec3 antenna{0, 0, 0};
  std::vector<std::string> repairs, warnings;

  Bounds bounds() const;
  VehicleDims dims() const;
  std::size_t triangle_count() const;
  std::map<std::string, double> area_by_material() const;
};

// Library-frame scene: one mesh per radio material, one object per part
// (kind "part"), planar face ids per part.
Scene to_scene(const VehicleModel& model);
// Inverse of to_scene for library files (parts come back by object).
VehicleModel from_scene(const Scene& scene, const std::string& name);

struct NormalizeReport {
  VehicleDims native;                  // after import, before scaling
  std::array<double, 3> scale{1, 1, 1};
  std::string orientation;             // what was done to put the front on +x
};

// Moves an imported model into the library frame: detects the front from part
// names ("front", "_F", "FL", "head"... vs "rear", "_B", "tail") and the
// length axis from the bounding box, rotates about z accordingly, puts the
// front bumper centre on the ground at the origin, then scales each axis to
// `target` (a zero component keeps the native size on that axis).
NormalizeReport normalize(VehicleModel& model, const VehicleDims& target);

// Antenna mount: above the highest surface point over (x, y) by `offset` m.
Vec3 roof_mount(const VehicleModel& model, double x, double y, double offset);

// Edge topology over all parts with vertices welded by position: a closed
// vehicle surface has no boundary edges.
EdgeReport welded_edge_report(const VehicleModel& model);

}  // namespace raysweep::meshkit
