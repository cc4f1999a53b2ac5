// Diffuse scattering (effective roughness): first-order scattering
// integrated over surface tiles (tracer/src/diffuse_tiles.hpp) and / or the
// power the shoot-and-bounce rays gathered at their hits
// (tracer/src/shoot/), as one record per scattering object and delay bin.
#include <chrono>
#include <optional>

#include "diffuse_tiles.hpp"
#include "mechanisms/mechanism.hpp"

namespace raysweep::tracer {

namespace {

class Diffuse final : public Mechanism {
 public:
  void prepare(SnapshotPlan& plan, SnapshotStats& stats) override {
    if (plan.n < 2) return;
    if (plan.tile_diffuse) {
      const auto t0 = std::chrono::steady_clock::now();
      tiles_.emplace(plan.scene, plan.em, plan.nodes, plan.is_source, plan.cfg, plan.range);
      plan.search_rays += tiles_->rays();
      stats.diffuse_tiles = tiles_->tile_count();
      stats.diffuse_views = tiles_->views();
      stats.time.diffuse_views = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    }
    if (plan.ray_diffuse) gathered_ = &plan.shoot().diffuse;
  }

  void add_paths(const SnapshotPlan& plan, const PairTrace& pair, PairResult& res) const override {
    const std::size_t first = res.paths.size();
    if (tiles_) tiles_->pair_paths(pair.tx, pair.rx, 1.0 / plan.radio.bandwidth_hz, res.paths);
    if (gathered_) add_gathered(plan, (*gathered_)[pair.slot], res);
    for (std::size_t q = first; q < res.paths.size(); ++q) res.paths[q].origin.kind = PathOrigin::Kind::diffuse;
  }

  double SnapshotStats::Timing::*pair_time() const override { return &SnapshotStats::Timing::diffuse; }

 private:
  // The rays' records of one pair, each named by its strongest sample's
  // chain of interactions.
  static void add_gathered(const SnapshotPlan& plan, const std::map<DiffuseKey, DiffuseAcc>& records,
                           PairResult& res) {
    const auto& scene = plan.scene;
    for (const auto& entry : records) {
      const DiffuseAcc& acc = entry.second;
      if (!(acc.power > 0)) continue;
      Path path = diffuse_record(acc.power, acc.tau, acc.departure, acc.arrival, acc.doppler, plan.lambda);
      const double w = 1.0 / acc.power;
      const FaceRef last = acc.faces[acc.n - 1];
      const Interaction scatter{InteractionType::diffuse, scene.object(last), scene.material(last), w * acc.point};
      const auto reflection = [&](int q) {
        return Interaction{InteractionType::specular, scene.object(acc.faces[q]), scene.material(acc.faces[q]),
                           acc.prefix[q]};
      };
      if (acc.scatter_first) {  // scattered first, then the reflections in reverse order
        path.interactions.push_back(scatter);
        for (int q = acc.n - 2; q >= 0; --q) path.interactions.push_back(reflection(q));
      } else {
        for (int q = 0; q + 1 < acc.n; ++q) path.interactions.push_back(reflection(q));
        path.interactions.push_back(scatter);
      }
      res.paths.push_back(std::move(path));
    }
  }

  std::optional<DiffuseTiles> tiles_;
  const std::vector<std::map<DiffuseKey, DiffuseAcc>>* gathered_ = nullptr;
};

}  // namespace

std::unique_ptr<Mechanism> make_diffuse(const TracerConfig& cfg) {
  return cfg.diffuse && cfg.max_depth > 0 ? std::make_unique<Diffuse>() : nullptr;
}

}  // namespace raysweep::tracer
