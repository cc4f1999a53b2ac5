#include "generators/dataset/dataset_tables.hpp"

#include <cstdint>

namespace raysweep::generators {

void write_node_and_object_tables(hdf5::ColumnFile& out, const std::vector<NodeInfo>& nodes,
                                  const std::vector<std::string>& objects) {
  using hdf5::Dtype;
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
  out.table("nodes", "id", Dtype::str, nodes.size(), ids.data());
  out.table("nodes", "kind", Dtype::u8, nodes.size(), kinds.data());
  out.table("nodes", "vclass", Dtype::str, nodes.size(), vclasses.data());
  out.table("nodes", "vtype", Dtype::str, nodes.size(), vtypes.data());
  out.table("nodes", "dimensions", Dtype::f32, nodes.size(), dims.data());
  out.table("objects", "name", Dtype::str, objects.size(), names.data());
}

}  // namespace raysweep::generators
