#include "meshkit/vehicle_parametric.hpp"

#include <cmath>
#include <functional>
#include <map>
#include <stdexcept>

namespace raysweep::meshkit {

namespace {

using Part = std::pair<std::string, std::string>;  // name, material
const Part kBody{"body", "metal"}, kWindows{"windows", "glass"}, kWheels{"wheels", "rubber"},
    kLights{"lights", "glass"}, kRider{"rider", "human"};

class Builder {
 public:
  explicit Builder(VehicleModel& m) : m_(m) {}

  // A convex solid from its faces (each a planar convex polygon); faces are
  // fan-triangulated and turned to face away from the solid's centroid.
  void solid(const std::vector<std::pair<std::vector<Vec3>, Part>>& faces) {
    Vec3 c{0, 0, 0};
    std::size_t n = 0;
    for (const auto& [poly, part] : faces)
      for (const auto& p : poly) {
        for (int k = 0; k < 3; ++k) c[k] += p[k];
        ++n;
      }
    for (int k = 0; k < 3; ++k) c[k] /= n;
    for (const auto& [poly, part] : faces) {
      VehiclePart& vp = get(part);
      const auto base = static_cast<std::uint32_t>(vp.vertices.size());
      vp.vertices.insert(vp.vertices.end(), poly.begin(), poly.end());
      // Outward test on the polygon's normal (Newell) against the centroid.
      Vec3 nrm{0, 0, 0}, fc{0, 0, 0};
      for (std::size_t i = 0; i < poly.size(); ++i) {
        const Vec3 &a = poly[i], &b = poly[(i + 1) % poly.size()];
        nrm[0] += (a[1] - b[1]) * (a[2] + b[2]);
        nrm[1] += (a[2] - b[2]) * (a[0] + b[0]);
        nrm[2] += (a[0] - b[0]) * (a[1] + b[1]);
        for (int k = 0; k < 3; ++k) fc[k] += a[k] / poly.size();
      }
      const bool flip = nrm[0] * (fc[0] - c[0]) + nrm[1] * (fc[1] - c[1]) + nrm[2] * (fc[2] - c[2]) < 0;
      for (std::uint32_t i = 1; i + 1 < poly.size(); ++i) {
        if (flip)
          vp.triangles.push_back({base, base + i + 1, base + i});
        else
          vp.triangles.push_back({base, base + i, base + i + 1});
      }
    }
  }

  void box(double x0, double x1, double y0, double y1, double z0, double z1, const Part& part) {
    prism({{x0, z0}, {x1, z0}, {x1, z1}, {x0, z1}}, y0, y1, [&](int) { return part; });
  }

  // Convex polygon in the x-z plane (any winding) extruded over y0..y1.
  // part_of(-1) names the two caps, part_of(i) the side on edge i -> i+1.
  void prism(const std::vector<std::array<double, 2>>& xz, double y0, double y1,
             const std::function<Part(int)>& part_of) {
    std::vector<std::pair<std::vector<Vec3>, Part>> faces;
    std::vector<Vec3> cap0, cap1;
    for (const auto& p : xz) {
      cap0.push_back({p[0], y0, p[1]});
      cap1.push_back({p[0], y1, p[1]});
    }
    faces.push_back({cap0, part_of(-1)});
    faces.push_back({cap1, part_of(-1)});
    for (std::size_t i = 0; i < xz.size(); ++i) {
      const auto &a = xz[i], &b = xz[(i + 1) % xz.size()];
      faces.push_back({{{a[0], y0, a[1]}, {b[0], y0, b[1]}, {b[0], y1, b[1]}, {a[0], y1, a[1]}},
                       part_of(static_cast<int>(i))});
    }
    solid(faces);
  }

  // Wheel: a 16-sided cylinder with its axis along y.
  void wheel(double x, double radius, double y0, double y1) {
    std::vector<std::array<double, 2>> xz;
    const int n = 16;
    // Vertices at angle 0, 90, 180, 270 deg make the wheel touch the ground
    // (z = 0) and reach exactly x +- radius.
    for (int i = 0; i < n; ++i) {
      const double a = 2 * M_PI * i / n;
      xz.push_back({x + radius * std::cos(a), radius + radius * std::sin(a)});
    }
    prism(xz, y0, y1, [](int) { return kWheels; });
  }

 private:
  VehiclePart& get(const Part& part) {
    for (auto& p : m_.parts)
      if (p.name == part.first) return p;
    m_.parts.push_back(VehiclePart{part.first, "", part.second, "parametric", {}, {}});
    return m_.parts.back();
  }
  VehicleModel& m_;
};

// Side window caps and windscreen are glass; roof and hidden faces are body.
std::function<Part(int)> cabin_parts(std::vector<int> glass_edges) {
  return [glass_edges](int e) {
    if (e < 0) return kWindows;
    for (int g : glass_edges)
      if (g == e) return kWindows;
    return kBody;
  };
}

void wheels(Builder& b, const std::vector<double>& axles_x, double r, double W, double tire_w) {
  for (double x : axles_x) {
    b.wheel(x, r, W / 2 - 0.02 - tire_w, W / 2 - 0.02);
    b.wheel(x, r, -W / 2 + 0.02, -W / 2 + 0.02 + tire_w);
  }
}

void lamps(Builder& b, double L, double W, double z_front, double z_rear, double h) {
  for (double s : {-1.0, 1.0}) {
    const double y0 = s * 0.25 * W, y1 = s * 0.42 * W;
    b.box(-0.06, 0.0, std::min(y0, y1), std::max(y0, y1), z_front, z_front + h, kLights);
    b.box(-L, -L + 0.06, std::min(y0, y1), std::max(y0, y1), z_rear, z_rear + h, kLights);
  }
}

}  // namespace

VehicleModel parametric_vehicle(const std::string& name, const std::string& vclass, const std::string& archetype,
                                const VehicleDims& d, double antenna_offset_m) {
  if (!(d.length > 0.5 && d.width > 0.2 && d.height > 0.5))
    throw std::invalid_argument(name + ": implausible vehicle dimensions");
  VehicleModel m;
  m.name = name;
  m.vclass = vclass;
  m.source = "parametric";
  Builder b(m);
  const double L = d.length, W = d.width, H = d.height;
  const double e = 0.01;  // solids overlap by 1 cm so no coplanar faces touch
  double antenna_x = -L / 2;

  if (archetype == "car") {
    const double c = 0.12 * H, r = 0.21 * H, belt = 0.62 * H;
    b.prism({{-L + e, c}, {-e, c}, {-e, 0.5 * H}, {-0.22 * L, belt}, {-L + e, belt}}, -W / 2, W / 2,
            [](int) { return kBody; });
    b.prism({{-0.78 * L, belt - e}, {-0.24 * L, belt - e}, {-0.42 * L, H}, {-0.70 * L, H}}, -0.46 * W, 0.46 * W,
            cabin_parts({1, 3}));
    wheels(b, {-0.19 * L, -0.79 * L}, r, W, 0.13 * W);
    lamps(b, L, W, 0.38 * H, 0.52 * H, 0.08 * H);
    antenna_x = -0.56 * L;
  } else if (archetype == "van") {
    const double c = 0.07 * H, r = 0.12 * H, belt = 0.45 * H;
    b.prism({{-L + e, c}, {-e, c}, {-e, belt - 0.1 * H}, {-0.08 * L, belt}, {-L + e, belt}}, -W / 2, W / 2,
            [](int) { return kBody; });
    b.prism({{-0.30 * L, belt - e}, {-0.08 * L, belt - e}, {-0.20 * L, 0.85 * H}, {-0.30 * L, 0.85 * H}},
            -0.47 * W, 0.47 * W, cabin_parts({1}));
    b.box(-L + e, -0.29 * L, -0.49 * W, 0.49 * W, belt - e, H, kBody);  // cargo box
    wheels(b, {-0.17 * L, -0.78 * L}, r, W, 0.1 * W);
    lamps(b, L, W, 0.3 * H, 0.3 * H, 0.05 * H);
    if (vclass == "emergency") b.box(-0.28 * L, -0.2 * L, -0.3 * W, 0.3 * W, 0.85 * H - e, 0.85 * H + 0.12, kLights);
    antenna_x = -0.6 * L;
  } else if (archetype == "truck" || archetype == "semitrailer") {
    const bool semi = archetype == "semitrailer";
    const double cab = semi ? std::min(0.22 * L, 3.0) : 0.3 * L;
    const double c = 0.1 * std::min(H, 2.6), r = 0.2 * std::min(H, 2.6), belt = 0.5 * std::min(H, 3.0);
    const double cab_top = semi ? std::min(H, 3.6) - 0.2 : H;
    b.box(-cab, -e, -W / 2, W / 2, c, belt, kBody);
    b.prism({{-cab, belt - e}, {-e, belt - e}, {-0.04 * cab / 0.3, cab_top}, {-cab, cab_top}}, -0.49 * W, 0.49 * W,
            cabin_parts({1}));
    if (semi) {
      b.box(-L + e, -cab - 0.3, -W / 2, W / 2, 0.3 * H, H, kBody);  // trailer box
      b.box(-cab - 1.0, -cab + 0.2, -0.35 * W, 0.35 * W, c, 0.3 * H + e, kBody);  // fifth wheel / chassis
      wheels(b, {-0.35 * cab, -cab + 0.1 - r, -L + 1.2 + 2 * r, -L + 1.2}, r, W, 0.12 * W);
    } else {
      b.box(-L + e, -cab - 0.1, -W / 2, W / 2, 0.45 * H, H, kBody);  // cargo body
      b.box(-L + 0.3, -cab + 0.1, -0.35 * W, 0.35 * W, c, 0.45 * H + e, kBody);  // chassis
      wheels(b, {-0.16 * L, -0.75 * L}, r, W, 0.12 * W);
    }
    lamps(b, L, W, 0.25 * std::min(H, 3.0), 0.3 * std::min(H, 3.0), 0.05 * std::min(H, 3.0));
    antenna_x = -cab / 2;
  } else if (archetype == "bus") {
    const double c = 0.09 * H, r = 0.15 * H, belt = 0.35 * H, top = 0.85 * H;
    b.box(-L + e, -e, -W / 2, W / 2, c, belt, kBody);
    b.prism({{-L + e, belt - e}, {-e, belt - e}, {-e, top + e}, {-L + e, top + e}}, -0.49 * W, 0.49 * W,
            cabin_parts({1, 3}));
    b.box(-L + e, -e, -W / 2, W / 2, top, H, kBody);  // roof
    wheels(b, {-0.2 * L, -0.78 * L}, r, W, 0.1 * W);
    lamps(b, L, W, 0.2 * H, 0.2 * H, 0.05 * H);
  } else if (archetype == "motorcycle") {
    const double r = 0.3;
    for (double x : {-r, -L + r}) b.wheel(x, r, -0.06, 0.06);  // single track
    b.box(-L + 0.45, -0.45, -0.2, 0.2, 0.3, 0.85, kBody);
    b.box(-0.47, -0.42, -W / 2, W / 2, 0.98, 1.03, kBody);  // handlebar
    b.box(-0.45, -0.33, -0.08, 0.08, 0.85, 0.97, kLights);
    b.box(-L + 0.12, -L + 0.2, -0.06, 0.06, 0.72, 0.78, kLights);
    b.box(-0.6 * L - 0.2, -0.6 * L + 0.2, -0.25, 0.25, 0.7, H, kRider);
    antenna_x = -0.6 * L;
  } else if (archetype == "bicycle") {
    const double r = 0.34;
    for (double x : {-r, -L + r}) b.wheel(x, r, -0.02, 0.02);
    b.box(-L + 0.4, -0.4, -0.02, 0.02, 0.7, 0.76, kBody);  // frame
    b.box(-0.42, -0.38, -W / 2, W / 2, 1.0, 1.03, kBody);  // handlebar
    b.box(-0.36, -0.3, -0.04, 0.04, 0.8, 0.86, kLights);
    b.box(-0.6 * L - 0.18, -0.6 * L + 0.18, -0.2, 0.2, 0.78, H, kRider);
    antenna_x = -0.6 * L;
  } else {
    throw std::invalid_argument(name + ": unknown vehicle archetype '" + archetype + "'");
  }
  m.antenna = roof_mount(m, antenna_x, 0, antenna_offset_m);
  return m;
}

}  // namespace raysweep::meshkit
