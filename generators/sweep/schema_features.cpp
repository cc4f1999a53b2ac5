// The context-feature file (raysweep-features) beyond its schema: rows in
// the channel dataset's link order and range, vehicle slots filled before the
// empty ones; its summary for `raysweep info`.
#include "generators/dataset/schema_validator.hpp"

#include <cmath>
#include <cstdio>
#include <sstream>

#include "generators/sweep/context_features.hpp"

namespace raysweep::generators::schema {

namespace {

class FeaturesValidator : public Validator {
 public:
  using Validator::Validator;

 protected:
  void rules() override {
    guarded("/links/link", [&] { check_rows(); });
    guarded("/vehicles/vclass", [&] { check_slots(); });
  }

 private:
  std::uint64_t root(const char* name) const {
    auto it = attr_values_.find(std::string("/") + name);
    return it == attr_values_.end() ? ~std::uint64_t{0} : it->second;
  }

  void check_rows() {
    const hdf5::Dataset* link = dset("/links/link"), *frame = dset("/links/frame");
    if (!link || !frame) return;
    const hsize_t m = link->rows();
    const auto l = link->read<std::uint64_t>(0, m);
    const auto f = frame->read<std::uint64_t>(0, m);
    const std::uint64_t L = root("dataset_link_count"), F = root("dataset_frame_count");
    Tally order, range;
    for (hsize_t i = 0; i < m; ++i) {
      if (i > 0 && (l[i] <= l[i - 1] || f[i] < f[i - 1])) order.add(i, "link " + std::to_string(l[i]));
      if (l[i] >= L || f[i] >= F) range.add(i, "link " + std::to_string(l[i]) + ", frame " + std::to_string(f[i]));
    }
    order.report(problems_, "/links/link", "not after the previous row's link and frame");
    range.report(problems_, "/links", "beyond the channel dataset's links or frames (dataset_link_count, dataset_frame_count)");
  }

  // Slots below count hold a vehicle class of the table, the others 255.
  void check_slots() {
    const hdf5::Dataset* count = dset("/vehicles/count"), *vclass = dset("/vehicles/vclass");
    if (!count || !vclass) return;
    const auto k = dim("K");
    if (!k || *k == 0) return;
    const hsize_t m = count->rows();
    const auto& table = schema_.at("codes").at("vehicle_class").at("values");
    Tally bad;
    for (hsize_t start = 0; start < m; start += kBlockRows) {
      const hsize_t n = std::min(kBlockRows, m - start);
      const auto c = count->read<std::uint64_t>(start, n);
      const auto v = vclass->read<std::uint64_t>(start, n, *k);
      for (hsize_t r = 0; r < n; ++r) {
        if (c[r] > *k) bad.add(start + r, "count " + std::to_string(c[r]) + " > max_vehicles");
        for (hsize_t s = 0; s < *k; ++s) {
          const std::uint64_t code = v[r * *k + s];
          const bool ok = s < c[r] ? table.contains(std::to_string(code)) : code == kNoVehicle;
          if (!ok) bad.add(start + r, "slot " + std::to_string(s) + " class " + std::to_string(code));
        }
      }
    }
    bad.report(problems_, "/vehicles", "with a filled slot outside the vehicle_class table or an empty slot not 255");
  }
};

void validate_features(const hdf5::CheckedFile& file, const nlohmann::json& schema, std::vector<std::string>& problems) {
  FeaturesValidator(file, schema, problems).run();
}

nlohmann::json features_info(const hdf5::CheckedFile& r) {
  nlohmann::json info = identity_info(r, kFeaturesFormat);
  for (const char* k : {"along_cells", "across_cells", "max_vehicles", "frame_stride", "dataset_link_count"})
    info[k] = r.attr_if<std::uint64_t>("/", k).value_or(0);
  for (const char* k : {"half_width_m", "height_scale_m", "map_resolution_m"})
    info[k] = r.attr_if<double>("/", k).value_or(0.0);
  const hsize_t rows = r.column_rows("/links/link");
  info["rows"] = rows;
  std::uint64_t vehicles = 0;
  r.scan_u64("/vehicles/count", [&](const std::vector<std::uint64_t>& v) {
    for (auto c : v) vehicles += c;
  });
  info["mean_vehicles_per_row"] = rows ? static_cast<double>(vehicles) / static_cast<double>(rows) : 0.0;
  add_file_size(info, r.path(), rows, "bytes_per_row");
  return info;
}

std::string format_features_info(const nlohmann::json& info) {
  auto num = [&](const char* k) { return static_cast<unsigned long long>(info.value(k, nlohmann::json(0)).get<std::uint64_t>()); };
  auto real = [&](const char* k) { return info.value(k, nlohmann::json(0.0)).get<double>(); };
  std::ostringstream o;
  char buf[256];
  o << identity_lines(info);
  std::snprintf(buf, sizeof buf, "rows          %llu (frame stride %llu; the dataset has %llu links)\n",
                num("rows"), num("frame_stride"), num("dataset_link_count"));
  o << buf;
  std::snprintf(buf, sizeof buf, "corridor      %llu x %llu cells, +-%.1f m wide, heights in %.2f m steps, map %.2f m\n",
                num("along_cells"), num("across_cells"), real("half_width_m"), real("height_scale_m"),
                real("map_resolution_m"));
  o << buf;
  std::snprintf(buf, sizeof buf, "vehicles      %.2f a row on average (%llu slots)\n", real("mean_vehicles_per_row"),
                num("max_vehicles"));
  o << buf;
  std::snprintf(buf, sizeof buf, "size          %s (%.0f bytes a row)\n",
                human_bytes(static_cast<double>(info.value("file_bytes", nlohmann::json(0)).get<std::uint64_t>())).c_str(),
                real("bytes_per_row"));
  o << buf;
  return o.str();
}

}  // namespace

const FileFormat kFeaturesFile{kFeaturesFormat, &features_schema, &validate_features, &features_info,
                               &format_features_info};

}  // namespace raysweep::generators::schema
