// PLACEHOLDER: replaced by the real command.
#include <spdlog/spdlog.h>

#include "cli/commands.hpp"

namespace scenecal::cli {

CommandRunner AddSimulateCommand(CLI::App& app) {
  app.add_subcommand("simulate", "(not built yet)");
  return [] {
    spdlog::error("'simulate' is not built yet");
    return kExitFailure;
  };
}

}  // namespace scenecal::cli
