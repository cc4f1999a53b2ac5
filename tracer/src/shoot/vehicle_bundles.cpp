#include "shoot/vehicle_bundles.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "snapshot_plan.hpp"

namespace raysweep::tracer {

namespace {

// 1 - cos of the half angle of the cap the sphere subtends from `from`
// (its solid angle over 2 pi); 2, the whole sphere, from inside it.
double cap_one_minus_cos(const Vec3& from, const TraceScene::Sphere& s) {
  const double d = norm(s.centre - from);
  if (!(d > s.radius)) return 2;
  const double sin_half = s.radius / d;
  return sin_half * sin_half / (1 + std::sqrt(1 - sin_half * sin_half));
}

// The bundles' share of a turned lattice (TracerConfig::lattice_turn): the
// cap spiral turned about its axis and its rings shifted within their
// equal-area strata, so that each turn aims other rays at a vehicle.
struct CapTurn {
  double angle = 0, offset = 0.5;  // unturned: the strata's middles
  explicit CapTurn(std::uint64_t turn) {
    if (turn == 0) return;
    // One turned direction: uniform on the sphere, so its azimuth and
    // (Archimedes) its z are uniform.
    const auto d0 = fibonacci_sphere(1, turn)[0];
    angle = std::atan2(d0[1], d0[0]);
    offset = 0.5 * (1 - d0[2]) * 0.999 + 0.0005;
  }
};

// Directions from `from` spread evenly in solid angle over the cap the
// sphere subtends (a Fibonacci spiral), `n` of them; none from inside it.
// Returns the cap's 1 - cos (0 from inside).
double cap_directions(const Vec3& from, const TraceScene::Sphere& s, int n, const CapTurn& turn,
                      std::vector<Vec3>& out) {
  const Vec3 c = s.centre - from;
  const double d = norm(c);
  if (!(d > s.radius)) return 0;
  const Vec3 w = (1 / d) * c, u = any_perpendicular(w), v = cross(w, u);
  const double one_minus_cos = cap_one_minus_cos(from, s);
  const double golden = kPi * (3 - std::sqrt(5.0));
  for (int k = 0; k < n; ++k) {
    const double z = 1 - one_minus_cos * (k + turn.offset) / n, r = std::sqrt(std::fmax(0.0, 1 - z * z));
    const double phi = golden * k + turn.angle;
    out.push_back(std::cos(phi) * r * u + std::sin(phi) * r * v + z * w);
  }
  return one_minus_cos;
}

// The angular spacing of n rays over a cap (solid angle 2 pi (1 - cos)).
double bundle_spacing(double one_minus_cos, int n) { return std::sqrt(2 * kPi * one_minus_cos / n); }

// Lattice rays a cap of this size receives (solid angle 2 pi (1 - cos) over
// 4 pi / rays each).
double lattice_rays_on_cap(double one_minus_cos, int rays) { return one_minus_cos * rays / 2; }

// A bundle from source s through face f (ImageFaces' index) at vehicle v:
// from s's image in f, n rays over the smaller of the caps of f's and v's
// spheres, kept where they cross f's plane within f's sphere and pass
// within v's; each cast from s at its crossing point. With `sparse_only`,
// none when the lattice already gives v's cap from the image n rays.
void bundle_through_face(const ImageFaces& faces, const Vec3& s, std::uint32_t f, std::uint32_t v, int n, int rays,
                         bool sparse_only, const CapTurn& turn, std::vector<Vec3>& dirs,
                         std::vector<BundleTarget>& targets) {
  const Plane& pl = faces.planes[f];
  const Vec3 img = s - 2 * (dot(pl.normal, s) - pl.offset) * pl.normal;
  const auto& fs = faces.spheres[f];
  const auto& vs = faces.vehicle_spheres[v];
  const double cap_v = cap_one_minus_cos(img, vs);
  if (sparse_only && lattice_rays_on_cap(cap_v, rays) >= n) return;
  const TraceScene::Sphere face_sphere{fs.centre, fs.radius + faces.tol[f]};
  const double cap_f = cap_one_minus_cos(img, face_sphere);
  const bool aim_at_face = cap_f < cap_v;
  std::vector<Vec3> aimed;
  const double cap = cap_directions(img, aim_at_face ? face_sphere : vs, n, turn, aimed);
  const BundleTarget target{faces.refs[f], true, bundle_spacing(cap, n)};
  for (const Vec3& e : aimed) {
    const double den = dot(pl.normal, e);
    if (den == 0) continue;
    const double t = (pl.offset - dot(pl.normal, img)) / den;
    const Vec3 p = img + t * e;
    const Vec3 off = p - face_sphere.centre;
    if (!(t > 0) || dot(off, off) > face_sphere.radius * face_sphere.radius) continue;
    const Vec3 c = vs.centre - img;
    const double along = dot(c, e);
    if (along < t || dot(c, c) - along * along > vs.radius * vs.radius) continue;
    dirs.push_back(normalize(p - s));
    targets.push_back(target);
  }
}

// The first bundles of one source (TracerConfig::vehicle_bundles): at every
// other vehicle the lattice covers with fewer than vehicle_bundle_rays rays,
// and through every static face whose beam the lattice showed reaching one.
void first_bundles(const SnapshotPlan& plan, const ImageFaces& faces, std::uint32_t src,
                   std::vector<BeamVehicle> combos, std::vector<Vec3>& dirs, std::vector<BundleTarget>& targets) {
  const int n = plan.cfg.vehicle_bundle_rays, rays = plan.cfg.rays_per_source;
  const CapTurn turn(plan.cfg.lattice_turn);
  const Vec3 s = plan.nodes[src].position;
  const auto own = static_cast<std::uint32_t>(plan.nodes[src].vehicle);
  for (std::uint32_t v = 0; v < faces.vehicle_spheres.size(); ++v) {
    if (v == own) continue;
    const std::size_t at = dirs.size();
    const double cap = cap_directions(s, faces.vehicle_spheres[v], n, turn, dirs);
    if (lattice_rays_on_cap(cap, rays) >= n) dirs.resize(at);
    targets.resize(dirs.size(), BundleTarget{{v + 1, 0}, false, bundle_spacing(cap, n)});
  }
  if (!plan.cfg.vehicle_bundles_via_faces) return;
  std::sort(combos.begin(), combos.end());
  combos.erase(std::unique(combos.begin(), combos.end()), combos.end());
  for (const BeamVehicle& c : combos)
    if (c.vehicle != own) bundle_through_face(faces, s, c.face, c.vehicle, n, rays, true, turn, dirs, targets);
}

// One round of bundles: each source's rays in tasks of kShootChunk, their
// finds merged into the pass; with `marks`, the (vehicle face, vehicle)
// beams the rays show, per source.
void shoot_bundles(const SnapshotPlan& plan, const ImageFaces& faces, const std::vector<std::vector<Vec3>>& dirs,
                   const std::vector<std::vector<BundleTarget>>& targets, ShootPass& pass,
                   std::vector<std::vector<BeamVehicle>>* marks) {
  struct Job {
    std::uint32_t src;
    std::size_t begin, end;
  };
  std::vector<Job> jobs;
  for (const auto src : plan.sources)
    for (std::size_t b = 0; b < dirs[src].size(); b += kShootChunk)
      jobs.push_back({src, b, std::min(dirs[src].size(), b + kShootChunk)});
  std::vector<ShootFinds> tasks(jobs.size());
  std::vector<std::uint32_t> task_src(jobs.size());
  tbb::parallel_for(std::size_t{0}, jobs.size(), [&](std::size_t t) {
    const Job& j = jobs[t];
    task_src[t] = j.src;
    TracerConfig local = plan.cfg;
    local.specular = true;
    const ShootFeeds feeds{.faces = &faces,
                           .bundle = &targets[j.src],
                           .bundle_marks = marks != nullptr,
                           .spacing_rays = static_cast<std::size_t>(plan.cfg.rays_per_source)};
    shoot_from({plan.scene, plan.em, local, plan.nodes}, j.src, dirs[j.src], j.begin, j.end, feeds, tasks[t]);
  });
  if (marks) {
    marks->assign(plan.n, {});
    for (std::size_t t = 0; t < tasks.size(); ++t) {
      auto& m = (*marks)[task_src[t]];
      m.insert(m.end(), tasks[t].beams.begin(), tasks[t].beams.end());
      tasks[t].beams.clear();
    }
  }
  merge_tasks(plan, tasks, task_src, pass);
}

}  // namespace

void shoot_vehicle_bundles(const SnapshotPlan& plan, const ImageFaces& faces, ShootPass& pass) {
  std::vector<std::vector<Vec3>> dirs(plan.n);
  std::vector<std::vector<BundleTarget>> targets(plan.n);
  tbb::parallel_for(std::size_t{0}, plan.sources.size(), [&](std::size_t k) {
    const auto src = plan.sources[k];
    first_bundles(plan, faces, src, pass.beams.empty() ? std::vector<BeamVehicle>{} : pass.beams[src], dirs[src],
                  targets[src]);
  });
  std::vector<std::vector<BeamVehicle>> marks;
  shoot_bundles(plan, faces, dirs, targets, pass, &marks);
  tbb::parallel_for(std::size_t{0}, plan.sources.size(), [&](std::size_t k) {
    const auto src = plan.sources[k];
    auto& m = marks[src];
    std::sort(m.begin(), m.end());
    m.erase(std::unique(m.begin(), m.end()), m.end());
    dirs[src].clear();
    targets[src].clear();
    const CapTurn turn(plan.cfg.lattice_turn);
    for (const BeamVehicle& c : m)
      bundle_through_face(faces, plan.nodes[src].position, c.face, c.vehicle, plan.cfg.vehicle_bundle_rays,
                          plan.cfg.rays_per_source, false, turn, dirs[src], targets[src]);
  });
  shoot_bundles(plan, faces, dirs, targets, pass, nullptr);
}

}  // namespace raysweep::tracer
