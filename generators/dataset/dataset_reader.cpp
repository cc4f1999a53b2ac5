#include "generators/dataset/dataset_reader.hpp"

#include <cmath>
#include <limits>
#include <map>

#include "generators/dataset/store_level.hpp"
#include "generators/hdf5/checked_file.hpp"
#include "meshkit/errors.hpp"

namespace raysweep::generators {

using hdf5::QuietHdf5;

struct DatasetReader::Impl {
  std::string file;
  hdf5::CheckedFile h5;
  DatasetHeader header;
  std::string schema_version;
  bool complete = false;
  std::vector<NodeInfo> nodes;
  std::vector<std::string> objects;
  std::vector<double> time;
  std::vector<std::uint64_t> node_offset, link_offset;
  std::vector<std::uint32_t> node_count, link_count;
  std::map<std::string, hdf5::Dataset> dsets;
  hsize_t S = 0, L = 0, P = 0, I = 0, K = 0;

  explicit Impl(std::string path) : file(std::move(path)), h5(file) {}

  [[noreturn]] void fail(const std::string& object, const std::string& what) const { h5.fail(object, what); }

  // Datasets stay open: frames() reads every column again for each block of frames.
  const hdf5::Dataset& dset(const std::string& name) {
    auto it = dsets.find(name);
    if (it == dsets.end()) it = dsets.emplace(name, h5.dataset(name)).first;
    return it->second;
  }
  hsize_t rows(const std::string& name) { return dset(name).rows(); }
  template <class T>
  std::vector<T> read(const std::string& name, hsize_t start, hsize_t n, hsize_t width = 1) {
    return dset(name).read<T>(start, n, width);
  }
  // A column added in a later minor version: `fill` in files written before it.
  template <class T>
  std::vector<T> read_or(const std::string& name, hsize_t start, hsize_t n, hsize_t width, T fill) {
    if (!h5.exists(name)) return std::vector<T>(static_cast<std::size_t>(n * width), fill);
    return read<T>(name, start, n, width);
  }
  bool stores_paths() const { return header.store >= StoreLevel::paths; }
  std::string str_attr(const std::string& name) { return h5.attr<std::string>("/", name); }
  nlohmann::json json_attr(const std::string& name) {
    const std::string text = str_attr(name);
    if (!nlohmann::json::accept(text)) fail("attribute " + name, "not valid JSON text");
    return nlohmann::json::parse(text);
  }

  void open() {
    h5.open();
    if (!h5.has_attr("/", "format") || str_attr("format") != kDatasetFormat)
      fail("attribute format", std::string("not a raysweep channel dataset (format is not ") + kDatasetFormat + ")");
    schema_version = str_attr("schema_version");
    int supported = 0;
    std::sscanf(kDatasetSchemaVersion, "%d", &supported);
    if (hdf5::major_version(schema_version) != supported)
      fail("attribute schema_version", schema_version + " is not " + std::to_string(supported) + ".x");
    complete = h5.has_attr("/", "complete");
    header.raysweep_version = str_attr("raysweep_version");
    header.git_hash = str_attr("git_hash");
    header.config = json_attr("config");
    header.inputs = json_attr("inputs");
    header.provenance = json_attr("provenance");
    header.seed = h5.attr<std::uint64_t>("/", "seed");
    header.carrier_hz = h5.attr<double>("/", "carrier_hz");
    header.bandwidth_hz = h5.attr<double>("/", "bandwidth_hz");
    if (h5.has_attr("/", "shard")) header.shard = str_attr("shard");
    if (h5.has_attr("/", "store")) {
      try {
        header.store = parse_store_level(str_attr("store"));
      } catch (const std::invalid_argument& e) {
        fail("attribute store", e.what());
      }
    }
    if (h5.has_attr("/", "paths_top_k")) header.paths_top_k = h5.attr<std::uint32_t>("/", "paths_top_k");
    if (h5.exists("/cfr")) {
      h5.group("/cfr");
      header.cfr_subcarriers = h5.attr<std::uint32_t>("/cfr", "subcarriers");
      header.cfr_subcarrier_spacing_hz = h5.attr<double>("/cfr", "subcarrier_spacing_hz");
      K = header.cfr_subcarriers;
    }

    const hsize_t F = rows("/frames/time_s");
    time = read<double>("/frames/time_s", 0, F);
    node_offset = read<std::uint64_t>("/frames/node_offset", 0, F);
    link_offset = read<std::uint64_t>("/frames/link_offset", 0, F);
    node_count = read<std::uint32_t>("/frames/node_count", 0, F);
    link_count = read<std::uint32_t>("/frames/link_count", 0, F);
    S = rows("/node_states/node");
    L = rows("/links/tx");
    if (stores_paths()) {
      P = rows("/paths/tau_s");
      I = rows("/interactions/type");
    }
    std::uint64_t s = 0, l = 0;
    for (hsize_t f = 0; f < F; ++f) {
      if (node_offset[f] != s || link_offset[f] != l)
        fail("/frames", "offsets of frame " + std::to_string(f) + " are not the running sums of the counts");
      s += node_count[f];
      l += link_count[f];
    }
    if (s != S || l != L) fail("/frames", "counts do not add up to the /node_states and /links sizes");

    if (complete) {
      const hsize_t N = rows("/nodes/id");
      const auto ids = dset("/nodes/id").strings();
      const auto vclass = dset("/nodes/vclass").strings();
      const auto vtype = dset("/nodes/vtype").strings();
      const auto kind = read<std::uint8_t>("/nodes/kind", 0, N);
      const auto dims = read<float>("/nodes/dimensions", 0, N, 3);
      if (vclass.size() != N || vtype.size() != N) fail("/nodes", "tables of different lengths");
      for (hsize_t i = 0; i < N; ++i)
        nodes.push_back({ids[i], static_cast<NodeKind>(kind[i]), vclass[i], vtype[i], dims[3 * i], dims[3 * i + 1],
                         dims[3 * i + 2]});
      objects = dset("/objects/name").strings();
    }
  }

  std::uint64_t path_start(std::uint64_t link) {
    return link >= L || !stores_paths() ? P : read<std::uint64_t>("/links/path_offset", link, 1)[0];
  }
  std::uint64_t interaction_start(std::uint64_t path) {
    return path >= P ? I : read<std::uint64_t>("/paths/interaction_offset", path, 1)[0];
  }

  FrameRows rows_at(std::uint64_t f) {
    if (f > time.size()) fail("", "frame " + std::to_string(f) + " beyond its " + std::to_string(time.size()) + " frames");
    FrameRows r;
    r.states = f < time.size() ? node_offset[f] : S;
    r.links = f < time.size() ? link_offset[f] : L;
    r.paths = path_start(r.links);
    r.interactions = interaction_start(r.paths);
    return r;
  }

  std::vector<FrameRecord> frames(std::uint64_t first, std::uint64_t count) {
    if (first + count > time.size())
      fail("", "frames " + std::to_string(first) + "+" + std::to_string(count) + " beyond its " +
           std::to_string(time.size()) + " frames");
    const FrameRows a = rows_at(first), b = rows_at(first + count);
    if (b.paths < a.paths || b.interactions < a.interactions) fail("/links, /paths", "offsets decrease");
    const hsize_t ns = b.states - a.states, nl = b.links - a.links, np = b.paths - a.paths,
                  ni = b.interactions - a.interactions;

    const auto s_node = read<std::uint32_t>("/node_states/node", a.states, ns);
    const auto s_pos = read<double>("/node_states/position", a.states, ns, 3);
    const auto s_vel = read<float>("/node_states/velocity", a.states, ns, 3);
    const auto s_head = read<float>("/node_states/heading_deg", a.states, ns);

    const auto l_tx = read<std::uint32_t>("/links/tx", a.links, nl);
    const auto l_rx = read<std::uint32_t>("/links/rx", a.links, nl);
    const auto l_los = read<std::uint8_t>("/links/los_class", a.links, nl);
    const auto l_flags = read<std::uint8_t>("/links/flags", a.links, nl);
    const auto l_block = read<std::uint16_t>("/links/blocker_count", a.links, nl);
    const auto l_gc = read<float>("/links/gain_coherent_db", a.links, nl);
    const auto l_gi = read<float>("/links/gain_incoherent_db", a.links, nl);
    const auto l_fd = read<double>("/links/first_delay_s", a.links, nl);
    const auto l_rms = read<float>("/links/rms_delay_spread_s", a.links, nl);
    const auto l_pc = read<std::uint32_t>("/links/path_count", a.links, nl);
    const bool paths = stores_paths();
    const auto l_po = paths ? read<std::uint64_t>("/links/path_offset", a.links, nl)
                            : std::vector<std::uint64_t>(nl, 0);
    const float inf = std::numeric_limits<float>::infinity(), nan = std::numeric_limits<float>::quiet_NaN();
    const auto l_below = read_or<std::uint32_t>("/links/paths_below_threshold", a.links, nl, 1, 0);
    const auto l_losf = read_or<std::uint8_t>("/links/los_class_fresnel", a.links, nl, 1, 0);
    const auto l_clear = read_or<float>("/links/fresnel_clearance", a.links, nl, 1, 1);
    const auto l_vloss = read_or<float>("/links/vehicle_loss_db", a.links, nl, 1, 0);
    const auto l_beyond = read_or<std::uint32_t>("/links/paths_beyond_top_k", a.links, nl, 1, 0);
    const auto l_diffuse = read_or<float>("/links/diffuse_gain_db", a.links, nl, 1, -inf);
    const auto l_kf = read_or<float>("/links/k_factor_db", a.links, nl, 1, -inf);
    const auto l_dsp = read_or<float>("/links/rms_doppler_spread_hz", a.links, nl, 1, 0);
    const auto l_asd = read_or<float>("/links/aod_spread_rad", a.links, nl, 2, 0);
    const auto l_asa = read_or<float>("/links/aoa_spread_rad", a.links, nl, 2, 0);
    const auto l_sd = read_or<float>("/links/strongest_excess_delay_s", a.links, nl, 1, 0);
    const auto l_sod = read_or<float>("/links/strongest_aod", a.links, nl, 2, 0);
    const auto l_soa = read_or<float>("/links/strongest_aoa", a.links, nl, 2, 0);

    std::vector<std::complex<float>> p_a;
    std::vector<double> p_tau;
    std::vector<float> p_aod, p_aoa, p_dop, i_pt;
    std::vector<std::uint8_t> p_ic, i_type;
    std::vector<std::uint64_t> p_io;
    std::vector<std::uint32_t> i_obj;
    if (paths) {
      p_a = read<std::complex<float>>("/paths/a", a.paths, np);
      p_tau = read<double>("/paths/tau_s", a.paths, np);
      p_aod = read<float>("/paths/aod", a.paths, np, 2);
      p_aoa = read<float>("/paths/aoa", a.paths, np, 2);
      p_dop = read<float>("/paths/doppler_hz", a.paths, np);
      p_ic = read<std::uint8_t>("/paths/interaction_count", a.paths, np);
      p_io = read<std::uint64_t>("/paths/interaction_offset", a.paths, np);
      i_type = read<std::uint8_t>("/interactions/type", a.interactions, ni);
      i_obj = read<std::uint32_t>("/interactions/object", a.interactions, ni);
      i_pt = header.store >= StoreLevel::full ? read<float>("/interactions/point", a.interactions, ni, 3)
                                              : std::vector<float>(static_cast<std::size_t>(3 * ni), nan);
    }

    std::vector<std::complex<float>> cfr;
    if (K > 0) cfr = read<std::complex<float>>("/cfr/h", a.links, nl, K);

    std::vector<FrameRecord> out(static_cast<std::size_t>(count));
    std::size_t s = 0, l = 0, p = 0, i = 0;
    std::uint64_t po = a.paths, io = a.interactions;
    for (std::uint64_t k = 0; k < count; ++k) {
      const std::uint64_t f = first + k;
      FrameRecord& fr = out[k];
      fr.time_s = time[f];
      for (std::uint32_t j = 0; j < node_count[f]; ++j, ++s)
        fr.nodes.push_back({s_node[s], s_pos[3 * s], s_pos[3 * s + 1], s_pos[3 * s + 2], s_vel[3 * s], s_vel[3 * s + 1],
                            s_vel[3 * s + 2], s_head[s]});
      const std::size_t l0 = l;
      for (std::uint32_t j = 0; j < link_count[f]; ++j, ++l) {
        LinkRecord rec{l_tx[l], l_rx[l], l_los[l], l_flags[l], l_block[l], l_gc[l], l_gi[l], l_fd[l], l_rms[l],
                       l_pc[l], l_below[l], l_losf[l], l_clear[l], l_vloss[l], l_beyond[l], l_diffuse[l], l_kf[l],
                       l_dsp[l], {l_asd[2 * l], l_asd[2 * l + 1]}, {l_asa[2 * l], l_asa[2 * l + 1]}, l_sd[l],
                       {l_sod[2 * l], l_sod[2 * l + 1]}, {l_soa[2 * l], l_soa[2 * l + 1]}};
        fr.links.push_back(rec);
        if (!paths) continue;
        if (l_po[l] != po) fail("/links/path_offset", "row " + std::to_string(a.links + l) + " is not the running sum");
        for (std::uint32_t q = 0; q < l_pc[l]; ++q, ++p, ++po) {
          if (p >= np || p_io[p] != io)
            fail("/paths/interaction_offset", "row " + std::to_string(a.paths + p) + " is not the running sum");
          fr.paths.push_back({p_a[p], p_tau[p], p_aod[2 * p], p_aod[2 * p + 1], p_aoa[2 * p], p_aoa[2 * p + 1], p_dop[p],
                              p_ic[p]});
          for (std::uint8_t m = 0; m < p_ic[p]; ++m, ++i, ++io) {
            if (i >= ni) fail("/interactions", "fewer rows than the paths' interaction counts");
            fr.interactions.push_back({i_type[i], i_obj[i], i_pt[3 * i], i_pt[3 * i + 1], i_pt[3 * i + 2]});
          }
        }
      }
      if (K > 0) fr.cfr.assign(cfr.begin() + static_cast<std::ptrdiff_t>(l0 * K), cfr.begin() + static_cast<std::ptrdiff_t>(l * K));
    }
    if (p != np || i != ni) fail("/paths, /interactions", "rows left over after the frames' links and paths");
    return out;
  }
};

DatasetReader::DatasetReader(const std::filesystem::path& path) {
  QuietHdf5 quiet;
  impl_ = std::make_unique<Impl>(path.string());
  impl_->open();
}

DatasetReader::~DatasetReader() = default;

const std::string& DatasetReader::path() const { return impl_->file; }
const DatasetHeader& DatasetReader::header() const { return impl_->header; }
const std::string& DatasetReader::schema_version() const { return impl_->schema_version; }
bool DatasetReader::complete() const { return impl_->complete; }
std::uint64_t DatasetReader::frame_count() const { return impl_->time.size(); }
const std::vector<NodeInfo>& DatasetReader::nodes() const { return impl_->nodes; }
const std::vector<std::string>& DatasetReader::objects() const { return impl_->objects; }

std::vector<FrameRecord> DatasetReader::frames(std::uint64_t first, std::uint64_t count) {
  QuietHdf5 quiet;
  return impl_->frames(first, count);
}

FrameRows DatasetReader::rows_at(std::uint64_t frame) {
  QuietHdf5 quiet;
  return impl_->rows_at(frame);
}

}  // namespace raysweep::generators
