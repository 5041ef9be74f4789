// scenecal: targetless lidar-camera calibration from a drive.
#include <csignal>
#include <exception>
#include <map>
#include <new>
#include <string>

#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include "cli/commands.hpp"
#include "cli/interrupt_handling.hpp"
#include "core/interrupt.hpp"
#include "io/error.hpp"

int main(int argc, char** argv) {
  using namespace scenecal::cli;
  InstallInterruptHandlers();  // before any thread starts (TBB, MPI)
  // Progress and diagnostics go to stderr; stdout carries results only.
  auto logger = spdlog::stderr_color_mt("scenecal");
  spdlog::set_default_logger(logger);
  spdlog::set_pattern("[%H:%M:%S.%e] %^%l%$ %v");

  CLI::App app{
      "scenecal: targetless extrinsic calibration of lidars against a multi-camera unit\n"
      "from data recorded while a vehicle drives through an ordinary street.\n"
      "Data formats: docs/FORMAT.md. Exit codes: 0 success, 2 invalid arguments or input data,\n"
      "1 any other failure, 130 / 143 interrupted by SIGINT / SIGTERM (no output written).",
      "scenecal"};
  app.require_subcommand(1);
  bool verbose = false;
  bool quiet = false;
  app.add_flag("-v,--verbose", verbose, "Log debug detail on stderr");
  app.add_flag("-q,--quiet", quiet, "Log warnings and errors only");
  app.set_version_flag("--version", "scenecal 0.1.0");

  std::map<const CLI::App*, CommandRunner> runners;
  const auto add = [&](CommandRunner runner) { runners[app.get_subcommands({}).back()] = std::move(runner); };
  add(AddSimulateCommand(app));
  add(AddInspectCommand(app));
  add(AddImportCommand(app));
  add(AddCalibrateCommand(app));
  add(AddExperimentCommand(app));
  add(AddProfileCommand(app));
  add(AddOdometryCommand(app));

  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    app.exit(e);
    return kExitInvalidInput;
  }
  spdlog::set_level(verbose ? spdlog::level::debug : quiet ? spdlog::level::warn : spdlog::level::info);

  try {
    for (const auto& [subcommand, runner] : runners) {
      if (subcommand->parsed()) return runner();
    }
    spdlog::error("no command given; see scenecal --help");
    return kExitInvalidInput;
  } catch (const scenecal::Interrupted&) {
    // The destructors on the way out removed the temporary files and staging folders.
    spdlog::error("interrupted by {}; no output written", InterruptSignalName());
    return InterruptExitCode();
  } catch (const scenecal::io::InputError& e) {
    spdlog::error("{}", e.what());
    return kExitInvalidInput;
  } catch (const std::bad_alloc&) {
    spdlog::error("out of memory");
    return kExitFailure;
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return kExitFailure;
  } catch (...) {
    spdlog::error("unknown failure");
    return kExitFailure;
  }
}
