// Geographic -> scene coordinates, exactly as SUMO's netconvert does it:
// x,y = proj(lon, lat) + netOffset, with the PROJ string from the network.
#pragma once

#include <array>
#include <memory>
#include <string>

namespace raysweep::meshkit {

using Vec2 = std::array<double, 2>;

class Projection {
 public:
  // `proj_string` as in net.xml's projParameter ("+proj=utm +zone=32 ...").
  // "!" (SUMO's "no projection") means the input is already planar.
  Projection(const std::string& proj_string, Vec2 offset);
  ~Projection();
  Projection(Projection&&) noexcept;
  Projection& operator=(Projection&&) noexcept;

  Vec2 forward(double lon_deg, double lat_deg) const;  // scene x,y (metres)
  const std::string& proj_string() const { return proj_string_; }
  Vec2 offset() const { return offset_; }

  // UTM zone of (lon, lat): a default when neither a network nor an explicit
  // projection is given.
  static std::string utm_for(double lon_deg, double lat_deg);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::string proj_string_;
  Vec2 offset_;
};

}  // namespace raysweep::meshkit
