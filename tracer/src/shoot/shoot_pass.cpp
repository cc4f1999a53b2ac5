#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>

#include "search/image_search.hpp"
#include "search/visibility.hpp"
#include "shoot/shoot.hpp"
#include "shoot/vehicle_bundles.hpp"
#include "snapshot_plan.hpp"

namespace raysweep::tracer {

namespace {

// Per source, the receivers its rays gather diffuse power for: the lower
// end's rays gather towards the higher end, and with both ends on, the
// higher end's rays towards the lower.
std::vector<DiffuseTargets> diffuse_targets(const SnapshotPlan& plan) {
  const auto& cfg = plan.cfg;
  std::vector<DiffuseTargets> targets(plan.n);
  for (std::size_t p = 0; p < plan.pairs.size(); ++p) {
    if (!plan.in_range[p]) continue;
    auto [i, j] = plan.pairs[p];
    targets[i].rx.push_back(j);
    if (cfg.diffuse_both_ends) targets[j].rev.push_back(i);
  }
  for (auto& t : targets) {
    std::sort(t.rx.begin(), t.rx.end());
    std::sort(t.rev.begin(), t.rev.end());
    t.both_ends = cfg.diffuse_both_ends;
    t.first_order = !plan.tile_diffuse;
    t.bin_s = 1.0 / plan.radio.bandwidth_hz;
    t.roulette = roulette_power(cfg, plan.radio);
  }
  return targets;
}

// The rough static faces one convex face hides whole from each source: the
// diffuse gathering's shadow rays from them to it are blocked, so not cast.
// With the image search's slab bounds, a face they bound by one slab or more
// (a convex face across every segment to it, first in line or not).
std::vector<std::vector<std::uint64_t>> hidden_faces(const SnapshotPlan& plan) {
  const auto& faces = plan.faces();
  const SlabBounds* slabs = plan.image_search ? &plan.slab_bounds() : nullptr;
  std::vector<std::vector<std::uint64_t>> hidden(plan.n);
  tbb::parallel_for(std::uint32_t{0}, plan.n, [&](std::uint32_t j) {
    if (!plan.is_source[j]) return;
    auto& bits = hidden[j];
    bits.assign((faces.static_count + 63) / 64, 0);
    for (std::uint32_t f = 0; f < faces.static_count; ++f) {
      if (!(plan.em.material(plan.scene.material(faces.refs[f])).scattering.s > 0)) continue;
      const FaceRef self{0, f};
      if (slabs ? slabs->at(j, f) >= 1
                : hidden_by_convex_face(plan.scene, faces, plan.nodes[j].position,
                                        &faces.outline[faces.outline_begin[f]],
                                        faces.outline_begin[f + 1] - faces.outline_begin[f], &self, faces.tol[f]))
        bits[f >> 6] |= std::uint64_t{1} << (f & 63);
    }
  });
  return hidden;
}

constexpr std::size_t kNoSlot = ~std::size_t{0};

// The pair slot of each task's finds (kNoSlot: no requested, in-range pair,
// or a sequence the image search already enumerated completely), with the
// sequences and bins turned to run from the pair's lower end.
void slot_finds(const SnapshotPlan& plan, const ImageFaces* image_faces, std::uint32_t src, ShootFinds& out,
                std::vector<std::size_t>& found_slot, std::vector<std::size_t>& bin_slot) {
  const auto& cfg = plan.cfg;
  found_slot.assign(out.found.size(), kNoSlot);
  for (std::size_t q = 0; q < out.found.size(); ++q) {
    auto& k = out.found[q];
    if (image_faces && image_complete(plan.scene, *image_faces, k.faces, cfg.ground_order3 && cfg.max_depth >= 3))
      continue;
    const std::uint32_t a = std::min(src, k.other), b = std::max(src, k.other);
    const auto it = plan.slot.find(SnapshotPlan::key(a, b));
    if (it == plan.slot.end() || !plan.in_range[it->second]) continue;
    if (src > k.other) std::reverse(k.faces.begin(), k.faces.end());
    found_slot[q] = it->second;
  }
  bin_slot.assign(out.bins.size(), kNoSlot);
  for (std::size_t q = 0; q < out.bins.size(); ++q) {
    auto& dk = out.bins[q].first;
    // Both ends' samples of a pair's bin merge into one record.
    const std::uint32_t a = dk.reverse ? dk.rx : src, b = dk.reverse ? src : dk.rx;
    const auto it = plan.slot.find(SnapshotPlan::key(a, b));
    if (it == plan.slot.end()) continue;
    dk.rx = b;
    dk.reverse = false;
    bin_slot[q] = it->second;
  }
}

// Per pair, its entries in task order: (task, index) lists by counting.
struct Entry {
  std::uint32_t task, index;
};
struct Grouped {
  std::vector<std::size_t> begin;  // pair p's entries: [begin[p], begin[p + 1])
  std::vector<Entry> entries;
};
Grouped group_by_pair(const std::vector<std::vector<std::size_t>>& slots, std::size_t pairs) {
  std::vector<std::size_t> begin(pairs + 1, 0);
  for (const auto& v : slots)
    for (auto sl : v)
      if (sl != kNoSlot) ++begin[sl + 1];
  for (std::size_t p = 0; p < pairs; ++p) begin[p + 1] += begin[p];
  std::vector<Entry> entries(begin.back());
  std::vector<std::size_t> at(begin.begin(), begin.end() - 1);
  for (std::size_t t = 0; t < slots.size(); ++t)
    for (std::size_t q = 0; q < slots[t].size(); ++q)
      if (slots[t][q] != kNoSlot)
        entries[at[slots[t][q]]++] = Entry{static_cast<std::uint32_t>(t), static_cast<std::uint32_t>(q)};
  return Grouped{std::move(begin), std::move(entries)};
}

}  // namespace

// Merged in task order, so the sums are the same for any thread count; the
// slot lookups run per task and the merging per pair, both in parallel (a
// serial merge held one core idle for 20-30 ms).
void merge_tasks(const SnapshotPlan& plan, std::vector<ShootFinds>& tasks, const std::vector<std::uint32_t>& task_src,
                 ShootPass& pass) {
  // The image search enumerated these sequences completely already.
  const ImageFaces* image_faces = plan.image_search ? &plan.faces() : nullptr;
  std::vector<std::vector<std::size_t>> found_slot(tasks.size()), bin_slot(tasks.size());
  tbb::parallel_for(std::size_t{0}, tasks.size(), [&](std::size_t task) {
    slot_finds(plan, image_faces, task_src[task], tasks[task], found_slot[task], bin_slot[task]);
  });
  const Grouped found_by_pair = group_by_pair(found_slot, plan.pairs.size());
  const Grouped bins_by_pair = group_by_pair(bin_slot, plan.pairs.size());
  tbb::parallel_for(std::size_t{0}, plan.pairs.size(), [&](std::size_t p) {
    for (std::size_t e = found_by_pair.begin[p]; e < found_by_pair.begin[p + 1]; ++e) {
      const Entry& en = found_by_pair.entries[e];
      pass.candidates[p].push_back(std::move(tasks[en.task].found[en.index].faces));
    }
    for (std::size_t e = bins_by_pair.begin[p]; e < bins_by_pair.begin[p + 1]; ++e) {
      const Entry& en = bins_by_pair.entries[e];
      const auto& bin = tasks[en.task].bins[en.index];
      pass.diffuse[p][bin.first].add(bin.second);
    }
  });
  for (std::size_t task = 0; task < tasks.size(); ++task) {
    pass.rays += tasks[task].rays;
    if (!pass.beams.empty()) {
      auto& b = pass.beams[task_src[task]];
      b.insert(b.end(), tasks[task].beams.begin(), tasks[task].beams.end());
    }
    if (!pass.beam_pairs.empty()) {
      auto& b = pass.beam_pairs[task_src[task]];
      b.insert(b.end(), tasks[task].beam_pairs.begin(), tasks[task].beam_pairs.end());
    }
  }
  tbb::parallel_for(std::size_t{0}, tasks.size(), [&](std::size_t t) { tasks[t] = ShootFinds{}; });
}

ShootPass run_shoot_pass(const SnapshotPlan& plan) {
  const auto& cfg = plan.cfg;
  const auto t0 = std::chrono::steady_clock::now();
  ShootPass pass;
  pass.candidates.resize(plan.pairs.size());
  pass.diffuse.resize(plan.ray_diffuse ? plan.pairs.size() : 0);
  // A static face then any vehicle: the rays say which combinations can
  // exist, the image method enumerates their faces exactly.
  const bool beam_search = plan.image_search && cfg.max_depth >= 2;
  // A static face, then a static or vehicle face, then the third (order 3).
  const bool triple_search = beam_search && cfg.max_depth >= 3 && cfg.beam_order3;
  pass.beams.resize(beam_search ? plan.n : 0);
  pass.beam_pairs.resize(triple_search ? plan.n : 0);
  if (!(plan.sbr_specular || plan.ray_diffuse) || plan.n <= 1) return pass;
  std::vector<DiffuseTargets> targets;
  std::vector<std::vector<std::uint64_t>> hidden;
  if (plan.ray_diffuse) {
    targets = diffuse_targets(plan);
    hidden = hidden_faces(plan);
    for (auto& t : targets) t.hidden = &hidden;
  }
  // Lattice 0 is the frame's own; the others (TracerConfig::diffuse_turns)
  // only gather diffuse power, every lattice's samples weighted alike.
  const bool more = plan.ray_diffuse && !cfg.diffuse_turns.empty();
  std::vector<std::uint64_t> turns{cfg.lattice_turn};
  if (more) turns.insert(turns.end(), cfg.diffuse_turns.begin(), cfg.diffuse_turns.end());
  // The roulette's threshold scales with a sample's weight: each lattice's
  // samples meet the roulette as a lattice of its own would, so the mean of
  // D lattices has 1 / D of the roulette's variance too.
  for (auto& t : targets) {
    t.share = 1.0 / static_cast<double>(turns.size());
    t.roulette *= t.share;
  }
  std::vector<std::vector<Vec3>> lattices;
  for (auto turn : turns) lattices.push_back(fibonacci_sphere(cfg.rays_per_source, turn));
  const std::size_t chunk = kShootChunk, chunks = (cfg.rays_per_source + chunk - 1) / chunk;
  const std::size_t per_lattice = plan.sources.size() * chunks;
  std::vector<ShootFinds> tasks(per_lattice * lattices.size());
  const ImageFaces* faces = beam_search ? &plan.faces() : nullptr;
  tbb::parallel_for(std::size_t{0}, tasks.size(), [&](std::size_t task) {
    const std::size_t l = task / per_lattice, in = task % per_lattice;
    const auto src = plan.sources[in / chunks];
    const std::size_t c = in % chunks;
    const auto& lattice = lattices[l];
    ShootFinds& out = tasks[task];
    TracerConfig local = cfg;
    local.specular = plan.sbr_specular;
    const ShootFeeds feeds{.diffuse = plan.ray_diffuse ? &targets[src] : nullptr,
                           .faces = l == 0 ? faces : nullptr,
                           .beams = l == 0 && beam_search,
                           .beam_pairs = l == 0 && triple_search,
                           .propose = l == 0,
                           .sample_salt = more ? turns[l] : 0};
    shoot_from({plan.scene, plan.em, local, plan.nodes}, src, lattice, c * chunk,
               std::min(lattice.size(), (c + 1) * chunk), feeds, out);
    if (!plan.sbr_specular) out.found.clear();
  });
  std::vector<std::uint32_t> task_src(tasks.size());
  for (std::size_t t = 0; t < tasks.size(); ++t) task_src[t] = plan.sources[(t % per_lattice) / chunks];
  merge_tasks(plan, tasks, task_src, pass);
  if (faces && plan.sbr_specular && cfg.vehicle_bundles) shoot_vehicle_bundles(plan, *faces, pass);
  pass.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return pass;
}

}  // namespace raysweep::tracer
