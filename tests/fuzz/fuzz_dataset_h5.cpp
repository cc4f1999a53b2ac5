// Channel datasets (HDF5, format raysweep-channels), structure-aware (see
// h5_mutate.hpp): edits of a valid dataset, then every reader of it the CLI
// has: generators::DatasetReader (merge: all frames, row offsets),
// sinr::ChannelTrace::load (the SINR stage), build_ns3_table (`raysweep
// ns3-table`), write_features (`raysweep features`) and dataset_info
// (`raysweep info`); the feature file it writes is validated.
#include "generators/dataset/dataset_reader.hpp"
#include "generators/formats.hpp"
#include "generators/sinr/channel_trace.hpp"
#include "generators/sweep/context_features.hpp"
#include "h5_bases.hpp"
#include "h5_mutate.hpp"

using namespace raysweep;

namespace {
std::vector<std::uint8_t> g_base;
}

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  fuzz::quiet();
  fuzz::quiet_hdf5();
  g_base = fuzz::base_bytes("base.h5", fuzz::write_channel_base);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = fuzz::mutated_file("dataset.h5", g_base, data, size);
  fuzz::expect_clear_errors("DatasetReader", path, [&] {
    generators::DatasetReader r(path);
    r.frames(0, r.frame_count());
    r.rows_at(r.frame_count());
  });
  fuzz::expect_clear_errors("ChannelTrace::load", path, [&] { generators::sinr::ChannelTrace::load(path); });
  fuzz::expect_clear_errors("build_ns3_table", path, [&] {
    generators::Ns3TableHeader h;
    generators::build_ns3_table(path, fuzz::scratch() / "table.h5", h, 2);
  });
  fuzz::expect_clear_errors("write_features", path, [&] {
    // An empty height map: the corridors are open ground, the node states and links are read.
    generators::FeatureGridSpec spec;
    spec.along_cells = 8, spec.across_cells = 4;
    const auto out = fuzz::scratch() / "features.h5";
    generators::FeaturesHeader h;
    h.config = nlohmann::json::object(), h.inputs = nlohmann::json::array(), h.provenance = nlohmann::json::object();
    generators::write_features(spec, generators::HeightMap{}, path, out, h);
    const auto problems = generators::validate_dataset(out.string());
    if (!problems.empty()) fuzz::finding("write_features wrote an invalid file: " + problems.front());
  });
  fuzz::expect_clear_errors("dataset_info", path, [&] { generators::dataset_info(path); });
  return 0;
}
