#include "meshkit/osm_tags.hpp"

#include <cctype>
#include <cmath>
#include <cstdlib>
#include <string>

namespace raysweep::meshkit {

namespace {

std::string_view trim(std::string_view s) {
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.front()))) s.remove_prefix(1);
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.remove_suffix(1);
  return s;
}

// Reads a non-negative decimal number at the front of `s` (dot or a single
// comma as decimal separator) and advances past it.
std::optional<double> take_number(std::string_view& s) {
  std::string digits;
  std::size_t i = 0;
  bool seen_sep = false, seen_digit = false;
  for (; i < s.size(); ++i) {
    const char c = s[i];
    if (std::isdigit(static_cast<unsigned char>(c))) {
      digits.push_back(c);
      seen_digit = true;
    } else if ((c == '.' || c == ',') && !seen_sep) {
      digits.push_back('.');
      seen_sep = true;
    } else {
      break;
    }
  }
  if (!seen_digit) return std::nullopt;
  s.remove_prefix(i);
  return std::strtod(digits.c_str(), nullptr);
}

}  // namespace

std::optional<double> parse_osm_length(std::string_view text) {
  std::string_view s = trim(text);
  if (s.empty()) return std::nullopt;
  auto value = take_number(s);
  if (!value) return std::nullopt;
  s = trim(s);
  double metres;
  if (s.empty() || s == "m" || s == "meter" || s == "meters" || s == "metre" || s == "metres") {
    metres = *value;
  } else if (s == "ft" || s == "feet" || s == "'") {
    metres = *value * 0.3048;
  } else if (s.front() == '\'') {
    // feet'inches"
    s.remove_prefix(1);
    s = trim(s);
    auto inches = take_number(s);
    if (!inches || trim(s) != "\"") return std::nullopt;
    metres = *value * 0.3048 + *inches * 0.0254;
  } else if (s == "cm") {
    metres = *value / 100.0;
  } else {
    return std::nullopt;
  }
  if (!std::isfinite(metres) || metres < 0) return std::nullopt;
  return metres;
}

std::optional<double> parse_osm_levels(std::string_view text) {
  std::string_view s = trim(text);
  if (auto semi = s.find(';'); semi != std::string_view::npos) s = trim(s.substr(0, semi));
  auto value = take_number(s);
  if (!value || !trim(s).empty() || !std::isfinite(*value)) return std::nullopt;
  return *value;
}

const char* to_string(HeightSource s) {
  switch (s) {
    case HeightSource::Height: return "height";
    case HeightSource::Levels: return "levels";
    case HeightSource::Default: return "default";
  }
  return "unknown";
}

ResolvedHeight resolve_height(const BuildingTags& tags, const HeightRules& rules) {
  ResolvedHeight r;
  auto note = [&r](const std::string& w) { r.warning += (r.warning.empty() ? "" : "; ") + w; };
  auto plausible = [&](double h) { return h > 0 && h <= rules.max_height_m; };

  if (tags.min_height) {
    auto v = parse_osm_length(tags.min_height);
    if (v && *v <= rules.max_height_m)
      r.base_m = *v;
    else
      note(std::string("unparsable min_height='") + tags.min_height + "'");
  } else if (tags.min_level) {
    auto v = parse_osm_levels(tags.min_level);
    if (v && *v >= 0)
      r.base_m = *v * rules.level_height_m;
    else
      note(std::string("unparsable building:min_level='") + tags.min_level + "'");
  }

  if (tags.height) {
    auto v = parse_osm_length(tags.height);
    if (v && plausible(*v) && *v > r.base_m) {
      r.top_m = *v;
      r.source = HeightSource::Height;
      return r;
    }
    note(std::string("unusable height='") + tags.height + "'");
  }
  if (tags.levels) {
    auto v = parse_osm_levels(tags.levels);
    double roof = 0;
    if (tags.roof_levels) {
      auto rl = parse_osm_levels(tags.roof_levels);
      if (rl && *rl >= 0)
        roof = *rl;
      else
        note(std::string("unparsable roof:levels='") + tags.roof_levels + "'");
    }
    if (v && *v >= 0 && (*v + roof) > 0) {
      const double h = (*v + roof) * rules.level_height_m;
      if (plausible(h) && h > r.base_m) {
        r.top_m = h;
        r.source = HeightSource::Levels;
        return r;
      }
    }
    note(std::string("unusable building:levels='") + tags.levels + "'");
  }
  r.top_m = std::max(rules.default_height_m, r.base_m + rules.level_height_m);
  r.source = HeightSource::Default;
  return r;
}

}  // namespace raysweep::meshkit
