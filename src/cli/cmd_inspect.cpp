// PLACEHOLDER: replaced by the real command.
#include <spdlog/spdlog.h>

#include "cli/commands.hpp"

namespace scenecal::cli {

CommandRunner AddInspectCommand(CLI::App& app) {
  app.add_subcommand("inspect", "(not built yet)");
  return [] {
    spdlog::error("'inspect' is not built yet");
    return kExitFailure;
  };
}

}  // namespace scenecal::cli
