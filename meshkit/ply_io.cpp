#include "meshkit/ply_io.hpp"

#include <CGAL/IO/PLY.h>
#include <CGAL/Simple_cartesian.h>

#include <array>
#include <cctype>
#include <charconv>
#include <fstream>
#include <iterator>
#include <regex>
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

std::vector<std::string> words_of(const std::string& line) {
  std::istringstream ss(line);
  std::vector<std::string> out;
  for (std::string t; ss >> t;) out.push_back(t);
  return out;
}

// A scalar type's size and signedness; throws for unknown types.
struct ScalarType {
  std::size_t size = 0;
  bool is_signed = false;
};

ScalarType scalar_type(const std::string& t, const std::string& path, const std::string& where) {
  if (t == "char" || t == "int8") return {1, true};
  if (t == "uchar" || t == "uint8") return {1, false};
  if (t == "short" || t == "int16") return {2, true};
  if (t == "ushort" || t == "uint16") return {2, false};
  if (t == "int" || t == "int32") return {4, true};
  if (t == "uint" || t == "uint32") return {4, false};
  if (t == "float" || t == "float32") return {4, true};
  if (t == "double" || t == "float64") return {8, true};
  throw InputError(path, where, "unknown property type '" + t + "'");
}

}  // namespace

void check_ply_layout(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, "", "cannot open PLY file");
  struct Property {
    ScalarType count;  // size 0: a scalar property
    ScalarType item;
  };
  struct Element {
    std::string name;
    std::size_t count = 0;
    std::vector<Property> properties;
  };
  std::vector<Element> elements;
  std::string line, format;
  // OpenMesh takes the magic token-wise and in any case (" PLY" passes), so
  // this does too; the readers report files that do not start with it. An
  // upper-case magic once skipped every check below and let a broken header
  // loop OpenMesh's reader (tests/fuzz/corpus/ply-timeout-5b27385a...).
  std::size_t number = 1;
  for (; std::getline(in, line); ++number)
    if (!words_of(line).empty()) break;
  if (!in) return;
  std::string magic = words_of(line)[0];
  for (char& c : magic) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (magic != "ply") return;
  bool ended = false;
  for (++number; std::getline(in, line); ++number) {
    const auto t = words_of(line);
    if (t.empty()) continue;
    const std::string where = "header line " + std::to_string(number);
    if (t[0] == "end_header") {
      ended = true;
      break;
    }
    // OpenMesh 9.0's PLY reader reads the header token by token and loops
    // forever once its stream fails; only the keywords of the PLY format pass.
    if (t[0] != "format" && t[0] != "element" && t[0] != "property" && t[0] != "comment" && t[0] != "obj_info")
      throw InputError(path, where, "unknown header keyword " + std::string(1, '\'') + t[0] + "'");
    if (t[0] == "format") {
      // OpenMesh 9.0's PLY reader loops forever printing "Unsupported keyword"
      // when the version is not a number (tests/fuzz/fuzz_ply), so the line is
      // checked in full: format ascii|binary_little_endian|binary_big_endian 1.0.
      if (t.size() != 3 || (t[1] != "ascii" && t[1] != "binary_little_endian" && t[1] != "binary_big_endian"))
        throw InputError(path, where, "malformed format line (expected 'format ascii|binary_little_endian|"
                                      "binary_big_endian 1.0')");
      if (t[2] != "1.0" && t[2] != "1") throw InputError(path, where, "unsupported PLY version '" + t[2] + "'");
      format = t[1];
    } else if (t[0] == "element") {
      Element e;
      std::size_t count = 0;
      const auto [ptr, ec] = t.size() < 3 ? std::from_chars_result{nullptr, std::errc::invalid_argument}
                                          : std::from_chars(t[2].data(), t[2].data() + t[2].size(), count);
      if (ec != std::errc() || ptr != t[2].data() + t[2].size())
        throw InputError(path, where, "malformed element line");
      e.name = t[1];
      e.count = count;
      elements.push_back(e);
    } else if (t[0] == "property") {
      if (elements.empty()) throw InputError(path, where, "property before any element");
      Property p;
      if (t.size() >= 5 && t[1] == "list") {
        p.count = scalar_type(t[2], path, where);
        if (t[2] == "float" || t[2] == "float32" || t[2] == "double" || t[2] == "float64")
          throw InputError(path, where, "list length type '" + t[2] + "' is not an integer type");
        p.item = scalar_type(t[3], path, where);
      } else if (t.size() >= 3) {
        p.item = scalar_type(t[1], path, where);
      } else {
        throw InputError(path, where, "malformed property line");
      }
      elements.back().properties.push_back(p);
    }
  }
  if (!ended) throw InputError(path, "header", "no end_header (file truncated?)");
  for (const Element& e : elements)  // the readers would loop over them, reading nothing
    if (e.count > 0 && e.properties.empty())
      throw InputError(path, "element " + e.name, "has " + std::to_string(e.count) + " items but no properties");

  if (format == "ascii") {
    // Token-wise, as the readers read it: every list length must be a
    // non-negative integer that fits its type, and its items must follow.
    std::vector<std::string> tokens;
    for (std::string tok; in >> tok;) tokens.push_back(tok);
    // Every value a plain decimal number: OpenMesh reads "7-3" as 7 and then
    // -3 as the next list length and grew a face to 3 GB (tests/fuzz/fuzz_ply).
    static const std::regex decimal(R"([+-]?([0-9]+\.?[0-9]*|\.[0-9]+)([eE][+-]?[0-9]+)?)");
    auto check_number = [&](const std::string& tok, const std::string& where) {
      if (!std::regex_match(tok, decimal)) throw InputError(path, where, "'" + tok + "' is not a number");
    };
    std::size_t at = 0;
    for (const Element& e : elements)
      for (std::size_t i = 0; i < e.count; ++i)
        for (const Property& p : e.properties) {
          const std::string where = e.name + " " + std::to_string(i);
          if (at >= tokens.size()) throw InputError(path, where, "truncated: the file ends here");
          if (p.count.size) {
            const std::string& tok = tokens[at];
            std::size_t n = 0;
            const auto [ptr, ec] = std::from_chars(tok.data(), tok.data() + tok.size(), n);
            if (ec != std::errc() || ptr != tok.data() + tok.size())
              throw InputError(path, where, "unreadable list length '" + tok + "'");
            const unsigned bits = 8 * static_cast<unsigned>(p.count.size) - (p.count.is_signed ? 1 : 0);
            if (bits < 64 && n >> bits)
              throw InputError(path, where, "list length " + tok + " does not fit its type");
            if (n > tokens.size() - at - 1) throw InputError(path, where, "truncated: list of " + tok + " items");
            for (std::size_t k = 1; k <= n; ++k) check_number(tokens[at + k], where);
            at += n;
          } else {
            check_number(tokens[at], where);
          }
          ++at;
        }
    return;
  }
  if (format != "binary_little_endian" && format != "binary_big_endian")
    throw InputError(path, "header", "unknown format '" + format + "'");
  const bool big = format == "binary_big_endian";
  const std::vector<unsigned char> data((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::size_t at = 0;
  for (const Element& e : elements)
    for (std::size_t i = 0; i < e.count; ++i)
      for (const Property& p : e.properties) {
        const std::string where = e.name + " " + std::to_string(i);
        std::size_t n = 1;
        if (p.count.size) {
          const std::size_t cs = p.count.size;
          if (cs > data.size() - at) throw InputError(path, where, "truncated: the file ends here");
          n = 0;
          for (std::size_t b = 0; b < cs; ++b)
            n |= static_cast<std::size_t>(data[at + (big ? b : cs - 1 - b)]) << (8 * (cs - 1 - b));
          if (p.count.is_signed && (n >> (8 * cs - 1)))
            throw InputError(path, where, "negative list length (corrupt data)");
          at += cs;
        }
        if (n > (data.size() - at) / p.item.size)
          throw InputError(path, where, "truncated: the file ends here (or a corrupt list length)");
        at += n * p.item.size;
      }
}

PlyMesh read_ply(const std::string& path) {
  using Point = CGAL::Simple_cartesian<double>::Point_3;
  {
    std::ifstream header(path, std::ios::binary);
    if (!header) throw InputError(path, "", "cannot open PLY file");
    check_header(header, path);
  }
  check_ply_layout(path);
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
