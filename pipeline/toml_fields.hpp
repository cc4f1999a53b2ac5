// Typed reads of TOML values for the stage configs: every error names the
// file, the full key and its line (ConfigError).
#pragma once

#include <toml++/toml.h>

#include <cstdint>
#include <string>
#include <vector>

#include "pipeline/config.hpp"

namespace raysweep::pipeline::toml_fields {

inline std::string where(const std::string& path, const std::string& key, const toml::node& n) {
  return path + ": key '" + key + "' (line " + std::to_string(n.source().begin.line) + ")";
}
inline double number(const std::string& path, const std::string& key, const toml::node& n) {
  if (auto v = n.value<double>()) return *v;
  throw ConfigError(where(path, key, n) + ": expected a number");
}
inline int integer(const std::string& path, const std::string& key, const toml::node& n) {
  if (auto v = n.value<std::int64_t>()) return static_cast<int>(*v);
  throw ConfigError(where(path, key, n) + ": expected an integer");
}
inline bool boolean(const std::string& path, const std::string& key, const toml::node& n) {
  if (auto v = n.value<bool>()) return *v;
  throw ConfigError(where(path, key, n) + ": expected true or false");
}
inline std::string text(const std::string& path, const std::string& key, const toml::node& n) {
  if (auto v = n.value<std::string>()) return *v;
  throw ConfigError(where(path, key, n) + ": expected a string");
}

inline std::vector<std::string> strings(const std::string& path, const std::string& key, const toml::node& n) {
  const toml::array* a = n.as_array();
  if (!a) throw ConfigError(where(path, key, n) + ": expected an array of strings");
  std::vector<std::string> out;
  for (const auto& e : *a) out.push_back(text(path, key, e));
  return out;
}

}  // namespace raysweep::pipeline::toml_fields
