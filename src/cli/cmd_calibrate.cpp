// PLACEHOLDER: replaced by the real command.
#include <spdlog/spdlog.h>

#include "cli/commands.hpp"

namespace scenecal::cli {

CommandRunner AddCalibrateCommand(CLI::App& app) {
  app.add_subcommand("calibrate", "(not built yet)");
  return [] {
    spdlog::error("'calibrate' is not built yet");
    return kExitFailure;
  };
}

}  // namespace scenecal::cli
