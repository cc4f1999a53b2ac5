// PLY meshes, ascii and binary: meshkit::read_ply (CGAL, the Mitsuba/Sionna
// scene meshes of `raysweep scene --from-mitsuba`, behind check_ply_layout)
// and meshkit::import_model (OpenMesh, `raysweep vehicles --model car.ply`).
#include "fuzz_common.hpp"
#include "meshkit/model_import.hpp"
#include "meshkit/ply_io.hpp"

using namespace raysweep;

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  fuzz::quiet();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = fuzz::write_input("input.ply", data, size);
  fuzz::expect_clear_errors("read_ply", path, [&] { meshkit::read_ply(path); });
  fuzz::expect_clear_errors("import_model", path, [&] {
    meshkit::ImportOptions o;
    o.vclass = "bus";
    o.class_length = 12;
    meshkit::import_model(path, o);
  });
  return 0;
}
