// SUMO vehicle type ids (the `type` of FCD vehicles) -> the vehicle class
// raysweep models and its dimensions, from the scenario's route and
// additional files.
#pragma once

#include <cstddef>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "meshkit/sumo_net.hpp"

namespace raysweep::pipeline {

struct ResolvedType {
  std::string vtype;   // the type id asked for
  std::string vclass;  // a class of meshkit::vehicle_classes()
  double length_m = 0, width_m = 0, height_m = 0;
  bool known = false;  // false: the id was neither in a file nor a SUMO built-in (passenger assumed)
};

// A route or additional file a sumocfg names.
struct SumocfgInput {
  std::string key;   // "route-files" or "additional-files"
  std::string path;  // resolved against the cfg's folder
  long line = 0;     // of the option element in the cfg
};

// The route and additional files of a SUMO configuration, in order (the
// <route-files>/<additional-files> options, also their SUMO synonyms <routes>
// and <additional>, wherever they are in the file; values separated by commas
// or spaces). Does not check that the files exist.
std::vector<SumocfgInput> sumocfg_inputs(const std::string& sumocfg_path);

class VTypeMap {
 public:
  // Every <vType> of a route/additional file (plain or gzip), members of
  // <vTypeDistribution>s included, by their own ids. A later definition of an
  // id with the same class and dimensions is accepted; a conflicting one throws
  // InputError naming both places.
  void add_file(const std::string& path);
  // add_file for each route and additional file of the configuration. A file
  // that does not exist throws InputError naming the cfg, the line and the key.
  void add_sumocfg(const std::string& sumocfg_path);

  // The vType's vClass (SUMO default "passenger") mapped to a library class,
  // with its length/width/height where given and the class defaults otherwise.
  // SUMO's road classes without a library entry of their own (hov, vip,
  // authority, army, custom1, custom2) map to passenger. SUMO's built-in ids
  // (DEFAULT_VEHTYPE, DEFAULT_BIKETYPE, DEFAULT_TAXITYPE, ...) resolve without a
  // file unless one redefines them. An unknown id resolves to passenger with
  // known = false (the caller warns once per type). std::nullopt for types
  // whose class raysweep does not model (pedestrian, rail, tram, ship, ...).
  std::optional<ResolvedType> resolve(const std::string& type_id) const;

  // Number of vType ids read from files.
  std::size_t size() const;

 private:
  struct Entry {
    meshkit::SumoVType type;
    std::string file;
  };
  std::map<std::string, Entry> types_;
};

// The vTypes of route/additional files and .sumocfg files (add_sumocfg for
// those, add_file for the others), in order.
VTypeMap read_vtype_files(const std::vector<std::string>& files);

}  // namespace raysweep::pipeline
