// Test support: a simulated dataset made once and shared by the processes of one test executable.
//
// gtest_discover_tests runs every test in a process of its own, so a suite's SetUpTestSuite runs
// once per test: without sharing, a suite of 26 tests simulates the same drive 26 times (seconds
// each, ten times that under AddressSanitizer). The first process to need a dataset simulates it
// into a private folder and renames that into place (atomic: a folder that exists is complete);
// the others read it. Tests must not change the shared folder (write their outputs elsewhere, copy
// it to edit it).
#pragma once

#include <unistd.h>

#include <filesystem>
#include <string>
#include <system_error>

namespace scenecal::test {

// The folder `<cache>/<executable>-<its modification time>/<name>`, made by `simulate(folder)` on
// first use. The executable's time keys it: a change to the simulator relinks every test that
// calls it, so a rebuilt executable never reads an older build's data. Entries of this executable's
// older builds are removed when a new one is made.
template <typename SimulateInto>
std::filesystem::path SharedSimulation(const std::string& name, SimulateInto&& simulate) {
  namespace fs = std::filesystem;
  const fs::path executable = fs::read_symlink("/proc/self/exe");
  const std::string prefix = executable.filename().string() + "-";
  const std::string stamp = std::to_string(fs::last_write_time(executable).time_since_epoch().count());
  const fs::path cache = SCENECAL_TEST_CACHE_DIR;
  const fs::path root = cache / (prefix + stamp);
  const fs::path folder = root / name;
  if (fs::is_directory(folder)) return folder;

  fs::create_directories(root);
  std::error_code ignored;
  for (const fs::directory_entry& entry : fs::directory_iterator(cache)) {
    const std::string entry_name = entry.path().filename().string();
    if (entry.path() != root && entry_name.rfind(prefix, 0) == 0) fs::remove_all(entry.path(), ignored);
  }
  const fs::path scratch = root / (name + ".partial-" + std::to_string(::getpid()));
  fs::remove_all(scratch);
  simulate(scratch);
  fs::rename(scratch, folder, ignored);  // fails when another process renamed its copy first
  fs::remove_all(scratch, ignored);
  if (!fs::is_directory(folder)) throw fs::filesystem_error("shared simulation not in place", folder, ignored);
  return folder;
}

}  // namespace scenecal::test
