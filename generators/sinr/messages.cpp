#include "generators/sinr/messages.hpp"

#include <algorithm>
#include <cmath>

namespace raysweep::generators::sinr {

namespace {

std::uint64_t splitmix(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

double heading_change_deg(double a, double b) {
  const double d = std::fmod(std::abs(a - b), 360.0);
  return d > 180.0 ? 360.0 - d : d;
}

}  // namespace

double hash_uniform(std::uint64_t seed, std::uint64_t a, std::uint64_t b, std::uint64_t c) {
  std::uint64_t h = splitmix(seed);
  h = splitmix(h ^ a);
  h = splitmix(h ^ b);
  h = splitmix(h ^ c);
  return static_cast<double>(h >> 11) * 0x1.0p-53;
}

bool CamTrigger::check(const Kinematics& k) {
  // Tolerance for check instants that land a rounding error before T_GenCam.
  constexpr double eps = 1e-9;
  bool send = false;
  if (first_) {
    send = true;
    first_ = false;
    time_triggered_ = 0;
  } else {
    const double elapsed = k.t - last_.t;
    const bool dynamics = elapsed + eps >= c_.t_gen_min_s &&
                          (heading_change_deg(k.heading_deg, last_.heading_deg) > c_.heading_deg ||
                           std::hypot(k.x - last_.x, k.y - last_.y) > c_.position_m ||
                           std::abs(k.speed_mps - last_.speed_mps) > c_.speed_mps);
    if (dynamics) {
      send = true;
      t_gen_cam_ = elapsed;
      time_triggered_ = 0;
    } else if (elapsed + eps >= t_gen_cam_) {
      send = true;
      if (++time_triggered_ >= c_.n_gen_cam) {
        t_gen_cam_ = c_.t_gen_max_s;
        time_triggered_ = 0;
      }
    }
  }
  if (send) {
    lf_due_ = !has_lf_ || k.t - last_lf_ + eps >= 0.5;
    if (lf_due_) last_lf_ = k.t, has_lf_ = true;
    last_ = k;
  }
  return send;
}

std::vector<GeneratedMessage> generate_messages(const ChannelTrace& trace, const std::vector<Rat>& rats,
                                                const SinrConfig& config, double begin_s, double end_s) {
  std::vector<GeneratedMessage> out;
  if (trace.frames() == 0) return out;
  const double check = config.cam.check_period_s;
  for (std::uint32_t node = 0; node < rats.size(); ++node) {
    if (rats[node] == Rat::none) continue;
    if (config.cam.enabled) {
      const double phase = hash_uniform(config.seed, 0xCA4, node) * check;
      CamTrigger trigger(config.cam);
      bool present_before = false;
      for (std::uint64_t i = 0;; ++i) {
        const double t = begin_s + phase + static_cast<double>(i) * check;
        if (t >= end_s) break;
        const std::size_t f = trace.frame_at(t);
        const NodeState* s = trace.state(f, node);
        if (!s || trace.time(f) > t) {
          if (present_before) trigger = CamTrigger(config.cam);
          present_before = false;
          continue;
        }
        present_before = true;
        const Kinematics k{t, s->x, s->y, std::hypot(s->vx, s->vy), s->heading_deg};
        if (trigger.check(k))
          out.push_back({t, node, Message::cam,
                         config.cam.bytes + (trigger.low_frequency_due() ? config.cam.low_frequency_bytes : 0)});
      }
    }
    if (config.cpm.enabled) {
      const double phase = hash_uniform(config.seed, 0xC93, node) * config.cpm.period_s;
      for (std::uint64_t i = 0;; ++i) {
        const double t = begin_s + phase + static_cast<double>(i) * config.cpm.period_s;
        if (t >= end_s) break;
        const std::size_t f = trace.frame_at(t);
        if (trace.time(f) <= t && trace.state(f, node)) out.push_back({t, node, Message::cpm, config.cpm.bytes});
      }
    }
  }
  std::sort(out.begin(), out.end(), [](const GeneratedMessage& a, const GeneratedMessage& b) {
    return a.t != b.t ? a.t < b.t : a.node != b.node ? a.node < b.node : a.message < b.message;
  });
  return out;
}

}  // namespace raysweep::generators::sinr
