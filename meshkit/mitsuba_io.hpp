// Mitsuba 3 scene files as Sionna RT 0.x loads them: scene.xml with one
// diffuse bsdf per radio material ("mat-itu_<material>", the name Sionna maps
// to its ITU materials) and one PLY shape per mesh. Per-triangle object and
// face ids have no place there (Sionna does not read them); the glb carries
// them.
#pragma once

#include <map>
#include <string>

#include "meshkit/scene.hpp"

namespace raysweep::meshkit {

// Writes dir/scene.xml and dir/meshes/<mesh name>.ply (creating both folders).
// Meshes without triangles are left out, since Mitsuba refuses empty PLYs.
// Throws std::invalid_argument for a non-ITU material or a mesh name that is
// not a plain, unique file name, std::runtime_error when writing fails.
void write_mitsuba(const Scene& scene, const std::string& dir);

// A material's parameters at one carrier, as Sionna RT 2's "radio-material"
// plugin reads them (meshkit names materials; the tracer computes these).
struct MitsubaRadioMaterial {
  double relative_permittivity = 1;
  double conductivity = 0;  // S/m
  double thickness_m = 0.1;
  double scattering_coefficient = 0;
  double xpd_coefficient = 0;
};

// The same files with each material written with its parameters
// (<bsdf type="radio-material" id="mat-raysweep_<material>">), so that a
// peer reads exactly the values raysweep traces with instead of its own
// tables. Every material of a mesh must be in `radio`.
void write_mitsuba(const Scene& scene, const std::string& dir, const std::map<std::string, MitsubaRadioMaterial>& radio);

// Reads a Mitsuba scene of PLY shapes. Each shape becomes one Mesh (name = the
// shape id without "mesh-") and one SceneObject {"mesh", shape id}; faces are
// grouped from coplanar neighbouring triangles. A shape's bsdf comes from
// <ref id=... name="bsdf"/> or a nested <bsdf id=...>; for bsdfs wrapping
// others (twosided) the outer id counts. Supported to_world transforms:
// <matrix> (16 or 9 values), <translate>, <scale>, <rotate>.
// Throws InputError naming the xml file and the shape for materials that are
// not ITU materials (never a silent vacuum), unsupported shape types or
// transforms, and missing or broken PLY files (naming their path too).
Scene read_mitsuba(const std::string& scene_xml);

}  // namespace raysweep::meshkit
