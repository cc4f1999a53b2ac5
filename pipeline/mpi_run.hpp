// `mpirun -n N raysweep run CITY.toml --mpi`: one city over N MPI ranks.
// Rank 0 builds the stages every shard shares (scene, vehicles, traffic),
// every rank r then traces shard r/N, and rank 0 merges the shards and runs
// the later stages. A rank that fails logs its error and calls MPI_Abort, so
// the whole job fails with that error; finished shards are stamped, so a
// rerun (with --resume for the interrupted shard's blocks) redoes only what
// is missing. Built with MPI only when CMake finds it (pipeline/mpi/).
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "pipeline/city_run.hpp"

namespace raysweep::pipeline {

// The summary of run_city() on rank 0, nullopt on the other ranks. Without
// MPI support: std::invalid_argument saying so.
std::optional<nlohmann::json> run_city_mpi(const CityRunArgs& args, const std::vector<std::string>& argv);

}  // namespace raysweep::pipeline
