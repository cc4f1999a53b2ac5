#include "pipeline/settings/overrides.hpp"

#include <cstdio>

#include "pipeline/settings/schema.hpp"

namespace raysweep::pipeline {

namespace {

// `s` as a TOML basic string.
std::string quoted(const std::string& s) {
  std::string out = "\"";
  for (const char c : s) {
    if (c == '"' || c == '\\') {
      out += '\\';
      out += c;
    } else if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\u%04x", static_cast<unsigned>(static_cast<unsigned char>(c)));
      out += buf;
    } else {
      out += c;
    }
  }
  return out + "\"";
}

std::string trimmed(const std::string& s) {
  const auto b = s.find_first_not_of(" \t");
  const auto e = s.find_last_not_of(" \t");
  return b == std::string::npos ? std::string() : s.substr(b, e - b + 1);
}

// "KEY = VALUE" as a one-line document whose nodes name the option.
toml::table parse_one(const std::string& key, const std::string& value, const std::string& where) {
  // A line break would let the value open other tables: such a value is text.
  if (value.find_first_of("\r\n") == std::string::npos) {
    try {
      return toml::parse(key + " = " + value, where);
    } catch (const toml::parse_error&) {
    }
  }
  try {
    return toml::parse(key + " = " + quoted(value), where);
  } catch (const toml::parse_error& e) {
    throw ConfigError(where + ": " + std::string(e.description()));
  }
}

// `from` into `into`: tables the dotted key opened are merged key by key,
// anything else (a value, an array, an inline table) replaces what is there.
void merge(toml::table& into, toml::table& from) {
  for (auto&& [k, v] : from) {
    toml::table* sub = v.as_table();
    toml::table* dst = into[k].as_table();
    if (sub && dst && !sub->is_inline()) {
      merge(*dst, *sub);
      continue;
    }
    // Moved, not copied: a copy would drop the source that names the option.
    v.visit([&, key = k](auto&& node) { into.insert_or_assign(key, std::move(node)); });
  }
}

}  // namespace

void apply_overrides(toml::table& root, const std::vector<std::string>& sets) {
  for (const auto& set : sets) {
    const auto eq = set.find('=');
    const std::string key = trimmed(set.substr(0, eq));
    if (eq == std::string::npos || key.find('.') == std::string::npos)
      throw ConfigError(schema::kSetPrefix + set + ": expected TABLE.KEY=VALUE");
    toml::table one = parse_one(key, trimmed(set.substr(eq + 1)), schema::kSetPrefix + key);
    merge(root, one);
  }
}

}  // namespace raysweep::pipeline
