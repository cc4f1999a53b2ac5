// TraceScene's state: the Embree device and top-level scene, the static
// shape and the vehicle models, the current frame's instances, and what
// is derived from the static scene once (edges, ground).
#pragma once

#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "scene/shape.hpp"
#include "tracer/precompute.hpp"

namespace raysweep::tracer {

struct TraceScene::Impl {
  RTCDevice device = nullptr;
  Vec3 origin{0, 0, 0};  // Embree's float frame is relative to this point
  meshkit::Bounds bounds = meshkit::Bounds::none();
  std::vector<std::string> static_objects;
  Shape world;
  std::vector<std::unique_ptr<Shape>> models;
  RTCScene top = nullptr;
  std::vector<RTCGeometry> slots;  // vehicle instance v lives at top-level geometry id v + 1
  std::vector<bool> slot_enabled;
  std::vector<double> cos_yaw, sin_yaw;
  std::vector<Edge> edges;
  std::vector<char> ground;  // per static face: is_ground
  std::shared_ptr<const PrecomputeStore> store;
  mutable std::mutex memo_mutex;
  mutable std::map<std::string, std::shared_ptr<const void>> memo;

  const Shape& shape_of(const FaceRef& f, const std::vector<VehiclePose>& vehicles) const {
    return f.instance == 0 ? world : *models[vehicles[f.instance - 1].model];
  }
  // Step that clears float rounding of a point at distance `t` along a ray
  // whose origin is `o_local` away from the Embree origin.
  static double step(double o_local, double t) { return std::max(1e-4, 4e-7 * (o_local + t)); }

  // One traversal instead of one per crossing: an intersection-context
  // filter sees every candidate hit. It either records it and rejects it
  // (all_hits: the traversal goes on to tfar), or rejects only the faces a
  // query ignores (occluded: the first other hit ends the traversal).
  struct RawHit {
    float t;
    FaceRef face;
  };
  struct FilterContext {
    RTCIntersectContext ctx;  // first member: Embree hands back its address
    const Impl* impl = nullptr;
    const std::vector<VehiclePose>* vehicles = nullptr;
    std::vector<RawHit>* collect = nullptr;
    const FaceRef* ignore[2] = {nullptr, nullptr};
  };
  static void filter(const RTCFilterFunctionNArguments* args) {
    auto* fc = reinterpret_cast<FilterContext*>(args->context);
    for (unsigned i = 0; i < args->N; ++i) {
      if (args->valid[i] != -1) continue;
      const std::uint32_t inst = instance_of(RTCHitN_instID(args->hit, args->N, i, 0));
      const std::uint32_t prim = RTCHitN_primID(args->hit, args->N, i);
      const Shape& s = inst == 0 ? fc->impl->world : *fc->impl->models[(*fc->vehicles)[inst - 1].model];
      const FaceRef face{inst, s.tri_face[prim]};
      if (fc->collect) {
        fc->collect->push_back(RawHit{RTCRayN_tfar(args->ray, args->N, i), face});
        args->valid[i] = 0;
      } else if ((fc->ignore[0] && face == *fc->ignore[0]) || (fc->ignore[1] && face == *fc->ignore[1])) {
        args->valid[i] = 0;
      }
    }
  }
};

}  // namespace raysweep::tracer
