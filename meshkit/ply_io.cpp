#include "meshkit/ply_io.hpp"

#include <CGAL/IO/PLY.h>
#include <CGAL/Simple_cartesian.h>

#include <array>
#include <fstream>
#include <sstream>

#include "meshkit/errors.hpp"

namespace raysweep::meshkit {

namespace {

bool is_scalar_type(const std::string& t) {
  static const char* const known[] = {"char",  "int8",   "uchar", "uint8",   "short",  "int16",
                                      "ushort", "uint16", "int",   "int32",   "uint",   "uint32",
                                      "float", "float32", "double", "float64"};
  for (const char* k : known)
    if (t == k) return true;
  return false;
}
bool is_real_type(const std::string& t) {
  return t == "float" || t == "float32" || t == "double" || t == "float64";
}
bool is_index_type(const std::string& t) {
  return t == "int" || t == "int32" || t == "uint" || t == "uint32";
}

// CGAL's PLY reader trusts its header: an unknown type is skipped without
// consuming bytes, integer coordinates trip an assertion that release builds
// compile out, and a header cut short reads as an empty mesh. Checking the
// header first turns all of these into errors that name the file.
void check_header(std::istream& in, const std::string& path) {
  std::string line;
  if (!std::getline(in, line) || line.rfind("ply", 0) != 0)
    throw InputError(path, "header", "not a PLY file (missing 'ply' signature)");
  std::string element;
  bool has_vertex = false, has_face = false, ended = false;
  int coords = 0;
  bool face_indices = false;
  long line_no = 1;
  auto finish_element = [&] {
    if ((element == "vertex" || element == "vertices") && coords != 3)
      throw InputError(path, "header", "vertex element needs float or double x, y and z");
    if ((element == "face" || element == "faces") && !face_indices)
      throw InputError(path, "header",
                       "face element needs a list property vertex_indices of int or uint");
  };
  while (std::getline(in, line)) {
    ++line_no;
    std::istringstream ls(line);
    std::string keyword;
    if (!(ls >> keyword)) continue;
    const std::string where = "header line " + std::to_string(line_no);
    if (keyword == "format") {
      std::string format;
      ls >> format;
      if (format != "ascii" && format != "binary_little_endian" && format != "binary_big_endian")
        throw InputError(path, where, "unknown PLY format '" + format + "'");
    } else if (keyword == "element") {
      finish_element();
      long long count = -1;
      if (!(ls >> element >> count) || count < 0)
        throw InputError(path, where, "malformed element line");
      coords = 0;
      face_indices = false;
      has_vertex |= element == "vertex" || element == "vertices";
      has_face |= element == "face" || element == "faces";
    } else if (keyword == "property") {
      if (element.empty()) throw InputError(path, where, "property before any element");
      std::string type, name;
      if (!(ls >> type)) throw InputError(path, where, "malformed property line");
      if (type == "list") {
        std::string count_type, item_type;
        if (!(ls >> count_type >> item_type >> name) || !is_scalar_type(count_type) ||
            !is_scalar_type(item_type))
          throw InputError(path, where, "unsupported list property '" + line + "'");
        if ((name == "vertex_indices" || name == "vertex_index") && is_index_type(item_type))
          face_indices = true;
      } else {
        if (!(ls >> name) || !is_scalar_type(type))
          throw InputError(path, where, "unsupported property '" + line + "'");
        if ((name == "x" || name == "y" || name == "z") && is_real_type(type)) ++coords;
      }
    } else if (keyword == "end_header") {
      ended = true;
      break;
    }
  }
  if (!ended) throw InputError(path, "header", "no end_header (file truncated?)");
  finish_element();
  if (!has_vertex) throw InputError(path, "header", "no vertex element");
  (void)has_face;  // a PLY without faces is a valid, empty mesh
}

}  // namespace

PlyMesh read_ply(const std::string& path) {
  using Point = CGAL::Simple_cartesian<double>::Point_3;
  {
    std::ifstream header(path, std::ios::binary);
    if (!header) throw InputError(path, "", "cannot open PLY file");
    check_header(header, path);
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, "", "cannot open PLY file");
  CGAL::IO::set_mode(in, CGAL::IO::BINARY);
  std::vector<Point> points;
  std::vector<std::vector<std::size_t>> polygons;
  if (!CGAL::IO::read_PLY(in, points, polygons, CGAL::parameters::verbose(false)))
    throw InputError(path, "", "truncated or malformed PLY data");

  PlyMesh mesh;
  mesh.vertices.reserve(points.size());
  for (const Point& p : points) mesh.vertices.push_back({p.x(), p.y(), p.z()});
  for (std::size_t f = 0; f < polygons.size(); ++f) {
    const auto& poly = polygons[f];
    if (poly.size() < 3)
      throw InputError(path, "face " + std::to_string(f),
                       "has " + std::to_string(poly.size()) + " corners, need at least 3");
    for (std::size_t v : poly)
      if (v >= points.size())
        throw InputError(path, "face " + std::to_string(f),
                         "vertex index " + std::to_string(static_cast<long long>(v)) +
                             " out of range (" + std::to_string(points.size()) + " vertices)");
    // Fans keep the polygon's winding, so normals match the source polygon.
    for (std::size_t k = 1; k + 1 < poly.size(); ++k) {
      mesh.triangles.push_back({static_cast<std::uint32_t>(poly[0]),
                                static_cast<std::uint32_t>(poly[k]),
                                static_cast<std::uint32_t>(poly[k + 1])});
      mesh.triangle_polygon.push_back(static_cast<std::uint32_t>(f));
    }
  }
  return mesh;
}

void write_ply(const std::string& path, const std::vector<Vec3>& vertices,
               const std::vector<Tri>& triangles) {
  using Point = CGAL::Simple_cartesian<float>::Point_3;
  std::vector<Point> points;
  points.reserve(vertices.size());
  for (const Vec3& v : vertices)
    points.emplace_back(static_cast<float>(v[0]), static_cast<float>(v[1]), static_cast<float>(v[2]));
  for (const Tri& t : triangles)
    for (auto v : t)
      if (v >= vertices.size())
        throw std::invalid_argument("write_ply " + path + ": vertex index " + std::to_string(v) +
                                    " out of range");
  std::vector<std::array<int, 3>> faces;
  faces.reserve(triangles.size());
  for (const Tri& t : triangles)
    faces.push_back({static_cast<int>(t[0]), static_cast<int>(t[1]), static_cast<int>(t[2])});

  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) throw std::runtime_error("cannot write " + path);
  CGAL::IO::set_mode(out, CGAL::IO::BINARY);
  if (!CGAL::IO::write_PLY(out, points, faces) || !out.flush())
    throw std::runtime_error("error writing " + path);
}

}  // namespace raysweep::meshkit
