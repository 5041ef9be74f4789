// scenecal import FORMAT SOURCE --output DATASET: converts other data layouts
// into a native dataset (FORMAT.md).
#include <spdlog/spdlog.h>

#include "cli/commands.hpp"
#include "io/opencalib.hpp"

namespace scenecal::cli {

CommandRunner AddImportCommand(CLI::App& app) {
  struct Options {
    std::string format;
    std::string source;
    std::string output;
    bool force = false;
  };
  auto options = std::make_shared<Options>();
  CLI::App* command = app.add_subcommand(
      "import",
      "Convert data from another layout into a native dataset.\n"
      "  opencalib: a folder with calib.txt (K, D, T = T_camera_lidar), calib.pcd and calib.jpg|calib.png\n"
      "  (OpenCalib lidar2camera) -> a static dataset with one camera, one 3d lidar and the reference T\n"
      "  as the initial guess and as ground_truth.yaml.");
  command->add_option("format", options->format, "Source layout")->required()->check(CLI::IsMember({"opencalib"}));
  command->add_option("source", options->source, "Source folder")->required();
  command->add_option("-o,--output", options->output, "Dataset folder to create")->required();
  command->add_flag("--force", options->force, "Replace a non-empty output folder");
  return [options] {
    const io::OpenCalibImportSummary summary = io::ImportOpenCalib(options->source, options->output, options->force);
    spdlog::info("imported {} -> {}: image {}x{}, {} lidar points ({} no-returns)", options->source,
                 summary.dataset.string(), summary.image_width, summary.image_height, summary.points,
                 summary.no_returns);
    return kExitSuccess;
  };
}

}  // namespace scenecal::cli
