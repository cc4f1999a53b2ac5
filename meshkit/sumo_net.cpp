#include "meshkit/sumo_net.hpp"

#include <cstdlib>
#include <string_view>

#include "meshkit/errors.hpp"
#include "meshkit/xml_reader.hpp"

namespace raysweep::meshkit {

namespace {

// SUMO shape syntax: "x1,y1 x2,y2 ..." (an optional third z component is ignored).
std::vector<Vec2> parse_shape(const char* text, const std::string& file, const std::string& element) {
  std::vector<Vec2> pts;
  const char* p = text;
  while (*p) {
    while (*p == ' ') ++p;
    if (!*p) break;
    char* end = nullptr;
    const double x = std::strtod(p, &end);
    if (end == p || *end != ',') throw InputError(file, element, std::string("bad shape '") + text + "'");
    p = end + 1;
    const double y = std::strtod(p, &end);
    if (end == p) throw InputError(file, element, std::string("bad shape '") + text + "'");
    p = end;
    if (*p == ',') {
      std::strtod(p + 1, &end);
      p = end;
    }
    pts.push_back({x, y});
  }
  return pts;
}

}  // namespace

SumoNetwork read_sumo_network(const std::string& path) {
  SumoNetwork net;
  net.path = path;
  bool have_location = false, in_internal_edge = false, in_net = false;
  XmlCallbacks cb;
  cb.start = [&](const XmlStart& e) {
    if (e.name == "net") {
      in_net = true;
    } else if (e.name == "location") {
      const std::string where = "line " + std::to_string(e.line) + " <location>";
      const char* off = e.attr("netOffset");
      const char* proj = e.attr("projParameter");
      const char* conv = e.attr("convBoundary");
      if (!off || !proj) throw InputError(path, where, "needs netOffset and projParameter");
      auto o = parse_shape(off, path, where);
      if (o.size() != 1) throw InputError(path, where, "bad netOffset");
      net.net_offset = o[0];
      net.proj_parameter = proj;
      if (conv) {
        char* end = nullptr;
        const char* p = conv;
        for (int i = 0; i < 4; ++i) {
          net.conv_boundary[i] = std::strtod(p, &end);
          p = (*end == ',') ? end + 1 : end;
        }
      }
      have_location = true;
    } else if (e.name == "edge") {
      const char* fn = e.attr("function");
      in_internal_edge = fn && std::string_view(fn) == "internal";
      if (!in_internal_edge) ++net.edge_count;
    } else if (e.name == "lane" && !in_internal_edge) {
      if (const char* shape = e.attr("shape")) {
        const char* id = e.attr("id");
        net.lane_shapes.push_back(
            parse_shape(shape, path, "line " + std::to_string(e.line) + " lane " + (id ? id : "?")));
      }
    }
  };
  cb.end = [&](std::string_view name) {
    if (name == "edge") in_internal_edge = false;
  };
  parse_xml_file(path, cb);
  if (!in_net) throw InputError(path, "", "not a SUMO network (no <net> root element)");
  if (!have_location) throw InputError(path, "<location>", "missing: the network is not geo-referenced");
  return net;
}

std::vector<SumoPolygon> read_sumo_polygons(const std::string& path) {
  std::vector<SumoPolygon> polys;
  XmlCallbacks cb;
  cb.start = [&](const XmlStart& e) {
    if (e.name != "poly") return;
    const char* id = e.attr("id");
    const char* shape = e.attr("shape");
    const std::string where = "line " + std::to_string(e.line) + " poly " + (id ? id : "?");
    if (!id || !shape) throw InputError(path, where, "needs id and shape");
    const char* type = e.attr("type");
    polys.push_back({id, type ? type : "", parse_shape(shape, path, where)});
  };
  parse_xml_file(path, cb);
  return polys;
}

std::vector<SumoVType> read_sumo_vtypes(const std::string& path) {
  std::vector<SumoVType> out;
  XmlCallbacks cb;
  cb.start = [&](const XmlStart& e) {
    if (e.name != "vType") return;
    SumoVType t;
    t.line = e.line;
    const char* id = e.attr("id");
    if (!id) throw InputError(path, "line " + std::to_string(e.line) + " vType", "has no id");
    t.id = id;
    t.vclass = e.attr("vClass") ? e.attr("vClass") : "passenger";
    auto number = [&](const char* key, double& value) {
      const char* v = e.attr(key);
      if (!v) return;
      char* end = nullptr;
      value = std::strtod(v, &end);
      if (end == v || *end != '\0' || !(value > 0))
        throw InputError(path, "line " + std::to_string(e.line) + " vType " + t.id,
                         std::string(key) + "='" + v + "' is not a positive length in metres");
    };
    number("length", t.length);
    number("width", t.width);
    number("height", t.height);
    out.push_back(std::move(t));
  };
  parse_xml_file(path, cb);
  return out;
}

}  // namespace raysweep::meshkit
