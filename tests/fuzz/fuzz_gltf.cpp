// glTF models and scenes: binary .glb (inputs starting with the "glTF"
// magic) or JSON .gltf. Each goes through meshkit::import_model (`raysweep
// vehicles --model`: tinygltf, node hierarchy, parts, units) and
// meshkit::read_glb (the scene reader of trace, sweep and radiomap: raysweep's
// extras, Draco, id accessors).
#include <cstring>

#include "fuzz_common.hpp"
#include "meshkit/gltf_io.hpp"
#include "meshkit/model_import.hpp"

using namespace raysweep;

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  fuzz::quiet();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const bool binary = size >= 4 && std::memcmp(data, "glTF", 4) == 0;
  const std::string path = fuzz::write_input(binary ? "input.glb" : "input.gltf", data, size);
  fuzz::expect_clear_errors("import_model", path, [&] {
    meshkit::ImportOptions o;
    o.vclass = "passenger";
    o.class_length = 4.5;
    meshkit::import_model(path, o);
  });
  fuzz::expect_clear_errors("read_glb", path, [&] { meshkit::read_glb(path); });
  return 0;
}
