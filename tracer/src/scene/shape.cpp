#include "scene/shape.hpp"

#include <tbb/parallel_for.h>

#include <map>
#include <stdexcept>

#include "meshkit/planar_faces.hpp"
#include "tracer/em/constants.hpp"

namespace raysweep::tracer {

void build_normal_index(TraceScene::Shape& s) {
  NormalIndex& ix = s.normals;
  const auto nf = static_cast<std::uint32_t>(s.face_plane.size());
  ix.all.resize(nf);
  for (std::uint32_t f = 0; f < nf; ++f) ix.all[f] = f;
  ix.lists.assign(5 * kCells * kCells, {});
  // Rows of cells on every core: each cell's lists are its own.
  tbb::parallel_for(0, kCells, [&](int i) {
    for (int j = 0; j < kCells; ++j) {
      const double u0 = -1 + 2.0 * i / kCells, v0 = -1 + 2.0 * j / kCells, h = 2.0 / kCells;
      const Vec3 c = octa_dir(u0 + h / 2, v0 + h / 2);
      // Angular radius of the cell: the farthest of a 9 x 9 grid over it
      // (with margin: the map is smooth within a cell); acos decreases, so
      // one acos of the smallest cosine.
      double min_cos = 1;
      for (int a = 0; a <= 8; ++a)
        for (int b = 0; b <= 8; ++b) min_cos = std::min(min_cos, dot(c, octa_dir(u0 + h * a / 8, v0 + h * b / 8)));
      const double radius = std::acos(std::clamp(min_cos, -1.0, 1.0)) * 1.25 + 1e-3;
      for (int level = 0; level < 5; ++level) {
        const double cos_max = std::cos(std::min(kPi / 2, NormalIndex::kLevels[level] + radius));
        auto& list = ix.lists[(level * kCells + i) * kCells + j];
        for (std::uint32_t f = 0; f < nf; ++f)
          if (std::fabs(dot(s.face_plane[f].normal, c)) >= cos_max) list.push_back(f);
      }
    }
  });
}

void attach_triangles(RTCDevice device, const TraceScene::Shape& s, const Vec3& origin, RTCScene scene) {
  RTCGeometry g = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
  auto* vb = static_cast<float*>(
      rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), s.vertices.size()));
  for (std::size_t i = 0; i < s.vertices.size(); ++i)
    for (int k = 0; k < 3; ++k) vb[3 * i + k] = static_cast<float>(s.vertices[i][k] - origin[k]);
  auto* ib = static_cast<unsigned*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                            3 * sizeof(unsigned), s.triangles.size()));
  for (std::size_t i = 0; i < s.triangles.size(); ++i)
    for (int k = 0; k < 3; ++k) ib[3 * i + k] = s.triangles[i][k];
  rtcSetGeometryBuildQuality(g, RTC_BUILD_QUALITY_HIGH);
  rtcCommitGeometry(g);
  rtcAttachGeometryByID(scene, g, 0);
  rtcReleaseGeometry(g);
}

void build_shape(TraceScene::Shape& s, const meshkit::Scene& scene,
                 const std::function<std::uint16_t(const std::string&)>& material_index,
                 std::uint32_t object_base) {
  std::map<std::pair<std::size_t, std::uint32_t>, std::uint32_t> face_index;
  for (std::size_t mi = 0; mi < scene.meshes.size(); ++mi) {
    const auto& m = scene.meshes[mi];
    // A non-finite vertex would make the bounds, hence Embree's origin and
    // every tolerance, infinite and lose every path without a word.
    for (std::size_t v = 0; v < m.vertices.size(); ++v)
      for (double c : m.vertices[v])
        if (!std::isfinite(c))
          throw std::invalid_argument(s.name + ": mesh '" + m.name + "' (material " + m.material + "): vertex " +
                                      std::to_string(v) + " is not finite");
    const std::uint16_t mat = material_index(m.material);
    std::vector<std::uint32_t> faces = m.triangle_face;
    if (faces.size() != m.triangles.size()) faces = meshkit::group_planar_faces(m.vertices, m.triangles, 0);
    const auto base = static_cast<std::uint32_t>(s.vertices.size());
    s.vertices.insert(s.vertices.end(), m.vertices.begin(), m.vertices.end());
    for (std::size_t t = 0; t < m.triangles.size(); ++t) {
      const auto& tri = m.triangles[t];
      s.triangles.push_back({tri[0] + base, tri[1] + base, tri[2] + base});
      auto [it, inserted] = face_index.try_emplace({mi, faces[t]}, static_cast<std::uint32_t>(s.face_material.size()));
      if (inserted) {
        s.face_material.push_back(mat);
        const std::uint32_t obj = t < m.triangle_object.size() ? m.triangle_object[t] : 0;
        s.face_object.push_back(object_base + obj);
      }
      s.tri_face.push_back(it->second);
    }
  }
  // Planes: area-weighted normal through the area-weighted centroid.
  const std::size_t nf = s.face_material.size();
  std::vector<Vec3> nsum(nf, Vec3{0, 0, 0}), csum(nf, Vec3{0, 0, 0});
  std::vector<double> asum(nf, 0);
  for (std::size_t t = 0; t < s.triangles.size(); ++t) {
    const auto& tri = s.triangles[t];
    const Vec3 &a = s.vertices[tri[0]], &b = s.vertices[tri[1]], &c = s.vertices[tri[2]];
    const Vec3 n2 = cross(b - a, c - a);
    const double area2 = norm(n2);
    const auto f = s.tri_face[t];
    nsum[f] = nsum[f] + n2;
    csum[f] = csum[f] + (area2 / 3.0) * (a + b + c);
    asum[f] += area2;
  }
  s.face_plane.resize(nf);
  s.face_flatness.assign(nf, 0);
  for (std::size_t f = 0; f < nf; ++f) {
    const Vec3 n = normalize(nsum[f]);
    const Vec3 c = asum[f] > 0 ? (1.0 / asum[f]) * csum[f] : Vec3{0, 0, 0};
    s.face_plane[f] = Plane{n, dot(n, c)};
  }
  for (std::size_t t = 0; t < s.triangles.size(); ++t) {
    const auto f = s.tri_face[t];
    for (auto vi : s.triangles[t])
      s.face_flatness[f] =
          std::max(s.face_flatness[f], std::fabs(dot(s.face_plane[f].normal, s.vertices[vi]) - s.face_plane[f].offset));
  }

  // Triangle membership and edge constraints for face_contains.
  s.face_tri_begin.assign(nf + 1, 0);
  for (auto f : s.tri_face) ++s.face_tri_begin[f + 1];
  for (std::size_t f = 0; f < nf; ++f) s.face_tri_begin[f + 1] += s.face_tri_begin[f];
  s.face_tris.resize(s.triangles.size());
  {
    std::vector<std::uint32_t> fill(s.face_tri_begin.begin(), s.face_tri_begin.end() - 1);
    for (std::uint32_t t = 0; t < s.triangles.size(); ++t) s.face_tris[fill[s.tri_face[t]]++] = t;
  }
  s.edge_normal.assign(3 * s.triangles.size(), Vec3{0, 0, 0});
  s.edge_offset.assign(3 * s.triangles.size(), 1e300);  // degenerate triangles contain nothing
  for (std::size_t t = 0; t < s.triangles.size(); ++t) {
    const auto& tri = s.triangles[t];
    const Vec3 n = s.face_plane[s.tri_face[t]].normal;
    const Vec3 a = s.vertices[tri[0]], b = s.vertices[tri[1]], c = s.vertices[tri[2]];
    const double orient = dot(cross(b - a, c - a), n) >= 0 ? 1.0 : -1.0;
    const Vec3 pts[3] = {a, b, c};
    bool degenerate = false;
    Vec3 en[3];
    for (int k = 0; k < 3; ++k) {
      en[k] = orient * cross(n, pts[(k + 1) % 3] - pts[k]);  // points into the triangle
      if (norm(en[k]) < 1e-12) degenerate = true;
      en[k] = normalize(en[k]);
    }
    if (degenerate) continue;
    for (int k = 0; k < 3; ++k) {
      s.edge_normal[3 * t + k] = en[k];
      s.edge_offset[3 * t + k] = dot(en[k], pts[k]);
    }
  }
  s.face_sphere.assign(nf, TraceScene::Sphere{});
  {
    std::vector<Vec3> lo(nf, Vec3{1e300, 1e300, 1e300}), hi(nf, Vec3{-1e300, -1e300, -1e300});
    for (std::size_t t = 0; t < s.triangles.size(); ++t)
      for (auto vi : s.triangles[t])
        for (int k = 0; k < 3; ++k) {
          lo[s.tri_face[t]][k] = std::min(lo[s.tri_face[t]][k], s.vertices[vi][k]);
          hi[s.tri_face[t]][k] = std::max(hi[s.tri_face[t]][k], s.vertices[vi][k]);
        }
    for (std::size_t f = 0; f < nf; ++f) {
      s.face_sphere[f].centre = 0.5 * (lo[f] + hi[f]);
      s.face_sphere[f].radius = 0.5 * norm(hi[f] - lo[f]);
    }
  }

  {
    Vec3 lo{1e300, 1e300, 1e300}, hi{-1e300, -1e300, -1e300};
    for (const auto& v : s.vertices)
      for (int k = 0; k < 3; ++k) {
        lo[k] = std::min(lo[k], v[k]);
        hi[k] = std::max(hi[k], v[k]);
      }
    if (!s.vertices.empty()) s.bounds = TraceScene::Sphere{0.5 * (lo + hi), 0.5 * norm(hi - lo)};
  }
}

}  // namespace raysweep::tracer
