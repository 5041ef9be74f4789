// Sub-commands of the scenecal CLI. Each Add*Command registers its options on
// a sub-command of `app` and returns the function that runs it (exit code).
#pragma once

#include <functional>

#include <CLI/CLI.hpp>

namespace scenecal::cli {

// Exit codes of every command.
constexpr int kExitSuccess = 0;
constexpr int kExitFailure = 1;       // any other failure (e.g. data that cannot be calibrated)
constexpr int kExitInvalidInput = 2;  // invalid arguments or input data

using CommandRunner = std::function<int()>;

CommandRunner AddSimulateCommand(CLI::App& app);
CommandRunner AddInspectCommand(CLI::App& app);
CommandRunner AddImportCommand(CLI::App& app);
CommandRunner AddCalibrateCommand(CLI::App& app);
CommandRunner AddExperimentCommand(CLI::App& app);
CommandRunner AddProfileCommand(CLI::App& app);
CommandRunner AddOdometryCommand(CLI::App& app);

}  // namespace scenecal::cli
