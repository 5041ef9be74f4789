// OpenCalib's calib.txt (K, D, T): io::ParseOpenCalibCalibration.
#include "fuzz_common.hpp"
#include "io/opencalib.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace scenecal;
  return fuzz::RunParser(data, size, [](const std::string& text) {
    const io::OpenCalibCalibration calibration = io::ParseOpenCalibCalibration(text, "calib.txt");
    fuzz::Check(std::isfinite(calibration.fx) && std::isfinite(calibration.fy) && std::isfinite(calibration.cx) &&
                    std::isfinite(calibration.cy),
                "finite K");
    fuzz::Check(calibration.distortion.size() == 4 || calibration.distortion.size() == 5, "4 or 5 distortion terms");
    for (const double k : calibration.distortion) fuzz::Check(std::isfinite(k), "finite D");
    fuzz::Check(fuzz::IsFinite(calibration.T_camera_lidar), "finite T");
    const Eigen::Matrix3d rotation = calibration.T_camera_lidar.linear();
    fuzz::Check((rotation * rotation.transpose() - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() < 1e-9,
                "T's rotation orthonormal");
  });
}
