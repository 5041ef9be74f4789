#include "cli/odometry_plugin.hpp"

#include <dlfcn.h>

#include <filesystem>
#include <mutex>
#include <stdexcept>
#include <string>

namespace scenecal::cli {

odometry::RunLidarOdometryFn LoadOdometryPlugin() {
  static std::once_flag once;
  static odometry::RunLidarOdometryFn run = nullptr;
  static std::string failure;
  std::call_once(once, [] {
    std::error_code error;
    const std::filesystem::path executable = std::filesystem::read_symlink("/proc/self/exe", error);
    const std::filesystem::path file = executable.parent_path() / odometry::kPluginFileName;
    // Kept loaded for the process's life (never dlclose'd: its code may still be on the stack of a caller).
    void* handle = dlopen(file.c_str(), RTLD_NOW | RTLD_LOCAL);
    if (handle == nullptr) {
      failure = "cannot load the lidar odometry plugin " + file.string() + " (" + dlerror() +
                "); it is built beside the scenecal executable";
      return;
    }
    const auto entry = reinterpret_cast<odometry::PluginEntryFn>(dlsym(handle, odometry::kPluginEntryPoint));
    if (entry == nullptr) {
      failure = file.string() + " has no " + odometry::kPluginEntryPoint + ": not scenecal's odometry plugin";
      return;
    }
    run = entry();
  });
  if (run == nullptr) throw std::runtime_error(failure);
  return run;
}

}  // namespace scenecal::cli
