// Streaming HDF5 writer of the channel dataset. The datasets, their file types,
// shapes, chunk shapes, units and descriptions come from the embedded schema
// (schemas/raysweep_dataset.schema.json) through the shared column machinery
// (hdf5/column_file.hpp); this file only knows which record field goes into which
// dataset and checks at creation that the schema's dtype is the one it writes.
#include "generators/dataset/dataset_writer.hpp"

#include "generators/dataset/dataset_tables.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "generators/dataset/dataset_schema.hpp"
#include "generators/dataset/store_level.hpp"
#include "generators/hdf5/column_file.hpp"

namespace raysweep::generators {

using hdf5::Column;
using hdf5::ColumnFile;
using hdf5::Dtype;
using hdf5::QuietHdf5;

struct DatasetWriter::Impl {
  std::string file;  // for messages
  DatasetHeader header;
  ColumnFile out;
  bool finished = false;

  // Columns by dataset.
  Column *f_time, *f_node_offset, *f_node_count, *f_link_offset, *f_link_count;
  Column *s_node, *s_position, *s_velocity, *s_heading;
  Column *l_frame, *l_tx, *l_rx, *l_los, *l_flags, *l_blockers, *l_gain_c, *l_gain_i, *l_first_delay, *l_rms,
      *l_path_count, *l_los_fresnel, *l_clearance, *l_vehicle_loss, *l_below;
  Column *l_beyond, *l_diffuse, *l_k_factor, *l_doppler_spread, *l_aod_spread, *l_aoa_spread, *l_strongest_delay,
      *l_strongest_aod, *l_strongest_aoa;
  // Absent below their store level.
  Column* l_path_offset = nullptr;
  Column *p_a = nullptr, *p_tau = nullptr, *p_aod = nullptr, *p_aoa = nullptr, *p_doppler = nullptr,
         *p_icount = nullptr, *p_ioffset = nullptr;
  Column *i_type = nullptr, *i_object = nullptr, *i_point = nullptr;
  Column* c_h = nullptr;
  FrameRecord reduced;  // the frame being appended, reduced to the level

  // Running totals.
  std::uint64_t frame_count = 0, state_count = 0, link_count = 0, interaction_count = 0;
  std::uint64_t path_count = 0;   // sum of the links' path_count (= rows of /paths where stored)
  std::uint64_t path_rows = 0;
  double last_time = -std::numeric_limits<double>::infinity();
  std::int64_t max_node = -1, max_object = -1;

  Impl(const std::filesystem::path& path, const DatasetHeader& h)
      : file(path.string()), header(h), out(file, dataset_schema(), {{"K", h.cfr_subcarriers}}) {}

  Column* column(const std::string& group, const std::string& name, Dtype expect) {
    return out.column(group, name, expect);
  }
  void table(const std::string& group, const std::string& name, Dtype expect, hsize_t rows, const void* data) {
    out.table(group, name, expect, rows, data);
  }

  void create() {
    for (const auto& [dim, rows] : header.expected_rows) out.expect_rows(dim, rows);
    out.create();
    out.identity_attrs(kDatasetFormat, kDatasetSchemaVersion, header.raysweep_version, header.git_hash, header.config, header.inputs,
                       header.provenance, header.seed);
    out.attr("", "carrier_hz", header.carrier_hz);
    out.attr("", "bandwidth_hz", header.bandwidth_hz);
    if (!header.shard.empty()) out.attr("", "shard", header.shard);
    out.attr("", "store", std::string(store_level_name(header.store)));
    out.attr("", "paths_top_k", std::uint32_t{header.paths_top_k});

    f_time = column("frames", "time_s", Dtype::f64);
    f_node_offset = column("frames", "node_offset", Dtype::u64);
    f_node_count = column("frames", "node_count", Dtype::u32);
    f_link_offset = column("frames", "link_offset", Dtype::u64);
    f_link_count = column("frames", "link_count", Dtype::u32);

    s_node = column("node_states", "node", Dtype::u32);
    s_position = column("node_states", "position", Dtype::f64);
    s_velocity = column("node_states", "velocity", Dtype::f32);
    s_heading = column("node_states", "heading_deg", Dtype::f32);

    l_frame = column("links", "frame", Dtype::u32);
    l_tx = column("links", "tx", Dtype::u32);
    l_rx = column("links", "rx", Dtype::u32);
    l_los = column("links", "los_class", Dtype::u8);
    l_flags = column("links", "flags", Dtype::u8);
    l_blockers = column("links", "blocker_count", Dtype::u16);
    l_gain_c = column("links", "gain_coherent_db", Dtype::f32);
    l_gain_i = column("links", "gain_incoherent_db", Dtype::f32);
    l_first_delay = column("links", "first_delay_s", Dtype::f64);
    l_rms = column("links", "rms_delay_spread_s", Dtype::f32);
    l_path_count = column("links", "path_count", Dtype::u32);
    l_below = column("links", "paths_below_threshold", Dtype::u32);
    l_los_fresnel = column("links", "los_class_fresnel", Dtype::u8);
    l_clearance = column("links", "fresnel_clearance", Dtype::f32);
    l_vehicle_loss = column("links", "vehicle_loss_db", Dtype::f32);
    l_beyond = column("links", "paths_beyond_top_k", Dtype::u32);
    l_diffuse = column("links", "diffuse_gain_db", Dtype::f32);
    l_k_factor = column("links", "k_factor_db", Dtype::f32);
    l_doppler_spread = column("links", "rms_doppler_spread_hz", Dtype::f32);
    l_aod_spread = column("links", "aod_spread_rad", Dtype::f32);
    l_aoa_spread = column("links", "aoa_spread_rad", Dtype::f32);
    l_strongest_delay = column("links", "strongest_excess_delay_s", Dtype::f32);
    l_strongest_aod = column("links", "strongest_aod", Dtype::f32);
    l_strongest_aoa = column("links", "strongest_aoa", Dtype::f32);

    if (header.store >= StoreLevel::paths) {
      l_path_offset = column("links", "path_offset", Dtype::u64);
      p_a = column("paths", "a", Dtype::c64);
      p_tau = column("paths", "tau_s", Dtype::f64);
      p_aod = column("paths", "aod", Dtype::f32);
      p_aoa = column("paths", "aoa", Dtype::f32);
      p_doppler = column("paths", "doppler_hz", Dtype::f32);
      p_icount = column("paths", "interaction_count", Dtype::u8);
      p_ioffset = column("paths", "interaction_offset", Dtype::u64);
      i_type = column("interactions", "type", Dtype::u8);
      i_object = column("interactions", "object", Dtype::u32);
      if (header.store >= StoreLevel::full) i_point = column("interactions", "point", Dtype::f32);
    }

    if (header.cfr_subcarriers > 0 && header.store >= StoreLevel::cfr) {
      out.attr("cfr", "carrier_hz", header.carrier_hz);
      out.attr("cfr", "subcarrier_spacing_hz", header.cfr_subcarrier_spacing_hz);
      out.attr("cfr", "subcarriers", std::uint32_t{header.cfr_subcarriers});
      c_h = column("cfr", "h", Dtype::c64);
    }
  }

  void check(const FrameRecord& fr) const {
    auto bad = [&](const std::string& what) {
      throw std::invalid_argument(file + ": frame " + std::to_string(frame_count) + " (t = " +
                                  std::to_string(fr.time_s) + " s): " + what);
    };
    if (!std::isfinite(fr.time_s)) bad("time is not finite");
    if (fr.time_s < last_time) bad("time is before the previous frame's");
    constexpr std::size_t u32max = std::numeric_limits<std::uint32_t>::max();
    if (fr.nodes.size() > u32max || fr.links.size() > u32max) bad("too many nodes or links for one frame");
    for (std::size_t i = 1; i < fr.nodes.size(); ++i)
      if (fr.nodes[i].node <= fr.nodes[i - 1].node) bad("node states not strictly sorted by node at " + std::to_string(i));
    auto present = [&](std::uint32_t n) {
      auto it = std::lower_bound(fr.nodes.begin(), fr.nodes.end(), n,
                                 [](const NodeState& s, std::uint32_t v) { return s.node < v; });
      return it != fr.nodes.end() && it->node == n;
    };
    std::uint64_t paths = 0;
    for (std::size_t i = 0; i < fr.links.size(); ++i) {
      const auto& l = fr.links[i];
      const std::string at = "link " + std::to_string(i) + " (" + std::to_string(l.tx) + ", " + std::to_string(l.rx) + ")";
      if (l.tx >= l.rx) bad(at + ": tx >= rx");
      if (i > 0 && std::pair(fr.links[i - 1].tx, fr.links[i - 1].rx) >= std::pair(l.tx, l.rx))
        bad(at + ": links not strictly sorted by (tx, rx)");
      if (!present(l.tx) || !present(l.rx)) bad(at + ": node not present in the frame's node states");
      if (l.los_class > 2) bad(at + ": los_class " + std::to_string(l.los_class) + " not in 0..2");
      if (l.los_class_fresnel > 2)
        bad(at + ": los_class_fresnel " + std::to_string(l.los_class_fresnel) + " not in 0..2");
      if (!(l.fresnel_clearance <= 1)) bad(at + ": fresnel_clearance above 1 or not a number");
      if (!(l.vehicle_loss_db >= 0) || !std::isfinite(l.vehicle_loss_db))
        bad(at + ": vehicle_loss_db negative or not finite");
      if (l.flags & ~(kLinkCached | kLinkOutOfRange | kLinkEnclosed)) bad(at + ": unknown flag bits");
      if ((l.flags & kLinkOutOfRange) && l.path_count > 0) bad(at + ": out-of-range link with paths");
      paths += l.path_count;
    }
    if (paths != fr.paths.size() && !(header.store < StoreLevel::paths && fr.paths.empty()))
      bad("links' path counts sum to " + std::to_string(paths) + " but the frame has " + std::to_string(fr.paths.size()) +
          " paths");
    std::uint64_t interactions = 0;
    for (const auto& p : fr.paths) interactions += p.interaction_count;
    if (interactions != fr.interactions.size())
      bad("paths' interaction counts sum to " + std::to_string(interactions) + " but the frame has " +
          std::to_string(fr.interactions.size()) + " interactions");
    for (std::size_t i = 0; i < fr.interactions.size(); ++i)
      if (fr.interactions[i].type < 1 || fr.interactions[i].type > 4)
        bad("interaction " + std::to_string(i) + ": type " + std::to_string(fr.interactions[i].type) + " not in 1..4");
    const std::uint64_t cfr_expected = std::uint64_t{fr.links.size()} * header.cfr_subcarriers;
    if (fr.cfr.size() != cfr_expected && !(header.store < StoreLevel::cfr && fr.cfr.empty()))
      bad("cfr has " + std::to_string(fr.cfr.size()) + " values, expected links x subcarriers = " +
          std::to_string(cfr_expected));
  }

  void append(const FrameRecord& frame) {
    if (finished) throw std::runtime_error(file + ": append() after finish()");
    check(frame);
    const bool reduce = header.store < StoreLevel::full || header.paths_top_k > 0;
    if (reduce) {
      reduced = frame;
      reduce_frame(reduced, header.store, header.paths_top_k);
    }
    const FrameRecord& fr = reduce ? reduced : frame;

    const std::uint32_t frame_index = static_cast<std::uint32_t>(frame_count);
    if (frame_count >= std::numeric_limits<std::uint32_t>::max()) throw std::invalid_argument(file + ": too many frames");
    f_time->put(fr.time_s);
    f_node_offset->put(std::uint64_t{state_count});
    f_node_count->put(static_cast<std::uint32_t>(fr.nodes.size()));
    f_link_offset->put(std::uint64_t{link_count});
    f_link_count->put(static_cast<std::uint32_t>(fr.links.size()));

    for (Column* c : {s_node, s_position, s_velocity, s_heading}) c->reserve_rows(fr.nodes.size());
    for (const auto& s : fr.nodes) {
      s_node->put(s.node);
      s_position->put(s.x), s_position->put(s.y), s_position->put(s.z);
      s_velocity->put(s.vx), s_velocity->put(s.vy), s_velocity->put(s.vz);
      s_heading->put(s.heading_deg);
      max_node = std::max<std::int64_t>(max_node, s.node);
    }

    for (Column* c : {l_frame, l_tx, l_rx, l_los, l_flags, l_blockers, l_gain_c, l_gain_i, l_first_delay, l_rms,
                      l_path_count, l_below, l_los_fresnel, l_clearance, l_vehicle_loss, l_beyond, l_diffuse,
                      l_k_factor, l_doppler_spread, l_aod_spread, l_aoa_spread, l_strongest_delay, l_strongest_aod,
                      l_strongest_aoa, l_path_offset})
      if (c) c->reserve_rows(fr.links.size());
    std::uint64_t frame_paths = 0;
    for (const auto& l : fr.links) {
      l_frame->put(frame_index);
      l_tx->put(l.tx);
      l_rx->put(l.rx);
      l_los->put(l.los_class);
      l_flags->put(l.flags);
      l_blockers->put(l.blocker_count);
      l_gain_c->put(l.gain_coherent_db);
      l_gain_i->put(l.gain_incoherent_db);
      l_first_delay->put(l.first_delay_s);
      l_rms->put(l.rms_delay_spread_s);
      l_path_count->put(l.path_count);
      l_below->put(l.paths_below_threshold);
      l_los_fresnel->put(l.los_class_fresnel);
      l_clearance->put(l.fresnel_clearance);
      l_vehicle_loss->put(l.vehicle_loss_db);
      l_beyond->put(l.paths_beyond_top_k);
      l_diffuse->put(l.diffuse_gain_db);
      l_k_factor->put(l.k_factor_db);
      l_doppler_spread->put(l.rms_doppler_spread_hz);
      l_aod_spread->put(l.aod_spread[0]), l_aod_spread->put(l.aod_spread[1]);
      l_aoa_spread->put(l.aoa_spread[0]), l_aoa_spread->put(l.aoa_spread[1]);
      l_strongest_delay->put(l.strongest_excess_delay_s);
      l_strongest_aod->put(l.strongest_aod[0]), l_strongest_aod->put(l.strongest_aod[1]);
      l_strongest_aoa->put(l.strongest_aoa[0]), l_strongest_aoa->put(l.strongest_aoa[1]);
      if (l_path_offset) l_path_offset->put(path_rows + frame_paths);
      frame_paths += l.path_count;
    }
    path_count += frame_paths;
    if (p_a) append_paths(fr);
    if (c_h) {
      c_h->reserve_rows(fr.links.size());
      for (const auto& v : fr.cfr) c_h->put(v);
    }

    for (const auto& l : fr.links) max_node = std::max<std::int64_t>(max_node, l.rx);
    ++frame_count;
    state_count += fr.nodes.size();
    link_count += fr.links.size();
    last_time = fr.time_s;
    out.maybe_flush();
  }

  void append_paths(const FrameRecord& fr) {
    for (Column* c : {p_a, p_tau, p_aod, p_aoa, p_doppler, p_icount, p_ioffset}) c->reserve_rows(fr.paths.size());
    std::uint64_t interaction_offset = interaction_count;
    for (const auto& p : fr.paths) {
      p_a->put(p.a);  // std::complex<float> is {re, im}, the compound's layout
      p_tau->put(p.tau_s);
      p_aod->put(p.theta_t), p_aod->put(p.phi_t);
      p_aoa->put(p.theta_r), p_aoa->put(p.phi_r);
      p_doppler->put(p.doppler_hz);
      p_icount->put(p.interaction_count);
      p_ioffset->put(interaction_offset);
      interaction_offset += p.interaction_count;
    }

    for (Column* c : {i_type, i_object, i_point})
      if (c) c->reserve_rows(fr.interactions.size());
    for (const auto& it : fr.interactions) {
      i_type->put(it.type);
      i_object->put(it.object);
      if (i_point) i_point->put(it.x), i_point->put(it.y), i_point->put(it.z);
      max_object = std::max<std::int64_t>(max_object, it.object);
    }
    path_rows += fr.paths.size();
    interaction_count = interaction_offset;
  }

  void flush_all() { out.flush_all(); }

  void finish(const std::vector<NodeInfo>& nodes, const std::vector<std::string>& objects) {
    if (finished) throw std::runtime_error(file + ": finish() called twice");
    if (max_node >= static_cast<std::int64_t>(nodes.size()))
      throw std::invalid_argument(file + ": records name node " + std::to_string(max_node) + " but the node table has " +
                                  std::to_string(nodes.size()) + " nodes");
    if (max_object >= static_cast<std::int64_t>(objects.size()))
      throw std::invalid_argument(file + ": interactions name object " + std::to_string(max_object) +
                                  " but the object table has " + std::to_string(objects.size()) + " objects");
    flush_all();

    write_node_and_object_tables(out, nodes, objects);

    out.attr("", "frame_count", std::uint64_t{frame_count});
    out.attr("", "node_count", std::uint64_t{nodes.size()});
    out.attr("", "link_count", std::uint64_t{link_count});
    out.attr("", "path_count", std::uint64_t{path_count});
    close_all(true);
    finished = true;
  }

  void close_all(bool mark_complete) { out.close_all(mark_complete); }
};

DatasetWriter::DatasetWriter(const std::filesystem::path& path, const DatasetHeader& header) {
  QuietHdf5 quiet;
  impl_ = std::make_unique<Impl>(path, header);
  impl_->create();
}

DatasetWriter::~DatasetWriter() {
  if (!impl_ || impl_->finished) return;
  QuietHdf5 quiet;
  try {
    impl_->flush_all();
  } catch (...) {
  }
  try {
    impl_->close_all(false);
  } catch (...) {
  }
}

void DatasetWriter::append(const FrameRecord& frame) {
  QuietHdf5 quiet;
  impl_->append(frame);
}

void DatasetWriter::finish(const std::vector<NodeInfo>& nodes, const std::vector<std::string>& objects) {
  QuietHdf5 quiet;
  impl_->finish(nodes, objects);
}

std::uint64_t DatasetWriter::frames() const { return impl_->frame_count; }
std::uint64_t DatasetWriter::links() const { return impl_->link_count; }
std::uint64_t DatasetWriter::paths() const { return impl_->path_count; }

}  // namespace raysweep::generators
