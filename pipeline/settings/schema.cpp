#include "pipeline/settings/schema.hpp"

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <sstream>

namespace raysweep::pipeline::schema {

std::optional<std::string> set_option(const toml::node& n) {
  const auto& path = n.source().path;
  if (path && path->rfind(kSetPrefix, 0) == 0) return *path;
  return std::nullopt;
}

void At::fail(const toml::node& n, const std::string& msg) const {
  if (const auto set = set_option(n)) throw ConfigError(*set + ": " + (key.empty() ? "" : key + ": ") + msg);
  const auto line = n.source().begin.line;
  std::string where = src ? src->file : std::string("config");
  if (line > 0) where += ":" + std::to_string(line);
  throw ConfigError(where + ": " + (key.empty() ? "" : key + ": ") + msg);
}

void At::expected(const toml::node& n, const std::string& expect) const {
  fail(n, "expected " + expect + ", got " + describe(n));
}

std::string describe(const toml::node& n) {
  if (n.is_table()) return "a table";
  if (const toml::array* a = n.as_array())
    return a->empty() ? "an empty array" : "an array of " + std::to_string(a->size()) + (a->size() == 1 ? " value" : " values");
  if (auto s = n.value_exact<std::string>()) {
    std::string v = *s;
    if (v.size() > 60) v = v.substr(0, 57) + "...";
    return "\"" + v + "\"";
  }
  if (auto b = n.value_exact<bool>()) return *b ? "true" : "false";
  if (n.is_integer()) return std::to_string(*n.value_exact<std::int64_t>());
  if (auto d = n.value_exact<double>()) {
    std::ostringstream s;
    s << *d;
    return s.str();
  }
  return "a date or time";
}

namespace {

// Edits (insert, delete, substitute, swap two neighbours) from a to b: a
// swapped pair is one typo, not two.
std::size_t edit_distance(const std::string& a, const std::string& b) {
  std::vector<std::vector<std::size_t>> d(a.size() + 1, std::vector<std::size_t>(b.size() + 1));
  for (std::size_t i = 0; i <= a.size(); ++i) d[i][0] = i;
  for (std::size_t j = 0; j <= b.size(); ++j) d[0][j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i)
    for (std::size_t j = 1; j <= b.size(); ++j) {
      d[i][j] = std::min({d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + (a[i - 1] == b[j - 1] ? 0 : 1)});
      if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1]) d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
    }
  return d[a.size()][b.size()];
}

std::string fmt_number(double v) {
  std::ostringstream s;
  s << std::setprecision(15) << v;
  return s.str();
}

}  // namespace

std::string suggest(const std::string& word, const std::vector<std::string>& names) {
  // A typo is a few edits away; anything farther is another word, and a
  // wrong suggestion misleads more than none.
  const std::size_t limit = std::max<std::size_t>(1, std::min<std::size_t>(3, (word.size() + 1) / 3));
  std::string best;
  std::size_t best_d = limit + 1;
  for (const auto& n : names) {
    std::size_t d = edit_distance(word, n);
    // A key without its unit suffix (d0 for d0_m) is one slip, however short.
    if (!word.empty() && n.rfind(word + "_", 0) == 0) d = std::min<std::size_t>(d, 1);
    if (d < best_d) best = n, best_d = d;
  }
  return best;
}

std::string quoted_alternatives(const std::vector<std::string>& names) {
  std::string out;
  for (std::size_t i = 0; i < names.size(); ++i) {
    if (i > 0) out += i + 1 == names.size() ? " or " : ", ";
    out += "\"" + names[i] + "\"";
  }
  return out;
}

std::optional<std::int64_t> integral(const toml::node& n) {
  if (auto i = n.value_exact<std::int64_t>()) return i;
  const auto d = n.value_exact<double>();
  // 2^63 is exact as a double; everything in [-2^63, 2^63) converts safely.
  if (!d || !std::isfinite(*d) || *d < -0x1p63 || *d >= 0x1p63 || std::trunc(*d) != *d) return std::nullopt;
  return static_cast<std::int64_t>(*d);
}

std::string plural(const std::string& type) { return !type.empty() && type.back() == 's' ? type : type + "s"; }

std::string doc_value(const nlohmann::json& j) {
  if (j.is_number_float()) return fmt_number(j.get<double>());
  if (j.is_array()) {
    std::string out = "[";
    for (std::size_t i = 0; i < j.size(); ++i) out += (i ? ", " : "") + doc_value(j[i]);
    return out + "]";
  }
  if (j.is_object()) {  // as a TOML inline table
    std::string out;
    for (const auto& [k, v] : j.items()) out += (out.empty() ? "{ " : ", ") + k + " = " + doc_value(v);
    return out.empty() ? "{}" : out + " }";
  }
  return j.dump();
}

std::string Range::text() const {
  if (min && max)
    return "in " + std::string(min_open ? "(" : "[") + fmt_number(*min) + ", " + fmt_number(*max) + (max_open ? ")" : "]");
  if (min) return (min_open ? "> " : ">= ") + fmt_number(*min);
  if (max) return (max_open ? "< " : "<= ") + fmt_number(*max);
  return "";
}

bool Range::contains(double v) const {
  if (min && (min_open ? !(v > *min) : !(v >= *min))) return false;
  if (max && (max_open ? !(v < *max) : !(v <= *max))) return false;
  return true;
}

Value<bool> boolean() {
  Value<bool> v;
  v.type = "boolean";
  v.expect = "true or false";
  v.read = [](const toml::node& n, const At& at) {
    const auto b = n.value_exact<bool>();
    if (!b) at.expected(n, "true or false");
    return *b;
  };
  v.write = [](const bool& b) { return nlohmann::json(b); };
  return v;
}

Value<double> number(Range r) {
  Value<double> v;
  v.type = "number";
  v.range = r.text();
  // NaN and infinities are never meant: they would slip through every later
  // comparison unnoticed.
  v.expect = "a finite number" + (v.range.empty() ? "" : " " + v.range);
  v.read = [r, expect = v.expect](const toml::node& n, const At& at) {
    const auto x = n.is_boolean() ? std::nullopt : n.value<double>();
    if (!x || !std::isfinite(*x) || !r.contains(*x)) at.expected(n, expect);
    return *x;
  };
  v.write = [](const double& x) { return nlohmann::json(x); };
  return v;
}

Value<std::string> text() {
  Value<std::string> v;
  v.type = "string";
  v.expect = "a string";
  v.read = [](const toml::node& n, const At& at) {
    const auto s = n.value_exact<std::string>();
    if (!s) at.expected(n, "a string");
    return *s;
  };
  v.write = [](const std::string& s) { return nlohmann::json(s); };
  return v;
}

Value<std::string> choice(std::vector<std::string> names) {
  std::vector<std::pair<std::string, std::string>> pairs;
  for (const auto& n : names) pairs.emplace_back(n, n);
  Value<std::string> v = enumeration(pairs);
  // A field may hold a value outside the names that means "decide later"
  // (radiomap.region ""): it is written as it is.
  v.write = [](const std::string& s) { return nlohmann::json(s); };
  return v;
}

}  // namespace raysweep::pipeline::schema
