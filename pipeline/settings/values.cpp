#include "pipeline/settings/values.hpp"

#include <filesystem>

#include "meshkit/materials.hpp"

namespace raysweep::pipeline::schema {

namespace fs = std::filesystem;
using json = nlohmann::json;

std::string joined(const std::vector<std::string>& names) {
  std::string out;
  for (const auto& n : names) out += (out.empty() ? "" : ", ") + n;
  return out;
}

std::string unknown(const std::string& what, const std::string& s, const std::vector<std::string>& names) {
  const std::string hint = suggest(s, names);
  return "unknown " + what + " '" + s + "'" + (hint.empty() ? " (" + joined(names) + ")" : " (did you mean '" + hint + "'?)");
}

Value<std::string> path() {
  Value<std::string> v = text();
  v.type = "path";
  v.range = "relative to the file";
  auto inner = v.read;
  v.read = [inner](const toml::node& n, const At& at) {
    const std::string p = inner(n, at);
    if (p.empty() || fs::path(p).is_absolute() || !at.src) return p;
    if (set_option(n)) return fs::absolute(p).lexically_normal().string();
    return (at.src->dir / p).lexically_normal().string();
  };
  return v;
}

Value<std::string> itu_material() {
  const auto& names = meshkit::itu_material_names();
  return parsed<std::string>(
      "string", "a P.2040 name: " + joined(names), "an ITU-R P.2040 material name",
      [&names](const std::string& s) {
        const auto m = meshkit::itu_material_from_id(s);
        if (!m) throw std::invalid_argument(unknown("ITU-R P.2040 material", s, names));
        return *m;
      },
      [](const std::string& s) { return json(s); });
}

std::vector<std::string> radio_material_names() {
  std::vector<std::string> names = meshkit::itu_material_names();
  for (const auto& c : meshkit::custom_materials()) names.push_back(c.name);
  return names;
}

Value<std::string> radio_material() {
  return parsed<std::string>(
      "string", "a P.2040 or custom material: " + joined(radio_material_names()), "a radio material name",
      [](const std::string& s) {
        if (!meshkit::is_radio_material(s)) throw std::invalid_argument(unknown("radio material", s, radio_material_names()));
        return s;
      },
      [](const std::string& s) { return json(s); });
}

Value<int> draco_bits() {
  return checked(integer<int>(), std::function<bool(const int&)>([](const int& b) { return b == 0 || (b >= 8 && b <= 30); }),
                 "an integer, 0 (lossless) or in 8..30", "0 or 8..30");
}

}  // namespace raysweep::pipeline::schema
