// raysweep without MPI (CMake found no MPI C library): --mpi is a usage error.
#include "pipeline/mpi_run.hpp"

#include <stdexcept>

namespace raysweep::pipeline {

std::optional<nlohmann::json> run_city_mpi(const CityRunArgs&, const std::vector<std::string>&) {
  throw std::invalid_argument(
      "--mpi: this raysweep was built without MPI (install openmpi-bin and libopenmpi-dev, then rerun setup.sh); "
      "without MPI run the shards with --shard I/N and merge with --merge (docs/scaleout.md)");
}

}  // namespace raysweep::pipeline
