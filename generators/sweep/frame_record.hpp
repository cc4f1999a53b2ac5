// Dataset records (dataset.hpp) of traced results, as the sweep stores them
// and a one-shot trace writes them: the same rounding to the dataset's types
// wherever a channel is written.
#pragma once

#include <complex>
#include <cstdint>
#include <vector>

#include "generators/dataset/dataset.hpp"
#include "tracer/channel.hpp"
#include "tracer/solver.hpp"

namespace raysweep::generators {

LinkRecord link_record(const tracer::PairResult& res, std::uint32_t tx, std::uint32_t rx);
PathRecord path_record(const tracer::Path& path);
// `object`: the interaction's object in the dataset's object table.
InteractionRecord interaction_record(const tracer::Interaction& in, std::uint32_t object);
// The paths' frequency response on `grid`, in the dataset's precision.
std::vector<std::complex<float>> cfr_record(const std::vector<tracer::Path>& paths, const tracer::OfdmGrid& grid);

}  // namespace raysweep::generators
