#include "generators/dataset/dataset_virtual.hpp"

#include <map>
#include <memory>

#include "generators/dataset/dataset_reader.hpp"
#include "generators/dataset/dataset_schema.hpp"
#include "generators/dataset/dataset_tables.hpp"
#include "generators/dataset/store_level.hpp"
#include "generators/hdf5/checked_file.hpp"
#include "generators/hdf5/column_file.hpp"
#include "meshkit/errors.hpp"

namespace raysweep::generators {

using hdf5::Column;
using hdf5::ColumnFile;
using hdf5::Dtype;

namespace {

// The columns holding row numbers of the whole file: computed, not mapped.
bool computed(const std::string& group, const std::string& name) {
  return group == "frames" || (group == "links" && (name == "frame" || name == "path_offset")) ||
         (group == "paths" && name == "interaction_offset");
}

// A schema group's or dataset's presence at a store level ("stored_from").
bool stored_at(const nlohmann::json& spec, StoreLevel level) {
  return !spec.contains("stored_from") || level >= parse_store_level(spec.at("stored_from").get<std::string>());
}

struct Piece {
  const VirtualPiece* spec;
  DatasetReader* reader;
  std::unique_ptr<hdf5::CheckedFile> source;  // for its index columns
  FrameRows a, b, end;  // rows at the first frame, after the last, and the source's sizes
};

template <class T>
std::vector<T> read_source(const Piece& p, const std::string& name, hsize_t start, hsize_t n) {
  std::string why;
  const auto d = p.source->find_dataset(name, &why);
  if (!d) throw meshkit::InputError(p.spec->file.string(), name, "cannot open");
  return d->read<T>(start, n);
}

// The row tables' columns of the level (all but the computed ones) as
// virtual datasets mapping the pieces' rows in order.
void map_row_tables(ColumnFile& cf, StoreLevel level, hsize_t K, const std::vector<Piece>& ps, const FrameRows& total) {
  for (const auto& g : dataset_schema().at("groups")) {
    const std::string group = g.at("name");
    if (group == "nodes" || group == "objects" || (group == "cfr" && K == 0) || !stored_at(g, level)) continue;
    for (const auto& d : g.at("datasets")) {
      const std::string name = d.at("name");
      if (computed(group, name) || !stored_at(d, level)) continue;
      const Dtype dtype = hdf5::parse_dtype(d.at("dtype").get<std::string>());
      auto rows = [&](const FrameRows& r) {
        return group == "node_states" ? r.states
               : group == "paths"     ? r.paths
               : group == "interactions" ? r.interactions
                                         : r.links;
      };
      const hsize_t n_total = rows(total);
      if (n_total == 0) {  // nothing to map: an empty column like the writer's
        cf.column(group, name, dtype);
        continue;
      }
      std::vector<hdf5::VirtualSource> sources;
      for (const auto& p : ps) sources.push_back({p.spec->mapped_name, rows(p.end), rows(p.a), rows(p.b) - rows(p.a)});
      cf.virtual_table(group, name, n_total, sources);
    }
  }
}

}  // namespace

void write_virtual_dataset(const std::filesystem::path& out, const DatasetHeader& header,
                           const std::vector<NodeInfo>& nodes, const std::vector<std::string>& objects,
                           const std::vector<VirtualPiece>& pieces) {
  hdf5::QuietHdf5 quiet;
  const std::string file = out.string();
  std::map<std::filesystem::path, std::unique_ptr<DatasetReader>> readers;
  std::vector<Piece> ps;
  FrameRows total;
  std::uint64_t frames = 0;
  for (const auto& spec : pieces) {
    auto& r = readers[spec.file];
    if (!r) r = std::make_unique<DatasetReader>(spec.file);
    Piece p{&spec, r.get(), std::make_unique<hdf5::CheckedFile>(spec.file.string()), {}, {}, {}};
    p.source->open();
    p.a = r->rows_at(spec.first_frame);
    p.b = r->rows_at(spec.first_frame + spec.frame_count);
    p.end = r->rows_at(r->frame_count());
    total.states += p.b.states - p.a.states;
    total.links += p.b.links - p.a.links;
    total.paths += p.b.paths - p.a.paths;
    total.interactions += p.b.interactions - p.a.interactions;
    frames += spec.frame_count;
    ps.push_back(std::move(p));
  }

  const hsize_t K = header.cfr_subcarriers;
  ColumnFile cf(file, dataset_schema(), {{"K", K}});
  cf.create();
  cf.identity_attrs(kDatasetFormat, kDatasetSchemaVersion, header.raysweep_version, header.git_hash, header.config,
                    header.inputs, header.provenance, header.seed);
  cf.attr("", "carrier_hz", header.carrier_hz);
  cf.attr("", "bandwidth_hz", header.bandwidth_hz);
  if (!header.shard.empty()) cf.attr("", "shard", header.shard);
  cf.attr("", "store", std::string(store_level_name(header.store)));
  cf.attr("", "paths_top_k", std::uint32_t{header.paths_top_k});
  const bool paths = header.store >= StoreLevel::paths;
  if (K > 0) {
    cf.attr("cfr", "carrier_hz", header.carrier_hz);
    cf.attr("cfr", "subcarrier_spacing_hz", header.cfr_subcarrier_spacing_hz);
    cf.attr("cfr", "subcarriers", std::uint32_t{header.cfr_subcarriers});
  }

  // Computed columns.
  Column* f_time = cf.column("frames", "time_s", Dtype::f64);
  Column* f_noff = cf.column("frames", "node_offset", Dtype::u64);
  Column* f_ncount = cf.column("frames", "node_count", Dtype::u32);
  Column* f_loff = cf.column("frames", "link_offset", Dtype::u64);
  Column* f_lcount = cf.column("frames", "link_count", Dtype::u32);
  Column* l_frame = cf.column("links", "frame", Dtype::u32);
  Column* l_poff = paths ? cf.column("links", "path_offset", Dtype::u64) : nullptr;
  Column* p_ioff = paths ? cf.column("paths", "interaction_offset", Dtype::u64) : nullptr;
  std::uint64_t path_count = 0;  // the links' path counts, stored or not (the root attribute)
  FrameRows at;  // rows of the pieces before this one
  std::uint64_t frame = 0;
  for (const auto& p : ps) {
    const auto& s = *p.spec;
    const auto time = read_source<double>(p, "/frames/time_s", s.first_frame, s.frame_count);
    const auto ncount = read_source<std::uint32_t>(p, "/frames/node_count", s.first_frame, s.frame_count);
    const auto lcount = read_source<std::uint32_t>(p, "/frames/link_count", s.first_frame, s.frame_count);
    std::uint64_t st = at.states, lk = at.links;
    for (std::uint64_t k = 0; k < s.frame_count; ++k) {
      f_time->put(time[k]);
      f_noff->put(st);
      f_ncount->put(ncount[k]);
      f_loff->put(lk);
      f_lcount->put(lcount[k]);
      for (std::uint32_t j = 0; j < lcount[k]; ++j) l_frame->put(static_cast<std::uint32_t>(frame + k));
      st += ncount[k];
      lk += lcount[k];
    }
    const hsize_t nl = p.b.links - p.a.links, np = p.b.paths - p.a.paths;
    for (auto v : read_source<std::uint64_t>(p, "/links/path_count", p.a.links, nl)) path_count += v;
    if (paths) {
      for (auto v : read_source<std::uint64_t>(p, "/links/path_offset", p.a.links, nl))
        l_poff->put(std::uint64_t{v - p.a.paths + at.paths});
      for (auto v : read_source<std::uint64_t>(p, "/paths/interaction_offset", p.a.paths, np))
        p_ioff->put(std::uint64_t{v - p.a.interactions + at.interactions});
    }
    cf.maybe_flush();
    frame += s.frame_count;
    at.states += p.b.states - p.a.states;
    at.links += nl;
    at.paths += np;
    at.interactions += p.b.interactions - p.a.interactions;
  }

  map_row_tables(cf, header.store, K, ps, total);

  cf.flush_all();
  write_node_and_object_tables(cf, nodes, objects);
  cf.attr("", "frame_count", std::uint64_t{frames});
  cf.attr("", "node_count", std::uint64_t{nodes.size()});
  cf.attr("", "link_count", std::uint64_t{total.links});
  cf.attr("", "path_count", std::uint64_t{path_count});
  cf.close_all(true);
}

}  // namespace raysweep::generators
