#include "generators/dataset/store_level.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <stdexcept>
#include <vector>

#include "generators/hdf5/checked_file.hpp"
#include "meshkit/errors.hpp"

namespace raysweep::generators {

const char* store_level_name(StoreLevel level) {
  switch (level) {
    case StoreLevel::links: return "links";
    case StoreLevel::cfr: return "cfr";
    case StoreLevel::paths: return "paths";
    case StoreLevel::full: return "full";
  }
  return "?";
}

StoreLevel parse_store_level(const std::string& name) {
  for (StoreLevel l : {StoreLevel::links, StoreLevel::cfr, StoreLevel::paths, StoreLevel::full})
    if (name == store_level_name(l)) return l;
  throw std::invalid_argument("store level \"" + name + "\": expected one of links, cfr, paths, full");
}

namespace {

// Keeps each link's `k` strongest paths with their interactions.
void keep_strongest(FrameRecord& frame, std::uint32_t k) {
  std::vector<PathRecord> paths;
  std::vector<InteractionRecord> interactions;
  std::size_t p0 = 0, i0 = 0;
  std::vector<std::size_t> order;
  std::vector<unsigned char> keep;
  for (LinkRecord& l : frame.links) {
    const std::size_t n = l.path_count;
    keep.assign(n, n <= k);
    if (n > k) {
      order.resize(n);
      std::iota(order.begin(), order.end(), std::size_t{0});
      auto power = [&](std::size_t i) { return std::norm(frame.paths[p0 + i].a); };
      // Stable: of equal powers the earlier path wins, whatever the sort.
      std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return power(a) > power(b); });
      for (std::size_t j = 0; j < k; ++j) keep[order[j]] = 1;
      l.paths_beyond_top_k += static_cast<std::uint32_t>(n - k);
      l.path_count = k;
    }
    for (std::size_t i = 0; i < n; ++i) {
      const PathRecord& p = frame.paths[p0 + i];
      if (keep[i]) {
        paths.push_back(p);
        interactions.insert(interactions.end(), frame.interactions.begin() + static_cast<std::ptrdiff_t>(i0),
                            frame.interactions.begin() + static_cast<std::ptrdiff_t>(i0 + p.interaction_count));
      }
      i0 += p.interaction_count;
    }
    p0 += n;
  }
  frame.paths = std::move(paths);
  frame.interactions = std::move(interactions);
}

}  // namespace

void reduce_frame(FrameRecord& frame, StoreLevel level, std::uint32_t paths_top_k) {
  if (level < StoreLevel::cfr) frame.cfr.clear();
  if (level < StoreLevel::paths) {
    frame.paths.clear();
    frame.interactions.clear();
    return;
  }
  if (paths_top_k > 0) keep_strongest(frame, paths_top_k);
  if (level < StoreLevel::full)
    for (InteractionRecord& in : frame.interactions) in.x = in.y = in.z = std::numeric_limits<float>::quiet_NaN();
}

StoreLevel file_store_level(const hdf5::CheckedFile& file) {
  const auto name = file.attr_if<std::string>("/", "store");
  if (!name) return StoreLevel::full;
  try {
    return parse_store_level(*name);
  } catch (const std::invalid_argument& e) {
    file.fail("attribute store", e.what());
  }
}

void require_store_level(const hdf5::CheckedFile& file, StoreLevel needed, const std::string& stage) {
  const StoreLevel have = file_store_level(file);
  if (have >= needed) return;
  const std::string level = store_level_name(needed);
  throw meshkit::InputError(file.path(), "attribute store",
                            std::string("the dataset stores level ") + store_level_name(have) + " but " + stage +
                                " reads level " + level + ": sweep with [sweep] store = \"" + level +
                                "\" (or --set sweep.store=" + level + ")");
}

}  // namespace raysweep::generators
