#include "generators/sinr/outcomes.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <set>
#include <stdexcept>
#include <unordered_map>

#include "generators/sinr/coexistence.hpp"
#include "generators/sinr/messages.hpp"
#include "generators/sinr/schedule.hpp"

namespace raysweep::generators::sinr {

std::vector<Rat> assign_rats(const ChannelTrace& trace, const RatAssignment& a, std::uint64_t seed) {
  const auto& nodes = trace.nodes();
  std::vector<Rat> rats(nodes.size(), Rat::none);
  std::unordered_map<std::string, std::uint32_t> by_id;
  for (std::uint32_t n = 0; n < nodes.size(); ++n) by_id.emplace(nodes[n].id, n);
  std::vector<char> fixed(nodes.size(), 0);
  auto apply = [&](const std::vector<std::string>& ids, Rat r, const char* list) {
    for (const auto& id : ids) {
      auto it = by_id.find(id);
      if (it == by_id.end())
        throw std::invalid_argument(std::string(list) + ": node '" + id + "' is not in the channel dataset");
      rats[it->second] = r;
      fixed[it->second] = 1;
    }
  };
  apply(a.nr_ids, Rat::nr_v2x, "nr_ids");
  apply(a.wifi_ids, Rat::wifi80211p, "wifi_ids");
  apply(a.silent_ids, Rat::none, "silent_ids");

  std::vector<std::uint32_t> free;
  std::uint32_t vehicles = 0;
  for (std::uint32_t n = 0; n < nodes.size(); ++n) {
    if (nodes[n].kind != NodeKind::vehicle) continue;
    if (a.active_vehicles > 0 && vehicles >= a.active_vehicles) {
      if (!fixed[n]) fixed[n] = 1;  // present but silent
      continue;
    }
    ++vehicles;
    if (fixed[n]) continue;
    auto v = a.by_vtype.find(nodes[n].vtype);
    if (v != a.by_vtype.end()) {
      rats[n] = v->second;
      continue;
    }
    free.push_back(n);
  }
  // An exact split: order the free vehicles by a hash of (seed, id) and give the first share NR.
  std::vector<std::pair<double, std::uint32_t>> order;
  for (std::uint32_t n : free) {
    std::uint64_t h = 1469598103934665603ULL;
    for (unsigned char ch : nodes[n].id) h = (h ^ ch) * 1099511628211ULL;
    order.emplace_back(hash_uniform(seed, h), n);
  }
  std::sort(order.begin(), order.end());
  const auto nr_count = static_cast<std::size_t>(std::llround(a.nr_fraction * static_cast<double>(order.size())));
  for (std::size_t i = 0; i < order.size(); ++i) rats[order[i].second] = i < nr_count ? Rat::nr_v2x : Rat::wifi80211p;
  for (auto& r : rats) {
    if (a.enabled == "80211p-only" && r == Rat::nr_v2x) r = Rat::none;
    if (a.enabled == "nrv2x-only" && r == Rat::wifi80211p) r = Rat::none;
  }
  return rats;
}

std::pair<double, double> sinr_window(const ChannelTrace& trace, const SinrConfig& c) {
  if (trace.frames() == 0) return {0, 0};
  const double first = trace.time(0), end = trace.time(trace.frames() - 1) + trace.frame_step();
  const double b = c.begin_s >= 0 ? std::max(first, c.begin_s) : first;
  const double e = c.end_s >= 0 ? std::min(end, c.end_s) : end;
  return {b, std::max(b, e)};
}

namespace {

struct Row {
  Reception r;
  std::vector<Interferer> overlaps;
};

// PRR bookkeeping: a packet is received at a receiver when any attempt was decoded.
struct PacketState {
  std::uint32_t tx = 0;
  Rat rat = Rat::none;
  int attempts_left = 0;
  std::map<std::uint32_t, std::pair<float, bool>> receivers;  // rx -> (distance at first attempt, decoded)
};

struct PrrAcc {
  std::uint64_t packets = 0, received = 0;
  double distance_sum = 0;
};

}  // namespace

SinrRunStats run_sinr(const ChannelTrace& trace, const ChannelModel& channel, const SinrConfig& c,
                      const std::vector<Rat>& rats, const std::vector<Transmission>* reuse, SinrWriter& writer,
                      const std::function<void(const SinrRunProgress&)>& progress) {
  c.check();
  const auto nodes = static_cast<std::uint32_t>(trace.nodes().size());
  if (rats.size() != nodes) throw std::invalid_argument("RAT assignment size differs from the node count");
  SinrRunStats stats;
  std::tie(stats.time_start_s, stats.time_end_s) = sinr_window(trace, c);

  Schedule sched;
  if (reuse) {
    for (const auto& t : *reuse)
      if (t.node >= nodes) throw std::invalid_argument("reused schedule names node " + std::to_string(t.node) +
                                                       " but the channel dataset has " + std::to_string(nodes));
    sched = schedule_from(trace, channel, *reuse);
  } else {
    const auto messages = generate_messages(trace, rats, c, stats.time_start_s, stats.time_end_s);
    sched = schedule_transmissions(trace, channel, rats, messages, c);
  }
  const auto& tx = sched.transmissions;
  stats.packets = sched.packets;
  stats.transmissions = tx.size();
  stats.wifi_dropped = sched.wifi_dropped;
  stats.nr_dropped = sched.nr_dropped;
  stats.nr_mean_latency_s = sched.nr_mean_latency_s;
  stats.wifi_mean_latency_s = sched.wifi_mean_latency_s;
  for (const auto& t : tx) writer.add_transmission(t);

  double max_duration = 0;
  std::unordered_map<std::uint64_t, int> attempts;
  for (const auto& t : tx) {
    max_duration = std::max(max_duration, t.duration_s);
    ++attempts[t.packet];
  }
  std::unordered_map<std::uint64_t, PacketState> open;
  std::map<std::pair<std::uint32_t, std::uint32_t>, std::pair<Rat, PrrAcc>> links;
  std::map<Rat, PrrAcc> per_rat;

  // Evaluates one transmission at all its receivers; independent of every other, so
  // blocks of transmissions run in parallel and results do not depend on threads.
  auto evaluate = [&](std::size_t s, std::vector<Row>& rows) {
    const Transmission& sig = tx[s];
    const std::size_t f = trace.frame_at(sig.start_s);
    const NodeState* st = trace.state(f, sig.node);
    if (!st) return;
    // Transmissions overlapping in time (the table is sorted by start).
    std::vector<std::size_t> overlapping;
    const auto first = std::lower_bound(tx.begin(), tx.end(), sig.start_s - max_duration,
                                        [](const Transmission& t, double v) { return t.start_s < v; });
    for (auto it = first; it != tx.end() && it->start_s < sig.end_s(); ++it) {
      const std::size_t j = static_cast<std::size_t>(it - tx.begin());
      if (j == s || it->end_s() <= sig.start_s || it->node == sig.node) continue;
      if (overlap(sig.f_lo_hz, sig.f_hi_hz, it->f_lo_hz, it->f_hi_hz) <= 0) continue;
      overlapping.push_back(j);
    }
    for (std::uint32_t rx = 0; rx < nodes; ++rx) {
      if (rx == sig.node || rats[rx] != sig.rat) continue;
      const NodeState* sr = trace.state(f, rx);
      if (!sr) continue;
      const double d = std::sqrt((sr->x - st->x) * (sr->x - st->x) + (sr->y - st->y) * (sr->y - st->y) +
                                 (sr->z - st->z) * (sr->z - st->z));
      if (c.max_receiver_distance_m > 0 && d > c.max_receiver_distance_m) continue;
      std::vector<OverlapInput> in;
      bool half_duplex = false;
      for (std::size_t j : overlapping) {
        if (tx[j].node == rx) {
          half_duplex = true;  // the receiver is itself transmitting: it hears nothing
          continue;
        }
        in.push_back({static_cast<std::uint32_t>(j), &tx[j], sched.gain(j, rx)});
      }
      const SinrBreakdown b = coexistence_sinr(sig, sched.gain(s, rx), in, c);
      Row row;
      Reception& r = row.r;
      r.transmission = static_cast<std::uint32_t>(s);
      r.rx = rx;
      r.distance_m = static_cast<float>(d);
      r.prx_dbm = static_cast<float>(b.prx_dbm);
      r.intra_dbm = static_cast<float>(b.intra_dbm);
      r.inter_dbm = static_cast<float>(b.inter_dbm);
      r.noise_dbm = static_cast<float>(b.noise_dbm);
      r.sinr_db = static_cast<float>(b.sinr_db);
      r.los_class = channel.link(f, sig.node, rx).los_class;
      r.interferers = b.counted;
      const double u = hash_uniform(c.seed, 0xB1E, s, rx);
      r.decoded = !half_duplex && decodable(sig.rat, b.sinr_db, b.prx_dbm, c, u);
      row.overlaps = std::move(b.overlaps);
      rows.push_back(std::move(row));
    }
  };

  auto account = [&](const Transmission& t, const std::vector<Row>& rows) {
    auto [it, inserted] = open.try_emplace(t.packet);
    PacketState& p = it->second;
    if (inserted) p = PacketState{t.node, t.rat, attempts[t.packet], {}};
    for (const auto& row : rows) {
      auto [rit, added] = p.receivers.try_emplace(row.r.rx, row.r.distance_m, false);
      rit->second.second = rit->second.second || row.r.decoded;
    }
    if (--p.attempts_left > 0) return;
    for (const auto& [rx, dd] : p.receivers) {
      if (dd.first > c.prr_range_m) continue;
      auto& [rat, acc] = links[{p.tx, rx}];
      rat = p.rat;
      ++acc.packets;
      acc.received += dd.second;
      acc.distance_sum += dd.first;
      auto& all = per_rat[p.rat];
      ++all.packets;
      all.received += dd.second;
      all.distance_sum += dd.first;
    }
    open.erase(it);
  };

  constexpr std::size_t kBlock = 1024;
  SinrRunProgress prog{0, tx.size()};
  for (std::size_t b0 = 0; b0 < tx.size(); b0 += kBlock) {
    const std::size_t b1 = std::min(tx.size(), b0 + kBlock);
    std::vector<std::vector<Row>> block(b1 - b0);
    tbb::parallel_for(b0, b1, [&](std::size_t s) { evaluate(s, block[s - b0]); });
    for (std::size_t s = b0; s < b1; ++s) {
      for (const auto& row : block[s - b0]) {
        writer.add_reception(row.r, row.overlaps);
        ++stats.receptions;
        stats.decoded += row.r.decoded;
        stats.interferers += row.r.interferers;
      }
      account(tx[s], block[s - b0]);
    }
    prog.done = b1;
    if (progress) progress(prog);
  }

  std::vector<PrrEntry> prr_links;
  for (const auto& [key, v] : links) {
    const auto& [rat, acc] = v;
    prr_links.push_back({key.first, key.second, rat, acc.packets, acc.received,
                         static_cast<float>(acc.distance_sum / static_cast<double>(acc.packets))});
  }
  for (const auto& [rat, acc] : per_rat)
    stats.prr_rats.push_back({0, 0, rat, acc.packets, acc.received,
                              static_cast<float>(acc.packets ? acc.distance_sum / static_cast<double>(acc.packets) : 0)});
  std::vector<SinrNode> table;
  for (std::uint32_t n = 0; n < nodes; ++n) table.push_back({trace.nodes()[n].id, trace.nodes()[n].kind, rats[n]});
  writer.finish(table, prr_links, stats.prr_rats);
  return stats;
}

}  // namespace raysweep::generators::sinr
