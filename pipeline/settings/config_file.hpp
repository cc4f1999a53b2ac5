// One config file, parsed once and checked against the whole schema
// (tables.hpp) before any stage reads it.
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "pipeline/settings/schema.hpp"

namespace raysweep::pipeline {

// TOML syntax, unknown tables, and every key of every table (unknown, wrong
// type, out of range) are checked on construction, so that a typo anywhere
// fails before any stage runs. `sets` (`--set TABLE.KEY=VALUE`, overrides.hpp)
// change the parsed file before the checks; an empty path is an empty file.
// Throws ConfigError naming file, line and key (or the --set option).
class ConfigFile {
 public:
  explicit ConfigFile(const std::string& path, const std::vector<std::string>& sets = {});
  // Reads table `t` into `cfg` when the file has it; returns whether it has.
  template <class Cfg>
  bool read(const schema::Table<Cfg>& t, Cfg& cfg) const {
    const toml::table* node = root_[t.name()].as_table();
    if (node) t.read(*node, schema::At{&src_, t.name()}, cfg);
    return node != nullptr;
  }
  const std::string& path() const { return src_.file; }
  // A ConfigError about table.key that spans several keys (end before begin):
  // at the key's line when the file gives it, else at the table's, else the file.
  [[noreturn]] void fail(const std::string& table, const std::string& key, const std::string& msg) const;
  // Every table with every key, defaults filled in (`raysweep config`, provenance, stamps).
  const nlohmann::json& effective() const { return effective_; }

 private:
  schema::Source src_;
  toml::table root_;
  nlohmann::json effective_;
};

// ConfigFile(path, sets).effective(); the defaults for an empty path and no sets.
nlohmann::json effective_config(const std::string& path, const std::vector<std::string>& sets = {});

}  // namespace raysweep::pipeline
