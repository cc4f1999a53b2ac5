#include "pipeline/mpi_run.hpp"

#include <mpi.h>
#include <spdlog/spdlog.h>

#include <stdexcept>

#include "meshkit/errors.hpp"
#include "pipeline/settings/config_error.hpp"

namespace raysweep::pipeline {

std::optional<nlohmann::json> run_city_mpi(const CityRunArgs& args, const std::vector<std::string>& argv) {
  if (args.shard || args.merge || !args.until.empty())
    throw std::invalid_argument("--mpi splits the run itself: leave out --shard, --merge and --until");
  MPI_Init(nullptr, nullptr);
  int rank = 0, size = 1;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  MPI_Comm_size(MPI_COMM_WORLD, &size);
  // Every rank logs to the same terminal: say which one speaks.
  spdlog::set_pattern("[%H:%M:%S] [rank " + std::to_string(rank) + "/" + std::to_string(size) + "] %^%l%$ %v");
  auto abort = [&](int code, const std::string& what) {
    spdlog::error("{}", what);
    spdlog::error("rank {} of {} failed: aborting the job (rerun with --resume to keep the finished shards and "
                  "committed blocks)",
                  rank, size);
    spdlog::default_logger()->flush();
    MPI_Abort(MPI_COMM_WORLD, code);
  };
  std::optional<nlohmann::json> result;
  try {
    if (rank == 0) {
      CityRunArgs shared = args;
      shared.until = "traffic";
      run_city(shared, argv);
    }
    MPI_Barrier(MPI_COMM_WORLD);
    CityRunArgs mine = args;
    mine.shard = ShardSpec{static_cast<std::uint32_t>(rank), static_cast<std::uint32_t>(size)};
    run_city(mine, argv);
    MPI_Barrier(MPI_COMM_WORLD);
    if (rank == 0) {
      CityRunArgs merge = args;
      merge.merge = true;
      merge.merge_count = static_cast<std::uint32_t>(size);
      result = run_city(merge, argv);
    }
  } catch (const meshkit::InputError& e) {
    abort(2, e.what());
  } catch (const ConfigError& e) {
    abort(2, e.what());
  } catch (const std::invalid_argument& e) {
    abort(2, e.what());
  } catch (const std::exception& e) {
    abort(1, e.what());
  }
  MPI_Finalize();
  return result;
}

}  // namespace raysweep::pipeline
