// Streaming HDF5 writer of the channel dataset. The datasets, their file types,
// shapes, chunk shapes, units and descriptions come from the embedded schema
// (schemas/raysweep_dataset.schema.json); this file only knows which record
// field goes into which dataset and checks at creation that the schema's dtype
// is the one it writes.
#include "generators/dataset_writer.hpp"

#include <hdf5.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <unordered_map>

#include "generators/dataset_schema.hpp"
#include "generators/hdf5_util.hpp"

namespace raysweep::generators {

namespace {

using hdf5::Closer;
using hdf5::Handle;
using hdf5::QuietHdf5;
using hdf5::hdf5_error_text;


[[noreturn]] void fail(const std::string& file, const std::string& object, const std::string& what) {
  std::string msg = "HDF5 " + file + ": " + object + ": " + what;
  const std::string h5 = hdf5_error_text();
  if (!h5.empty()) msg += " (" + h5 + ")";
  throw std::runtime_error(msg);
}

// ---------------------------------------------------------------------------
// Types.

enum class Dtype { u8, u16, u32, u64, f32, f64, c64, str };

Dtype parse_dtype(const std::string& s) {
  static const std::unordered_map<std::string, Dtype> m = {{"u8", Dtype::u8},   {"u16", Dtype::u16},
                                                           {"u32", Dtype::u32}, {"u64", Dtype::u64},
                                                           {"f32", Dtype::f32}, {"f64", Dtype::f64},
                                                           {"c64", Dtype::c64}, {"str", Dtype::str}};
  auto it = m.find(s);
  if (it == m.end()) throw std::logic_error("dataset schema: unknown dtype " + s);
  return it->second;
}

std::size_t dtype_bytes(Dtype t) {
  switch (t) {
    case Dtype::u8: return 1;
    case Dtype::u16: return 2;
    case Dtype::u32: return 4;
    case Dtype::u64: return 8;
    case Dtype::f32: return 4;
    case Dtype::f64: return 8;
    case Dtype::c64: return 8;
    case Dtype::str: return sizeof(const char*);
  }
  return 0;
}

// Memory and file types. Predefined types are not owned; the compound and string
// types are created once per writer.
struct Types {
  Handle c64_mem, c64_file, str;
  Types(const std::string& file) {
    c64_mem = Handle(H5Tcreate(H5T_COMPOUND, 2 * sizeof(float)), H5Tclose);
    if (c64_mem.get() < 0 || H5Tinsert(c64_mem.get(), "r", 0, H5T_NATIVE_FLOAT) < 0 ||
        H5Tinsert(c64_mem.get(), "i", sizeof(float), H5T_NATIVE_FLOAT) < 0)
      fail(file, "complex memory type", "cannot create");
    c64_file = Handle(H5Tcreate(H5T_COMPOUND, 8), H5Tclose);
    if (c64_file.get() < 0 || H5Tinsert(c64_file.get(), "r", 0, H5T_IEEE_F32LE) < 0 ||
        H5Tinsert(c64_file.get(), "i", 4, H5T_IEEE_F32LE) < 0)
      fail(file, "complex file type", "cannot create");
    str = Handle(H5Tcopy(H5T_C_S1), H5Tclose);
    if (str.get() < 0 || H5Tset_size(str.get(), H5T_VARIABLE) < 0 || H5Tset_cset(str.get(), H5T_CSET_UTF8) < 0)
      fail(file, "string type", "cannot create");
  }
  hid_t mem(Dtype t) const {
    switch (t) {
      case Dtype::u8: return H5T_NATIVE_UINT8;
      case Dtype::u16: return H5T_NATIVE_UINT16;
      case Dtype::u32: return H5T_NATIVE_UINT32;
      case Dtype::u64: return H5T_NATIVE_UINT64;
      case Dtype::f32: return H5T_NATIVE_FLOAT;
      case Dtype::f64: return H5T_NATIVE_DOUBLE;
      case Dtype::c64: return c64_mem.get();
      case Dtype::str: return str.get();
    }
    return H5I_INVALID_HID;
  }
  hid_t file(Dtype t) const {
    switch (t) {
      case Dtype::u8: return H5T_STD_U8LE;
      case Dtype::u16: return H5T_STD_U16LE;
      case Dtype::u32: return H5T_STD_U32LE;
      case Dtype::u64: return H5T_STD_U64LE;
      case Dtype::f32: return H5T_IEEE_F32LE;
      case Dtype::f64: return H5T_IEEE_F64LE;
      case Dtype::c64: return c64_file.get();
      case Dtype::str: return str.get();
    }
    return H5I_INVALID_HID;
  }
};

// ---------------------------------------------------------------------------
// Attributes.

void write_attr(const std::string& file, hid_t loc, const std::string& where, const std::string& name, hid_t ftype,
                hid_t mtype, const void* value) {
  Handle space(H5Screate(H5S_SCALAR), H5Sclose);
  if (space.get() < 0) fail(file, where + " attribute " + name, "cannot create dataspace");
  Handle attr(H5Acreate2(loc, name.c_str(), ftype, space.get(), H5P_DEFAULT, H5P_DEFAULT), H5Aclose);
  if (attr.get() < 0) fail(file, where + " attribute " + name, "cannot create");
  if (H5Awrite(attr.get(), mtype, value) < 0) fail(file, where + " attribute " + name, "cannot write");
  if (attr.close() < 0) fail(file, where + " attribute " + name, "cannot close");
}

void write_str_attr(const std::string& file, const Types& types, hid_t loc, const std::string& where,
                    const std::string& name, const std::string& value) {
  const char* p = value.c_str();
  write_attr(file, loc, where, name, types.str.get(), types.str.get(), &p);
}

// ---------------------------------------------------------------------------
// Columns: one extendible dataset plus the rows buffered for it.

constexpr std::size_t kFlushBytes = std::size_t{1} << 20;  // write when a buffer holds about this much

struct Column {
  std::string name;  // "/links/tx"
  Dtype dtype = Dtype::u8;
  hid_t mem_type = H5I_INVALID_HID;
  Handle dset;
  int rank = 1;
  hsize_t width = 1;       // elements per row (second dimension, 1 for 1-D)
  hsize_t chunk_rows = 1;  // rows per chunk
  hsize_t rows_written = 0;
  std::vector<unsigned char> buf;

  std::size_t row_bytes() const { return static_cast<std::size_t>(width) * dtype_bytes(dtype); }
  hsize_t buffered_rows() const { return buf.size() / row_bytes(); }
  hsize_t total_rows() const { return rows_written + buffered_rows(); }

  template <class T>
  void put(const T& v) {
    static_assert(std::is_trivially_copyable_v<T>);
    const std::size_t n = buf.size();
    buf.resize(n + sizeof(T));
    std::memcpy(buf.data() + n, &v, sizeof(T));
  }
  void reserve_rows(std::size_t rows) { buf.reserve(buf.size() + rows * row_bytes()); }

  // Writes the buffered rows: all of them, or only whole chunks (the rest stays
  // buffered, so every chunk is compressed and written exactly once).
  void flush(const std::string& file, bool all) {
    hsize_t rows = buffered_rows();
    if (!all) rows = rows / chunk_rows * chunk_rows;
    if (rows == 0) return;
    const hsize_t new_dims[2] = {rows_written + rows, width};
    if (H5Dset_extent(dset.get(), new_dims) < 0) fail(file, name, "cannot extend dataset");
    Handle fspace(H5Dget_space(dset.get()), H5Sclose);
    if (fspace.get() < 0) fail(file, name, "cannot get dataspace");
    const hsize_t start[2] = {rows_written, 0};
    const hsize_t count[2] = {rows, width};
    if (H5Sselect_hyperslab(fspace.get(), H5S_SELECT_SET, start, nullptr, count, nullptr) < 0)
      fail(file, name, "cannot select rows");
    Handle mspace(H5Screate_simple(rank, count, nullptr), H5Sclose);
    if (mspace.get() < 0) fail(file, name, "cannot create memory dataspace");
    if (H5Dwrite(dset.get(), mem_type, mspace.get(), fspace.get(), H5P_DEFAULT, buf.data()) < 0)
      fail(file, name, "cannot write rows");
    const std::size_t bytes = static_cast<std::size_t>(rows) * row_bytes();
    buf.erase(buf.begin(), buf.begin() + static_cast<std::ptrdiff_t>(bytes));
    rows_written += rows;
  }
  void maybe_flush(const std::string& file) {
    if (buf.size() >= kFlushBytes && buffered_rows() >= chunk_rows) flush(file, false);
  }
};

const nlohmann::json& schema_group(const std::string& group) {
  for (const auto& g : dataset_schema().at("groups"))
    if (g.at("name") == group) return g;
  throw std::logic_error("dataset schema: no group " + group);
}

const nlohmann::json& schema_dataset(const std::string& group, const std::string& name) {
  for (const auto& d : schema_group(group).at("datasets"))
    if (d.at("name") == name) return d;
  throw std::logic_error("dataset schema: no dataset /" + group + "/" + name);
}

// Dimension value of a schema shape entry: a number, or "K" (subcarriers); other
// symbols are the growing first axis.
hsize_t fixed_dim(const nlohmann::json& d, std::uint32_t k) {
  if (d.is_number_unsigned()) return d.get<hsize_t>();
  if (d == "K") return k;
  throw std::logic_error("dataset schema: unexpected dimension " + d.dump());
}

}  // namespace

// ---------------------------------------------------------------------------

struct DatasetWriter::Impl {
  std::string file;  // for messages
  DatasetHeader header;
  Types types;
  Handle fid;
  std::unordered_map<std::string, Handle> groups;
  std::vector<std::unique_ptr<Column>> columns;
  bool finished = false;

  // Columns by dataset.
  Column *f_time, *f_node_offset, *f_node_count, *f_link_offset, *f_link_count;
  Column *s_node, *s_position, *s_velocity, *s_heading;
  Column *l_frame, *l_tx, *l_rx, *l_los, *l_flags, *l_blockers, *l_gain_c, *l_gain_i, *l_first_delay, *l_rms,
      *l_path_count, *l_path_offset;
  Column *p_a, *p_tau, *p_aod, *p_aoa, *p_doppler, *p_icount, *p_ioffset;
  Column *i_type, *i_object, *i_point;
  Column* c_h = nullptr;

  // Running totals.
  std::uint64_t frame_count = 0, state_count = 0, link_count = 0, path_count = 0, interaction_count = 0;
  double last_time = -std::numeric_limits<double>::infinity();
  std::int64_t max_node = -1, max_object = -1;

  Impl(const std::filesystem::path& path, const DatasetHeader& h) : file(path.string()), header(h), types(file) {}

  hid_t group(const std::string& name) {
    auto it = groups.find(name);
    if (it != groups.end()) return it->second.get();
    Handle gcpl(H5Pcreate(H5P_GROUP_CREATE), H5Pclose);
    if (gcpl.get() < 0 || H5Pset_obj_track_times(gcpl.get(), 0) < 0) fail(file, "/" + name, "cannot set group properties");
    Handle g(H5Gcreate2(fid.get(), ("/" + name).c_str(), H5P_DEFAULT, gcpl.get(), H5P_DEFAULT), H5Gclose);
    if (g.get() < 0) fail(file, "/" + name, "cannot create group");
    const hid_t id = g.get();
    groups.emplace(name, std::move(g));
    return id;
  }

  void dataset_attrs(hid_t dset, const std::string& where, const nlohmann::json& spec) {
    write_str_attr(file, types, dset, where, "units", spec.at("units").get<std::string>());
    write_str_attr(file, types, dset, where, "description", spec.at("description").get<std::string>());
  }

  // Creates an extendible, chunked, compressed dataset from its schema entry.
  Column* column(const std::string& group_name, const std::string& name, Dtype expect) {
    const auto& spec = schema_dataset(group_name, name);
    auto c = std::make_unique<Column>();
    c->name = "/" + group_name + "/" + name;
    c->dtype = parse_dtype(spec.at("dtype").get<std::string>());
    if (c->dtype != expect) throw std::logic_error("dataset schema: " + c->name + " dtype differs from the writer's");
    c->mem_type = types.mem(c->dtype);
    const auto& shape = spec.at("shape");
    const auto& chunk = spec.at("chunk");
    c->rank = static_cast<int>(shape.size());
    if (c->rank == 2) c->width = fixed_dim(shape[1], header.cfr_subcarriers);
    c->chunk_rows = chunk[0].get<hsize_t>();
    const hsize_t dims[2] = {0, c->width};
    const hsize_t maxdims[2] = {H5S_UNLIMITED, c->width};
    const hsize_t chunk_dims[2] = {c->chunk_rows, std::max<hsize_t>(1, c->width)};
    Handle space(H5Screate_simple(c->rank, dims, maxdims), H5Sclose);
    if (space.get() < 0) fail(file, c->name, "cannot create dataspace");
    Handle dcpl(H5Pcreate(H5P_DATASET_CREATE), H5Pclose);
    if (dcpl.get() < 0 || H5Pset_chunk(dcpl.get(), c->rank, chunk_dims) < 0 || H5Pset_shuffle(dcpl.get()) < 0 ||
        H5Pset_deflate(dcpl.get(), 4) < 0 || H5Pset_obj_track_times(dcpl.get(), 0) < 0 ||
        H5Pset_fill_time(dcpl.get(), H5D_FILL_TIME_NEVER) < 0)
      fail(file, c->name, "cannot set dataset creation properties");
    c->dset = Handle(H5Dcreate2(group(group_name), name.c_str(), types.file(c->dtype), space.get(), H5P_DEFAULT,
                                dcpl.get(), H5P_DEFAULT),
                     H5Dclose);
    if (c->dset.get() < 0) fail(file, c->name, "cannot create dataset");
    dataset_attrs(c->dset.get(), c->name, spec);
    columns.push_back(std::move(c));
    return columns.back().get();
  }

  // A small fixed-size contiguous table written in one go (finish()).
  void table(const std::string& group_name, const std::string& name, Dtype expect, hsize_t rows, const void* data) {
    const auto& spec = schema_dataset(group_name, name);
    const std::string where = "/" + group_name + "/" + name;
    const Dtype dtype = parse_dtype(spec.at("dtype").get<std::string>());
    if (dtype != expect) throw std::logic_error("dataset schema: " + where + " dtype differs from the writer's");
    const auto& shape = spec.at("shape");
    const int rank = static_cast<int>(shape.size());
    const hsize_t dims[2] = {rows, rank == 2 ? fixed_dim(shape[1], header.cfr_subcarriers) : 1};
    Handle space(H5Screate_simple(rank, dims, nullptr), H5Sclose);
    if (space.get() < 0) fail(file, where, "cannot create dataspace");
    Handle dcpl(H5Pcreate(H5P_DATASET_CREATE), H5Pclose);
    if (dcpl.get() < 0 || H5Pset_obj_track_times(dcpl.get(), 0) < 0) fail(file, where, "cannot set properties");
    Handle dset(H5Dcreate2(group(group_name), name.c_str(), types.file(dtype), space.get(), H5P_DEFAULT, dcpl.get(),
                           H5P_DEFAULT),
                H5Dclose);
    if (dset.get() < 0) fail(file, where, "cannot create dataset");
    if (rows > 0 && H5Dwrite(dset.get(), types.mem(dtype), H5S_ALL, H5S_ALL, H5P_DEFAULT, data) < 0)
      fail(file, where, "cannot write");
    dataset_attrs(dset.get(), where, spec);
    if (dset.close() < 0) fail(file, where, "cannot close dataset");
  }

  void create() {
    Handle fcpl(H5Pcreate(H5P_FILE_CREATE), H5Pclose);
    // The root group has no time stamps either (file creation lists are group creation lists).
    if (fcpl.get() < 0 || H5Pset_obj_track_times(fcpl.get(), 0) < 0) fail(file, "/", "cannot set file properties");
    fid = Handle(H5Fcreate(file.c_str(), H5F_ACC_TRUNC, fcpl.get(), H5P_DEFAULT), H5Fclose);
    if (fid.get() < 0) fail(file, "/", "cannot create file");

    const hid_t root = fid.get();
    write_str_attr(file, types, root, "/", "format", kDatasetFormat);
    write_str_attr(file, types, root, "/", "schema_version", kDatasetSchemaVersion);
    write_str_attr(file, types, root, "/", "raysweep_version", header.raysweep_version);
    write_str_attr(file, types, root, "/", "git_hash", header.git_hash);
    write_str_attr(file, types, root, "/", "config", header.config.dump());
    write_str_attr(file, types, root, "/", "inputs", header.inputs.dump());
    write_str_attr(file, types, root, "/", "provenance", header.provenance.dump());
    write_attr(file, root, "/", "seed", H5T_STD_U64LE, H5T_NATIVE_UINT64, &header.seed);
    write_attr(file, root, "/", "carrier_hz", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, &header.carrier_hz);
    write_attr(file, root, "/", "bandwidth_hz", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, &header.bandwidth_hz);

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
    i_point = column("interactions", "point", Dtype::f32);

    if (header.cfr_subcarriers > 0) {
      const hid_t g = group("cfr");
      write_attr(file, g, "/cfr", "carrier_hz", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, &header.carrier_hz);
      write_attr(file, g, "/cfr", "subcarrier_spacing_hz", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE,
                 &header.cfr_subcarrier_spacing_hz);
      write_attr(file, g, "/cfr", "subcarriers", H5T_STD_U32LE, H5T_NATIVE_UINT32, &header.cfr_subcarriers);
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
      if (l.flags & ~(kLinkCached | kLinkOutOfRange)) bad(at + ": unknown flag bits");
      if ((l.flags & kLinkOutOfRange) && l.path_count > 0) bad(at + ": out-of-range link with paths");
      paths += l.path_count;
    }
    if (paths != fr.paths.size())
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
    if (fr.cfr.size() != cfr_expected)
      bad("cfr has " + std::to_string(fr.cfr.size()) + " values, expected links x subcarriers = " +
          std::to_string(cfr_expected));
  }

  void append(const FrameRecord& fr) {
    if (finished) throw std::runtime_error(file + ": append() after finish()");
    check(fr);

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
                      l_path_count, l_path_offset})
      c->reserve_rows(fr.links.size());
    std::uint64_t path_offset = path_count;
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
      l_path_offset->put(path_offset);
      path_offset += l.path_count;
    }

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

    for (Column* c : {i_type, i_object, i_point}) c->reserve_rows(fr.interactions.size());
    for (const auto& it : fr.interactions) {
      i_type->put(it.type);
      i_object->put(it.object);
      i_point->put(it.x), i_point->put(it.y), i_point->put(it.z);
      max_object = std::max<std::int64_t>(max_object, it.object);
    }

    if (c_h) {
      c_h->reserve_rows(fr.links.size());
      for (const auto& v : fr.cfr) c_h->put(v);
    }

    for (const auto& l : fr.links) max_node = std::max<std::int64_t>(max_node, l.rx);
    ++frame_count;
    state_count += fr.nodes.size();
    link_count += fr.links.size();
    path_count = path_offset;
    interaction_count = interaction_offset;
    last_time = fr.time_s;
    for (auto& c : columns) c->maybe_flush(file);
  }

  void flush_all() {
    for (auto& c : columns) c->flush(file, true);
  }

  void finish(const std::vector<NodeInfo>& nodes, const std::vector<std::string>& objects) {
    if (finished) throw std::runtime_error(file + ": finish() called twice");
    if (max_node >= static_cast<std::int64_t>(nodes.size()))
      throw std::invalid_argument(file + ": records name node " + std::to_string(max_node) + " but the node table has " +
                                  std::to_string(nodes.size()) + " nodes");
    if (max_object >= static_cast<std::int64_t>(objects.size()))
      throw std::invalid_argument(file + ": interactions name object " + std::to_string(max_object) +
                                  " but the object table has " + std::to_string(objects.size()) + " objects");
    flush_all();

    std::vector<const char*> ids, vclasses, vtypes, names;
    std::vector<std::uint8_t> kinds;
    std::vector<float> dims;
    for (const auto& n : nodes) {
      ids.push_back(n.id.c_str());
      vclasses.push_back(n.vclass.c_str());
      vtypes.push_back(n.vtype.c_str());
      kinds.push_back(static_cast<std::uint8_t>(n.kind));
      dims.insert(dims.end(), {n.length_m, n.width_m, n.height_m});
    }
    for (const auto& o : objects) names.push_back(o.c_str());
    table("nodes", "id", Dtype::str, nodes.size(), ids.data());
    table("nodes", "kind", Dtype::u8, nodes.size(), kinds.data());
    table("nodes", "vclass", Dtype::str, nodes.size(), vclasses.data());
    table("nodes", "vtype", Dtype::str, nodes.size(), vtypes.data());
    table("nodes", "dimensions", Dtype::f32, nodes.size(), dims.data());
    table("objects", "name", Dtype::str, objects.size(), names.data());

    const hid_t root = fid.get();
    const std::uint64_t counts[4] = {frame_count, nodes.size(), link_count, path_count};
    write_attr(file, root, "/", "frame_count", H5T_STD_U64LE, H5T_NATIVE_UINT64, &counts[0]);
    write_attr(file, root, "/", "node_count", H5T_STD_U64LE, H5T_NATIVE_UINT64, &counts[1]);
    write_attr(file, root, "/", "link_count", H5T_STD_U64LE, H5T_NATIVE_UINT64, &counts[2]);
    write_attr(file, root, "/", "path_count", H5T_STD_U64LE, H5T_NATIVE_UINT64, &counts[3]);
    close_all(true);
    finished = true;
  }

  // Closes datasets, groups and the file (in that order). complete = 1 is written
  // last, just before the file is closed, so a file that has it has everything.
  void close_all(bool mark_complete) {
    for (auto& c : columns)
      if (c->dset.close() < 0) fail(file, c->name, "cannot close dataset");
    columns.clear();
    for (auto& [name, g] : groups)
      if (g.close() < 0) fail(file, "/" + name, "cannot close group");
    groups.clear();
    if (mark_complete) {
      const std::uint8_t one = 1;
      write_attr(file, fid.get(), "/", "complete", H5T_STD_U8LE, H5T_NATIVE_UINT8, &one);
    }
    if (fid.get() >= 0 && fid.close() < 0) fail(file, "/", "cannot close file");
  }
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
