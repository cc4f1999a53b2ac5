// The dataset's static tables (/nodes, /objects), written the same way by
// the dataset writer and by the virtual merge.
#pragma once

#include <string>
#include <vector>

#include "generators/dataset/dataset.hpp"
#include "generators/hdf5/column_file.hpp"

namespace raysweep::generators {

void write_node_and_object_tables(hdf5::ColumnFile& out, const std::vector<NodeInfo>& nodes,
                                  const std::vector<std::string>& objects);

}  // namespace raysweep::generators
