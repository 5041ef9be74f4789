// KITTI calib_cam_to_cam.txt (R_rect_00, P_rect_00..03): io::ParseKittiCamToCam.
#include "fuzz_common.hpp"
#include "io/kitti.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace scenecal;
  return fuzz::RunParser(data, size, [](const std::string& text) {
    io::KittiCalibration calibration;
    io::ParseKittiCamToCam(text, "calib_cam_to_cam.txt", {0, 1, 2, 3}, &calibration);
    fuzz::Check(calibration.R_rect_00.allFinite(), "finite R_rect_00");
    for (const auto& projection : calibration.P_rect) {
      fuzz::Check(projection.has_value() && projection->allFinite(), "finite P_rect for every camera asked for");
      fuzz::Check((*projection)(0, 0) > 0 && (*projection)(1, 1) > 0, "positive focal lengths");
    }
  });
}
