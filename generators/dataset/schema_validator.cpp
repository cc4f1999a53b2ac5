// The generic, schema-driven validator (see schema_validator.hpp): attributes,
// groups, datasets (type, shape, symbolic dimensions, units), root counts,
// codes, bits, references, offsets, and a full read of every dataset; and the
// helpers every format's summary uses.
#include "generators/dataset/schema_validator.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>

namespace raysweep::generators::schema {

// The file's size, and per row of its main table (`per_key`).
void add_file_size(nlohmann::json& info, const std::string& path, std::uint64_t rows, const char* per_key) {
  std::error_code ec;
  const auto bytes = std::filesystem::file_size(path, ec);
  info["file_bytes"] = ec ? 0 : bytes;
  info[per_key] = rows && !ec ? static_cast<double>(bytes) / static_cast<double>(rows) : 0.0;
}

void Validator::run() {
  check_attributes("/", schema_.at("attributes"));
  for (const auto& g : schema_.at("groups")) check_group(g);
  check_root_counts(schema_.at("attributes"));
  for (const auto& g : schema_.at("groups"))
    for (const auto& d : g.at("datasets")) guarded(path_of(g, d), [&] { check_values(g, d); });
  rules();
  // Every row of every dataset, so damaged data is found even where no rule looks.
  for (const auto& entry : good_) guarded(entry.first, [&] { entry.second.read_every_row(); });
}

void Validator::check_attributes(const std::string& where, const nlohmann::json& specs) {
  const std::string prefix = where == "/" ? "attribute " : "attribute " + where + "@";
  for (const auto& a : specs) {
    const std::string name = a.at("name");
    const std::string dtype = a.at("dtype");
    const std::string label = prefix + name;
    if (!file_.has_attr(where, name)) {
      if (a.value("optional", false)) continue;
      if (name == "complete")
        problem(label + " missing: the file was not finished (its writer stopped before finish())");
      else
        problem(label + " missing");
      continue;
    }
    std::string why;
    const auto attr = file_.find_attr(where, name, &why);
    if (!attr) {
      problem(label + ": cannot open (" + why + ")");
      continue;
    }
    if (auto m = attr->type_mismatch(dtype); !m.empty()) {
      problem(label + ": type is " + m + ", expected " + dtype);
      continue;
    }
    if (!attr->scalar()) {
      problem(label + ": not a scalar");
      continue;
    }
    try {
      if (dtype == "str") {
        const std::string v = attr->str((where == "/" ? "/" : where + " ") + "attribute " + name);
        if (a.contains("value") && v != a.at("value").get<std::string>())
          problem(label + " is \"" + v + "\", expected \"" + a.at("value").get<std::string>() + "\"");
        if (a.value("json", false) && !nlohmann::json::accept(v)) problem(label + ": not valid JSON text");
        if (a.contains("one_of")) {
          const auto& allowed = a.at("one_of");
          if (std::find(allowed.begin(), allowed.end(), v) == allowed.end())
            problem(label + " is \"" + v + "\", expected one of " + allowed.dump());
        }
        if (name == "store") {
          store_name_ = v;
          store_rank_ = level_rank(v);
        }
        if (name == "schema_version") {
          file_version_ = v;
          const auto major = major_version(v);
          if (!major)
            problem(label + " \"" + v + "\" is not a MAJOR.MINOR.PATCH version");
          else if (*major != supported_major_)
            problem(label + " is " + v + ": major version " + std::to_string(*major) +
                    " is not supported (this program reads " + std::to_string(supported_major_) + ".x)");
        }
      } else if (dtype[0] == 'u') {
        const auto v = attr->num<std::uint64_t>(where + "attribute " + name);
        attr_values_[where + name] = v;
        if (a.contains("value") && v != a.at("value").get<std::uint64_t>())
          problem(label + " is " + std::to_string(v) + ", expected " + a.at("value").dump());
        if (a.contains("defines_dim")) bind(a.at("defines_dim"), v, label, "is");
        if (a.contains("codes") &&
            !schema_.at("codes").at(a.at("codes").get<std::string>()).at("values").contains(std::to_string(v)))
          problem(label + " is " + std::to_string(v) + ", not in the code table " + a.at("codes").get<std::string>());
      } else {
        const auto v = attr->num<double>(where + "attribute " + name);
        if (!std::isfinite(v)) problem(label + " is not finite");
      }
    } catch (const std::exception& e) {
      problem(label + ": " + text_of(e));
    }
  }
}

std::optional<std::size_t> Validator::level_rank(const std::string& level) const {
  for (const auto& a : schema_.at("attributes")) {
    if (a.at("name") != "store" || !a.contains("one_of")) continue;
    const auto& levels = a.at("one_of");
    for (std::size_t i = 0; i < levels.size(); ++i)
      if (levels[i] == level) return i;
  }
  return std::nullopt;
}

bool Validator::stored(const nlohmann::json& spec, const std::string& p, bool present) {
  if (!spec.contains("stored_from") || !store_rank_) return true;
  const auto from = level_rank(spec.at("stored_from").get<std::string>());
  if (!from || *store_rank_ >= *from) return true;
  if (present)
    problem(p + ": present, but the file's store level " + store_name_ + " stores it only from level " +
            spec.at("stored_from").get<std::string>());
  return false;
}

void Validator::check_group(const nlohmann::json& g) {
  const std::string name = g.at("name");
  const std::string gpath = "/" + name;
  if (!stored(g, gpath, file_.exists(gpath))) return;
  if (!file_.exists(gpath)) {
    if (!g.value("optional", false)) problem(gpath + ": group missing");
    return;
  }
  if (std::string why; !file_.is_group(gpath, &why)) {
    problem(gpath + ": not a group (" + why + ")");
    return;
  }
  if (g.contains("attributes")) check_attributes(gpath, g.at("attributes"));
  for (const auto& d : g.at("datasets")) check_dataset(g, d);
}

void Validator::check_dataset(const nlohmann::json& g, const nlohmann::json& d) {
  const std::string p = path_of(g, d);
  if (!stored(d, p, file_.exists(p))) return;
  if (!file_.exists(p)) {
    // Added in a later minor version: files written before it lack it.
    if (d.contains("since") &&
        version_triple(file_version_) < version_triple(d.at("since").get<std::string>()))
      return;
    problem(p + ": dataset missing");
    return;
  }
  std::string why;
  auto ds = file_.find_dataset(p, &why);
  if (!ds) {
    problem(p + ": not a dataset or unreadable (" + why + ")");
    return;
  }
  const std::string dtype = d.at("dtype");
  const auto m = ds->type_mismatch(dtype);
  if (!m) {
    problem(p + ": cannot get type");
    return;
  }
  if (!m->empty()) {
    problem(p + ": type is " + *m + ", expected " + dtype);
    return;
  }
  std::vector<hsize_t> dims;
  try {
    dims = ds->dims();
  } catch (const std::exception& e) {
    problem(text_of(e));
    return;
  }
  const auto& shape = d.at("shape");
  if (dims.size() != shape.size()) {
    problem(p + ": rank " + std::to_string(dims.size()) + ", expected " + std::to_string(shape.size()) + " (shape " +
            shape.dump() + ")");
    return;
  }
  bool ok = true;
  for (std::size_t i = 0; i < dims.size(); ++i) {
    if (shape[i].is_number()) {
      if (dims[i] != shape[i].get<hsize_t>()) {
        problem(p + ": dimension " + std::to_string(i) + " is " + std::to_string(dims[i]) + ", expected " +
                shape[i].dump());
        ok = false;
      }
    } else {
      ok = bind(shape[i].get<std::string>(), dims[i], p, i == 0 ? "has length" : "dimension " + std::to_string(i) + " is") && ok;
    }
  }
  for (const char* attr : {"units", "description"}) {
    if (!file_.has_attr(p, attr)) {
      problem(p + ": attribute " + std::string(attr) + " missing");
      continue;
    }
    try {
      const std::string v = file_.attr<std::string>(p, attr);
      if (std::string(attr) == "units" && v != d.at("units").get<std::string>())
        problem(p + ": units are \"" + v + "\", expected \"" + d.at("units").get<std::string>() + "\"");
    } catch (const std::exception& e) {
      problem(p + ": " + text_of(e));
    }
  }
  if (ok) good_.emplace(p, std::move(*ds));
}

void Validator::check_root_counts(const nlohmann::json& specs) {
  for (const auto& a : specs) {
    if (!a.contains("equals_dim")) continue;
    const std::string name = a.at("name");
    auto it = attr_values_.find("/" + name);
    const auto d = dim(a.at("equals_dim"));
    if (it == attr_values_.end() || !d) continue;
    if (it->second != *d)
      problem("attribute " + name + " is " + std::to_string(it->second) + " but " + a.at("equals_dim").get<std::string>() +
              " = " + std::to_string(*d) + " (from " + dims_.at(a.at("equals_dim")).second + ")");
  }
}

void Validator::check_values(const nlohmann::json& g, const nlohmann::json& d) {
  const std::string p = path_of(g, d);
  const hdf5::Dataset* ds = dset(p);
  if (!ds) return;
  const auto& codes = schema_.at("codes");
  std::set<std::uint64_t> allowed;
  std::string allowed_text;
  if (d.contains("codes")) {
    for (const auto& [k, v] : codes.at(d.at("codes").get<std::string>()).at("values").items()) {
      allowed.insert(std::stoull(k));
      allowed_text += (allowed_text.empty() ? "" : ", ") + k;
    }
  }
  std::uint64_t mask = ~std::uint64_t{0};
  if (d.contains("bits")) {
    mask = 0;
    for (const auto& [k, v] : codes.at(d.at("bits").get<std::string>()).at("bits").items())
      mask |= std::uint64_t{1} << std::stoul(k);
  }
  std::optional<hsize_t> limit;
  std::string ref;
  if (d.contains("references")) {
    ref = d.at("references");
    limit = dim(ref);
    if (!limit) return;  // the referenced table is missing: reported already
  }
  const bool offsets = d.contains("offsets");
  const hdf5::Dataset* count_ds = nullptr;
  std::string count_path, total_sym;
  if (offsets) {
    count_path = "/" + g.at("name").get<std::string>() + "/" + d.at("offsets").at("count").get<std::string>();
    total_sym = d.at("offsets").at("total");
    count_ds = dset(count_path);
    if (!count_ds) return;
  }
  if (allowed.empty() && mask == ~std::uint64_t{0} && !limit && !offsets) return;

  const hsize_t rows = ds->rows();
  Tally bad_code, bad_bits, bad_ref, bad_offset;
  std::uint64_t running = 0;
  for (hsize_t start = 0; start < rows; start += kBlockRows) {
    const hsize_t n = std::min(kBlockRows, rows - start);
    const auto v = ds->read<std::uint64_t>(start, n);
    std::vector<std::uint64_t> counts;
    if (offsets) counts = count_ds->read<std::uint64_t>(start, n);
    for (hsize_t i = 0; i < n; ++i) {
      const std::uint64_t x = v[i];
      if (!allowed.empty() && !allowed.count(x)) bad_code.add(start + i, std::to_string(x));
      if (x & ~mask) bad_bits.add(start + i, std::to_string(x));
      if (limit && x >= *limit) bad_ref.add(start + i, std::to_string(x));
      if (offsets) {
        if (x != running)
          bad_offset.add(start + i, std::to_string(x) + ", expected " + std::to_string(running));
        running += counts[i];
      }
    }
  }
  bad_code.report(problems_, p, "not in the code table {" + allowed_text + "}");
  bad_bits.report(problems_, p, "with unknown flag bits");
  bad_ref.report(problems_, p, "not below " + ref + " = " + std::to_string(limit.value_or(0)));
  bad_offset.report(problems_, p, "not equal to the running sum of " + count_path);
  if (offsets) {
    const auto total = dim(total_sym);
    bool ok = bad_offset.count == 0;
    if (total && running != *total) {
      problem(p + ": the counts in " + count_path + " sum to " + std::to_string(running) + " but " + total_sym + " = " +
              std::to_string(*total) + " (from " + dims_.at(total_sym).second + ")");
      ok = false;
    }
    if (ok && total) offsets_ok_.insert(p);
  }
}

std::string root_str(const hdf5::CheckedFile& r, const std::string& name, const std::string& fallback) {
  return r.attr_if<std::string>("/", name).value_or(fallback);
}

// Nodes by kind (the node table is written by finish(): absent in an unfinished file).
void add_node_kinds(nlohmann::json& info, const hdf5::CheckedFile& r) {
  std::uint64_t vehicles = 0, rsus = 0, nodes = 0;
  if (r.exists("/nodes/kind"))
    r.scan_u64("/nodes/kind", [&](const std::vector<std::uint64_t>& k) {
      for (auto v : k) (v == 1 ? rsus : vehicles) += 1;
      nodes += k.size();
    });
  info["nodes"] = nodes;
  info["vehicles"] = vehicles;
  info["rsus"] = rsus;
}

std::string human_bytes(double b) {
  const char* units[] = {"B", "KiB", "MiB", "GiB", "TiB"};
  int u = 0;
  while (b >= 1024 && u < 4) b /= 1024, ++u;
  char buf[64];
  std::snprintf(buf, sizeof buf, u == 0 ? "%.0f %s" : "%.1f %s", b, units[u]);
  return buf;
}

nlohmann::json identity_info(const hdf5::CheckedFile& r, const char* format) {
  nlohmann::json info;
  info["file"] = r.path();
  info["format"] = format;
  info["schema_version"] = root_str(r, "schema_version");
  info["raysweep_version"] = root_str(r, "raysweep_version");
  info["git_hash"] = root_str(r, "git_hash");
  info["complete"] = r.attr_if<std::uint64_t>("/", "complete").value_or(0) == 1;
  return info;
}

// The first lines of both formats' summaries: file, completeness, format and writer.
std::string identity_lines(const nlohmann::json& info) {
  auto text = [&](const char* k) { return info.value(k, std::string()); };
  return "file          " + text("file") + (info.value("complete", false) ? "" : "  (INCOMPLETE: writer did not finish)") +
         "\nformat        " + text("format") + " " + text("schema_version") + ", written by raysweep " +
         text("raysweep_version") + " (" + text("git_hash") + ")\n";
}

}  // namespace raysweep::generators::schema
