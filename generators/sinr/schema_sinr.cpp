// The SINR outcome file (raysweep-sinr) beyond its schema: schedule order,
// receptions vs transmissions, overlaps, PRR; its summary for `raysweep info`.
#include "generators/dataset/schema_validator.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <sstream>

#include "generators/sinr/sinr_file.hpp"

namespace raysweep::generators::schema {

namespace {

// Rules of the SINR outcome file (raysweep-sinr) beyond the schema: schedule
// order and physical sanity of the transmissions, receptions sorted and agreeing
// with their transmission, overlap rows agreeing with their reception, PRR values.
class SinrValidator : public Validator {
 public:
  using Validator::Validator;

 protected:
  void rules() override {
    guarded("/transmissions", [&] { check_transmissions(); });
    guarded("/receptions", [&] { check_receptions(); });
    guarded("/prr_links", [&] { check_prr("prr_links"); });
    guarded("/prr_rats", [&] { check_prr("prr_rats"); });
  }

 private:
  void check_transmissions() {
    const hdf5::Dataset* start = dset("/transmissions/start_s"), *dur = dset("/transmissions/duration_s");
    const hdf5::Dataset* band = dset("/transmissions/band_hz"), *rat = dset("/transmissions/rat");
    Tally order, duration, band_bad, rat_none;
    double prev = -std::numeric_limits<double>::infinity();
    if (start) {
      const hsize_t rows = start->rows();
      for (hsize_t s = 0; s < rows; s += kBlockRows) {
        const auto t = start->read<double>(s, std::min(kBlockRows, rows - s));
        for (std::size_t i = 0; i < t.size(); ++i) {
          if (!std::isfinite(t[i]))
            order.add(s + i, "not finite");
          else if (t[i] < prev)
            order.add(s + i, std::to_string(t[i]) + " s after " + std::to_string(prev) + " s");
          if (std::isfinite(t[i])) prev = t[i];
        }
      }
    }
    if (dur) {
      const hsize_t rows = dur->rows();
      for (hsize_t s = 0; s < rows; s += kBlockRows) {
        const auto d = dur->read<double>(s, std::min(kBlockRows, rows - s));
        for (std::size_t i = 0; i < d.size(); ++i)
          if (!(std::isfinite(d[i]) && d[i] > 0)) duration.add(s + i, std::to_string(d[i]) + " s");
      }
    }
    if (band) {
      const hsize_t rows = band->rows();
      for (hsize_t s = 0; s < rows; s += kBlockRows) {
        const hsize_t n = std::min(kBlockRows, rows - s);
        const auto b = band->read<double>(s, n, 2);
        for (hsize_t i = 0; i < n; ++i) {
          const double lo = b[2 * i], hi = b[2 * i + 1];
          if (!(std::isfinite(lo) && std::isfinite(hi) && lo < hi))
            band_bad.add(s + i, "[" + std::to_string(lo) + ", " + std::to_string(hi) + "] Hz");
        }
      }
    }
    if (rat) {
      const hsize_t rows = rat->rows();
      for (hsize_t s = 0; s < rows; s += kBlockRows) {
        const auto r = rat->read<std::uint64_t>(s, std::min(kBlockRows, rows - s));
        for (std::size_t i = 0; i < r.size(); ++i)
          if (r[i] == 0) rat_none.add(s + i, "rat 0");
      }
    }
    order.report(problems_, "/transmissions/start_s", "not finite or before the previous transmission's start");
    duration.report(problems_, "/transmissions/duration_s", "not finite and > 0");
    band_bad.report(problems_, "/transmissions/band_hz", "without finite f_lo < f_hi");
    rat_none.report(problems_, "/transmissions/rat", "of RAT none (0)");
  }

  // A column of /transmissions read as u64 or f64 for lookups by row; empty reader
  // when the dataset failed the structural checks.
  std::optional<BlockReader<std::uint64_t>> tx_u64(const std::string& name) const {
    const std::string p = "/transmissions/" + name;
    const hdf5::Dataset* ds = dset(p);
    if (!ds) return std::nullopt;
    return BlockReader<std::uint64_t>(*ds, ds->rows());
  }

  void check_receptions() {
    const hdf5::Dataset* tr = dset("/receptions/transmission"), *tx = dset("/receptions/tx"), *rx = dset("/receptions/rx");
    if (!tr) return;
    const hsize_t rows = tr->rows();
    const hsize_t transmissions = dim("T").value_or(0);
    auto t_node = tx_u64("node"), t_rat = tx_u64("rat"), t_packet = tx_u64("packet"), t_attempt = tx_u64("attempt");
    std::optional<BlockReader<double>> t_start;
    if (const hdf5::Dataset* ds = dset("/transmissions/start_s")) t_start.emplace(*ds, ds->rows());

    // The RAT of every transmission, for the inter_rat flag of overlaps (random access).
    std::vector<std::uint8_t> rat_of;
    if (t_rat)
      for (hsize_t i = 0; i < t_rat->rows(); ++i) rat_of.push_back(static_cast<std::uint8_t>(t_rat->at(i)));

    // Overlap rows, when their offsets passed (so every range lies inside /interferers).
    const bool overlaps = offsets_ok_.count("/receptions/overlap_offset") > 0;
    const hdf5::Dataset* o_tr = dset("/interferers/transmission"), *o_counted = dset("/interferers/counted");
    const hdf5::Dataset* o_inter = dset("/interferers/inter_rat");
    std::optional<BlockReader<std::uint64_t>> ov_tr, ov_counted, ov_inter;
    const hsize_t x = dim("X").value_or(0);
    if (overlaps && o_tr) ov_tr.emplace(*o_tr, x);
    if (overlaps && o_counted) ov_counted.emplace(*o_counted, x);
    if (overlaps && o_inter) ov_inter.emplace(*o_inter, x);

    auto column = [&](const char* name, hsize_t start, hsize_t n) {
      const std::string p = std::string("/receptions/") + name;
      const hdf5::Dataset* ds = dset(p);
      return ds ? ds->read<std::uint64_t>(start, n) : std::vector<std::uint64_t>();
    };
    Tally unsorted, self, tx_bad, rat_bad, packet_bad, attempt_bad, time_bad, count_bad, own, inter_bad;
    std::pair<std::uint64_t, std::uint64_t> prev{0, 0};
    for (hsize_t start = 0; start < rows; start += kBlockRows) {
      const hsize_t n = std::min(kBlockRows, rows - start);
      const auto t = tr->read<std::uint64_t>(start, n);
      const auto s = tx ? tx->read<std::uint64_t>(start, n) : std::vector<std::uint64_t>();
      const auto r = rx ? rx->read<std::uint64_t>(start, n) : std::vector<std::uint64_t>();
      const auto rat = column("rat", start, n), packet = column("packet", start, n), attempt = column("attempt", start, n);
      const auto counted = column("interferers", start, n);
      const auto ocount = overlaps ? column("overlap_count", start, n) : std::vector<std::uint64_t>();
      const auto ooffset = overlaps ? column("overlap_offset", start, n) : std::vector<std::uint64_t>();
      std::vector<double> time;
      if (const hdf5::Dataset* ds = dset("/receptions/time_s")) time = ds->read<double>(start, n);
      for (hsize_t i = 0; i < n; ++i) {
        const std::uint64_t row = start + i;
        if (!r.empty()) {
          const std::pair<std::uint64_t, std::uint64_t> key{t[i], r[i]};
          if (row > 0 && !(prev < key))
            unsorted.add(row, "(" + std::to_string(t[i]) + ", " + std::to_string(r[i]) + ") after (" +
                                  std::to_string(prev.first) + ", " + std::to_string(prev.second) + ")");
          prev = key;
          if (!s.empty() && s[i] == r[i]) self.add(row, "node " + std::to_string(r[i]));
        }
        if (t[i] >= transmissions) continue;  // out of range: reported by the reference check
        auto at = [&] { return "transmission " + std::to_string(t[i]); };
        if (!s.empty() && t_node && s[i] != t_node->at(t[i]))
          tx_bad.add(row, "tx " + std::to_string(s[i]) + ", " + at() + " is sent by node " + std::to_string(t_node->at(t[i])));
        if (!rat.empty() && t_rat && rat[i] != t_rat->at(t[i]))
          rat_bad.add(row, "rat " + std::to_string(rat[i]) + ", " + at() + " has " + std::to_string(t_rat->at(t[i])));
        if (!packet.empty() && t_packet && packet[i] != t_packet->at(t[i]))
          packet_bad.add(row, "packet " + std::to_string(packet[i]) + ", " + at() + " has " + std::to_string(t_packet->at(t[i])));
        if (!attempt.empty() && t_attempt && attempt[i] != t_attempt->at(t[i]))
          attempt_bad.add(row, "attempt " + std::to_string(attempt[i]) + ", " + at() + " has " +
                                   std::to_string(t_attempt->at(t[i])));
        if (!time.empty() && t_start && !(time[i] == t_start->at(t[i])))
          time_bad.add(row, std::to_string(time[i]) + " s, " + at() + " starts at " + std::to_string(t_start->at(t[i])) + " s");
        if (!ooffset.empty() && ov_tr) {
          std::uint64_t c = 0;
          for (std::uint64_t k = ooffset[i]; k < ooffset[i] + ocount[i]; ++k) {
            const std::uint64_t other = ov_tr->at(k);
            if (other == t[i]) own.add(k, "reception row " + std::to_string(row) + " overlaps its own " + at());
            if (ov_counted && ov_counted->at(k) == 1) ++c;
            if (ov_inter && !rat.empty() && other < rat_of.size() && ov_inter->at(k) != (rat_of[other] != rat[i] ? 1u : 0u))
              inter_bad.add(k, "inter_rat " + std::to_string(ov_inter->at(k)) + " but transmission " +
                                   std::to_string(other) + " has rat " + std::to_string(rat_of[other]) +
                                   " and the reception " + std::to_string(rat[i]));
          }
          if (ov_counted && !counted.empty() && counted[i] != c)
            count_bad.add(row, std::to_string(counted[i]) + " interferers, " + std::to_string(c) + " counted overlap rows");
        }
      }
    }
    unsorted.report(problems_, "/receptions/transmission", "not strictly sorted by (transmission, rx)");
    self.report(problems_, "/receptions/rx", "equal to /receptions/tx");
    tx_bad.report(problems_, "/receptions/tx", "differing from /transmissions/node of their transmission");
    rat_bad.report(problems_, "/receptions/rat", "differing from /transmissions/rat of their transmission");
    packet_bad.report(problems_, "/receptions/packet", "differing from /transmissions/packet of their transmission");
    attempt_bad.report(problems_, "/receptions/attempt", "differing from /transmissions/attempt of their transmission");
    time_bad.report(problems_, "/receptions/time_s", "differing from /transmissions/start_s of their transmission");
    count_bad.report(problems_, "/receptions/interferers",
                     "differing from the number of their /interferers rows with counted = 1");
    own.report(problems_, "/interferers/transmission", "naming the reception's own transmission");
    inter_bad.report(problems_, "/interferers/inter_rat", "disagreeing with the RATs of the transmissions");
  }

  // received <= packets; prr = received / packets (NaN when packets = 0); links tx != rx.
  void check_prr(const std::string& group) {
    const std::string g = "/" + group + "/";
    const hdf5::Dataset* pk = dset(g + "packets"), *rc = dset(g + "received"), *pr = dset(g + "prr");
    const hdf5::Dataset* tx = dset(g + "tx"), *rx = dset(g + "rx");
    Tally too_many, bad_prr, self;
    if (pk && rc) {
      const hsize_t rows = pk->rows();
      for (hsize_t s = 0; s < rows; s += kBlockRows) {
        const hsize_t n = std::min(kBlockRows, rows - s);
        const auto p = pk->read<std::uint64_t>(s, n), r = rc->read<std::uint64_t>(s, n);
        const auto q = pr ? pr->read<double>(s, n) : std::vector<double>();
        for (hsize_t i = 0; i < n; ++i) {
          if (r[i] > p[i]) too_many.add(s + i, std::to_string(r[i]) + " received of " + std::to_string(p[i]) + " packets");
          if (q.empty()) continue;
          auto detail = [&] {
            return "prr " + std::to_string(q[i]) + " with " + std::to_string(r[i]) + " of " + std::to_string(p[i]) +
                   " packets";
          };
          if (p[i] == 0) {
            if (!std::isnan(q[i])) bad_prr.add(s + i, detail());
          } else if (!(q[i] >= 0 && q[i] <= 1) ||
                     (r[i] <= p[i] && std::abs(q[i] - static_cast<double>(r[i]) / static_cast<double>(p[i])) > 1e-6)) {
            bad_prr.add(s + i, detail());
          }
        }
      }
    }
    if (tx && rx) {
      const hsize_t rows = tx->rows();
      for (hsize_t s = 0; s < rows; s += kBlockRows) {
        const hsize_t n = std::min(kBlockRows, rows - s);
        const auto a = tx->read<std::uint64_t>(s, n), b = rx->read<std::uint64_t>(s, n);
        for (hsize_t i = 0; i < n; ++i)
          if (a[i] == b[i]) self.add(s + i, "node " + std::to_string(a[i]));
      }
    }
    too_many.report(problems_, g + "received", "above " + g + "packets");
    bad_prr.report(problems_, g + "prr", "not received / packets in [0, 1] (NaN when packets = 0)");
    self.report(problems_, g + "rx", "equal to " + g + "tx");
  }
};

void validate_sinr(const hdf5::CheckedFile& file, const nlohmann::json& schema, std::vector<std::string>& problems) {
  SinrValidator(file, schema, problems).run();
}

// Summary of a SINR outcome file (format checked by the caller).
nlohmann::json sinr_info(const hdf5::CheckedFile& r) {
  nlohmann::json info = identity_info(r, sinr::kSinrFormat);
  info["channel_model"] = root_str(r, "channel_model", "");
  info["los_from_ray"] = r.attr_if<std::uint64_t>("/", "los_from_ray").value_or(0) != 0;
  for (const char* k :
       {"carrier_hz", "sinr_threshold_db", "sensitivity_dbm", "gain_threshold_db", "time_start_s", "time_end_s"})
    info[k] = r.attr_if<double>("/", k).value_or(0.0);

  // The node and PRR tables are written by finish(): absent in an unfinished file.
  info["nodes"] = r.exists("/nodes/id") ? r.column_rows("/nodes/id") : 0;
  info["transmissions"] = r.column_rows("/transmissions/start_s");
  info["receptions"] = r.column_rows("/receptions/decoded");
  info["interferers"] = r.column_rows("/interferers/transmission");
  std::uint64_t decoded = 0;
  r.scan_u64("/receptions/decoded", [&](const std::vector<std::uint64_t>& v) {
    for (auto d : v) decoded += d == 1 ? 1 : 0;
  });
  info["decoded"] = decoded;
  info["prr_links"] = r.exists("/prr_links/prr") ? r.column_rows("/prr_links/prr") : 0;

  nlohmann::json prr = nlohmann::json::object();
  if (r.exists("/prr_rats/rat")) {
    const auto rat = r.all_u64("/prr_rats/rat");
    const auto packets = r.all_u64("/prr_rats/packets");
    const auto received = r.all_u64("/prr_rats/received");
    const auto ratio = r.all_f64("/prr_rats/prr");
    if (packets.size() != rat.size() || received.size() != rat.size() || ratio.size() != rat.size())
      r.fail("/prr_rats", "datasets of different lengths");
    const auto& names = sinr_schema().at("codes").at("rat").at("values");
    for (std::size_t i = 0; i < rat.size(); ++i) {
      const std::string code = std::to_string(rat[i]);
      const std::string name = names.contains(code) ? names.at(code).get<std::string>() : "rat " + code;
      nlohmann::json entry = {{"packets", packets[i]}, {"received", received[i]}};
      entry["prr"] = std::isnan(ratio[i]) ? nlohmann::json(nullptr) : nlohmann::json(ratio[i]);
      prr[name] = entry;
    }
  }
  info["prr"] = prr;

  std::error_code ec;
  const auto bytes = std::filesystem::file_size(r.path(), ec);
  info["file_bytes"] = ec ? 0 : bytes;
  return info;
}

std::string format_sinr_info(const nlohmann::json& info) {
  auto num = [&](const char* k) { return info.value(k, nlohmann::json(0)).get<std::uint64_t>(); };
  auto real = [&](const char* k) { return info.value(k, nlohmann::json(0.0)).get<double>(); };
  auto text = [&](const char* k) { return info.value(k, std::string()); };
  std::ostringstream o;
  char buf[256];
  o << identity_lines(info);
  std::snprintf(buf, sizeof buf, "channel       %s%s, carrier %.6g GHz\n", text("channel_model").c_str(),
                info.value("los_from_ray", false) ? " (LoS class from the traced links)" : "", real("carrier_hz") / 1e9);
  o << buf;
  std::snprintf(buf, sizeof buf, "decoding      SINR >= %.6g dB, sensitivity %.6g dBm, inter-RAT gain >= %.6g dB\n",
                real("sinr_threshold_db"), real("sensitivity_dbm"), real("gain_threshold_db"));
  o << buf;
  std::snprintf(buf, sizeof buf, "interval      %.3f s .. %.3f s\n", real("time_start_s"), real("time_end_s"));
  o << buf;
  o << "nodes         " << num("nodes") << "\n";
  o << "transmissions " << num("transmissions") << "\n";
  const std::uint64_t receptions = num("receptions");
  std::snprintf(buf, sizeof buf, "receptions    %llu (%llu decoded, %.1f %%)\n", static_cast<unsigned long long>(receptions),
                static_cast<unsigned long long>(num("decoded")),
                receptions ? 100.0 * static_cast<double>(num("decoded")) / static_cast<double>(receptions) : 0.0);
  o << buf;
  o << "interferers   " << num("interferers") << " overlap rows\n";
  o << "PRR links     " << num("prr_links") << "\n";
  const auto prr = info.value("prr", nlohmann::json::object());
  if (prr.empty()) o << "PRR           none\n";
  bool first = true;
  for (const auto& [name, e] : prr.items()) {
    const auto packets = e.value("packets", std::uint64_t{0}), received = e.value("received", std::uint64_t{0});
    const std::string ratio = e.contains("prr") && e.at("prr").is_number()
                                  ? (std::snprintf(buf, sizeof buf, "%.4f", e.at("prr").get<double>()), std::string(buf))
                                  : std::string("n/a");
    std::snprintf(buf, sizeof buf, "%s%-7s %s (%llu of %llu packets)\n", first ? "PRR           " : "              ",
                  name.c_str(), ratio.c_str(), static_cast<unsigned long long>(received),
                  static_cast<unsigned long long>(packets));
    o << buf;
    first = false;
  }
  std::snprintf(buf, sizeof buf, "size          %s (%llu bytes)\n", human_bytes(static_cast<double>(num("file_bytes"))).c_str(),
                static_cast<unsigned long long>(num("file_bytes")));
  o << buf;
  return o.str();
}

}  // namespace

const FileFormat kSinrFile{sinr::kSinrFormat, &sinr_schema, &validate_sinr, &sinr_info, &format_sinr_info};

}  // namespace raysweep::generators::schema
