#include "meshkit/projection.hpp"

#include <proj.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace raysweep::meshkit {

struct Projection::Impl {
  PJ_CONTEXT* ctx = nullptr;
  PJ* pj = nullptr;
  ~Impl() {
    if (pj) proj_destroy(pj);
    if (ctx) proj_context_destroy(ctx);
  }
};

Projection::Projection(const std::string& proj_string, Vec2 offset)
    : impl_(std::make_unique<Impl>()), proj_string_(proj_string), offset_(offset) {
  if (proj_string == "!") return;
  // A context per projection keeps PROJ thread-safe when scenes build in parallel.
  impl_->ctx = proj_context_create();
  // The string is a projection operation, applied forward to geodetic radians,
  // which is how SUMO calls PROJ; no CRS-to-CRS axis-order rules apply.
  impl_->pj = proj_create(impl_->ctx, proj_string.c_str());
  if (!impl_->pj)
    throw std::invalid_argument("invalid projection '" + proj_string +
                                "': " + proj_context_errno_string(impl_->ctx, proj_context_errno(impl_->ctx)));
}

Projection::~Projection() = default;
Projection::Projection(Projection&&) noexcept = default;
Projection& Projection::operator=(Projection&&) noexcept = default;

Vec2 Projection::forward(double lon_deg, double lat_deg) const {
  if (!impl_->pj) return {lon_deg + offset_[0], lat_deg + offset_[1]};
  PJ_COORD in = proj_coord(proj_torad(lon_deg), proj_torad(lat_deg), 0, 0);
  PJ_COORD out = proj_trans(impl_->pj, PJ_FWD, in);
  if (!std::isfinite(out.xy.x) || !std::isfinite(out.xy.y) || out.xy.x == HUGE_VAL)
    throw std::runtime_error("projection failed for lon=" + std::to_string(lon_deg) +
                             " lat=" + std::to_string(lat_deg));
  return {out.xy.x + offset_[0], out.xy.y + offset_[1]};
}

std::string Projection::utm_for(double lon_deg, double lat_deg) {
  const int zone = std::clamp(static_cast<int>(std::floor((lon_deg + 180.0) / 6.0)) + 1, 1, 60);
  return "+proj=utm +zone=" + std::to_string(zone) + (lat_deg < 0 ? " +south" : "") +
         " +ellps=WGS84 +datum=WGS84 +units=m +no_defs";
}

}  // namespace raysweep::meshkit
