// build_ns3_table(): a channel dataset -> the ns-3 lookup table. The links and
// node states come from the SINR generator's loader (ChannelTrace); the
// frequency responses, when present, are read a frame at a time from /cfr/h.
#include <cmath>
#include <complex>
#include <limits>
#include <optional>
#include <stdexcept>

#include "generators/dataset/store_level.hpp"
#include "generators/hdf5/checked_file.hpp"
#include "generators/ns3_table/ns3_table.hpp"
#include "generators/sinr/channel_trace.hpp"
#include "meshkit/errors.hpp"

namespace raysweep::generators {

namespace {

float power_db(double mean_power) {
  return mean_power > 0 ? static_cast<float>(10.0 * std::log10(mean_power)) : -std::numeric_limits<float>::infinity();
}

// The /cfr group of a channel dataset, when it has one.
class CfrReader {
 public:
  explicit CfrReader(const std::string& path) : file_(path) {
    hdf5::QuietHdf5 quiet;
    file_.open();
    if (!file_.exists("/cfr")) return;
    file_.group("/cfr");
    subcarriers_ = file_.attr<std::uint32_t>("/cfr", "subcarriers");
    spacing_hz_ = file_.attr<double>("/cfr", "subcarrier_spacing_hz");
    carrier_hz_ = file_.attr<double>("/cfr", "carrier_hz");
    // The band centres derive from these (the table writer needs them increasing).
    if (!(std::isfinite(spacing_hz_) && spacing_hz_ > 0))
      file_.fail("/cfr attribute subcarrier_spacing_hz", "is not a positive number");
    if (!(std::isfinite(carrier_hz_) && carrier_hz_ > 0)) file_.fail("/cfr attribute carrier_hz", "is not a positive number");
    h_.emplace(file_.dataset("/cfr/h"));
    rows_ = h_->expect({std::nullopt, hsize_t{subcarriers_}}).rows();
  }
  bool present() const { return subcarriers_ > 0; }
  std::uint32_t subcarriers() const { return subcarriers_; }
  double spacing_hz() const { return spacing_hz_; }
  double carrier_hz() const { return carrier_hz_; }
  hsize_t rows() const { return rows_; }

  std::vector<std::complex<float>> read(hsize_t first, hsize_t count) const {
    hdf5::QuietHdf5 quiet;
    return h_->read<std::complex<float>>(first, count, subcarriers_);
  }

 private:
  hdf5::CheckedFile file_;
  std::optional<hdf5::Dataset> h_;
  std::uint32_t subcarriers_ = 0;
  double spacing_hz_ = 0, carrier_hz_ = 0;
  hsize_t rows_ = 0;
};

}  // namespace

Ns3TableBuildStats build_ns3_table(const std::string& dataset, const std::filesystem::path& out, Ns3TableHeader header,
                                   std::uint32_t subcarriers_per_band) {
  {
    // A table from a file without its frequency responses would silently
    // fall back to the incoherent gain: refuse it, naming the level to use.
    hdf5::QuietHdf5 quiet;
    hdf5::CheckedFile file(dataset);
    file.open();
    require_store_level(file, StoreLevel::cfr, "ns3-table");
  }
  const sinr::ChannelTrace trace = sinr::ChannelTrace::load(dataset);
  const CfrReader cfr(dataset);
  if (cfr.present() && cfr.rows() != trace.link_row(trace.frames()))
    throw meshkit::InputError(dataset, "/cfr/h",
                              std::to_string(cfr.rows()) + " rows but /links has " +
                                  std::to_string(trace.link_row(trace.frames())));
  header.carrier_hz = trace.carrier_hz();
  header.bandwidth_hz = trace.bandwidth_hz();
  header.gain_source = cfr.present() ? GainSource::cfr : GainSource::incoherent;

  Ns3TableBands bands;
  const std::uint32_t k = cfr.subcarriers();
  if (cfr.present() && subcarriers_per_band > 0) {
    if (k % subcarriers_per_band != 0)
      throw std::invalid_argument("subcarriers_per_band " + std::to_string(subcarriers_per_band) + " does not divide the " +
                                  std::to_string(k) + " subcarriers of " + dataset);
    bands.subcarriers_per_band = subcarriers_per_band;
    bands.band_width_hz = subcarriers_per_band * cfr.spacing_hz();
    for (std::uint32_t first = 0; first < k; first += subcarriers_per_band) {
      // Subcarrier j is at carrier + (j - floor(K / 2)) * spacing; a band's centre is its subcarriers' mean.
      const double mid = first + 0.5 * (subcarriers_per_band - 1) - std::floor(k / 2.0);
      bands.center_hz.push_back(cfr.carrier_hz() + mid * cfr.spacing_hz());
      // A carrier so large that the spacing vanishes in rounding gives equal
      // centres, which the table writer refused naming its own output
      // (tests/fuzz/fuzz_dataset_h5): name the dataset's attributes instead.
      if (bands.center_hz.size() > 1 && !(bands.center_hz.back() > bands.center_hz[bands.center_hz.size() - 2]))
        throw meshkit::InputError(dataset, "/cfr",
                                  "carrier_hz and subcarrier_spacing_hz give band centres that are not increasing");
    }
  }

  // Two frames at one time pass the channel reader (the SINR stage reads
  // the later one), but a table's frames must advance: found by
  // tests/fuzz/fuzz_dataset_h5, whose writer refused them naming its own
  // output. Name the dataset's row instead.
  for (std::size_t f = 1; f < trace.frames(); ++f)
    if (!(trace.time(f) > trace.time(f - 1)))
      throw meshkit::InputError(dataset, "/frames/time_s",
                                "row " + std::to_string(f) + ": time " + std::to_string(trace.time(f)) +
                                    " s is not after the previous frame's");

  Ns3TableWriter writer(out, header, bands);
  std::vector<NodeState> states;
  std::vector<Ns3Pair> pairs;
  std::vector<float> band_gains;
  for (std::size_t f = 0; f < trace.frames(); ++f) {
    states.assign(trace.states_begin(f), trace.states_end(f));
    pairs.clear();
    band_gains.clear();
    const std::size_t links = static_cast<std::size_t>(trace.links_end(f) - trace.links_begin(f));
    std::vector<std::complex<float>> h;
    if (cfr.present()) h = cfr.read(trace.link_row(f), links);
    for (std::size_t i = 0; i < links; ++i) {
      const auto& l = trace.links_begin(f)[i];
      Ns3Pair p{l.tx, l.rx, l.gain_db, l.los_class};
      if (cfr.present()) {
        double total = 0, band = 0;
        for (std::uint32_t j = 0; j < k; ++j) {
          const double pw = std::norm(std::complex<double>(h[i * k + j]));
          total += pw;
          band += pw;
          if (bands.count() && (j + 1) % subcarriers_per_band == 0) {
            band_gains.push_back(power_db(band / subcarriers_per_band));
            band = 0;
          }
        }
        p.gain_db = power_db(total / k);
      }
      pairs.push_back(p);
    }
    writer.add_frame(trace.time(f), states, pairs, band_gains);
  }
  writer.finish(trace.nodes());
  return {writer.frames(), writer.pairs(), trace.nodes().size(), bands.count(), header.gain_source};
}

}  // namespace raysweep::generators
