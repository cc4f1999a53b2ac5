#include "meshkit/mitsuba_io.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <optional>
#include <set>
#include <sstream>
#include <stdexcept>

#include "meshkit/mat4.hpp"
#include "meshkit/errors.hpp"
#include "meshkit/material_colors.hpp"
#include "meshkit/materials.hpp"
#include "meshkit/planar_faces.hpp"
#include "meshkit/ply_io.hpp"
#include "meshkit/xml_reader.hpp"

namespace raysweep::meshkit {

namespace fs = std::filesystem;

// ---------------------------------------------------------------- writing

namespace {

std::string xml_escape(const std::string& s) {
  std::string out;
  out.reserve(s.size());
  for (char c : s) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      case '\'': out += "&apos;"; break;
      default: out += c;
    }
  }
  return out;
}

void check_mesh_name(const std::string& name, std::set<std::string>& seen) {
  auto bad = [&](const std::string& why) {
    return std::invalid_argument("write_mitsuba: mesh name '" + name + "' " + why);
  };
  if (name.empty() || name == "." || name == "..") throw bad("is not a file name");
  for (unsigned char c : name)
    if (c == '/' || c == '\\' || c < 0x20) throw bad("contains a path separator or control character");
  if (!seen.insert(name).second) throw bad("is used twice (the PLY files would collide)");
}

}  // namespace

namespace {

std::string number(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

// Sionna 0.x style: a display colour; Sionna maps the id to its own ITU table.
void write_itu_bsdf(std::ostream& xml, const std::string& mat) {
  const std::string id = xml_escape("mat-" + radio_material_id(mat));
  const auto rgb = material_display_color(mat);
  char value[64];
  std::snprintf(value, sizeof value, "%.6f %.6f %.6f", rgb[0], rgb[1], rgb[2]);
  xml << "\t<bsdf type=\"diffuse\" id=\"" << id << "\" name=\"" << id << "\">\n"
      << "\t\t<rgb value=\"" << value << "\" name=\"reflectance\"/>\n"
      << "\t</bsdf>\n";
}

void write_radio_bsdf(std::ostream& xml, const std::string& mat, const MitsubaRadioMaterial& m) {
  const std::string id = xml_escape("mat-raysweep_" + mat);
  xml << "\t<bsdf type=\"radio-material\" id=\"" << id << "\" name=\"" << id << "\">\n";
  const std::pair<const char*, double> props[] = {{"relative_permittivity", m.relative_permittivity},
                                                  {"conductivity", m.conductivity},
                                                  {"thickness", m.thickness_m},
                                                  {"scattering_coefficient", m.scattering_coefficient},
                                                  {"xpd_coefficient", m.xpd_coefficient}};
  for (const auto& [name, v] : props)
    xml << "\t\t<float name=\"" << name << "\" value=\"" << number(v) << "\"/>\n";
  xml << "\t</bsdf>\n";
}

void write_scene_files(const Scene& scene, const std::string& dir,
                       const std::map<std::string, MitsubaRadioMaterial>* radio) {
  std::set<std::string> names;
  std::vector<std::string> materials;  // in order of first use, for a stable file
  for (const Mesh& m : scene.meshes) {
    if (m.triangles.empty()) continue;
    check_mesh_name(m.name, names);
    if (!is_radio_material(m.material))
      throw std::invalid_argument("write_mitsuba: mesh '" + m.name + "': material '" + m.material +
                                  "' is not a radio material");
    if (radio && !radio->count(m.material))
      throw std::invalid_argument("write_mitsuba: mesh '" + m.name + "': no parameters for material '" +
                                  m.material + "'");
    if (std::find(materials.begin(), materials.end(), m.material) == materials.end())
      materials.push_back(m.material);
  }

  const fs::path root(dir);
  std::error_code ec;
  fs::create_directories(root / "meshes", ec);
  if (ec) throw std::runtime_error("cannot create " + (root / "meshes").string() + ": " + ec.message());

  std::ostringstream xml;
  xml << "<scene version=\"2.1.0\">\n\n";
  if (radio) xml << "<!-- Materials: Sionna RT 2 radio-material plugins with raysweep's parameters -->\n\n";
  else xml << "<!-- Materials: Sionna RT maps mat-itu_<name> to ITU-R P.2040 materials -->\n\n";
  for (const std::string& mat : materials)
    radio ? write_radio_bsdf(xml, mat, radio->at(mat)) : write_itu_bsdf(xml, mat);
  xml << "\n<!-- Shapes -->\n\n";
  for (const Mesh& m : scene.meshes) {
    if (m.triangles.empty()) continue;
    write_ply((root / "meshes" / (m.name + ".ply")).string(), m.vertices, m.triangles);
    const std::string id = xml_escape("mesh-" + m.name);
    const std::string bsdf = radio ? "mat-raysweep_" + m.material : "mat-" + radio_material_id(m.material);
    xml << "\t<shape type=\"ply\" id=\"" << id << "\" name=\"" << id << "\">\n"
        << "\t\t<string name=\"filename\" value=\"meshes/" << xml_escape(m.name) << ".ply\"/>\n"
        << "\t\t<boolean name=\"face_normals\" value=\"true\"/>\n"
        << "\t\t<ref id=\"" << xml_escape(bsdf) << "\" name=\"bsdf\"/>\n"
        << "\t</shape>\n";
  }
  xml << "</scene>\n";

  const fs::path xml_path = root / "scene.xml";
  std::ofstream out(xml_path, std::ios::binary | std::ios::trunc);
  out << xml.str();
  if (!out.flush()) throw std::runtime_error("cannot write " + xml_path.string());
}

}  // namespace

void write_mitsuba(const Scene& scene, const std::string& dir) { write_scene_files(scene, dir, nullptr); }

void write_mitsuba(const Scene& scene, const std::string& dir,
                   const std::map<std::string, MitsubaRadioMaterial>& radio) {
  write_scene_files(scene, dir, &radio);
}

// ---------------------------------------------------------------- reading

namespace {


struct ShapeDef {
  std::string type;
  std::string id;  // may be empty
  long line = 0;
  std::string filename;
  std::string ref_bsdf;                  // <ref name="bsdf" id=...>
  std::vector<std::string> unnamed_refs;  // <ref id=...>: a bsdf if it names one
  bool has_inline_bsdf = false;    // nested <bsdf>
  std::string inline_bsdf_id;
  bool flip_normals = false;
  Mat4 to_world = identity();
  bool has_transform = false;

  std::string label() const {
    return id.empty() ? "shape at line " + std::to_string(line) : "shape '" + id + "'";
  }
};

std::vector<double> parse_numbers(const char* text) {
  std::vector<double> out;
  if (!text) return out;
  std::string s(text);
  for (char& c : s)
    if (c == ',') c = ' ';
  std::istringstream in(s);
  double v;
  while (in >> v) out.push_back(v);
  if (!in.eof()) out.push_back(std::nan(""));  // a token that was not a number
  return out;
}

class SceneParser {
 public:
  explicit SceneParser(const std::string& path) : path_(path) {}

  void parse() {
    XmlCallbacks cb;
    cb.start = [this](const XmlStart& e) { start(e); };
    cb.end = [this](std::string_view name) { end(name); };
    parse_xml_file(path_, cb);
  }

  const std::vector<ShapeDef>& shapes() const { return shapes_; }
  bool has_bsdf(const std::string& id) const { return bsdf_ids_.count(id) > 0; }

 private:
  [[noreturn]] void fail(const ShapeDef& s, const std::string& what) const {
    throw InputError(path_, s.label(), what);
  }

  std::string attr(const XmlStart& e, const char* key) const {
    const char* v = e.attr(key);
    if (v && std::string_view(v).find('$') != std::string_view::npos)
      throw InputError(path_, "line " + std::to_string(e.line),
                       std::string("parameter substitution ($...) in '") + v + "' is not supported");
    return v ? v : "";
  }

  void start(const XmlStart& e) {
    const std::size_t depth = stack_.size();
    stack_.emplace_back(e.name);
    if (e.name == "include")
      throw InputError(path_, "line " + std::to_string(e.line), "<include> is not supported");

    if (e.name == "bsdf") {
      if (in_shape_ && bsdf_depth_ == 0 && depth == shape_depth_ + 1) {
        shape_.has_inline_bsdf = true;
        shape_.inline_bsdf_id = attr(e, "id");
      } else if (!in_shape_ && bsdf_depth_ == 0) {
        // Only the outermost id names a material: a twosided wrapper's inner
        // bsdf is an implementation detail of the outer one.
        if (const std::string id = attr(e, "id"); !id.empty()) bsdf_ids_.insert(id);
      }
      ++bsdf_depth_;
      return;
    }
    if (e.name == "shape") {
      ShapeDef s;
      s.type = attr(e, "type");
      s.id = attr(e, "id");
      s.line = e.line;
      if (in_shape_) fail(s, "nested shapes are not supported");
      if (s.type != "ply") fail(s, "shape type '" + s.type + "' is not supported (only ply)");
      shape_ = std::move(s);
      in_shape_ = true;
      shape_depth_ = depth;
      return;
    }
    if (!in_shape_ || bsdf_depth_ > 0) return;

    if (depth == shape_depth_ + 1) {
      const std::string name = attr(e, "name");
      if (e.name == "string" && name == "filename") {
        shape_.filename = attr(e, "value");
      } else if (e.name == "boolean" && name == "flip_normals") {
        shape_.flip_normals = attr(e, "value") == "true";
      } else if (e.name == "ref" && name == "bsdf") {
        shape_.ref_bsdf = attr(e, "id");
      } else if (e.name == "ref" && name.empty()) {
        // A nameless ref may point at a medium or emitter; it is the bsdf
        // only if it names one, which is known once the whole file is read.
        shape_.unnamed_refs.push_back(attr(e, "id"));
      } else if (e.name == "transform") {
        if (name != "to_world") fail(shape_, "transform '" + name + "' is not supported (only to_world)");
        in_transform_ = true;
        shape_.has_transform = true;
      }
    } else if (in_transform_ && depth == shape_depth_ + 2) {
      shape_.to_world = multiply(transform_step(e), shape_.to_world);
    }
  }

  // One <transform> child; Mitsuba applies them in document order.
  Mat4 transform_step(const XmlStart& e) const {
    auto vec3 = [&](double fallback) {
      std::array<double, 3> v{fallback, fallback, fallback};
      if (e.attr("value")) {
        const auto n = parse_numbers(e.attr("value"));
        if (n.size() == 1) v = {n[0], n[0], n[0]};
        else if (n.size() == 3) v = {n[0], n[1], n[2]};
        else fail(shape_, "<" + std::string(e.name) + " value=...> needs 1 or 3 numbers");
      }
      const char* keys[3] = {"x", "y", "z"};
      for (int k = 0; k < 3; ++k)
        if (const char* a = e.attr(keys[k])) {
          const auto n = parse_numbers(a);
          if (n.size() != 1) fail(shape_, "bad number '" + std::string(a) + "'");
          v[k] = n[0];
        }
      for (double x : v)
        if (!std::isfinite(x)) fail(shape_, "non-numeric value in <" + std::string(e.name) + ">");
      return v;
    };
    Mat4 m = identity();
    if (e.name == "matrix") {
      const auto n = parse_numbers(e.attr("value"));
      if (n.size() == 16) {
        std::copy(n.begin(), n.end(), m.begin());
        if (m[12] != 0 || m[13] != 0 || m[14] != 0 || m[15] != 1)
          fail(shape_, "projective <matrix> is not supported");
      } else if (n.size() == 9) {
        for (int i = 0; i < 3; ++i)
          for (int j = 0; j < 3; ++j) m[i * 4 + j] = n[i * 3 + j];
      } else {
        fail(shape_, "<matrix> needs 16 or 9 numbers");
      }
      for (double x : m)
        if (!std::isfinite(x)) fail(shape_, "non-numeric value in <matrix>");
    } else if (e.name == "translate") {
      const auto t = vec3(0);
      for (int i = 0; i < 3; ++i) m[i * 4 + 3] = t[i];
    } else if (e.name == "scale") {
      const auto s = vec3(1);
      for (int i = 0; i < 3; ++i) m[i * 5] = s[i];
    } else if (e.name == "rotate") {
      auto axis = vec3(0);
      const auto angle = parse_numbers(e.attr("angle"));
      const double len = std::sqrt(axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]);
      if (angle.size() != 1 || !std::isfinite(angle[0]) || len == 0)
        fail(shape_, "<rotate> needs an axis and an angle");
      const double x = axis[0] / len, y = axis[1] / len, z = axis[2] / len;
      const double a = angle[0] * std::numbers::pi / 180.0, c = std::cos(a), s = std::sin(a), t = 1 - c;
      m = {t * x * x + c,     t * x * y - s * z, t * x * z + s * y, 0,
           t * x * y + s * z, t * y * y + c,     t * y * z - s * x, 0,
           t * x * z - s * y, t * y * z + s * x, t * z * z + c,     0,
           0,                 0,                 0,                 1};
    } else {
      fail(shape_, "<" + std::string(e.name) + "> in to_world is not supported");
    }
    return m;
  }

  void end(std::string_view name) {
    stack_.pop_back();
    const std::size_t depth = stack_.size();
    if (name == "bsdf") {
      --bsdf_depth_;
    } else if (in_shape_ && name == "shape" && depth == shape_depth_) {
      shapes_.push_back(std::move(shape_));
      in_shape_ = false;
    } else if (in_transform_ && name == "transform" && depth == shape_depth_ + 1) {
      in_transform_ = false;
    }
  }

  std::string path_;
  std::vector<std::string> stack_;
  std::set<std::string> bsdf_ids_;
  std::vector<ShapeDef> shapes_;
  ShapeDef shape_;
  bool in_shape_ = false;
  bool in_transform_ = false;
  std::size_t shape_depth_ = 0;
  int bsdf_depth_ = 0;
};

}  // namespace

Scene read_mitsuba(const std::string& scene_xml) {
  SceneParser parser(scene_xml);
  parser.parse();
  const fs::path base = fs::path(scene_xml).parent_path();

  Scene scene;
  std::uint32_t next_face = 0;
  for (const ShapeDef& s : parser.shapes()) {
    auto fail = [&](const std::string& what) -> InputError { return InputError(scene_xml, s.label(), what); };

    std::string bsdf_id;
    if (s.has_inline_bsdf) {
      if (s.inline_bsdf_id.empty())
        throw fail("nested bsdf has no id, so its radio material is unknown (use id=\"mat-itu_<material>\")");
      bsdf_id = s.inline_bsdf_id;
    } else if (!s.ref_bsdf.empty()) {
      if (!parser.has_bsdf(s.ref_bsdf)) throw fail("references bsdf '" + s.ref_bsdf + "', which is not defined");
      bsdf_id = s.ref_bsdf;
    } else {
      for (const std::string& ref : s.unnamed_refs)
        if (parser.has_bsdf(ref)) {
          bsdf_id = ref;
          break;
        }
      if (bsdf_id.empty()) throw fail("has no bsdf, so its radio material is unknown");
    }
    const auto material = radio_material_from_id(bsdf_id);
    if (!material)
      throw fail("bsdf '" + bsdf_id + "' is not a radio material (expected mat-itu_<" +
                 "concrete|brick|metal|...>)");

    if (s.filename.empty()) throw fail("has no <string name=\"filename\">");
    fs::path ply = fs::path(s.filename);
    if (ply.is_relative()) ply = base / ply;
    std::error_code ec;
    if (!fs::is_regular_file(ply, ec)) throw fail("PLY file '" + ply.string() + "' does not exist");
    PlyMesh pm;
    try {
      pm = read_ply(ply.string());
    } catch (const InputError& e) {
      throw fail(e.what());
    }

    Mesh m;
    m.name = s.id.rfind("mesh-", 0) == 0 ? s.id.substr(5) : !s.id.empty() ? s.id : ply.stem().string();
    m.material = *material;
    m.vertices = std::move(pm.vertices);
    m.triangles = std::move(pm.triangles);
    bool flip = s.flip_normals;
    if (s.has_transform) {
      const Mat4& t = s.to_world;
      for (Vec3& v : m.vertices) {
        const Vec3 p = v;
        for (int i = 0; i < 3; ++i)
          v[i] = t[i * 4] * p[0] + t[i * 4 + 1] * p[1] + t[i * 4 + 2] * p[2] + t[i * 4 + 3];
      }
      const double det = t[0] * (t[5] * t[10] - t[6] * t[9]) - t[1] * (t[4] * t[10] - t[6] * t[8]) +
                         t[2] * (t[4] * t[9] - t[5] * t[8]);
      if (det == 0) throw fail("to_world transform is singular");
      // A mirroring transform turns the winding inside out.
      if (det < 0) flip = !flip;
    }
    if (flip)
      for (Tri& tri : m.triangles) std::swap(tri[1], tri[2]);

    const std::uint32_t object = scene.add_object("mesh", s.id.empty() ? m.name : s.id);
    m.triangle_object.assign(m.triangles.size(), object);
    m.triangle_face = group_planar_faces(m.vertices, m.triangles, next_face, pm.triangle_polygon);
    for (auto f : m.triangle_face) next_face = std::max(next_face, f + 1);
    scene.meshes.push_back(std::move(m));
  }
  return scene;
}

}  // namespace raysweep::meshkit
