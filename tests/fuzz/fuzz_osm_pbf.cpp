// OSM PBF extracts (.osm.pbf) through meshkit::read_osm_buildings, what
// `raysweep scene --osm` reads (libosmium's PBF decoder: protobuf blocks, zlib, then raysweep's
// building assembly: closed ways, multipolygon relations, tags).
#include "fuzz_common.hpp"
#include "meshkit/osm_buildings.hpp"

using namespace raysweep;

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  fuzz::quiet();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = fuzz::write_input("input.osm.pbf", data, size);
  // A plain equirectangular projection: the projection itself is PROJ's, not under test.
  const meshkit::Projector project = [](double lon, double lat) { return meshkit::Vec2{lon * 7e4, lat * 1.1e5}; };
  fuzz::expect_clear_errors("read_osm_buildings", path, [&] { meshkit::read_osm_buildings(path, project); });
  return 0;
}
