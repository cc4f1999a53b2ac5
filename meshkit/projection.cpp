#include "meshkit/projection.hpp"

#include <dlfcn.h>
#include <proj.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace raysweep::meshkit {

namespace {

// PROJ is loaded when the first projection is made, not linked: libproj and
// what it needs (SQLite, libtiff, libcurl, GnuTLS) cost every raysweep
// process about 5 ms of loading and symbol binding at start
// (docs/performance.md), and only the scene stages project anything.
struct ProjApi {
  decltype(&proj_context_create) context_create;
  decltype(&proj_context_destroy) context_destroy;
  decltype(&proj_create) create;
  decltype(&proj_destroy) destroy;
  decltype(&proj_trans) trans;
  decltype(&proj_coord) coord;
  decltype(&proj_torad) torad;
  decltype(&proj_context_errno) context_errno;
  decltype(&proj_context_errno_string) errno_string;
};

template <class F>
void bind(void* lib, const char* name, F& f) {
  void* p = dlsym(lib, name);
  if (!p) throw std::runtime_error(std::string(RAYSWEEP_PROJ_SONAME) + " has no " + name);
  f = reinterpret_cast<F>(p);
}

const ProjApi& proj() {
  static const ProjApi api = [] {
    void* lib = dlopen(RAYSWEEP_PROJ_SONAME, RTLD_NOW | RTLD_LOCAL);
    if (!lib) throw std::runtime_error(std::string("cannot load PROJ: ") + dlerror());
    ProjApi a{};
    bind(lib, "proj_context_create", a.context_create);
    bind(lib, "proj_context_destroy", a.context_destroy);
    bind(lib, "proj_create", a.create);
    bind(lib, "proj_destroy", a.destroy);
    bind(lib, "proj_trans", a.trans);
    bind(lib, "proj_coord", a.coord);
    bind(lib, "proj_torad", a.torad);
    bind(lib, "proj_context_errno", a.context_errno);
    bind(lib, "proj_context_errno_string", a.errno_string);
    return a;
  }();
  return api;
}

}  // namespace

struct Projection::Impl {
  PJ_CONTEXT* ctx = nullptr;
  PJ* pj = nullptr;
  ~Impl() {
    if (pj) proj().destroy(pj);
    if (ctx) proj().context_destroy(ctx);
  }
};

Projection::Projection(const std::string& proj_string, Vec2 offset)
    : impl_(std::make_unique<Impl>()), proj_string_(proj_string), offset_(offset) {
  if (proj_string == "!") return;
  // A context per projection keeps PROJ thread-safe when scenes build in parallel.
  impl_->ctx = proj().context_create();
  // The string is a projection operation, applied forward to geodetic radians,
  // which is how SUMO calls PROJ; no CRS-to-CRS axis-order rules apply.
  impl_->pj = proj().create(impl_->ctx, proj_string.c_str());
  if (!impl_->pj)
    throw std::invalid_argument("invalid projection '" + proj_string +
                                "': " + proj().errno_string(impl_->ctx, proj().context_errno(impl_->ctx)));
}

Projection::~Projection() = default;
Projection::Projection(Projection&&) noexcept = default;
Projection& Projection::operator=(Projection&&) noexcept = default;

Vec2 Projection::forward(double lon_deg, double lat_deg) const {
  if (!impl_->pj) return {lon_deg + offset_[0], lat_deg + offset_[1]};
  const ProjApi& api = proj();
  PJ_COORD in = api.coord(api.torad(lon_deg), api.torad(lat_deg), 0, 0);
  PJ_COORD out = api.trans(impl_->pj, PJ_FWD, in);
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
