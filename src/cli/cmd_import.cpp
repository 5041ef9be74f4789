// PLACEHOLDER: replaced by the real command.
#include <spdlog/spdlog.h>

#include "cli/commands.hpp"

namespace scenecal::cli {

CommandRunner AddImportCommand(CLI::App& app) {
  app.add_subcommand("import", "(not built yet)");
  return [] {
    spdlog::error("'import' is not built yet");
    return kExitFailure;
  };
}

}  // namespace scenecal::cli
