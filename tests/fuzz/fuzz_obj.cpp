// OBJ vehicle models through meshkit::import_model (OpenMesh's reader, then
// raysweep's parts, repairs and unit guess), what `raysweep vehicles --model` reads.
#include "fuzz_common.hpp"
#include "meshkit/model_import.hpp"

using namespace raysweep;

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  fuzz::quiet();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = fuzz::write_input("input.obj", data, size);
  fuzz::expect_clear_errors("import_model", path, [&] {
    meshkit::ImportOptions o;
    o.vclass = "passenger";
    o.class_length = 4.5;
    meshkit::import_model(path, o);
  });
  return 0;
}
