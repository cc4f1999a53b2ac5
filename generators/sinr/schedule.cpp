#include "generators/sinr/schedule.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <queue>
#include <stdexcept>
#include <string>

namespace raysweep::generators::sinr {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr float kNoGain = -std::numeric_limits<float>::infinity();
// A transmission becomes visible to clear-channel assessment this long after it
// starts (aCCATime of the 10 MHz OFDM PHY): two stations whose backoff ends within
// it both transmit, as in the slotted real protocol.
constexpr double kCcaDelayS = 8e-6;
constexpr double kEps = 1e-12;

double mw(double dbm) { return std::pow(10.0, dbm / 10.0); }

// Deterministic per-node random stream (splitmix64), the same on every platform.
struct Rng {
  std::uint64_t s;
  explicit Rng(std::uint64_t seed) : s(seed) {}
  std::uint64_t next() {
    std::uint64_t z = (s += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
  }
  double uniform() { return static_cast<double>(next() >> 11) * 0x1.0p-53; }
  int below(int n) { return n <= 1 ? 0 : static_cast<int>(uniform() * n); }
  int between(int lo, int hi) { return lo + below(hi - lo + 1); }
};

void fill_gains(const ChannelTrace& trace, const ChannelModel& channel, std::uint32_t sender, double t,
                std::uint32_t nodes, float* out) {
  const std::size_t f = trace.frame_at(t);
  const bool sender_present = trace.time(f) <= t + kEps && trace.state(f, sender) != nullptr;
  for (std::uint32_t n = 0; n < nodes; ++n) {
    out[n] = kNoGain;
    if (!sender_present || n == sender || !trace.state(f, n)) continue;
    out[n] = static_cast<float>(channel.link(f, sender, n).gain_db);
  }
}

void fill_all_gains(const ChannelTrace& trace, const ChannelModel& channel, const std::vector<Transmission>& tx,
                    std::uint32_t nodes, std::vector<float>& gains) {
  gains.assign(tx.size() * std::size_t{nodes}, kNoGain);
  tbb::parallel_for(std::size_t{0}, tx.size(), [&](std::size_t i) {
    fill_gains(trace, channel, tx[i].node, tx[i].start_s, nodes, gains.data() + i * nodes);
  });
}

// ---------------------------------------------------------------------------
// NR-V2X Mode 2 SPS.

struct NrGrant {
  bool active = false;
  std::int64_t first_slot = 0;  // occasion k is at first_slot + k * period
  std::int64_t next_index = 0;  // first occasion not yet used or passed
  int sub_first = 0, sub_count = 0;
  int counter = 0;
  std::vector<int> retx;        // slot offsets of the blind retransmissions after an occasion
  double last_tx_s = -kInf, prev_tx_s = -kInf;  // the grant's last two transmissions
  std::int64_t occasion(std::int64_t k, std::int64_t period) const { return first_slot + k * period; }
};

class NrScheduler {
 public:
  NrScheduler(const ChannelTrace& trace, const ChannelModel& channel, const SinrConfig& c, std::uint32_t nodes)
      : trace_(trace), channel_(channel), c_(c), grants_(nodes), rng_() {
    rng_.reserve(nodes);
    for (std::uint32_t n = 0; n < nodes; ++n)
      rng_.emplace_back(static_cast<std::uint64_t>(hash_uniform(c.seed, 0x5B5, n) * 0x1.0p53));
    slot_ = c.nr.slot_s();
    period_ = std::max<std::int64_t>(1, std::llround(c.nr_mac.reservation_period_s / slot_));
    t2_ = c.nr_mac.t2_slots > 0 ? c.nr_mac.t2_slots : period_;
    counters_ = sps_counter_range(c.nr_mac.reservation_period_s);
  }

  void add(const GeneratedMessage& m, std::uint64_t packet, std::vector<Transmission>& out, Schedule& s) {
    const int need = c_.nr.subchannels_for(m.bytes);
    if (need > c_.nr.subchannels()) {
      ++s.nr_dropped;
      return;
    }
    NrGrant& g = grants_[m.node];
    Rng& rng = rng_[m.node];
    // n: the slot in which the packet arrives (selection is triggered there).
    const std::int64_t n = static_cast<std::int64_t>(std::floor(m.t / slot_ + 1e-9));
    const std::int64_t earliest = n + c_.nr_mac.t1_slots;
    if (g.active && need > g.sub_count) g.active = false;  // the packet does not fit: reselect
    // Occasions that passed unused still count down the reservation.
    while (g.active && g.occasion(g.next_index, period_) < earliest) {
      ++g.next_index;
      count_down(g, rng);
    }
    if (!g.active) select(m, n, need, g, rng);
    const std::int64_t slot = g.occasion(g.next_index, period_);
    ++g.next_index;
    emit(m, packet, slot, 0, g, out);
    for (std::size_t r = 0; r < g.retx.size(); ++r) emit(m, packet, slot + g.retx[r], static_cast<int>(r + 1), g, out);
    g.prev_tx_s = g.last_tx_s;
    g.last_tx_s = static_cast<double>(slot) * slot_;
    latency_sum_ += static_cast<double>(slot) * slot_ - m.t;
    ++sent_;
    count_down(g, rng);
  }

  double mean_latency() const { return sent_ ? latency_sum_ / static_cast<double>(sent_) : 0.0; }

 private:
  const ChannelTrace& trace_;
  const ChannelModel& channel_;
  const SinrConfig& c_;
  std::vector<NrGrant> grants_;
  std::vector<Rng> rng_;
  double slot_ = 0;
  std::int64_t period_ = 1, t2_ = 1;
  std::pair<int, int> counters_;
  double latency_sum_ = 0;
  std::uint64_t sent_ = 0;

  void count_down(NrGrant& g, Rng& rng) {
    if (--g.counter > 0) return;
    if (rng.uniform() < c_.nr_mac.keep_probability)
      g.counter = rng.between(counters_.first, counters_.second);
    else
      g.active = false;
  }

  void emit(const GeneratedMessage& m, std::uint64_t packet, std::int64_t slot, int attempt, const NrGrant& g,
            std::vector<Transmission>& out) const {
    Transmission t;
    t.node = m.node;
    t.rat = Rat::nr_v2x;
    t.message = m.message;
    t.packet = packet;
    t.attempt = static_cast<std::uint8_t>(attempt);
    t.size_bytes = m.bytes;
    t.start_s = static_cast<double>(slot) * slot_;
    t.duration_s = slot_;
    t.f_lo_hz = c_.nr.f_lo_hz(g.sub_first);
    t.f_hi_hz = c_.nr.f_hi_hz(g.sub_first, g.sub_count);
    t.power_dbm = c_.tx_power_dbm;
    out.push_back(t);
  }

  // Candidate single-slot resources in [n + T1, n + T2] x subchannel starts; with
  // sensing, those reserved by UEs heard above the RSRP threshold are excluded.
  void select(const GeneratedMessage& m, std::int64_t n, int need, NrGrant& g, Rng& rng) {
    const std::int64_t w0 = n + c_.nr_mac.t1_slots, w1 = n + t2_;
    const int starts = c_.nr.subchannels() - need + 1;
    const std::int64_t slots = w1 - w0 + 1;
    std::vector<char> excluded(static_cast<std::size_t>(slots * starts), 0);
    if (c_.nr_mac.sensing) exclude_sensed(m, w0, w1, need, starts, excluded);
    std::vector<std::size_t> free;
    for (std::size_t i = 0; i < excluded.size(); ++i)
      if (!excluded[i]) free.push_back(i);
    if (free.empty()) free.resize(excluded.size()), std::iota(free.begin(), free.end(), std::size_t{0});
    const std::size_t pick = free[static_cast<std::size_t>(rng.below(static_cast<int>(free.size())))];
    g.active = true;
    g.last_tx_s = g.prev_tx_s = -kInf;
    g.first_slot = w0 + static_cast<std::int64_t>(pick) / starts;
    g.next_index = 0;
    g.sub_first = static_cast<int>(pick % static_cast<std::size_t>(starts));
    g.sub_count = need;
    g.counter = rng.between(counters_.first, counters_.second);
    // Blind retransmissions: distinct later slots within 32 slots of the first (TS 38.214 8.1.4).
    g.retx.clear();
    std::vector<int> offsets;
    for (int o = 1; o <= 31 && o < period_; ++o) offsets.push_back(o);
    for (int r = 0; r < c_.nr_mac.retransmissions && !offsets.empty(); ++r) {
      const int i = rng.below(static_cast<int>(offsets.size()));
      g.retx.push_back(offsets[static_cast<std::size_t>(i)]);
      offsets.erase(offsets.begin() + i);
    }
    std::sort(g.retx.begin(), g.retx.end());
  }

  void exclude_sensed(const GeneratedMessage& m, std::int64_t w0, std::int64_t w1, int need, int starts,
                      std::vector<char>& excluded) const {
    struct Reserved {
      double rsrp_dbm;
      std::vector<std::int64_t> slots;
      int sub_first, sub_count;
    };
    std::vector<Reserved> heard;
    const std::size_t f = trace_.frame_at(m.t);
    for (std::uint32_t j = 0; j < grants_.size(); ++j) {
      const NrGrant& o = grants_[j];
      // The SCI of the grant's latest transmission already sent announces the reservation.
      const double heard_at = o.last_tx_s <= m.t ? o.last_tx_s : o.prev_tx_s;
      if (j == m.node || !o.active || heard_at < m.t - c_.nr_mac.sensing_window_s) continue;
      if (!trace_.state(f, j) || !trace_.state(f, m.node)) continue;
      const double res = 12.0 * o.sub_count * c_.nr.subchannel_rbs;
      const double rsrp = c_.tx_power_dbm - 10.0 * std::log10(res) + channel_.link(f, j, m.node).gain_db;
      Reserved r{rsrp, {}, o.sub_first, o.sub_count};
      // The reservation announced in the SCI: the next occasions and their retransmissions.
      for (std::int64_t k = std::max<std::int64_t>(0, o.next_index - 1);; ++k) {
        const std::int64_t s = o.occasion(k, period_);
        if (s > w1) break;
        r.slots.push_back(s);
        for (int off : o.retx) r.slots.push_back(s + off);
      }
      heard.push_back(std::move(r));
    }
    const std::size_t total = excluded.size();
    for (double thr = c_.nr_mac.sensing_threshold_dbm;; thr += 3.0) {
      std::fill(excluded.begin(), excluded.end(), 0);
      for (const auto& r : heard) {
        if (r.rsrp_dbm <= thr) continue;
        for (std::int64_t s : r.slots) {
          if (s < w0 || s > w1) continue;
          for (int c = 0; c < starts; ++c)
            if (c < r.sub_first + r.sub_count && r.sub_first < c + need)
              excluded[static_cast<std::size_t>((s - w0) * starts + c)] = 1;
        }
      }
      const auto kept = static_cast<double>(std::count(excluded.begin(), excluded.end(), 0));
      if (kept >= c_.nr_mac.min_candidate_ratio * static_cast<double>(total) || thr > 60.0) break;
    }
  }
};

// ---------------------------------------------------------------------------
// IEEE 802.11p EDCA (broadcast).

struct Ongoing {
  std::uint32_t node;
  Rat rat;
  double f_lo, f_hi, power_dbm;
  // Gains to every node: row `offset` of a gain table that may still grow (and
  // reallocate) while the transmission is on the air, so no raw pointer.
  const std::vector<float>* table;
  std::size_t offset;
  std::size_t key;  // identifies the transmission for removal
  float gain(std::uint32_t n) const { return (*table)[offset + n]; }
};

struct WifiNode {
  bool busy = false, transmitting = false;
  double idle_since = -kInf;
  double expiry = kInf;
  std::uint64_t token = 0;
  int backoff = -1;        // remaining backoff slots; -1: none drawn
  std::int64_t pending = -1;  // message index waiting for the medium
};

enum class Ev : int { medium_end = 0, medium_visible = 1, arrival = 2, backoff = 3, tx_end = 4 };

struct Event {
  double t;
  std::uint64_t seq;
  Ev type;
  std::uint32_t node;
  std::uint64_t arg;
  bool operator>(const Event& o) const { return t != o.t ? t > o.t : seq > o.seq; }
};

class WifiSimulator {
 public:
  WifiSimulator(const ChannelTrace& trace, const ChannelModel& channel, const std::vector<Rat>& rats,
                const SinrConfig& c, std::uint32_t nodes)
      : trace_(trace), channel_(channel), c_(c), nodes_(nodes), state_(nodes) {
    const EdcaParams p = edca_params(c.wifi_mac.access_category);
    aifs_ = WifiMacConfig::kSifsS + p.aifsn * WifiMacConfig::kSlotS;
    cw_min_ = p.cw_min;
    for (std::uint32_t n = 0; n < nodes; ++n) {
      if (rats[n] == Rat::wifi80211p) wifi_nodes_.push_back(n);
      rng_.emplace_back(static_cast<std::uint64_t>(hash_uniform(c.seed, 0x11B, n) * 0x1.0p53));
    }
    band_lo_ = c.wifi.f_lo_hz();
    band_hi_ = c.wifi.f_hi_hz();
    cca_energy_mw_ = mw(c.wifi_mac.cca_energy_dbm);
  }

  void run(const std::vector<GeneratedMessage>& messages, const std::vector<Transmission>& nr,
           const std::vector<float>& nr_gains, std::vector<Transmission>& out, std::vector<float>& out_gains,
           Schedule& s) {
    for (std::size_t i = 0; i < messages.size(); ++i)
      if (is_wifi(messages[i].node)) push(messages[i].t, Ev::arrival, messages[i].node, i);
    for (std::size_t i = 0; i < nr.size(); ++i) {
      push(nr[i].start_s + kCcaDelayS, Ev::medium_visible, 0, nr_key(i));
      push(nr[i].end_s(), Ev::medium_end, 0, nr_key(i));
    }
    double latency = 0;
    std::uint64_t sent = 0;
    while (!queue_.empty()) {
      const Event e = queue_.top();
      queue_.pop();
      WifiNode* w = e.type == Ev::arrival || e.type == Ev::backoff ? &state_[e.node] : nullptr;
      switch (e.type) {
        case Ev::arrival:
          if (w->pending >= 0) ++s.wifi_dropped;
          w->pending = static_cast<std::int64_t>(e.arg);
          if (!w->busy && !w->transmitting && e.t - w->idle_since + kEps >= aifs_ && w->backoff < 0) {
            transmit(e.node, e.t, messages, out, out_gains, latency, sent);
          } else {
            if (w->backoff < 0) w->backoff = rng_[e.node].below(cw_min_ + 1);
            if (!w->busy && !w->transmitting) arm(e.node, e.t);
          }
          break;
        case Ev::backoff:
          if (e.arg == w->token && w->pending >= 0) transmit(e.node, e.t, messages, out, out_gains, latency, sent);
          break;
        case Ev::medium_visible:
          add_ongoing(e.arg, nr, nr_gains, out, out_gains);
          update(e.t);
          break;
        case Ev::medium_end:
          remove_ongoing(e.arg);
          update(e.t);
          break;
        case Ev::tx_end: {
          WifiNode& own = state_[e.node];
          own.transmitting = false;
          remove_ongoing(e.arg);
          update(e.t);
          // The station's own frame never made its medium busy, so update() sees no
          // change for it: a message that arrived meanwhile is armed here.
          if (!own.busy) {
            own.idle_since = e.t;
            if (own.pending >= 0) {
              if (own.backoff < 0) own.backoff = rng_[e.node].below(cw_min_ + 1);
              arm(e.node, e.t);
            }
          }
          break;
        }
      }
    }
    s.wifi_mean_latency_s = sent ? latency / static_cast<double>(sent) : 0.0;
  }

 private:
  const ChannelTrace& trace_;
  const ChannelModel& channel_;
  const SinrConfig& c_;
  std::uint32_t nodes_;
  std::vector<WifiNode> state_;
  std::vector<std::uint32_t> wifi_nodes_;
  std::vector<Rng> rng_;
  std::vector<Ongoing> ongoing_;
  std::priority_queue<Event, std::vector<Event>, std::greater<Event>> queue_;
  std::uint64_t seq_ = 0;
  double aifs_ = 0, band_lo_ = 0, band_hi_ = 0, cca_energy_mw_ = 0;
  int cw_min_ = 15;

  static std::uint64_t nr_key(std::size_t i) { return (std::uint64_t{1} << 63) | i; }
  bool is_wifi(std::uint32_t n) const {
    return std::binary_search(wifi_nodes_.begin(), wifi_nodes_.end(), n);
  }
  void push(double t, Ev type, std::uint32_t node, std::uint64_t arg) { queue_.push({t, seq_++, type, node, arg}); }

  // Counts the backoff down from when the medium has been idle for AIFS.
  void arm(std::uint32_t n, double t) {
    WifiNode& w = state_[n];
    w.expiry = std::max(t, w.idle_since + aifs_ + std::max(0, w.backoff) * WifiMacConfig::kSlotS);
    push(w.expiry, Ev::backoff, n, ++w.token);
  }

  void transmit(std::uint32_t n, double t, const std::vector<GeneratedMessage>& messages,
                std::vector<Transmission>& out, std::vector<float>& out_gains, double& latency, std::uint64_t& sent) {
    WifiNode& w = state_[n];
    const GeneratedMessage& m = messages[static_cast<std::size_t>(w.pending)];
    Transmission tx;
    tx.node = n;
    tx.rat = Rat::wifi80211p;
    tx.message = m.message;
    tx.packet = static_cast<std::uint64_t>(w.pending);
    tx.size_bytes = m.bytes;
    tx.start_s = t;
    tx.duration_s = c_.wifi.frame_duration_s(m.bytes);
    tx.f_lo_hz = band_lo_;
    tx.f_hi_hz = band_hi_;
    tx.power_dbm = c_.tx_power_dbm;
    const std::size_t index = out.size();
    out.push_back(tx);
    out_gains.resize(out_gains.size() + nodes_);
    fill_gains(trace_, channel_, n, t, nodes_, out_gains.data() + index * nodes_);
    latency += t - m.t;
    ++sent;
    w.pending = -1;
    w.backoff = -1;
    w.expiry = kInf;
    ++w.token;
    w.transmitting = true;
    push(t + kCcaDelayS, Ev::medium_visible, n, index);
    push(tx.end_s(), Ev::tx_end, n, index);
  }

  void add_ongoing(std::uint64_t key, const std::vector<Transmission>& nr, const std::vector<float>& nr_gains,
                   const std::vector<Transmission>& wifi, const std::vector<float>& wifi_gains) {
    const bool is_nr = key >> 63;
    const std::size_t i = static_cast<std::size_t>(key & ~(std::uint64_t{1} << 63));
    const Transmission& t = is_nr ? nr[i] : wifi[i];
    ongoing_.push_back({t.node, t.rat, t.f_lo_hz, t.f_hi_hz, t.power_dbm, is_nr ? &nr_gains : &wifi_gains,
                        i * nodes_, static_cast<std::size_t>(key)});
  }
  void remove_ongoing(std::uint64_t key) {
    for (std::size_t i = 0; i < ongoing_.size(); ++i)
      if (ongoing_[i].key == static_cast<std::size_t>(key)) {
        ongoing_.erase(ongoing_.begin() + static_cast<std::ptrdiff_t>(i));
        return;
      }
    // A transmission that ends before it became visible (shorter than the CCA delay) is not there.
  }

  bool medium_busy(std::uint32_t n) const {
    double energy = 0;
    for (const auto& o : ongoing_) {
      if (o.node == n) continue;
      const double prx = o.power_dbm + o.gain(n);
      if (o.rat == Rat::wifi80211p && prx >= c_.wifi_mac.cca_signal_dbm) return true;
      energy += mw(prx) * overlap(o.f_lo, o.f_hi, band_lo_, band_hi_) / (o.f_hi - o.f_lo);
    }
    return energy >= cca_energy_mw_;
  }

  void update(double t) {
    for (std::uint32_t n : wifi_nodes_) {
      WifiNode& w = state_[n];
      const bool busy = medium_busy(n);
      if (busy == w.busy) continue;
      w.busy = busy;
      if (busy) {
        if (w.expiry < kInf && w.expiry > t + kEps) {
          // Freeze: the slots counted since AIFS ended are done.
          const double counting_since = w.idle_since + aifs_;
          if (t > counting_since) {
            const int done = static_cast<int>(std::floor((t - counting_since) / WifiMacConfig::kSlotS + 1e-9));
            w.backoff = std::max(0, w.backoff - done);
          }
          w.expiry = kInf;
          ++w.token;
        }
      } else {
        w.idle_since = t;
        if (w.pending >= 0 && !w.transmitting) arm(n, t);
      }
    }
  }
};

}  // namespace

EdcaParams edca_params(const std::string& ac) {
  if (ac == "BK") return {9, 15, 1023};
  if (ac == "BE") return {6, 15, 1023};
  if (ac == "VI") return {3, 7, 15};
  if (ac == "VO") return {2, 3, 7};
  throw std::invalid_argument("802.11p access category '" + ac + "' is not one of BK, BE, VI, VO");
}

std::pair<int, int> sps_counter_range(double period_s) {
  const double p_ms = period_s * 1e3;
  const int m = static_cast<int>(std::ceil(100.0 / std::max(20.0, p_ms) - 1e-9));
  return {5 * m, 15 * m};
}

namespace {

Schedule sorted_schedule(std::vector<Transmission> tx, std::vector<float> gains, std::uint32_t nodes, Schedule s) {
  std::vector<std::size_t> order(tx.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    const Transmission &x = tx[a], &y = tx[b];
    if (x.start_s != y.start_s) return x.start_s < y.start_s;
    if (x.node != y.node) return x.node < y.node;
    if (x.packet != y.packet) return x.packet < y.packet;
    return x.attempt < y.attempt;
  });
  s.nodes = nodes;
  s.transmissions.reserve(tx.size());
  s.gain_db.resize(gains.size());
  for (std::size_t i = 0; i < order.size(); ++i) {
    s.transmissions.push_back(tx[order[i]]);
    std::copy_n(gains.begin() + static_cast<std::ptrdiff_t>(order[i] * nodes), nodes,
                s.gain_db.begin() + static_cast<std::ptrdiff_t>(i * nodes));
  }
  return s;
}

}  // namespace

Schedule schedule_transmissions(const ChannelTrace& trace, const ChannelModel& channel, const std::vector<Rat>& rats,
                                const std::vector<GeneratedMessage>& messages, const SinrConfig& config) {
  const auto nodes = static_cast<std::uint32_t>(trace.nodes().size());
  if (rats.size() != nodes) throw std::invalid_argument("RAT assignment size differs from the node count");
  Schedule s;
  s.packets = messages.size();

  std::vector<Transmission> nr;
  NrScheduler nr_sched(trace, channel, config, nodes);
  for (std::size_t i = 0; i < messages.size(); ++i)
    if (rats[messages[i].node] == Rat::nr_v2x) nr_sched.add(messages[i], i, nr, s);
  s.nr_mean_latency_s = nr_sched.mean_latency();
  std::stable_sort(nr.begin(), nr.end(),
                   [](const Transmission& a, const Transmission& b) { return a.start_s < b.start_s; });
  std::vector<float> nr_gains;
  fill_all_gains(trace, channel, nr, nodes, nr_gains);

  std::vector<Transmission> wifi;
  std::vector<float> wifi_gains;
  WifiSimulator(trace, channel, rats, config, nodes).run(messages, nr, nr_gains, wifi, wifi_gains, s);

  wifi.insert(wifi.end(), nr.begin(), nr.end());
  wifi_gains.insert(wifi_gains.end(), nr_gains.begin(), nr_gains.end());
  return sorted_schedule(std::move(wifi), std::move(wifi_gains), nodes, std::move(s));
}

Schedule schedule_from(const ChannelTrace& trace, const ChannelModel& channel, std::vector<Transmission> transmissions) {
  Schedule s;
  s.nodes = static_cast<std::uint32_t>(trace.nodes().size());
  std::vector<float> gains;
  fill_all_gains(trace, channel, transmissions, s.nodes, gains);
  std::uint64_t packets = 0;
  for (const auto& t : transmissions) packets = std::max<std::uint64_t>(packets, t.packet + 1);
  s.packets = packets;
  return sorted_schedule(std::move(transmissions), std::move(gains), s.nodes, std::move(s));
}

}  // namespace raysweep::generators::sinr
