// Channel models of the SINR generator: the traced channel and the 3GPP
// stochastic baselines (TR 36.885 A.1.4, TR 37.885 6.2.1) with spatially
// consistent, hash-driven randomness.
#include "generators/sinr/channel_models.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <mutex>
#include <stdexcept>
#include <unordered_map>
#include <vector>

namespace raysweep::generators::sinr {

const char* channel_model_name(ChannelModelKind k) {
  switch (k) {
    case ChannelModelKind::ray: return "ray";
    case ChannelModelKind::tr36885: return "tr36885";
    case ChannelModelKind::tr37885_urban: return "tr37885-urban";
    case ChannelModelKind::tr37885_highway: return "tr37885-highway";
  }
  return "?";
}

ChannelModelKind parse_channel_model(const std::string& name) {
  for (auto k : {ChannelModelKind::ray, ChannelModelKind::tr36885, ChannelModelKind::tr37885_urban,
                 ChannelModelKind::tr37885_highway})
    if (name == channel_model_name(k)) return k;
  throw std::invalid_argument("unknown channel model '" + name + "' (ray, tr36885, tr37885-urban, tr37885-highway)");
}

std::string SinrModel::label() const {
  return std::string(channel_model_name(kind)) + (los_from_ray ? "+los-from-ray" : "");
}

SinrModel parse_sinr_model(const std::string& s) {
  SinrModel m;
  std::string name = s;
  const std::string suffix = "+los-from-ray";
  if (name.size() > suffix.size() && name.compare(name.size() - suffix.size(), suffix.size(), suffix) == 0) {
    m.los_from_ray = true;
    name.resize(name.size() - suffix.size());
  }
  m.kind = parse_channel_model(name);
  if (m.los_from_ray && m.kind == ChannelModelKind::ray)
    throw std::invalid_argument("'ray+los-from-ray' makes no sense: the ray model is the traced channel");
  return m;
}

// The formulas take distances as given; the models clamp them to min_distance_m
// first (TR 36.885: "pathloss at 3 m is used if distance is less than 3 m").
namespace formulas {

namespace {
double ghz(double fc_hz) { return fc_hz * 1e-9; }
}  // namespace

double tr36885_p_los(double d) { return std::min(18.0 / d, 1.0) * (1.0 - std::exp(-d / 36.0)) + std::exp(-d / 36.0); }

double tr36885_pathloss_db(bool los, double d, double fc_hz, double h_tx_m, double h_rx_m) {
  const double htx = h_tx_m - 1.0, hrx = h_rx_m - 1.0;  // effective heights: ground and vehicles lift the reflection plane
  const double d_bp = 4.0 * htx * hrx * fc_hz / 299792458.0;
  const double f = ghz(fc_hz);
  const double pl_los = d <= d_bp ? 22.7 * std::log10(d) + 27.0 + 20.0 * std::log10(f)
                                  : 40.0 * std::log10(d) + 7.56 - 17.3 * std::log10(htx) - 17.3 * std::log10(hrx) +
                                        2.7 * std::log10(f);
  if (los) return pl_los;
  // No street grid is known, so the Manhattan-grid NLOS of B1 cannot be used; the
  // hexagonal UMi NLOS (M.2135) stands in, never better than LOS.
  return std::max(pl_los, 36.7 * std::log10(d) + 22.7 + 26.0 * std::log10(f));
}

double tr37885_p_los(Tr37885Scenario s, double d) {
  if (s == Tr37885Scenario::urban) return std::min(1.0, 1.05 * std::exp(-0.0114 * d));
  if (d <= 475.0) return std::min(1.0, 2.1013e-6 * d * d - 0.002 * d + 1.0193);
  return std::max(0.0, 0.54 - 0.001 * (d - 475.0));
}

double tr37885_p_nlos(Tr37885Scenario s, double d) {
  if (s == Tr37885Scenario::highway) return 0.0;
  const double l = std::log(d) - 5.0063;
  const double p = 1.0 / (0.0312 * d) * std::exp(-(l * l) / 2.4544);
  // The fitted curve can exceed what LOS leaves; the three probabilities must sum to 1.
  return std::clamp(p, 0.0, 1.0 - tr37885_p_los(s, d));
}

// NLOSV returns the LOS value: its blockage loss is random and added by the model.
double tr37885_pathloss_db(Tr37885Scenario s, std::uint8_t los_class, double d, double fc_hz) {
  const double f = std::log10(ghz(fc_hz)), ld = std::log10(d);
  if (los_class >= 2) return 36.85 + 30.0 * ld + 18.9 * f;  // also for highways when the tracer says NLOS
  return s == Tr37885Scenario::highway ? 32.4 + 20.0 * ld + 20.0 * f : 38.77 + 16.7 * ld + 18.2 * f;
}

Blockage tr37885_nlosv_blockage(double d, double h_tx_m, double h_rx_m, double h_blocker_m) {
  const double extra = std::max(0.0, 15.0 * std::log10(d) - 41.0);
  if (std::min(h_tx_m, h_rx_m) > h_blocker_m) return {0.0, 0.0};
  if (std::max(h_tx_m, h_rx_m) < h_blocker_m) return {9.0 + extra, 4.5};
  return {5.0 + extra, 4.0};
}

double shadowing_sigma_db(ChannelModelKind k, std::uint8_t los_class) {
  if (k == ChannelModelKind::ray) return 0.0;  // the tracer resolves the obstacles shadowing stands for
  return los_class == 0 ? 3.0 : 4.0;
}

}  // namespace formulas

namespace {

using formulas::Tr37885Scenario;
constexpr double kNoGain = -std::numeric_limits<double>::infinity();

LinkState no_channel() { return LinkState{kNoGain, 2, 0.0}; }

double distance(const NodeState& a, const NodeState& b) {
  const double dx = a.x - b.x, dy = a.y - b.y, dz = a.z - b.z;
  return std::sqrt(dx * dx + dy * dy + dz * dz);
}

class RayModel final : public ChannelModel {
 public:
  explicit RayModel(const ChannelTrace& trace) : trace_(trace) {}
  ChannelModelKind kind() const override { return ChannelModelKind::ray; }

  LinkState link(std::size_t frame, std::uint32_t a, std::uint32_t b) const override {
    if (frame >= trace_.frames() || a == b) return no_channel();
    const NodeState* sa = trace_.state(frame, std::min(a, b));
    const NodeState* sb = trace_.state(frame, std::max(a, b));
    if (!sa || !sb) return no_channel();
    LinkState s = no_channel();
    s.distance_m = distance(*sa, *sb);
    const ChannelTrace::Link* l = trace_.link(frame, a, b);
    if (l && !(l->flags & kLinkOutOfRange)) {
      s.gain_db = l->gain_db;
      s.los_class = l->los_class;
    }
    return s;
  }

 private:
  const ChannelTrace& trace_;
};

// splitmix64's finalizer: a counter-based generator, so a draw is a pure function
// of its coordinates and needs no shared state between threads.
std::uint64_t mix(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

double standard_normal(std::uint64_t seed, std::uint64_t pair, std::uint64_t frame, std::uint64_t process) {
  const std::uint64_t h1 = mix(mix(mix(mix(seed) ^ pair) ^ frame) ^ process);
  const std::uint64_t h2 = mix(h1);
  const double u1 = (static_cast<double>(h1 >> 11) + 0.5) * 0x1p-53;  // (0, 1): log stays finite
  const double u2 = static_cast<double>(h2 >> 11) * 0x1p-53;
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(6.283185307179586 * u2);
}

class StochasticModel final : public ChannelModel {
 public:
  StochasticModel(ChannelModelKind kind, const ChannelTrace& trace, const StochasticOptions& o)
      : kind_(kind), trace_(trace), opt_(o), first_(trace.nodes().size(), kNever), last_(trace.nodes().size(), 0) {
    for (std::size_t f = 0; f < trace.frames(); ++f)
      for (const NodeState* s = trace.states_begin(f); s != trace.states_end(f); ++s) {
        if (first_[s->node] == kNever) first_[s->node] = f;
        last_[s->node] = f;
      }
  }
  ChannelModelKind kind() const override { return kind_; }

  LinkState link(std::size_t frame, std::uint32_t a, std::uint32_t b) const override {
    if (frame >= trace_.frames() || a == b) return no_channel();
    if (a > b) std::swap(a, b);
    const NodeState* sa = trace_.state(frame, a);
    const NodeState* sb = trace_.state(frame, b);
    if (!sa || !sb) return no_channel();
    const Sequence& q = sequence(a, b);
    const Entry& e = q.entries[frame - q.first];
    return LinkState{e.gain_db, e.los_class, distance(*sa, *sb)};
  }

 private:
  struct Entry {
    float gain_db;
    std::uint8_t los_class;
  };
  // A pair's channel over the frames from its first to its last common frame.
  struct Sequence {
    std::size_t first = 0;
    std::vector<Entry> entries;
  };
  struct Shard {
    std::mutex mutex;
    std::unordered_map<std::uint64_t, Sequence> pairs;  // node-based: references survive rehashing
  };
  static constexpr std::size_t kNever = std::numeric_limits<std::size_t>::max();
  static constexpr std::size_t kShards = 64;

  ChannelModelKind kind_;
  const ChannelTrace& trace_;
  StochasticOptions opt_;
  std::vector<std::size_t> first_, last_;  // per node: first and last frame it is present in
  mutable std::array<Shard, kShards> shards_;

  // Computing outside the lock lets threads work on different pairs at once; a
  // pair computed twice concurrently gives the same sequence, the first one stays.
  const Sequence& sequence(std::uint32_t a, std::uint32_t b) const {
    const std::uint64_t key = (std::uint64_t{a} << 32) | b;
    Shard& shard = shards_[mix(key) % kShards];
    {
      std::lock_guard<std::mutex> lock(shard.mutex);
      if (auto it = shard.pairs.find(key); it != shard.pairs.end()) return it->second;
    }
    Sequence q = compute(a, b, key);
    std::lock_guard<std::mutex> lock(shard.mutex);
    return shard.pairs.emplace(key, std::move(q)).first->second;
  }

  Sequence compute(std::uint32_t a, std::uint32_t b, std::uint64_t key) const {
    Sequence q;
    q.first = std::max(first_[a], first_[b]);
    const std::size_t last = std::min(last_[a], last_[b]);
    if (q.first == kNever || last < q.first) return q;
    q.entries.reserve(last - q.first + 1);
    double z[3] = {0, 0, 0};  // LoS draw, shadowing, blockage
    const NodeState* prev_a = nullptr;
    const NodeState* prev_b = nullptr;
    for (std::size_t f = q.first; f <= last; ++f) {
      const NodeState* sa = trace_.state(f, a);
      const NodeState* sb = trace_.state(f, b);
      if (!sa || !sb) {
        q.entries.push_back({static_cast<float>(kNoGain), 2});
        prev_a = prev_b = nullptr;  // the processes restart when the pair reappears
        continue;
      }
      double rho = 0;
      if (prev_a && opt_.decorrelation_m > 0)
        rho = std::exp(-(distance(*sa, *prev_a) + distance(*sb, *prev_b)) / opt_.decorrelation_m);
      const double innovation = std::sqrt(1.0 - rho * rho);  // keeps every z standard normal
      for (std::uint64_t k = 0; k < 3; ++k) z[k] = rho * z[k] + innovation * standard_normal(opt_.seed, key, f, k);
      q.entries.push_back(evaluate(f, a, b, *sa, *sb, z));
      prev_a = sa;
      prev_b = sb;
    }
    return q;
  }

  Entry evaluate(std::size_t f, std::uint32_t a, std::uint32_t b, const NodeState& sa, const NodeState& sb,
                 const double z[3]) const {
    const double dx = sa.x - sb.x, dy = sa.y - sb.y;
    const double d3 = std::max(opt_.min_distance_m, distance(sa, sb));
    const double d2 = std::max(opt_.min_distance_m, std::sqrt(dx * dx + dy * dy));
    const bool r36 = kind_ == ChannelModelKind::tr36885;
    const Tr37885Scenario scen =
        kind_ == ChannelModelKind::tr37885_highway ? Tr37885Scenario::highway : Tr37885Scenario::urban;
    std::uint8_t cls = 2;
    if (opt_.los_from_ray) {
      const ChannelTrace::Link* l = trace_.link(f, a, b);
      if (l && !(l->flags & kLinkOutOfRange) && l->los_class < 2) cls = l->los_class;
    } else {
      const double u = 0.5 * std::erfc(-z[0] / std::sqrt(2.0));  // Phi(z): uniform, correlated like z
      if (r36) {
        cls = u < formulas::tr36885_p_los(d2) ? 0 : 2;
      } else {
        const double p_los = formulas::tr37885_p_los(scen, d2);
        const double p_nlosv = 1.0 - p_los - formulas::tr37885_p_nlos(scen, d2);
        cls = u < p_los ? 0 : u < p_los + p_nlosv ? 1 : 2;
      }
    }
    if (r36 && cls == 1) cls = 2;  // two-state model
    const double h = opt_.antenna_height_m;
    double loss = 0;
    if (r36) {
      loss = formulas::tr36885_pathloss_db(cls == 0, d3, trace_.carrier_hz(), h, h);
    } else {
      loss = formulas::tr37885_pathloss_db(scen, cls, d3, trace_.carrier_hz());
      if (cls == 1) {
        const auto blk = formulas::tr37885_nlosv_blockage(d3, h, h, opt_.blocker_height_m);
        loss += std::max(0.0, blk.mean_db + blk.sigma_db * z[2]);
      }
    }
    if (opt_.shadowing) loss += formulas::shadowing_sigma_db(kind_, cls) * z[1];
    return Entry{static_cast<float>(-loss), cls};
  }
};

}  // namespace

std::unique_ptr<ChannelModel> make_channel_model(ChannelModelKind kind, const ChannelTrace& trace,
                                                 const StochasticOptions& options) {
  if (kind == ChannelModelKind::ray) return std::make_unique<RayModel>(trace);
  const std::string name = channel_model_name(kind);
  if (!(trace.carrier_hz() > 0)) throw std::invalid_argument(name + ": the trace has no carrier frequency");
  if (!(options.min_distance_m > 0)) throw std::invalid_argument(name + ": min_distance_m must be positive");
  if (!(options.decorrelation_m >= 0)) throw std::invalid_argument(name + ": decorrelation_m must be >= 0");
  if (kind == ChannelModelKind::tr36885 && !(options.antenna_height_m > 1.0))
    throw std::invalid_argument(name + ": antenna_height_m must exceed the 1 m effective-height offset");
  return std::make_unique<StochasticModel>(kind, trace, options);
}

}  // namespace raysweep::generators::sinr
