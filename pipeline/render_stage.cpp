#include "pipeline/render_stage.hpp"

#include <spdlog/spdlog.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <sstream>

#include "meshkit/gltf_io.hpp"
#include "meshkit/vehicle_model.hpp"
#include "pipeline/preview.hpp"
#include "pipeline/staged_output.hpp"
#include "pipeline/trace_inputs.hpp"

namespace raysweep::pipeline {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

std::string quote(const std::string& s) {
  std::string out = "'";
  for (char c : s) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}

// The vehicles at their poses as one glTF scene (library frame moved to each
// pose: yaw about z, then the front-bumper point).
void write_vehicles_glb(const RenderArgs& args, const std::string& path) {
  VehicleLibrary library(args.vehicles);
  meshkit::Scene out;
  for (const auto& p : read_poses_csv(args.poses)) {
    const meshkit::Scene model = meshkit::to_scene(library.model(p.vclass));
    const double yaw = yaw_from_heading(p.heading_deg), c = std::cos(yaw), s = std::sin(yaw);
    const auto object = out.add_object("vehicle", "vehicle/" + p.id);
    for (const auto& m : model.meshes) {
      meshkit::Mesh moved = m;
      for (auto& v : moved.vertices)
        v = {p.x + c * v[0] - s * v[1], p.y + s * v[0] + c * v[1], p.z + v[2]};
      for (auto& o : moved.triangle_object) o = object;
      out.mesh_for(m.material, "vehicles").append(moved);
    }
  }
  meshkit::write_glb(out, path);
}

}  // namespace

std::string find_blender() {
  if (const char* env = std::getenv("RAYSWEEP_BLENDER")) return ::access(env, X_OK) == 0 ? env : "";
  const char* path = std::getenv("PATH");
  std::stringstream ss(path ? path : "/usr/bin");
  for (std::string dir; std::getline(ss, dir, ':');) {
    const fs::path p = fs::path(dir) / "blender";
    if (::access(p.c_str(), X_OK) == 0) return p.string();
  }
  return {};
}

json run_render_stage(const RenderArgs& args, const std::vector<std::string>& /*argv*/) {
  const auto t0 = std::chrono::steady_clock::now();
  if (fs::path(args.out).extension() != ".png") throw std::invalid_argument(args.out + ": output must end in .png");
  const fs::path scene_file = fs::path(args.scene) / "scene.glb";
  if (!fs::exists(scene_file)) throw std::invalid_argument(args.scene + ": no scene.glb (run `raysweep scene` first)");
  for (const auto& [what, file] : {std::pair<std::string, std::string>{"--poses", args.poses},
                                   {"--paths", args.paths}, {"--radiomap", args.radiomap}})
    if (!file.empty() && !fs::exists(file)) throw std::invalid_argument(what + " " + file + ": no such file");
  if (!args.vehicles.empty() && !fs::is_directory(args.vehicles))
    throw std::invalid_argument("--vehicles " + args.vehicles + ": no such folder");
  int w = 0, h = 0;
  {
    char comma = 0, tail = 0;
    std::istringstream in(args.size);
    if (!(in >> w >> comma >> h) || comma != ',' || (in >> tail) || w < 16 || h < 16 || w > 8192 || h > 8192)
      throw std::invalid_argument("--size '" + args.size + "': expected W,H in pixels (16-8192)");
  }
  if (args.camera != "top" && args.camera != "oblique") {
    double v[6];
    if (std::sscanf(args.camera.c_str(), "%lf,%lf,%lf:%lf,%lf,%lf", &v[0], &v[1], &v[2], &v[3], &v[4], &v[5]) != 6)
      throw std::invalid_argument("--camera '" + args.camera + "': expected top, oblique or X,Y,Z:TX,TY,TZ");
  }
  if (args.samples < 1) throw std::invalid_argument("--samples must be >= 1");
  const std::string blender = find_blender();
  if (blender.empty())
    throw std::invalid_argument(
        "render needs Blender, which is not installed: apt-get install --no-install-recommends blender "
        "(Debian 12; or set RAYSWEEP_BLENDER to its binary). Nothing else in raysweep needs it.");

  const fs::path out(args.out);
  if (!out.parent_path().empty()) fs::create_directories(out.parent_path());
  const fs::path work = out.parent_path() / (out.stem().string() + ".render-tmp");
  fs::remove_all(work);
  fs::create_directories(work);
  // Blender renders into the scratch folder, which a failed render leaves behind with its blender.log.
  StagedFile staged(out, work / "render.png");
  std::vector<std::string> py{"--scene", scene_file.string(), "--out", staged.path().string(), "--camera",
                              args.camera, "--size", args.size, "--samples", std::to_string(args.samples),
                              "--max-pairs", std::to_string(args.max_pairs)};
  if (!args.poses.empty()) {
    write_vehicles_glb(args, (work / "vehicles.glb").string());
    py.insert(py.end(), {"--vehicles", (work / "vehicles.glb").string()});
  }
  if (!args.paths.empty()) py.insert(py.end(), {"--paths", args.paths});
  if (!args.radiomap.empty()) {
    // The slice as a texture (Debian's python3-openvdb reads the file; Blender's Python has no OpenVDB module).
    const fs::path tex = work / "slice.png";
    if (!run_python_script("radiomap_slice.py", {args.radiomap, args.scene, tex.string(), "--texture"}))
      throw std::runtime_error(args.radiomap + ": could not draw its slice (python3-openvdb and matplotlib needed)");
    py.insert(py.end(), {"--slice", tex.string(), "--slice-meta", tex.string() + ".json"});
  }
  std::string cmd = quote(blender) + " -b --factory-startup --python " +
                    quote((fs::path(RAYSWEEP_DEFAULT_PYTHON_DIR) / "render_blender.py").string());
  if (const char* env = std::getenv("RAYSWEEP_PYTHON_DIR"))
    cmd = quote(blender) + " -b --factory-startup --python " + quote((fs::path(env) / "render_blender.py").string());
  cmd += " --";
  for (const auto& a : py) cmd += " " + quote(a);
  cmd += " > " + quote((work / "blender.log").string()) + " 2>&1";
  spdlog::info("render: blender ({}x{}, {} samples, camera {})", w, h, args.samples, args.camera);
  const int rc = std::system(cmd.c_str());
  if (rc != 0 || !fs::exists(staged.path())) {
    std::string tail;
    if (FILE* f = std::fopen((work / "blender.log").c_str(), "r")) {
      char buf[4096];
      std::size_t n;
      while ((n = std::fread(buf, 1, sizeof buf, f)) > 0) tail.append(buf, n);
      std::fclose(f);
      if (tail.size() > 2000) tail = tail.substr(tail.size() - 2000);
    }
    throw std::runtime_error("render: blender failed (status " + std::to_string(rc) + "):\n" + tail);
  }
  staged.commit();
  fs::remove_all(work);
  const double sec = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  spdlog::info("render: {} in {:.1f} s", out.string(), sec);
  return {{"out", out.string()}, {"seconds", sec}};
}

}  // namespace raysweep::pipeline
