#include "tracer/trace_scene.hpp"

#include <embree3/rtcore.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <map>
#include <mutex>
#include <stdexcept>

#include "scene/model_tables.hpp"
#include "scene/scene_edges.hpp"
#include "scene/scene_impl.hpp"

namespace raysweep::tracer {

namespace {

void check_device(RTCDevice device, const char* what) {
  const RTCError e = rtcGetDeviceError(device);
  if (e != RTC_ERROR_NONE) throw std::runtime_error(std::string("Embree error ") + std::to_string(e) + " in " + what);
}

// The ground: large horizontal faces (a bounding radius of 25 m or more) at
// the scene's lowest level of such faces, within kGroundBand. A large flat
// roof is above that band: it stays a reflector and an obstacle like any
// other face, and does not multiply the ground's order-3 search (a town of
// 633 buildings had 71 such faces).
std::vector<char> ground_faces(const TraceScene::Shape& w) {
  constexpr double kGroundBand = 2.0;  // m: curbs, gentle slopes, ground split into patches
  const std::size_t nf = w.face_plane.size();
  std::vector<char> out(nf, 0);
  auto large_flat = [&](std::size_t f) {
    return std::fabs(w.face_plane[f].normal[2]) > 0.999 && w.face_sphere[f].radius >= 25;
  };
  auto height = [&](std::size_t f) { return w.face_plane[f].offset / w.face_plane[f].normal[2]; };
  double lowest = std::numeric_limits<double>::infinity();
  for (std::size_t f = 0; f < nf; ++f)
    if (large_flat(f)) lowest = std::min(lowest, height(f));
  for (std::size_t f = 0; f < nf; ++f) out[f] = large_flat(f) && height(f) <= lowest + kGroundBand;
  return out;
}

}  // namespace

TraceScene::TraceScene(const meshkit::Scene& static_scene) : impl_(std::make_unique<Impl>()) {
  auto& d = *impl_;
  d.device = rtcNewDevice("verbose=0");
  if (!d.device) throw std::runtime_error("cannot create an Embree device");
  d.bounds = static_scene.bounds();
  if (!d.bounds.empty())
    for (int k = 0; k < 3; ++k) d.origin[k] = std::round(0.5 * (d.bounds.min[k] + d.bounds.max[k]));
  for (const auto& o : static_scene.objects) d.static_objects.push_back(o.source_id);
  if (d.static_objects.empty()) d.static_objects.push_back("static");
  d.world.name = "static scene";
  build_shape(d.world, static_scene, [this](const std::string& m) { return material_index(m); }, 0);
  for (auto& o : d.world.face_object) o = std::min<std::uint32_t>(o, d.static_objects.size() - 1);
  d.edges = extract_edges(d.world, d.static_objects);
  d.ground = ground_faces(d.world);

  d.top = rtcNewScene(d.device);
  rtcSetSceneFlags(d.top, static_cast<RTCSceneFlags>(RTC_SCENE_FLAG_DYNAMIC | RTC_SCENE_FLAG_ROBUST |
                                                     RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION));
  rtcSetSceneBuildQuality(d.top, RTC_BUILD_QUALITY_LOW);
  // The static scene's triangles directly in the top-level scene, not as
  // an instance of the world's own scene: every ray then walks one BVH for
  // them (Embree's raw closest-hit rays 15-30 % faster on the bench scenes).
  if (!d.world.triangles.empty()) attach_triangles(d.device, d.world, d.origin, d.top);
  rtcCommitScene(d.top);
  check_device(d.device, "top-level scene");
  d.edges = exposed_parts(*this, d.edges);
}

TraceScene::~TraceScene() {
  auto& d = *impl_;
  for (auto g : d.slots) rtcReleaseGeometry(g);
  if (d.top) rtcReleaseScene(d.top);
  for (auto& m : d.models) rtcReleaseScene(m->scene);
  rtcReleaseDevice(d.device);
}

std::uint16_t TraceScene::material_index(const std::string& name) {
  for (std::size_t i = 0; i < materials_.size(); ++i)
    if (materials_[i] == name) return static_cast<std::uint16_t>(i);
  materials_.push_back(name);
  return static_cast<std::uint16_t>(materials_.size() - 1);
}

std::uint32_t TraceScene::add_vehicle_model(const std::string& name, const meshkit::Scene& model,
                                            const Vec3& antenna) {
  auto& d = *impl_;
  auto s = std::make_unique<Shape>();
  s->name = "vehicle model " + name;
  s->antenna = antenna;
  build_shape(*s, model, [this](const std::string& m) { return material_index(m); }, 0);
  // Only vehicles' faces are looked up by normal (vehicle_faces_near_normal):
  // the city's index would cost a process a few milliseconds for nothing.
  build_normal_index(*s);
  s->scene = rtcNewScene(d.device);
  rtcSetSceneFlags(s->scene, static_cast<RTCSceneFlags>(RTC_SCENE_FLAG_ROBUST | RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION));
  rtcSetSceneBuildQuality(s->scene, RTC_BUILD_QUALITY_HIGH);
  if (!s->triangles.empty()) attach_triangles(d.device, *s, Vec3{0, 0, 0}, s->scene);
  rtcCommitScene(s->scene);
  check_device(d.device, s->name.c_str());
  s->content_key = model_content_key(*s, materials_, rtcGetDeviceProperty(d.device, RTC_DEVICE_PROPERTY_VERSION));
  const std::uint32_t faces = static_cast<std::uint32_t>(s->face_plane.size());
  cached_table(
      d.store.get(), "mount-" + ContentKey().add(s->content_key).add(&antenna, sizeof antenna).hex(),
      [&](const std::vector<std::uint32_t>& w) { return decode_increasing(w, faces, s->seen_from_mount); },
      [&] { s->seen_from_mount = faces_seen_from(*s, antenna); },
      [&] { return s->seen_from_mount; });
  // Wedges only: a free border of a model's face is a modelling seam (an
  // open panel, a glass pane set into the body), not a thin screen.
  for (const Edge& e : extract_edges(*s, {}, true))
    if (e.face0 != e.face_n) s->model_edges.push_back(e);
  d.models.push_back(std::move(s));
  return static_cast<std::uint32_t>(d.models.size() - 1);
}

void TraceScene::set_precompute_store(std::shared_ptr<const PrecomputeStore> store) {
  impl_->store = std::move(store);
}

std::size_t TraceScene::model_count() const { return impl_->models.size(); }
const std::string& TraceScene::model_name(std::uint32_t model) const { return impl_->models.at(model)->name; }

void TraceScene::set_vehicles(const std::vector<VehiclePose>& vehicles) {
  auto& d = *impl_;
  for (const auto& v : vehicles)
    if (v.model >= d.models.size()) throw std::invalid_argument("vehicle " + v.id + ": unknown model index");
  vehicles_ = vehicles;
  d.cos_yaw.resize(vehicles.size());
  d.sin_yaw.resize(vehicles.size());
  for (std::size_t i = 0; i < vehicles.size(); ++i) {
    const auto& v = vehicles[i];
    d.cos_yaw[i] = std::cos(v.yaw_rad);
    d.sin_yaw[i] = std::sin(v.yaw_rad);
    if (i >= d.slots.size()) {
      RTCGeometry g = rtcNewGeometry(d.device, RTC_GEOMETRY_TYPE_INSTANCE);
      d.slots.push_back(g);
      d.slot_enabled.push_back(true);
      rtcAttachGeometryByID(d.top, g, static_cast<unsigned>(i + 1));
    } else if (!d.slot_enabled[i]) {
      rtcEnableGeometry(d.slots[i]);
      d.slot_enabled[i] = true;
    }
    RTCGeometry g = d.slots[i];
    rtcSetGeometryInstancedScene(g, d.models[v.model]->scene);
    const float c = static_cast<float>(d.cos_yaw[i]), s = static_cast<float>(d.sin_yaw[i]);
    const float xfm[12] = {c, s, 0, -s, c, 0, 0, 0, 1,
                           static_cast<float>(v.position[0] - d.origin[0]),
                           static_cast<float>(v.position[1] - d.origin[1]),
                           static_cast<float>(v.position[2] - d.origin[2])};
    rtcSetGeometryTransform(g, 0, RTC_FORMAT_FLOAT3X4_COLUMN_MAJOR, xfm);
    rtcCommitGeometry(g);
  }
  for (std::size_t i = vehicles.size(); i < d.slots.size(); ++i)
    if (d.slot_enabled[i]) {
      rtcDisableGeometry(d.slots[i]);
      d.slot_enabled[i] = false;
    }
  rtcCommitScene(d.top);
  check_device(d.device, "vehicle update");
}

Vec3 TraceScene::vehicle_antenna(std::size_t v) const {
  const auto& d = *impl_;
  const Vec3& a = d.models[vehicles_[v].model]->antenna;
  const double c = d.cos_yaw[v], s = d.sin_yaw[v];
  return Vec3{c * a[0] - s * a[1], s * a[0] + c * a[1], a[2]} + vehicles_[v].position;
}

Vec3 TraceScene::vehicle_forward(std::size_t v) const { return Vec3{impl_->cos_yaw[v], impl_->sin_yaw[v], 0}; }

bool TraceScene::closest_hit(const Vec3& origin, const Vec3& dir, double tnear, double tfar, Hit& hit,
                             const FaceRef* skip) const {
  const auto& d = *impl_;
  const Vec3 o = origin - d.origin;
  const double olen = norm(o);
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  for (int attempt = 0; attempt < 16; ++attempt) {
    RTCRayHit rh = make_ray(o, dir, tnear, tfar);
    rtcIntersect1(d.top, &ctx, &rh);
    if (rh.hit.geomID == kNone) return false;
    const std::uint32_t inst = instance_of(rh.hit.instID[0]);
    const Shape& s = inst == 0 ? d.world : *d.models[vehicles_[inst - 1].model];
    hit.t = rh.ray.tfar;
    hit.face = FaceRef{inst, s.tri_face[rh.hit.primID]};
    if (skip && hit.face == *skip) {
      tnear = hit.t + Impl::step(olen, hit.t);
      continue;
    }
    return true;
  }
  return false;
}

bool TraceScene::all_hits(const Vec3& origin, const Vec3& dir, double tnear, double tfar, std::vector<Hit>& hits,
                          std::size_t max_hits, const FaceRef* skip) const {
  hits.clear();
  if (!(tnear < tfar)) return true;
  const auto& d = *impl_;
  const Vec3 o = origin - d.origin;
  const double olen = norm(o);
  thread_local std::vector<Impl::RawHit> raw;
  raw.clear();
  Impl::FilterContext fc;
  rtcInitIntersectContext(&fc.ctx);
  fc.ctx.filter = &Impl::filter;
  fc.impl = &d;
  fc.vehicles = &vehicles_;
  fc.collect = &raw;
  RTCRayHit rh = make_ray(o, dir, tnear, tfar);
  rtcIntersect1(d.top, &fc.ctx, &rh);
  std::sort(raw.begin(), raw.end(), [](const Impl::RawHit& a, const Impl::RawHit& b) {
    return a.t != b.t ? a.t < b.t : a.face < b.face;
  });
  // Crossings as a walk from hit to hit would list them: a hit within
  // float rounding of the previous one (the same crossing seen on two
  // triangles, or a second face at the same point) is one crossing; the
  // face the ray leaves is stepped over.
  double cursor = tnear;
  for (const auto& r : raw) {
    if (r.t < cursor) continue;
    cursor = r.t + Impl::step(olen, r.t);
    if (skip && r.face == *skip) continue;
    if (hits.size() >= max_hits) return false;
    hits.push_back(Hit{r.t, r.face});
  }
  return true;
}

bool TraceScene::occluded(const Vec3& origin, const Vec3& dir, double tnear, double tfar, const FaceRef* ignore0,
                          const FaceRef* ignore1) const {
  if (!(tnear < tfar)) return false;
  const auto& d = *impl_;
  Impl::FilterContext fc;
  rtcInitIntersectContext(&fc.ctx);
  fc.ctx.filter = (ignore0 || ignore1) ? &Impl::filter : nullptr;
  fc.impl = &d;
  fc.vehicles = &vehicles_;
  fc.ignore[0] = ignore0;
  fc.ignore[1] = ignore1;
  RTCRayHit rh = make_ray(origin - d.origin, dir, tnear, tfar);
  rtcOccluded1(d.top, &fc.ctx, &rh.ray);
  return rh.ray.tfar < 0;
}

double TraceScene::slack(const Vec3& p, double t) const {
  return std::max(1e-3, 1e-6 * (norm(p - impl_->origin) + t));
}

Plane TraceScene::plane(const FaceRef& f) const {
  const auto& d = *impl_;
  if (f.instance == 0) return d.world.face_plane[f.face];
  const std::size_t v = f.instance - 1;
  const Plane& p = d.models[vehicles_[v].model]->face_plane[f.face];
  const double c = d.cos_yaw[v], s = d.sin_yaw[v];
  const Vec3 n{c * p.normal[0] - s * p.normal[1], s * p.normal[0] + c * p.normal[1], p.normal[2]};
  return Plane{n, p.offset + dot(n, vehicles_[v].position)};
}

std::uint16_t TraceScene::material(const FaceRef& f) const {
  return impl_->shape_of(f, vehicles_).face_material[f.face];
}

std::uint32_t TraceScene::object(const FaceRef& f) const {
  if (f.instance == 0) return impl_->world.face_object[f.face];
  return vehicle_object(f.instance - 1);
}

double TraceScene::flatness(const FaceRef& f) const { return impl_->shape_of(f, vehicles_).face_flatness[f.face]; }

Vec3 TraceScene::velocity(const FaceRef& f) const {
  return f.instance == 0 ? Vec3{0, 0, 0} : vehicles_[f.instance - 1].velocity;
}

std::size_t TraceScene::face_count(std::uint32_t instance) const {
  if (instance == 0) return impl_->world.face_plane.size();
  return impl_->models[vehicles_.at(instance - 1).model]->face_plane.size();
}

bool TraceScene::face_contains(const FaceRef& f, const Vec3& p, double tol) const {
  const auto& d = *impl_;
  const Shape& s = d.shape_of(f, vehicles_);
  Vec3 q = p;
  if (f.instance > 0) {  // into the model frame
    const std::size_t v = f.instance - 1;
    const Vec3 w = p - vehicles_[v].position;
    const double c = d.cos_yaw[v], sn = d.sin_yaw[v];
    q = Vec3{c * w[0] + sn * w[1], -sn * w[0] + c * w[1], w[2]};
  }
  const Sphere& b = s.face_sphere[f.face];
  const Vec3 w = q - b.centre;
  if (dot(w, w) > (b.radius + tol) * (b.radius + tol)) return false;
  for (std::uint32_t k = s.face_tri_begin[f.face]; k < s.face_tri_begin[f.face + 1]; ++k) {
    const std::uint32_t t = s.face_tris[k];
    if (dot(s.edge_normal[3 * t], q) >= s.edge_offset[3 * t] - tol &&
        dot(s.edge_normal[3 * t + 1], q) >= s.edge_offset[3 * t + 1] - tol &&
        dot(s.edge_normal[3 * t + 2], q) >= s.edge_offset[3 * t + 2] - tol)
      return true;
  }
  return false;
}

TraceScene::Sphere TraceScene::face_sphere(const FaceRef& f) const {
  const auto& d = *impl_;
  const Sphere& b = d.shape_of(f, vehicles_).face_sphere[f.face];
  if (f.instance == 0) return b;
  const std::size_t v = f.instance - 1;
  const double c = d.cos_yaw[v], sn = d.sin_yaw[v];
  const Vec3& m = b.centre;
  return Sphere{Vec3{c * m[0] - sn * m[1], sn * m[0] + c * m[1], m[2]} + vehicles_[v].position, b.radius};
}

void TraceScene::face_triangles(const FaceRef& f, std::vector<std::array<Vec3, 3>>& out) const {
  const auto& d = *impl_;
  const Shape& s = d.shape_of(f, vehicles_);
  double c = 1, sn = 0;
  Vec3 t{0, 0, 0};
  if (f.instance > 0) {
    const std::size_t v = f.instance - 1;
    c = d.cos_yaw[v];
    sn = d.sin_yaw[v];
    t = vehicles_[v].position;
  }
  for (std::uint32_t k = s.face_tri_begin[f.face]; k < s.face_tri_begin[f.face + 1]; ++k) {
    std::array<Vec3, 3> tri;
    for (int q = 0; q < 3; ++q) {
      const Vec3& m = s.vertices[s.triangles[s.face_tris[k]][q]];
      tri[q] = Vec3{c * m[0] - sn * m[1], sn * m[0] + c * m[1], m[2]} + t;
    }
    out.push_back(tri);
  }
}

bool TraceScene::is_ground(std::uint32_t f) const { return impl_->ground.at(f) != 0; }

TraceScene::Sphere TraceScene::vehicle_sphere(std::size_t v) const {
  const auto& d = *impl_;
  const Sphere& b = d.models[vehicles_[v].model]->bounds;
  const double c = d.cos_yaw[v], sn = d.sin_yaw[v];
  const Vec3& m = b.centre;
  return Sphere{Vec3{c * m[0] - sn * m[1], sn * m[0] + c * m[1], m[2]} + vehicles_[v].position, b.radius};
}

const std::vector<std::uint32_t>& TraceScene::vehicle_faces_near_normal(std::size_t v, const Vec3& dir,
                                                                        double delta) const {
  const auto& d = *impl_;
  const double c = d.cos_yaw[v], sn = d.sin_yaw[v];
  const Vec3 m{c * dir[0] + sn * dir[1], -sn * dir[0] + c * dir[1], dir[2]};  // into the model frame
  return d.models[vehicles_[v].model]->normals.query(m, delta);
}

const std::vector<std::uint32_t>* TraceScene::faces_seen_from_mount(std::size_t v, const Vec3& node) const {
  if (norm(node - vehicle_antenna(v)) > 1e-6) return nullptr;
  return &impl_->models[vehicles_[v].model]->seen_from_mount;
}

std::vector<std::string> TraceScene::object_names() const {
  std::vector<std::string> names = impl_->static_objects;
  for (const auto& v : vehicles_) names.push_back("vehicle/" + v.id);
  return names;
}

std::uint32_t TraceScene::static_object_count() const {
  return static_cast<std::uint32_t>(impl_->static_objects.size());
}

std::int64_t TraceScene::enclosing_object(const Vec3& p) const {
  // Per static object, the parity of its crossings along each ray: up,
  // then four horizontal directions (not down: building floors lie in the
  // ground's plane, and coincident crossings count once).
  static const Vec3 dirs[5] = {{0, 0, 1}, {1, 0, 0}, {0, 1, 0}, {-1, 0, 0}, {0, -1, 0}};
  std::vector<std::pair<std::uint32_t, std::array<bool, 5>>> odd;
  std::vector<Hit> hits;
  const double reach = 2 * norm(impl_->bounds.max - impl_->bounds.min) + 1;
  for (int r = 0; r < 5; ++r) {
    all_hits(p, dirs[r], 0, reach, hits, 256);
    for (const Hit& h : hits) {
      if (h.face.instance != 0) continue;
      const std::uint32_t o = object(h.face);
      auto it = std::find_if(odd.begin(), odd.end(), [o](const auto& e) { return e.first == o; });
      if (it == odd.end()) it = odd.insert(odd.end(), {o, {}});
      it->second[r] = !it->second[r];
    }
  }
  // Closed: crossed an odd number of times upwards (a roof), and so in at
  // least two horizontal directions (walls; a wall shared with a neighbour
  // may hide one).
  for (const auto& [o, parity] : odd)
    if (parity[0] && parity[1] + parity[2] + parity[3] + parity[4] >= 2) return o;
  return -1;
}

meshkit::Bounds TraceScene::static_bounds() const { return impl_->bounds; }
std::size_t TraceScene::static_triangle_count() const { return impl_->world.triangles.size(); }

std::size_t TraceScene::shoot_raw(const Vec3& origin, const std::vector<Vec3>& directions, double tfar) const {
  const auto& d = *impl_;
  const Vec3 o = origin - d.origin;
  return tbb::parallel_reduce(
      tbb::blocked_range<std::size_t>(0, directions.size(), 1024), std::size_t{0},
      [&](const tbb::blocked_range<std::size_t>& r, std::size_t n) {
        RTCIntersectContext ctx;
        rtcInitIntersectContext(&ctx);
        for (std::size_t i = r.begin(); i != r.end(); ++i) {
          RTCRayHit rh = make_ray(o, directions[i], 0, tfar);
          rtcIntersect1(d.top, &ctx, &rh);
          n += rh.hit.geomID != kNone;
        }
        return n;
      },
      std::plus<>());
}

std::shared_ptr<const void> TraceScene::static_memo(const std::string& key,
                                                    const std::function<std::shared_ptr<const void>()>& make) const {
  const auto& d = *impl_;
  const std::lock_guard<std::mutex> lock(d.memo_mutex);
  auto& slot = d.memo[key];
  if (!slot) slot = make();
  return slot;
}

}  // namespace raysweep::tracer
