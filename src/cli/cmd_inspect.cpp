// scenecal inspect DATASET: what is in a dataset and whether it can be calibrated.
#include <chrono>
#include <cstdio>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "cli/commands.hpp"
#include "io/dataset.hpp"
#include "io/inspect.hpp"

namespace scenecal::cli {

CommandRunner AddInspectCommand(CLI::App& app) {
  struct Options {
    std::string dataset;
    bool quick = false;
  };
  auto options = std::make_shared<Options>();
  CLI::App* command = app.add_subcommand(
      "inspect",
      "Summarise a dataset (sensors, intrinsics, initial extrinsics, time spans, rates, travel, points per scan)\n"
      "and say whether it can be calibrated. Reads every image and scan, so every problem shows now.\n"
      "Exit 0: can be calibrated; 1: valid but cannot be calibrated (reason on stderr); 2: invalid data.");
  command->add_option("dataset", options->dataset, "Dataset folder (docs/FORMAT.md)")->required();
  command->add_flag("--quick", options->quick, "Do not decode images and scans (file sizes only)");
  return [options] {
    const io::Dataset dataset = io::OpenDataset(options->dataset);
    io::SummaryOptions summary_options;
    summary_options.read_contents = !options->quick;
    // Progress on stderr at most every 2 s, so short runs stay quiet.
    auto last_report = std::chrono::steady_clock::now();
    const auto progress = [&last_report](std::size_t done, std::size_t total) {
      const auto now = std::chrono::steady_clock::now();
      if (now - last_report < std::chrono::seconds(2)) return;
      spdlog::info("read {} of {} images and scans", done, total);
      last_report = now;
    };
    const io::DatasetSummary summary = io::SummariseDataset(dataset, summary_options, progress);
    fmt::print("{}", io::FormatDatasetSummary(dataset, summary));
    std::fflush(stdout);
    if (!summary.can_calibrate) {
      std::string reasons;
      for (const std::string& problem : summary.problems) reasons += (reasons.empty() ? "" : "; ") + problem;
      spdlog::error("{}: cannot be calibrated: {}", options->dataset, reasons);
      return kExitFailure;
    }
    return kExitSuccess;
  };
}

}  // namespace scenecal::cli
