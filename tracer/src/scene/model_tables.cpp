#include "scene/model_tables.hpp"

namespace raysweep::tracer {

std::string model_content_key(const TraceScene::Shape& s, const std::vector<std::string>& materials,
                              long embree_version) {
  ContentKey k;
  k.add("raysweep vehicle model tables").add_u64(static_cast<std::uint64_t>(embree_version));
  k.add_vector(s.vertices).add_vector(s.triangles).add_vector(s.tri_face);
  for (auto m : s.face_material) k.add(materials.at(m));
  return k.hex();
}

std::vector<std::uint32_t> faces_seen_from(const TraceScene::Shape& s, const Vec3& antenna) {
  std::vector<char> seen(s.face_plane.size(), 0);
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  for (const Vec3& dir : fibonacci_sphere(1 << 16)) {
    float tnear = 0;
    for (int hop = 0; hop < 64; ++hop) {
      RTCRayHit rh = make_ray(antenna, dir, tnear, 1e3);
      rtcIntersect1(s.scene, &ctx, &rh);
      if (rh.hit.geomID == kNone) break;
      seen[s.tri_face[rh.hit.primID]] = 1;
      tnear = rh.ray.tfar + 1e-4f;
    }
  }
  std::vector<std::uint32_t> out;
  for (std::uint32_t f = 0; f < seen.size(); ++f)
    if (seen[f]) out.push_back(f);
  return out;
}

bool decode_increasing(const std::vector<std::uint32_t>& w, std::uint32_t faces, std::vector<std::uint32_t>& out) {
  for (std::size_t i = 0; i < w.size(); ++i)
    if (w[i] >= faces || (i > 0 && w[i] <= w[i - 1])) return false;
  out = w;
  return true;
}

}  // namespace raysweep::tracer
