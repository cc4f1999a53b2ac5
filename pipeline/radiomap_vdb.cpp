// The OpenVDB module (libraysweep_vdb.so): the only code that links OpenVDB.
// raysweep loads it when a radio map is written or read, so that the 57,000
// symbol bindings OpenVDB costs the dynamic loader (two thirds of every
// process's start) are paid by the commands that use it only.
#include "pipeline/radiomap_vdb.hpp"

#include <openvdb/io/File.h>
#include <openvdb/openvdb.h>

#include <filesystem>
#include <stdexcept>

#include "pipeline/staged_output.hpp"

namespace raysweep::pipeline {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

void put_meta(openvdb::MetaMap& m, const std::string& key, const json& v) {
  if (v.is_number_integer()) m.insertMeta(key, openvdb::Int64Metadata(v.get<std::int64_t>()));
  else if (v.is_number()) m.insertMeta(key, openvdb::DoubleMetadata(v.get<double>()));
  else if (v.is_string()) m.insertMeta(key, openvdb::StringMetadata(v.get<std::string>()));
  else if (v.is_boolean()) m.insertMeta(key, openvdb::BoolMetadata(v.get<bool>()));
  else m.insertMeta(key, openvdb::StringMetadata(v.dump()));
}

json get_meta(const openvdb::MetaMap& m) {
  json out = json::object();
  for (auto it = m.beginMeta(); it != m.endMeta(); ++it) {
    const auto& md = *it->second;
    if (auto* s = dynamic_cast<const openvdb::StringMetadata*>(&md)) out[it->first] = s->value();
    else if (auto* d = dynamic_cast<const openvdb::DoubleMetadata*>(&md)) out[it->first] = d->value();
    else if (auto* f = dynamic_cast<const openvdb::FloatMetadata*>(&md)) out[it->first] = f->value();
    else if (auto* i = dynamic_cast<const openvdb::Int64Metadata*>(&md)) out[it->first] = i->value();
    else if (auto* i32 = dynamic_cast<const openvdb::Int32Metadata*>(&md)) out[it->first] = i32->value();
    else if (auto* b = dynamic_cast<const openvdb::BoolMetadata*>(&md)) out[it->first] = b->value();
    else out[it->first] = md.str();
  }
  return out;
}

openvdb::math::Transform::Ptr make_transform(double voxel_m, double z0_m) {
  auto t = openvdb::math::Transform::createLinearTransform(voxel_m);
  t->postTranslate(openvdb::Vec3d(0, 0, z0_m));
  return t;
}

template <typename GridT, typename T>
typename GridT::Ptr fill(const std::vector<std::array<std::int32_t, 3>>& voxels, const std::vector<T>& values,
                         T background) {
  auto g = GridT::create(static_cast<typename GridT::ValueType>(background));
  auto acc = g->getAccessor();
  for (std::size_t n = 0; n < voxels.size(); ++n)
    acc.setValueOn(openvdb::Coord(voxels[n][0], voxels[n][1], voxels[n][2]),
                   static_cast<typename GridT::ValueType>(values[n]));
  return g;
}


void write_vdb(const std::string& path, double voxel_m, double z0_m,
               const std::vector<std::array<std::int32_t, 3>>& voxels, const std::vector<VdbGrid>& grids,
               const json& meta) {
  openvdb::initialize();
  const auto transform = make_transform(voxel_m, z0_m);
  openvdb::GridPtrVec out;
  for (const auto& g : grids) {
    if ((g.is_float ? g.f.size() : g.i.size()) != voxels.size())
      throw std::logic_error("radio map grid " + g.name + ": value count differs from the voxel count");
    openvdb::GridBase::Ptr grid;
    if (g.is_float) grid = fill<openvdb::FloatGrid>(voxels, g.f, g.float_background);
    else grid = fill<openvdb::Int32Grid>(voxels, g.i, g.int_background);
    grid->setName(g.name);
    grid->setTransform(transform->copy());
    grid->setGridClass(openvdb::GRID_UNKNOWN);
    for (const auto& [k, v] : g.meta.items()) put_meta(*grid, k, v);
    grid->setSaveFloatAsHalf(false);
    out.push_back(grid);
  }
  openvdb::MetaMap file_meta;
  for (const auto& [k, v] : meta.items()) put_meta(file_meta, k, v);
  StagedFile staged{fs::path(path)};
  {
    openvdb::io::File file(staged.path().string());
    file.setCompression(openvdb::io::COMPRESS_BLOSC | openvdb::io::COMPRESS_ACTIVE_MASK);
    if (!file.hasBloscCompression()) file.setCompression(openvdb::io::COMPRESS_ZIP | openvdb::io::COMPRESS_ACTIVE_MASK);
    file.write(out, file_meta);
    file.close();
  }
  staged.commit();
}

VdbSummary read_summary(const std::string& path) {
  openvdb::initialize();
  openvdb::io::File file(path);
  try {
    file.open();
  } catch (const openvdb::Exception& e) {
    throw std::invalid_argument(path + ": not a readable OpenVDB file (" + e.what() + ")");
  }
  VdbSummary s;
  s.meta = get_meta(*file.getMetadata());
  for (auto name = file.beginName(); name != file.endName(); ++name) {
    auto base = file.readGrid(name.gridName());
    VdbSummary::Grid g;
    g.name = base->getName();
    g.type = base->valueType();
    g.active = base->activeVoxelCount();
    g.voxel_m = base->voxelSize()[0];
    g.meta = get_meta(*base);
    if (auto fg = openvdb::gridPtrCast<openvdb::FloatGrid>(base)) {
      bool first = true;
      for (auto it = fg->cbeginValueOn(); it; ++it) {
        const double v = *it;
        g.min = first ? v : std::min(g.min, v);
        g.max = first ? v : std::max(g.max, v);
        first = false;
      }
    } else if (auto ig = openvdb::gridPtrCast<openvdb::Int32Grid>(base)) {
      bool first = true;
      for (auto it = ig->cbeginValueOn(); it; ++it) {
        const double v = *it;
        g.min = first ? v : std::min(g.min, v);
        g.max = first ? v : std::max(g.max, v);
        first = false;
      }
    }
    s.grids.push_back(std::move(g));
  }
  file.close();
  return s;
}

std::vector<VdbVoxel> read_voxels(const std::string& path, const std::string& grid) {
  openvdb::initialize();
  openvdb::io::File file(path);
  file.open();
  if (!file.hasGrid(grid)) throw std::invalid_argument(path + ": no grid " + grid);
  auto base = file.readGrid(grid);
  file.close();
  std::vector<VdbVoxel> out;
  auto emit = [&](const openvdb::Coord& c, double v) {
    const auto w = base->indexToWorld(c);
    out.push_back({{c.x(), c.y(), c.z()}, {w.x(), w.y(), w.z()}, v});
  };
  if (auto fg = openvdb::gridPtrCast<openvdb::FloatGrid>(base))
    for (auto it = fg->cbeginValueOn(); it; ++it) {
      if (it.isVoxelValue()) emit(it.getCoord(), *it);
    }
  else if (auto ig = openvdb::gridPtrCast<openvdb::Int32Grid>(base))
    for (auto it = ig->cbeginValueOn(); it; ++it) {
      if (it.isVoxelValue()) emit(it.getCoord(), *it);
    }
  std::sort(out.begin(), out.end(), [](const VdbVoxel& a, const VdbVoxel& b) { return a.ijk < b.ijk; });
  return out;
}

}  // namespace

}  // namespace raysweep::pipeline

extern "C" __attribute__((visibility("default"))) const raysweep::pipeline::VdbModule* raysweep_vdb_module() {
  using namespace raysweep::pipeline;
  static const VdbModule module{kVdbModuleVersion, &write_vdb, &read_summary, &read_voxels};
  return &module;
}
