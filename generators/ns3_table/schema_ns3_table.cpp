// The ns-3 lookup table (raysweep-ns3-table) beyond its schema (the reader's
// own checks); its summary for `raysweep info`.
#include "generators/dataset/schema_validator.hpp"

#include <cstdio>
#include <sstream>

#include "generators/ns3_table/ns3_table.hpp"
#include "meshkit/errors.hpp"

namespace raysweep::generators::schema {

namespace {

// Rules of the ns-3 lookup table (raysweep-ns3-table) beyond the schema: the
// reader's own checks (frame times increasing, states sorted by node, pairs
// a < b strictly sorted within their frame, LoS classes, no NaN gains), run
// when the structure is sound.
class Ns3TableValidator : public Validator {
 public:
  using Validator::Validator;

 protected:
  void rules() override {
    if (!problems_.empty()) return;
    try {
      Ns3Table::load(path_);
    } catch (const meshkit::InputError& e) {
      const std::string what = e.what();
      problem(what.rfind(path_ + ": ", 0) == 0 ? what.substr(path_.size() + 2) : what);
    }
  }
};

void validate_ns3_table(const hdf5::CheckedFile& file, const nlohmann::json& schema, std::vector<std::string>& problems) {
  Ns3TableValidator(file, schema, problems).run();
}

// Summary of an ns-3 lookup table (format checked by the caller).
nlohmann::json ns3_table_info(const hdf5::CheckedFile& r) {
  nlohmann::json info = identity_info(r, kNs3TableFormat);
  for (const char* k : {"carrier_hz", "bandwidth_hz", "time_start_s", "time_end_s", "frame_step_s"})
    info[k] = r.attr_if<double>("/", k).value_or(0.0);
  const auto source = r.attr_if<std::uint64_t>("/", "gain_source").value_or(255);
  info["gain_source"] = source <= 1 ? gain_source_name(static_cast<GainSource>(source)) : "unknown";
  add_node_kinds(info, r);
  info["frames"] = r.column_rows("/frames/time_s");
  info["node_states"] = r.column_rows("/node_states/node");
  const hsize_t pairs = r.column_rows("/pairs/los_class");
  std::uint64_t los[3] = {0, 0, 0}, other_class = 0;
  r.scan_u64("/pairs/los_class", [&](const std::vector<std::uint64_t>& v) {
    for (auto c : v) (c < 3 ? los[c] : other_class) += 1;
  });
  info["pairs"] = pairs;
  info["los_counts"] = {{"LOS", los[0]}, {"NLOSV", los[1]}, {"NLOS", los[2]}};
  if (other_class) info["los_counts"]["invalid"] = other_class;
  std::uint64_t bands = 0;
  if (r.exists("/spectrum")) {
    r.group("/spectrum");
    bands = r.attr_if<std::uint64_t>("/spectrum", "band_count").value_or(0);
    info["band_width_hz"] = r.attr_if<double>("/spectrum", "band_width_hz").value_or(0.0);
  }
  info["bands"] = bands;
  add_file_size(info, r.path(), pairs, "bytes_per_pair_frame");
  return info;
}

std::string format_ns3_table_info(const nlohmann::json& info) {
  auto num = [&](const char* k) { return info.value(k, nlohmann::json(0)).get<std::uint64_t>(); };
  auto real = [&](const char* k) { return info.value(k, nlohmann::json(0.0)).get<double>(); };
  std::ostringstream o;
  char buf[256];
  o << identity_lines(info);
  std::snprintf(buf, sizeof buf, "frames        %llu (%.3f s .. %.3f s, step %.3g s)\n",
                static_cast<unsigned long long>(num("frames")), real("time_start_s"), real("time_end_s"),
                real("frame_step_s"));
  o << buf;
  std::snprintf(buf, sizeof buf, "nodes         %llu (%llu vehicles, %llu RSUs), %llu node states\n",
                static_cast<unsigned long long>(num("nodes")), static_cast<unsigned long long>(num("vehicles")),
                static_cast<unsigned long long>(num("rsus")), static_cast<unsigned long long>(num("node_states")));
  o << buf;
  const double pairs = static_cast<double>(num("pairs"));
  const auto& los = info.value("los_counts", nlohmann::json::object());
  auto pct = [&](const char* k) { return pairs > 0 ? 100.0 * los.value(k, 0.0) / pairs : 0.0; };
  std::snprintf(buf, sizeof buf, "pairs         %llu pair-frames: LOS %.1f %%, NLOSV %.1f %%, NLOS %.1f %%\n",
                static_cast<unsigned long long>(num("pairs")), pct("LOS"), pct("NLOSV"), pct("NLOS"));
  o << buf;
  std::snprintf(buf, sizeof buf, "gain          wideband from %s; carrier %.6g GHz, bandwidth %.6g MHz\n",
                info.value("gain_source", std::string()).c_str(), real("carrier_hz") / 1e9, real("bandwidth_hz") / 1e6);
  o << buf;
  if (num("bands"))
    std::snprintf(buf, sizeof buf, "spectrum      %llu bands of %.6g kHz\n", static_cast<unsigned long long>(num("bands")),
                  real("band_width_hz") / 1e3);
  else
    std::snprintf(buf, sizeof buf, "spectrum      none\n");
  o << buf;
  std::snprintf(buf, sizeof buf, "size          %s (%llu bytes), %.2f bytes per pair-frame\n",
                human_bytes(static_cast<double>(num("file_bytes"))).c_str(),
                static_cast<unsigned long long>(num("file_bytes")), real("bytes_per_pair_frame"));
  o << buf;
  return o.str();
}

}  // namespace

const FileFormat kNs3TableFile{kNs3TableFormat, &ns3_table_schema, &validate_ns3_table, &ns3_table_info,
                               &format_ns3_table_info};

}  // namespace raysweep::generators::schema
