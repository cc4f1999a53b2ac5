// The direct path, with the vehicles in its first Fresnel zone as knife
// edges (ITU-R P.526, Deygout: tracer/src/fresnel_zone.hpp).
#include <cmath>

#include "exact_path.hpp"
#include "mechanisms/mechanism.hpp"

namespace raysweep::tracer {

namespace {

class Direct final : public Mechanism {
 public:
  void prepare(SnapshotPlan&, SnapshotStats&) override {}

  void add_paths(const SnapshotPlan& plan, const PairTrace& pair, PairResult& res) const override {
    const Node &a = plan.nodes[pair.tx], &b = plan.nodes[pair.rx];
    ++res.candidates;
    bool over = false;
    if (auto path = compute_path(plan.scene, plan.em, plan.cfg, a, b, {}, &over, pair.rays)) {
      path->origin.kind = PathOrigin::Kind::direct;
      res.paths.push_back(std::move(*path));
    }
    else if (over)
      ++res.dropped_transmission_cap;
    if (plan.cfg.vehicle_diffraction && res.los_class != LosClass::NLOS &&
        -std::sqrt(2.0) * pair.zone.vehicle_clearance > kKnifeEdgeOnset)
      add_knife_edges(plan, pair, res);
  }

  double SnapshotStats::Timing::*pair_time() const override { return &SnapshotStats::Timing::exact; }

 private:
  // A direct ray that only vehicles block is traced through them and
  // attenuated; when it also crosses their windows, the stronger of the two
  // is kept.
  static void add_knife_edges(const SnapshotPlan& plan, const PairTrace& pair, PairResult& res) {
    const Node &a = plan.nodes[pair.tx], &b = plan.nodes[pair.rx];
    const auto ke = plan.obstacles.vehicle_knife_edges(a.position, b.position, plan.lambda, a.vehicle, b.vehicle);
    if (!(ke.loss_db > 0)) return;
    res.vehicle_loss_db = ke.loss_db;
    const double scale = std::pow(10.0, -ke.loss_db / 20);
    const bool have = !res.paths.empty() && res.paths.front().interactions.empty();
    if (res.los_class == LosClass::LOS && have) {
      res.paths.front().a *= scale;
    } else if (auto direct = exact_path(plan.scene, plan.em, plan.cfg, a, b, {}, nullptr, pair.rays, true)) {
      direct->a *= scale;
      direct->origin.kind = PathOrigin::Kind::direct;
      if (!have) res.paths.insert(res.paths.begin(), std::move(*direct));
      else if (std::norm(direct->a) > std::norm(res.paths.front().a)) res.paths.front() = std::move(*direct);
    }
  }
};

}  // namespace

std::unique_ptr<Mechanism> make_direct(const TracerConfig& cfg) {
  return cfg.los ? std::make_unique<Direct>() : nullptr;
}

}  // namespace raysweep::tracer
