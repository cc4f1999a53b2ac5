// Reading what the scene needs from SUMO files: the network's geo-reference
// and lane geometry (net.xml[.gz]) and polyconvert's building polygons.
#pragma once

#include <array>
#include <string>
#include <vector>

#include "meshkit/projection.hpp"

namespace raysweep::meshkit {

struct SumoNetwork {
  std::string path;
  std::string proj_parameter;  // "!" when the network is not geo-referenced
  Vec2 net_offset{0, 0};
  std::array<double, 4> conv_boundary{0, 0, 0, 0};  // xmin, ymin, xmax, ymax
  // Centre lines of the network's (non-internal) lanes, in network coordinates.
  std::vector<std::vector<Vec2>> lane_shapes;
  std::size_t edge_count = 0;
};

// Streams the file (plain or gzip); throws InputError for malformed files or a
// missing <location> element.
SumoNetwork read_sumo_network(const std::string& path);

struct SumoPolygon {
  std::string id;
  std::string type;
  std::vector<Vec2> shape;
};

// All <poly> elements of a SUMO additional file (e.g. polyconvert output).
std::vector<SumoPolygon> read_sumo_polygons(const std::string& path);

struct SumoVType {
  std::string id;
  std::string vclass;  // "passenger" when the file does not say (SUMO's default)
  double length = 0, width = 0, height = 0;  // 0 when not given
  long line = 0;
};

// All <vType> elements of a SUMO route or additional file.
std::vector<SumoVType> read_sumo_vtypes(const std::string& path);

}  // namespace raysweep::meshkit
