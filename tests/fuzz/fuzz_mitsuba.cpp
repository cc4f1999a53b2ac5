// Mitsuba/Sionna scene.xml through meshkit::read_mitsuba (`raysweep scene
// --from-mitsuba`): bsdfs, shapes, references, to_world transforms. The
// scratch folder holds meshes/a.ply and meshes/b.ply (a valid triangle and a
// quad), so shapes the fuzzer names that way load and reach the transforms.
#include "fuzz_common.hpp"
#include "meshkit/mitsuba_io.hpp"

using namespace raysweep;

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  fuzz::quiet();
  const std::string tri =
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
      "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
  const std::string quad =
      "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
      "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n2 0 0\n2 2 0\n0 2 0\n4 0 1 2 3\n";
  fuzz::write_input("mitsuba/meshes/a.ply", reinterpret_cast<const std::uint8_t*>(tri.data()), tri.size());
  fuzz::write_input("mitsuba/meshes/b.ply", reinterpret_cast<const std::uint8_t*>(quad.data()), quad.size());
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = fuzz::write_input("mitsuba/scene.xml", data, size);
  fuzz::expect_clear_errors("read_mitsuba", path, [&] { meshkit::read_mitsuba(path); });
  return 0;
}
