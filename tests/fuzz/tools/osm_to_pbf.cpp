// Converts an .osm XML seed to .osm.pbf with libosmium's writer (how corpus/osm_pbf was made):
//   g++ -O1 -std=c++17 osm_to_pbf.cpp -o osm_to_pbf -lz -lexpat -lbz2 -lpthread
//   ./osm_to_pbf in.osm out.osm.pbf ["pbf,pbf_compression=none,pbf_dense_nodes=false"]
#include <osmium/io/any_input.hpp>
#include <osmium/io/any_output.hpp>
#include <osmium/io/output_iterator.hpp>
#include <osmium/io/header.hpp>
int main(int argc, char** argv) {
  osmium::io::Reader r{argv[1]};
  osmium::io::Header h = r.header();
  osmium::io::File out{argv[2], argc > 3 ? argv[3] : ""};
  osmium::io::Writer w{out, h, osmium::io::overwrite::allow};
  while (osmium::memory::Buffer b = r.read()) w(std::move(b));
  w.close(); r.close();
}
