// The calibration result file (FORMAT.md): io::ParseCalibrationResult. What it
// accepts must survive the writer: written again and read back, the same
// lidars, pairs and keys.
#include "core/calibration_result.hpp"
#include "fuzz_common.hpp"
#include "io/dataset.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace scenecal;
  return fuzz::RunParser(data, size, [](const std::string& text) {
    const CalibrationResult result = io::ParseCalibrationResult(text, "result.yaml");
    for (const LidarCalibration& lidar : result.lidars) {
      fuzz::Check(fuzz::IsFinite(lidar.T_base_lidar), "finite T_base_lidar");
      if (lidar.sigma) fuzz::Check(lidar.sigma->allFinite(), "finite sigma");
    }
    for (const PairCalibration& pair : result.pairs) fuzz::Check(fuzz::IsFinite(pair.T_camera_lidar), "finite pair");
    const std::string written = io::CalibrationResultToYaml(result);
    CalibrationResult again;
    try {
      again = io::ParseCalibrationResult(written, "result.yaml (written again)");
    } catch (const io::InputError& e) {
      std::fprintf(stderr, "%s\n--- written:\n%s\n", e.what(), written.c_str());
      fuzz::Violated("an accepted result, written again, does not read back");
    }
    fuzz::Check(again.lidars.size() == result.lidars.size() && again.pairs.size() == result.pairs.size(),
                "round trip keeps lidars and pairs");
    for (std::size_t i = 0; i < result.lidars.size(); ++i) {
      fuzz::Check(again.lidars[i].lidar == result.lidars[i].lidar, "round trip keeps lidar names");
    }
    for (std::size_t i = 0; i < result.pairs.size(); ++i) {
      fuzz::Check(again.pairs[i].camera == result.pairs[i].camera && again.pairs[i].lidar == result.pairs[i].lidar,
                  "round trip keeps pair names");
    }
    fuzz::Check(again.settings == result.settings && again.warnings == result.warnings &&
                    again.termination == result.termination && again.timings_s.size() == result.timings_s.size(),
                "round trip keeps settings, warnings, termination and timings");
  });
}
