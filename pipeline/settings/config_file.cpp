#include "pipeline/settings/config_file.hpp"

#include <filesystem>

#include "pipeline/settings/overrides.hpp"
#include "pipeline/settings/tables.hpp"

namespace raysweep::pipeline {

namespace fs = std::filesystem;
using json = nlohmann::json;
using namespace schema;

ConfigFile::ConfigFile(const std::string& path, const std::vector<std::string>& sets) {
  src_.file = path;
  src_.dir = path.empty() ? fs::current_path() : fs::absolute(path).parent_path();
  try {
    if (!path.empty()) root_ = toml::parse_file(path);
  } catch (const toml::parse_error& e) {
    throw ConfigError(path + ":" + std::to_string(e.source().begin.line) + ": " + std::string(e.description()));
  }
  apply_overrides(root_, sets);
  std::vector<std::string> names;
  for (const auto* t : config_tables()) names.push_back(t->name());
  const At top{&src_, ""};
  for (auto&& [k, node] : root_) {
    const std::string name(k.str());
    const TableBase* table = nullptr;
    for (const auto* t : config_tables())
      if (t->name() == name) table = t;
    if (!table) {
      const std::string hint = suggest(name, names);
      top.fail(node, "unknown table [" + name + "]" + (hint.empty() ? "" : " (did you mean [" + hint + "]?)"));
    }
    if (!node.is_table()) top.child(name).expected(node, "a table [" + name + "]");
    // Every table is checked here, whichever stage asked: a typo in [sinr]
    // must not wait for the SINR stage an hour later.
    effective_[name] = table->effective(node.as_table(), top.child(name));
  }
  for (const auto* t : config_tables())
    if (!effective_.contains(t->name())) effective_[t->name()] = t->effective(nullptr, At{&src_, t->name()});
}

void ConfigFile::fail(const std::string& table, const std::string& key, const std::string& msg) const {
  const At at{&src_, table + "." + key};
  if (const toml::node* n = root_.at_path(table + "." + key).node()) at.fail(*n, msg);
  if (const toml::node* n = root_.get(table)) at.fail(*n, msg);
  throw ConfigError(src_.file + ": " + at.key + ": " + msg);
}

json effective_config(const std::string& path, const std::vector<std::string>& sets) {
  if (!path.empty() || !sets.empty()) return ConfigFile(path, sets).effective();
  json out = json::object();
  for (const auto* t : config_tables()) out[t->name()] = t->effective(nullptr, At{});
  return out;
}

}  // namespace raysweep::pipeline
