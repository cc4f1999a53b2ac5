// The declared config schema: each TOML table is a Table<Cfg> whose keys bind
// a typed value (type, unit, range, help) to a field of the stage's settings
// struct, so the declaration is the parser, the writer of the effective config
// and the source of docs/config.md at once. Defaults are the struct's own
// initialisers (read from a default-constructed prototype), so they too are
// written down once.
//
// Every error is a ConfigError "FILE:LINE: table.key: expected ..., got ...".
#pragma once

#include <toml++/toml.h>

#include <array>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "pipeline/settings/config_error.hpp"

namespace raysweep::pipeline::schema {

// The file being read: errors name it, paths are relative to its folder.
struct Source {
  std::string file;
  std::filesystem::path dir;
};

// Where a value sits: the file and the full dotted key ("materials.glass.eps_r").
struct At {
  const Source* src = nullptr;
  std::string key;
  At child(const std::string& k) const { return {src, key.empty() ? k : key + "." + k}; }
  [[noreturn]] void fail(const toml::node& n, const std::string& msg) const;
  // "expected EXPECT, got <the value>".
  [[noreturn]] void expected(const toml::node& n, const std::string& expect) const;
};

// A value given on the command line (`--set TABLE.KEY=VALUE`) rather than in
// the file carries "--set TABLE.KEY" as its source: errors name that instead
// of a file line, and its relative paths start at the working directory.
// Returns that source, or nullopt for a value from the file.
std::optional<std::string> set_option(const toml::node& n);
inline constexpr const char* kSetPrefix = "--set ";

// The value as an error message shows it: 3, -1.5, "text", true, an array, a table.
std::string describe(const toml::node& n);
// The closest of `names` to `word` when it is a plausible typo, else "".
std::string suggest(const std::string& word, const std::vector<std::string>& names);
// "\"a\", \"b\" or \"c\"".
std::string quoted_alternatives(const std::vector<std::string>& names);
// An integer, or a float with an integral value that fits (2.0; not 2.5, 1e30,
// nan). toml++'s own value<int64_t>() casts any float first, which is
// undefined behaviour beyond the integer range; booleans are not integers.
std::optional<std::int64_t> integral(const toml::node& n);
// "numbers" for "number": element types in array descriptions.
std::string plural(const std::string& type);
// A default value as docs/config.md shows it: 5900000000, [1, 0.5], "text".
std::string doc_value(const nlohmann::json& j);

class TableBase;

// One typed value: how to read it from TOML, how to write it to JSON, and what
// docs/config.md says of it.
template <class T>
struct Value {
  std::string type;    // docs: "integer", "number", "string", "array of numbers", ...
  std::string range;   // docs: ">= 1", "in (0, 1]", "\"a\" or \"b\"", "" when any value of the type goes
  std::string expect;  // errors: "an integer >= 1"
  std::function<T(const toml::node&, const At&)> read;
  std::function<nlohmann::json(const T&)> write;
  const TableBase* sub = nullptr;  // docs: the sub-table this value is made of
};

// Numeric bounds; unset ends are open to any finite value.
struct Range {
  std::optional<double> min, max;
  bool min_open = false, max_open = false;
  std::string text() const;              // ">= 0", "> 0", "in (0, 1]", ""
  bool contains(double v) const;
};
inline Range at_least(double v) { return {v, std::nullopt, false, false}; }
inline Range above(double v) { return {v, std::nullopt, true, false}; }
inline Range between(double lo, double hi) { return {lo, hi, false, false}; }

Value<bool> boolean();
Value<double> number(Range r = {});
Value<std::string> text();
// A string that must be one of `names`.
Value<std::string> choice(std::vector<std::string> names);

// An integer into any integral field; the field type's limits apply too, so an
// unsigned field rejects negatives and nothing silently wraps.
template <class I>
Value<I> integer(Range r = {}) {
  if (!r.min && std::numeric_limits<I>::min() == 0) r.min = 0;
  Value<I> v;
  v.type = "integer";
  v.range = r.text();
  v.expect = "an integer" + (v.range.empty() ? "" : " " + v.range);
  v.read = [r, expect = v.expect](const toml::node& n, const At& at) -> I {
    const auto x = integral(n);
    if (!x || !r.contains(static_cast<double>(*x)) ||
        *x < static_cast<long double>(std::numeric_limits<I>::min()) ||
        *x > static_cast<long double>(std::numeric_limits<I>::max()))
      at.expected(n, expect);
    return static_cast<I>(*x);
  };
  v.write = [](const I& x) { return nlohmann::json(x); };
  return v;
}

// A string mapped to an enumerator (docs list the names).
template <class E>
Value<E> enumeration(std::vector<std::pair<std::string, E>> names) {
  std::vector<std::string> keys;
  for (const auto& [k, e] : names) keys.push_back(k);
  Value<E> v;
  v.type = "string";
  v.range = quoted_alternatives(keys);
  v.expect = v.range;
  v.read = [names, keys, expect = v.expect](const toml::node& n, const At& at) -> E {
    const auto s = n.value<std::string>();
    if (s)
      for (const auto& [k, e] : names)
        if (k == *s) return e;
    const std::string hint = s ? suggest(*s, keys) : "";
    at.fail(n, "expected " + expect + ", got " + describe(n) + (hint.empty() ? "" : " (did you mean \"" + hint + "\"?)"));
  };
  v.write = [names](const E& e) {
    for (const auto& [k, x] : names)
      if (x == e) return nlohmann::json(k);
    return nlohmann::json(nullptr);
  };
  return v;
}

// A string turned into T by `parse`, which throws std::invalid_argument with
// the reason (material names, OFDM grids, transmitter specs, ...).
template <class T>
Value<T> parsed(std::string type, std::string range, std::string expect, std::function<T(const std::string&)> parse,
                std::function<nlohmann::json(const T&)> write) {
  Value<T> v;
  v.type = std::move(type);
  v.range = std::move(range);
  v.expect = std::move(expect);
  v.read = [parse, expect = v.expect](const toml::node& n, const At& at) -> T {
    const auto s = n.value<std::string>();
    if (!s) at.expected(n, expect);
    try {
      return parse(*s);
    } catch (const std::invalid_argument& e) {
      at.fail(n, e.what());
    } catch (const std::exception&) {  // a parser's own limits (std::out_of_range...): still the file's fault
      at.expected(n, expect);
    }
  };
  v.write = std::move(write);
  return v;
}

// Adds a check of the whole value (a box's corners in order, ...).
template <class T>
Value<T> checked(Value<T> v, std::function<bool(const T&)> ok, std::string expect, std::string range = "") {
  auto inner = v.read;
  v.expect = expect;
  if (!range.empty()) v.range = std::move(range);
  v.read = [inner, ok, expect](const toml::node& n, const At& at) -> T {
    T x = inner(n, at);
    if (!ok(x)) at.expected(n, expect);
    return x;
  };
  return v;
}

// An array of values; `min`/`max` bound its length.
template <class T>
Value<std::vector<T>> list(Value<T> elem, std::size_t min = 0, std::size_t max = std::numeric_limits<std::size_t>::max()) {
  Value<std::vector<T>> v;
  const std::string of = min == max ? std::to_string(min) + " " + plural(elem.type) : plural(elem.type);
  const std::string at_least_min = min > 0 && min != max ? "at least " + std::to_string(min) : "";
  v.type = min == max ? of : "array of " + of;
  v.range = elem.range.empty() ? at_least_min : "each " + elem.range + (at_least_min.empty() ? "" : ", " + at_least_min);
  v.expect = "an array of " + of + (at_least_min.empty() ? "" : " (" + at_least_min + ")");
  v.sub = elem.sub;
  v.read = [elem, min, max, expect = v.expect](const toml::node& n, const At& at) {
    const toml::array* a = n.as_array();
    if (!a || a->size() < min || a->size() > max) at.expected(n, expect);
    std::vector<T> out;
    for (const auto& e : *a) out.push_back(elem.read(e, at));
    return out;
  };
  v.write = [elem](const std::vector<T>& xs) {
    nlohmann::json j = nlohmann::json::array();
    for (const auto& x : xs) j.push_back(elem.write(x));
    return j;
  };
  return v;
}

// N numbers into a std::array (a position, a box).
template <std::size_t N>
Value<std::array<double, N>> numbers(Range r = {}) {
  auto l = list(number(r), N, N);
  Value<std::array<double, N>> v;
  v.type = l.type;
  v.range = l.range;
  v.expect = l.expect;
  v.read = [l](const toml::node& n, const At& at) {
    const auto xs = l.read(n, at);
    std::array<double, N> out{};
    for (std::size_t i = 0; i < N; ++i) out[i] = xs[i];
    return out;
  };
  v.write = [](const std::array<double, N>& x) { return nlohmann::json(x); };
  return v;
}

// Absent by default (written as null): "use the built-in value".
template <class T>
Value<std::optional<T>> optional(Value<T> inner) {
  Value<std::optional<T>> v;
  v.type = inner.type;
  v.range = inner.range;
  v.expect = inner.expect;
  v.sub = inner.sub;
  v.read = [inner](const toml::node& n, const At& at) { return std::optional<T>(inner.read(n, at)); };
  v.write = [inner](const std::optional<T>& x) { return x ? inner.write(*x) : nlohmann::json(nullptr); };
  return v;
}

// A table of NAME = value. `name` turns a key into the map's key (e.g. a
// canonical material name) or throws std::invalid_argument.
template <class T>
Value<std::map<std::string, T>> map(Value<T> elem, std::string name_doc,
                                     std::function<std::string(const std::string&)> name = {}) {
  Value<std::map<std::string, T>> v;
  v.type = "table of " + name_doc + " = " + elem.type;
  v.range = elem.range;
  v.expect = "a table of " + name_doc + " = " + elem.type;
  v.sub = elem.sub;
  v.read = [elem, name, expect = v.expect](const toml::node& n, const At& at) {
    const toml::table* t = n.as_table();
    if (!t) at.expected(n, expect);
    std::map<std::string, T> out;
    for (auto&& [k, e] : *t) {
      const At here = at.child(std::string(k.str()));
      std::string key(k.str());
      if (name) {
        try {
          key = name(key);
        } catch (const std::invalid_argument& err) {
          here.fail(e, err.what());
        }
      }
      out[key] = elem.read(e, here);
    }
    return out;
  };
  v.write = [elem](const std::map<std::string, T>& m) {
    nlohmann::json j = nlohmann::json::object();
    for (const auto& [k, x] : m) j[k] = elem.write(x);
    return j;
  };
  return v;
}

// Docs of one key (docs/config.md).
struct KeyDoc {
  std::string key, type, range, unit, help;
  std::string default_value;  // Markdown: `value`, or words where the value alone says too little
  bool required = false;
  const TableBase* sub = nullptr;
};

// A table without its field type: what the registry, the unknown-key check
// and the docs need.
class TableBase {
 public:
  TableBase(std::string name, std::string help) : name_(std::move(name)), help_(std::move(help)) {}
  virtual ~TableBase() = default;
  const std::string& name() const { return name_; }  // "scene", "vehicles.class.<name>", "[vehicles.rules]"
  const std::string& help() const { return help_; }
  virtual std::vector<KeyDoc> docs() const = 0;
  // The table's effective settings from `t` (nullptr: absent), defaults filled
  // in; throws ConfigError like the stage's own read.
  virtual nlohmann::json effective(const toml::table* t, const At& at) const = 0;

 private:
  std::string name_, help_;
};

// A table bound to the settings struct Cfg. Fields are member pointers or
// generic lambdas `[](auto& c) -> auto& { return c.x.y; }`, so one accessor
// serves reading (Cfg&) and writing (const Cfg&).
template <class Cfg>
class Table : public TableBase {
 public:
  Table(std::string name, std::string help, Cfg prototype = Cfg{})
      : TableBase(std::move(name), std::move(help)), prototype_(std::move(prototype)) {}

  // Declares `key`. `default_doc` replaces the prototype's value in the docs
  // where the value alone would not say what it means ("all classes").
  template <class T, class Field>
  Table& key(std::string key, Value<T> v, Field field, std::string unit, std::string help,
             std::string default_doc = "") {
    Entry e;
    e.doc = {key, v.type, v.range, std::move(unit), std::move(help), std::move(default_doc), false, v.sub};
    e.read = [v, field](const toml::node& n, const At& at, Cfg& c) { std::invoke(field, c) = v.read(n, at); };
    e.write = [v, field](const Cfg& c) { return v.write(std::invoke(field, c)); };
    if constexpr (std::is_same_v<T, bool>) {
      e.get = [field](const Cfg& c) { return static_cast<bool>(std::invoke(field, c)); };
      e.flip = [field](Cfg& c) { std::invoke(field, c) = !std::invoke(field, c); };
    }
    e.doc.default_value = e.doc.default_value.empty() ? "`" + doc_value(e.write(prototype_)) + "`" : e.doc.default_value;
    entries_.push_back(std::move(e));
    return *this;
  }
  // The last declared key (a boolean) is a switch `raysweep tradeoff` flips
  // against the base setting where `applies(base)` holds (always when
  // empty): "-label" when it is on, "+label" when off, or `off_label` and
  // `on_label` in full when given. A mechanism's switch declares its study
  // here, so the tradeoff grid follows the declared config.
  Table& toggle(std::string label, std::function<bool(const Cfg&)> applies = {}, std::string off_label = "",
                std::string on_label = "") {
    Entry& e = entries_.back();
    if (!e.flip) throw std::logic_error("config schema: toggle on non-boolean key " + e.doc.key);
    toggles_.push_back({e.doc.key, off_label.empty() ? "-" + label : off_label,
                        on_label.empty() ? "+" + label : on_label, std::move(applies), e.get, e.flip});
    return *this;
  }
  // A declared switch (toggle()).
  struct Toggle {
    std::string key;
    std::string off_label, on_label;  // the variant's label when it turns the switch off / on
    std::function<bool(const Cfg&)> applies;
    std::function<bool(const Cfg&)> get;
    std::function<void(Cfg&)> flip;
  };
  const std::vector<Toggle>& toggles() const { return toggles_; }

  // The last declared key must be given.
  Table& required() {
    entries_.back().doc.required = true;
    entries_.back().doc.default_value = "required";
    return *this;
  }
  // Every key of the table is a NAME of the map `field` ([materials.<name>]).
  template <class T, class Field>
  Table& names(std::string name_doc, Value<std::map<std::string, T>> v, Field field, std::string help) {
    names_ = [v, field](const toml::table& t, const At& at, Cfg& c) { std::invoke(field, c) = v.read(t, at); };
    names_write_ = [v, field](const Cfg& c) { return v.write(std::invoke(field, c)); };
    entries_.push_back({{std::move(name_doc), v.type, v.range, "", std::move(help), "none", false, v.sub}, {}, {}});
    return *this;
  }

  // Reads the table's keys into `c`; unknown keys, wrong types and values out
  // of range throw ConfigError naming file, line and key.
  void read(const toml::table& t, const At& at, Cfg& c) const {
    if (names_) return names_(t, at, c);
    std::vector<std::string> keys;
    for (const auto& e : entries_) keys.push_back(e.doc.key);
    for (auto&& [k, n] : t) {
      const std::string key(k.str());
      const Entry* e = find(key);
      if (!e) {
        const std::string hint = suggest(key, keys);
        at.child(key).fail(n, "unknown key" + (hint.empty() ? "" : " (did you mean '" + hint + "'?)"));
      }
      e->read(n, at.child(key), c);
    }
    for (const auto& e : entries_)
      if (e.doc.required && !t.contains(e.doc.key))
        at.fail(t, "missing key '" + e.doc.key + "'");
  }
  nlohmann::json write(const Cfg& c) const {
    if (names_write_) return names_write_(c);
    nlohmann::json j = nlohmann::json::object();
    for (const auto& e : entries_) j[e.doc.key] = e.write(c);
    return j;
  }
  const Cfg& prototype() const { return prototype_; }

  std::vector<KeyDoc> docs() const override {
    std::vector<KeyDoc> out;
    for (const auto& e : entries_) out.push_back(e.doc);
    return out;
  }
  nlohmann::json effective(const toml::table* t, const At& at) const override {
    Cfg c = prototype_;
    if (t) read(*t, at, c);
    return write(c);
  }

 private:
  struct Entry {
    KeyDoc doc;
    std::function<void(const toml::node&, const At&, Cfg&)> read;
    std::function<nlohmann::json(const Cfg&)> write;
    std::function<bool(const Cfg&)> get;  // booleans only
    std::function<void(Cfg&)> flip;       // booleans only
  };
  const Entry* find(const std::string& key) const {
    for (const auto& e : entries_)
      if (e.doc.key == key) return &e;
    return nullptr;
  }
  Cfg prototype_;
  std::vector<Entry> entries_;
  std::vector<Toggle> toggles_;
  std::function<void(const toml::table&, const At&, Cfg&)> names_;
  std::function<nlohmann::json(const Cfg&)> names_write_;
};

// A value that is a table of `t`'s keys ([vehicles.class.<name>], [[vehicles.rules]]).
template <class S>
Value<S> table(const Table<S>& t) {
  Value<S> v;
  v.type = "table";
  v.expect = "a table";
  v.sub = &t;
  v.read = [&t](const toml::node& n, const At& at) {
    const toml::table* tt = n.as_table();
    if (!tt) at.expected(n, "a table");
    S s = t.prototype();
    t.read(*tt, at, s);
    return s;
  };
  v.write = [&t](const S& s) { return t.write(s); };
  return v;
}

}  // namespace raysweep::pipeline::schema
