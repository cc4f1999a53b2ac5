#include "pipeline/traffic_stage.hpp"

#include <fcntl.h>
#include <spdlog/spdlog.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "meshkit/errors.hpp"
#include "meshkit/vehicle_classes.hpp"
#include "pipeline/provenance.hpp"
#include "pipeline/staged_output.hpp"

namespace raysweep::pipeline {

namespace fs = std::filesystem;
using json = nlohmann::json;

std::string find_program(const std::string& name, const char* env_override) {
  if (env_override) {
    if (const char* v = std::getenv(env_override); v && *v) return ::access(v, X_OK) == 0 ? v : "";
  }
  const char* path = std::getenv("PATH");
  std::istringstream dirs(path ? path : "/usr/local/bin:/usr/bin:/bin");
  std::string dir;
  while (std::getline(dirs, dir, ':')) {
    const fs::path p = fs::path(dir.empty() ? "." : dir) / name;
    if (::access(p.c_str(), X_OK) == 0) return p.string();
  }
  return "";
}

void run_program(const std::vector<std::string>& argv, const std::string& log) {
  std::string shown;
  for (const auto& a : argv) shown += (shown.empty() ? "" : " ") + a;
  spdlog::info("running {}", shown);
  const int fd = ::open(log.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
  if (fd < 0) throw std::runtime_error(log + ": cannot open the log file");
  const pid_t pid = ::fork();
  if (pid < 0) {
    ::close(fd);
    throw std::runtime_error("cannot start " + argv[0]);
  }
  if (pid == 0) {
    ::dup2(fd, 1);
    ::dup2(fd, 2);
    std::vector<char*> args;
    for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
    args.push_back(nullptr);
    ::execv(args[0], args.data());
    ::_exit(127);
  }
  ::close(fd);
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    // The log may live in a folder that is removed on failure: quote its end.
    std::ifstream in(log);
    std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    if (text.size() > 2000) text = "..." + text.substr(text.size() - 2000);
    throw std::runtime_error("'" + shown + "' failed (exit " +
                             std::to_string(WIFEXITED(status) ? WEXITSTATUS(status) : -1) + "):\n" + text);
  }
}

namespace {

std::string num(double v) {
  std::ostringstream s;
  s.precision(10);
  s << v;
  return s.str();
}

// A vTypeDistribution "mix" with one vType per class, weighted.
std::string vtype_mix(const std::map<std::string, double>& classes) {
  std::string xml = "<additional>\n  <vTypeDistribution id=\"mix\">\n";
  for (const auto& [vclass, weight] : classes) {
    const auto* info = meshkit::find_vehicle_class(vclass);
    if (!info) throw std::invalid_argument("traffic: vehicle class '" + vclass + "' is not modelled by raysweep");
    if (!(weight > 0)) throw std::invalid_argument("traffic: weight of class '" + vclass + "' must be > 0");
    xml += "    <vType id=\"" + vclass + "\" vClass=\"" + vclass + "\" length=\"" + num(info->dims.length) +
           "\" width=\"" + num(info->dims.width) + "\" height=\"" + num(info->dims.height) + "\" probability=\"" +
           num(weight) + "\"/>\n";
  }
  return xml + "  </vTypeDistribution>\n</additional>\n";
}

}  // namespace

json run_traffic_stage(const TrafficArgs& args, const std::vector<std::string>& argv) {
  if (!fs::exists(args.net)) throw std::invalid_argument(args.net + ": SUMO network not found");
  if (!args.sumocfg.empty() && !fs::exists(args.sumocfg))
    throw std::invalid_argument(args.sumocfg + ": SUMO config not found");
  if (!(args.end_s > args.begin_s)) throw std::invalid_argument("traffic: end must be after begin");
  if (!(args.step_length_s > 0)) throw std::invalid_argument("traffic: step length must be > 0");
  if (args.sumocfg.empty() && !(args.period_s > 0)) throw std::invalid_argument("traffic: period must be > 0");

  const std::string sumo = find_program("sumo", "SUMO_BINARY");
  if (sumo.empty())
    throw std::runtime_error("the SUMO simulator (`sumo`) is not on PATH: install it with "
                             "`apt-get install sumo sumo-tools` (Debian 12) or set SUMO_BINARY to its path");
  const char* home_env = std::getenv("SUMO_HOME");
  const fs::path sumo_home = home_env && *home_env ? fs::path(home_env) : fs::path("/usr/share/sumo");
  // randomTrips.py and SUMO's XML validation need it (Debian's package puts it here).
  ::setenv("SUMO_HOME", sumo_home.c_str(), 0);

  StagedDirectory staged(args.out);
  const fs::path dir = staged.path();
  const std::string log = (dir / "sumo.log").string();
  json commands = json::array();
  std::vector<InputFile> inputs{{"net", args.net}};
  std::vector<std::string> vtype_files;

  std::vector<std::string> cmd;
  if (!args.sumocfg.empty()) {
    inputs.push_back({"sumocfg", args.sumocfg});
    vtype_files.push_back(fs::absolute(args.sumocfg).string());
    // --route-steps 0 loads the routes at once: configs in the wild (the
    // VaN3Twin ring road) have route files not sorted by departure, whose
    // late-listed vehicles SUMO would otherwise drop.
    cmd = {sumo, "-c", fs::absolute(args.sumocfg).string(), "-n", fs::absolute(args.net).string(), "--route-steps", "0"};
  } else {
    const fs::path random_trips = sumo_home / "tools" / "randomTrips.py";
    const std::string python = ::access("/usr/bin/python3", X_OK) == 0 ? "/usr/bin/python3" : find_program("python3");
    if (!fs::exists(random_trips) || python.empty())
      throw std::runtime_error(random_trips.string() + " (or python3) not found: install SUMO's tools with "
                               "`apt-get install sumo-tools` or set SUMO_HOME");
    {
      std::ofstream(dir / "vtypes.add.xml") << vtype_mix(args.classes);
    }
    vtype_files.push_back("vtypes.add.xml");
    const std::vector<std::string> trips = {python, random_trips.string(), "-n", fs::absolute(args.net).string(),
                                            "-o", (dir / "trips.rou.xml").string(), "--seed", std::to_string(args.seed),
                                            "-b", num(args.begin_s), "-e", num(args.end_s),
                                            "-p", num(args.period_s), "--fringe-factor", num(args.fringe_factor),
                                            "--trip-attributes", "type=\"mix\"",
                                            "--additional-file", (dir / "vtypes.add.xml").string()};
    run_program(trips, log);
    commands.push_back(trips);
    cmd = {sumo, "-n", fs::absolute(args.net).string(), "-a", (dir / "vtypes.add.xml").string(), "-r",
           (dir / "trips.rou.xml").string(), "--ignore-route-errors"};
  }
  for (const auto& a : std::vector<std::string>{"--begin", num(args.begin_s), "--end", num(args.end_s),
                                                "--step-length", num(args.step_length_s), "--seed",
                                                std::to_string(args.seed), "--fcd-output",
                                                (dir / "fcd.xml.gz").string(), "--no-step-log", "true"})
    cmd.push_back(a);
  run_program(cmd, log);
  commands.push_back(cmd);
  if (!fs::exists(dir / "fcd.xml.gz")) throw std::runtime_error("sumo wrote no FCD; see " + log);

  TrafficSettings effective;  // `raysweep traffic` has the [traffic] table's settings, from its options
  effective.sumo = args;
  const json config = effective.to_json();
  json record;
  record["fcd"] = "fcd.xml.gz";
  record["vtype_files"] = vtype_files;
  record["begin_s"] = args.begin_s;
  record["end_s"] = args.end_s;
  record["commands"] = commands;
  record["provenance"] = provenance("traffic", inputs, config, argv);
  record["fcd_bytes"] = fs::file_size(dir / "fcd.xml.gz");
  write_file_atomic(dir / "traffic.json", record.dump(1) + "\n");
  staged.commit();
  spdlog::info("traffic: {} ({} bytes of FCD, {:.1f}..{:.1f} s at {} s steps)", args.out,
               record["fcd_bytes"].get<std::uint64_t>(), args.begin_s, args.end_s, args.step_length_s);
  return record;
}

}  // namespace raysweep::pipeline
