// KITTI calib_velo_to_cam.txt and calib_imu_to_velo.txt (R, T):
// io::ParseKittiRigidTransform.
#include "fuzz_common.hpp"
#include "io/kitti.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace scenecal;
  return fuzz::RunParser(data, size, [](const std::string& text) {
    const Eigen::Isometry3d transform = io::ParseKittiRigidTransform(text, "calib_velo_to_cam.txt", "velodyne to camera 0");
    fuzz::Check(fuzz::IsFinite(transform), "finite transform");
    const Eigen::Matrix3d rotation = transform.linear();
    fuzz::Check((rotation * rotation.transpose() - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() < 1e-9,
                "orthonormal rotation");
  });
}
