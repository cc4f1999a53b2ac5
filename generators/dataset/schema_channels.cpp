// The channel dataset (raysweep-channels) beyond its schema: link sorting,
// presence of nodes, flags vs paths; its summary for `raysweep info`.
#include "generators/dataset/schema_validator.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>

#include "generators/dataset/dataset_schema.hpp"
#include "generators/dataset/dataset_writer.hpp"

namespace raysweep::generators::schema {

namespace {

// Rules of the channel dataset (raysweep-channels) beyond the schema.
class ChannelValidator : public Validator {
 public:
  using Validator::Validator;

 protected:
  void rules() override {
    guarded("/frames/time_s", [&] { check_times(); });
    guarded("/node_states", [&] { check_node_states(); });
    guarded("/links", [&] { check_links(); });
  }

 private:
  bool node_states_sorted_ = false;

  void check_times() {
    const hdf5::Dataset* ds = dset("/frames/time_s");
    if (!ds) return;
    const auto t = ds->read<double>(0, ds->rows());
    Tally bad;
    for (std::size_t i = 0; i < t.size(); ++i) {
      if (!std::isfinite(t[i]))
        bad.add(i, "not finite");
      else if (i > 0 && t[i] < t[i - 1])
        bad.add(i, "before the previous frame");
    }
    bad.report(problems_, "/frames/time_s", "not finite or decreasing");
  }

  // Node states of a frame sorted by node.
  void check_node_states() {
    const hdf5::Dataset *off = dset("/frames/node_offset"), *cnt = dset("/frames/node_count");
    const hdf5::Dataset* node = dset("/node_states/node");
    if (!off || !cnt || !node || !offsets_ok_.count("/frames/node_offset")) return;
    const hsize_t f = off->rows();
    const auto offset = off->read<std::uint64_t>(0, f);
    const auto count = cnt->read<std::uint64_t>(0, f);
    nodes_ = node->read<std::uint64_t>(0, node->rows());
    node_offset_ = offset;
    node_count_ = count;
    Tally bad;
    for (hsize_t fr = 0; fr < f; ++fr)
      for (std::uint64_t i = offset[fr] + 1; i < offset[fr] + count[fr]; ++i)
        if (nodes_[i] <= nodes_[i - 1]) bad.add(i, "frame " + std::to_string(fr) + ", node " + std::to_string(nodes_[i]));
    bad.report(problems_, "/node_states/node", "not strictly sorted by node within their frame");
    node_states_sorted_ = bad.count == 0;
  }
  std::vector<std::uint64_t> nodes_, node_offset_, node_count_;

  bool node_present(std::uint64_t frame, std::uint64_t node) const {
    const auto b = nodes_.begin() + static_cast<std::ptrdiff_t>(node_offset_[frame]);
    const auto e = b + static_cast<std::ptrdiff_t>(node_count_[frame]);
    return std::binary_search(b, e, node);
  }

  void check_links() {
    const hdf5::Dataset* tx = dset("/links/tx"), *rx = dset("/links/rx");
    if (!tx || !rx) return;
    const hdf5::Dataset* fr = dset("/links/frame"), *flags = dset("/links/flags"), *pc = dset("/links/path_count");
    const hdf5::Dataset* gc = dset("/links/gain_coherent_db"), *gi = dset("/links/gain_incoherent_db");
    const hdf5::Dataset* loff = dset("/frames/link_offset"), *lcnt = dset("/frames/link_count");
    const bool frames_ok = fr && loff && lcnt && offsets_ok_.count("/frames/link_offset");
    const bool presence = frames_ok && node_states_sorted_ && node_offset_.size() == dim("F").value_or(~hsize_t{0});
    std::vector<std::uint64_t> link_offset, link_count;
    if (frames_ok) {
      const hsize_t f = loff->rows();
      link_offset = loff->read<std::uint64_t>(0, f);
      link_count = lcnt->read<std::uint64_t>(0, f);
    }
    const hsize_t rows = tx->rows();
    Tally order, frame_bad, sorted, absent, oor_paths, no_path_gain;
    std::uint64_t f = 0;
    for (hsize_t start = 0; start < rows; start += kBlockRows) {
      const hsize_t n = std::min(kBlockRows, rows - start);
      const auto t = tx->read<std::uint64_t>(start, n);
      const auto r = rx->read<std::uint64_t>(start, n);
      std::vector<std::uint64_t> frame, fl, paths;
      std::vector<double> gain_c, gain_i;
      if (frames_ok) frame = fr->read<std::uint64_t>(start, n);
      if (flags && pc) {
        fl = flags->read<std::uint64_t>(start, n);
        paths = pc->read<std::uint64_t>(start, n);
      }
      if (pc && gc && gi) {
        if (paths.empty()) paths = pc->read<std::uint64_t>(start, n);
        gain_c = gc->read<double>(start, n);
        gain_i = gi->read<double>(start, n);
      }
      for (hsize_t i = 0; i < n; ++i) {
        const std::uint64_t row = start + i;
        const std::string pair = "(" + std::to_string(t[i]) + ", " + std::to_string(r[i]) + ")";
        if (t[i] >= r[i]) order.add(row, pair);
        if (frames_ok) {
          while (f < link_offset.size() && row >= link_offset[f] + link_count[f]) ++f;
          if (f < link_offset.size()) {
            if (frame[i] != f) frame_bad.add(row, "frame " + std::to_string(frame[i]) + ", expected " + std::to_string(f));
            if (row > link_offset[f] && !(prev_ < std::pair(t[i], r[i]))) sorted.add(row, pair);
            if (presence && (!node_present(f, t[i]) || !node_present(f, r[i])))
              absent.add(row, pair + " in frame " + std::to_string(f));
          }
        }
        prev_ = {t[i], r[i]};
        if (!fl.empty() && (fl[i] & 2u) && paths[i] != 0) oor_paths.add(row, std::to_string(paths[i]) + " paths");
        if (!gain_c.empty() && paths[i] == 0 && !(std::isinf(gain_c[i]) && gain_c[i] < 0 && std::isinf(gain_i[i]) && gain_i[i] < 0))
          no_path_gain.add(row, "gains " + std::to_string(gain_c[i]) + ", " + std::to_string(gain_i[i]) + " dB");
      }
    }
    order.report(problems_, "/links/tx", "with tx >= /links/rx");
    frame_bad.report(problems_, "/links/frame", "outside their frame's row range (/frames/link_offset, link_count)");
    sorted.report(problems_, "/links/tx", "not strictly sorted by (tx, rx) within their frame");
    absent.report(problems_, "/links/tx", "naming a node absent from the frame's /node_states");
    oor_paths.report(problems_, "/links/path_count", "out of range (/links/flags bit 1) but with paths");
    no_path_gain.report(problems_, "/links/gain_coherent_db", "without paths but with gains other than -inf");
  }
  std::pair<std::uint64_t, std::uint64_t> prev_{0, 0};
};

void validate_channels(const hdf5::CheckedFile& file, const nlohmann::json& schema, std::vector<std::string>& problems) {
  ChannelValidator(file, schema, problems).run();
}

// Summary of a channel dataset (format checked by the caller).
nlohmann::json channel_info(const hdf5::CheckedFile& r) {
  nlohmann::json info = identity_info(r, kDatasetFormat);
  info["carrier_hz"] = r.attr_if<double>("/", "carrier_hz").value_or(0.0);
  info["bandwidth_hz"] = r.attr_if<double>("/", "bandwidth_hz").value_or(0.0);

  // Frames and their time span.
  {
    const auto t = r.all_f64("/frames/time_s");
    info["frames"] = t.size();
    info["time_start_s"] = t.empty() ? 0.0 : t.front();
    info["time_end_s"] = t.empty() ? 0.0 : t.back();
  }

  add_node_kinds(info, r);

  // Links: LoS classes, flags, paths.
  const hsize_t links = r.column_rows("/links/los_class");
  std::uint64_t los[3] = {0, 0, 0}, other_class = 0, cached = 0, out_of_range = 0;
  r.scan_u64("/links/los_class", [&](const std::vector<std::uint64_t>& v) {
    for (auto c : v) (c < 3 ? los[c] : other_class) += 1;
  });
  r.scan_u64("/links/flags", [&](const std::vector<std::uint64_t>& v) {
    for (auto f : v) {
      if (f & 1u) ++cached;
      if (f & 2u) ++out_of_range;
    }
  });
  // Files below the paths level store none: their links' path counts say how many the gains sum.
  const bool paths_stored = r.exists("/paths");
  const hsize_t paths =
      paths_stored ? r.column_rows("/paths/tau_s") : r.attr_if<std::uint64_t>("/", "path_count").value_or(0);
  info["store"] = root_str(r, "store", "full");
  info["paths_top_k"] = r.attr_if<std::uint64_t>("/", "paths_top_k").value_or(0);
  info["paths_stored"] = paths_stored;
  info["links"] = links;
  info["los_counts"] = {{"LOS", los[0]}, {"NLOSV", los[1]}, {"NLOS", los[2]}};
  if (other_class) info["los_counts"]["invalid"] = other_class;
  if (r.exists("/links/los_class_fresnel")) {
    std::uint64_t zone[3] = {0, 0, 0};
    r.scan_u64("/links/los_class_fresnel", [&](const std::vector<std::uint64_t>& v) {
      for (auto c : v) zone[std::min<std::uint64_t>(c, 2)] += 1;
    });
    info["los_counts_fresnel"] = {{"LOS", zone[0]}, {"NLOSV", zone[1]}, {"NLOS", zone[2]}};
  }
  info["cached_links"] = cached;
  info["out_of_range_links"] = out_of_range;
  info["paths"] = paths;
  info["interactions"] = r.exists("/interactions/type") ? r.column_rows("/interactions/type") : 0;
  info["objects"] = r.exists("/objects/name") ? r.column_rows("/objects/name") : 0;
  info["mean_paths_per_link"] = links ? static_cast<double>(paths) / static_cast<double>(links) : 0.0;
  const std::uint64_t in_range = links - std::min<std::uint64_t>(links, out_of_range);
  info["mean_paths_per_in_range_link"] = in_range ? static_cast<double>(paths) / static_cast<double>(in_range) : 0.0;

  // Frequency responses.
  const bool has_cfr = r.exists("/cfr");
  info["has_cfr"] = has_cfr;
  std::uint64_t subcarriers = 0;
  if (has_cfr) {
    r.group("/cfr");
    subcarriers = r.attr_if<std::uint64_t>("/cfr", "subcarriers").value_or(0);
  }
  info["subcarriers"] = subcarriers;
  // Shard files of a split sweep say which part of it they hold.
  if (r.has_attr("/", "shard")) {
    const std::string text = root_str(r, "shard", "");
    if (nlohmann::json::accept(text)) info["shard"] = nlohmann::json::parse(text);
  }

  add_file_size(info, r.path(), links, "bytes_per_link");
  return info;
}

// " LOS n (x %) NLOSV ... NLOS ..." of a class count object.
std::string class_shares(const nlohmann::json& counts, std::uint64_t links) {
  std::string out;
  char buf[96];
  for (const char* c : {"LOS", "NLOSV", "NLOS"}) {
    const auto n = counts.value(c, std::uint64_t{0});
    std::snprintf(buf, sizeof buf, " %s %llu (%.1f %%)", c, static_cast<unsigned long long>(n),
                  links ? 100.0 * static_cast<double>(n) / static_cast<double>(links) : 0.0);
    out += buf;
  }
  return out;
}

std::string format_channel_info(const nlohmann::json& info) {
  auto num = [&](const char* k) { return info.value(k, nlohmann::json(0)).get<std::uint64_t>(); };
  auto real = [&](const char* k) { return info.value(k, nlohmann::json(0.0)).get<double>(); };
  std::ostringstream o;
  char buf[256];
  o << identity_lines(info);
  std::snprintf(buf, sizeof buf, "frames        %llu (%.3f s .. %.3f s)\n", static_cast<unsigned long long>(num("frames")),
                real("time_start_s"), real("time_end_s"));
  o << buf;
  o << "nodes         " << num("nodes") << " (" << num("vehicles") << " vehicles, " << num("rsus") << " RSUs)\n";
  const std::uint64_t links = num("links");
  o << "links         " << links << " pair-frames (" << num("cached_links") << " cached, " << num("out_of_range_links")
    << " out of range)\n";
  o << "LoS classes  ";
  if (info.contains("los_counts")) o << class_shares(info["los_counts"], links);
  o << "\n";
  if (info.contains("los_counts_fresnel"))
    o << "Fresnel zone " << class_shares(info["los_counts_fresnel"], links) << "  (0.6 F1)\n";
  const std::string level = info.value("store", std::string("full"));
  o << "store         " << level;
  if (num("paths_top_k") > 0) o << ", the " << num("paths_top_k") << " strongest paths of each link";
  o << (level == "links"   ? " (link columns and summaries)"
        : level == "cfr"   ? " (link columns, summaries and frequency responses)"
        : level == "paths" ? " (+ paths, without interaction points)"
                           : " (everything: paths with interaction points)")
    << "\n";
  std::snprintf(buf, sizeof buf, "paths         %llu (%.2f per link, %.2f per in-range link)%s\n",
                static_cast<unsigned long long>(num("paths")), real("mean_paths_per_link"),
                real("mean_paths_per_in_range_link"), info.value("paths_stored", true) ? "" : ", not stored");
  o << buf;
  o << "interactions  " << (info.value("paths_stored", true) ? std::to_string(num("interactions")) : "not stored") << "\n";
  o << "objects       " << num("objects") << "\n";
  std::snprintf(buf, sizeof buf, "carrier       %.6g GHz, bandwidth %.6g MHz\n", real("carrier_hz") / 1e9,
                real("bandwidth_hz") / 1e6);
  o << buf;
  o << "cfr           " << (info.value("has_cfr", false) ? std::to_string(num("subcarriers")) + " subcarriers" : "none")
    << "\n";
  if (info.contains("shard") && info["shard"].is_object()) {
    const auto& sh = info["shard"];
    o << "shard         " << sh.value("index", 0) << " of " << sh.value("count", 0) << ": "
      << sh.value("blocks", nlohmann::json::array()).size() << " of the sweep's " << sh.value("blocks_total", 0)
      << " blocks (" << sh.value("frames_total", 0) << " frames); raysweep merge joins the shards\n";
  }
  std::snprintf(buf, sizeof buf, "size          %s (%llu bytes), %.1f bytes per link\n",
                human_bytes(static_cast<double>(num("file_bytes"))).c_str(),
                static_cast<unsigned long long>(num("file_bytes")), real("bytes_per_link"));
  o << buf;
  return o.str();
}

}  // namespace

const FileFormat kChannelsFile{kDatasetFormat, &dataset_schema, &validate_channels, &channel_info,
                               &format_channel_info};

}  // namespace raysweep::generators::schema
