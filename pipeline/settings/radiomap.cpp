#include "pipeline/settings/radiomap.hpp"

#include <cctype>
#include <cmath>
#include <sstream>
#include <stdexcept>

namespace raysweep::pipeline {

RadioMapTx parse_radiomap_tx(const std::string& spec, const std::string& what) {
  std::vector<std::string> parts;
  std::stringstream ss(spec);
  for (std::string p; std::getline(ss, p, ',');) parts.push_back(p);
  if (parts.size() < 4 || parts.size() > 5 || parts[0].empty())
    throw std::invalid_argument(what + " '" + spec + "': expected ID,X,Y,Z[,POWER_DBM]");
  RadioMapTx tx;
  tx.id = parts[0];
  for (char c : tx.id)
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-'))
      throw std::invalid_argument(what + " '" + spec + "': the id may hold letters, digits, '_' and '-' only");
  try {
    for (int k = 0; k < 3; ++k) {
      std::size_t used = 0;
      tx.position[k] = std::stod(parts[k + 1], &used);
      if (used != parts[k + 1].size() || !std::isfinite(tx.position[k])) throw std::invalid_argument("");
    }
    if (parts.size() == 5) {
      std::size_t used = 0;
      tx.power_dbm = std::stod(parts[4], &used);
      if (used != parts[4].size() || !std::isfinite(tx.power_dbm)) throw std::invalid_argument("");
      tx.power_given = true;
    }
  } catch (const std::exception&) {
    throw std::invalid_argument(what + " '" + spec + "': coordinates and power must be finite numbers");
  }
  return tx;
}

}  // namespace raysweep::pipeline
