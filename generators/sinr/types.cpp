#include "generators/sinr/types.hpp"

#include <stdexcept>

namespace raysweep::generators::sinr {

const char* rat_name(Rat r) {
  switch (r) {
    case Rat::none: return "none";
    case Rat::wifi80211p: return "80211p";
    case Rat::nr_v2x: return "nrv2x";
  }
  return "?";
}

Rat parse_rat(const std::string& s) {
  for (Rat r : {Rat::none, Rat::wifi80211p, Rat::nr_v2x})
    if (s == rat_name(r)) return r;
  throw std::invalid_argument("unknown RAT '" + s + "' (80211p, nrv2x, none)");
}

const char* message_name(Message m) { return m == Message::cam ? "cam" : "cpm"; }

}  // namespace raysweep::generators::sinr
