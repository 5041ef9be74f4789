// rig.yaml (FORMAT.md): io::ParseRig.
#include "core/rig.hpp"
#include "fuzz_common.hpp"
#include "io/dataset.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace scenecal;
  return fuzz::RunParser(data, size, [](const std::string& text) {
    const Rig rig = io::ParseRig(text, "rig.yaml");
    fuzz::Check(!rig.cameras.empty() && rig.cameras.size() <= io::kMaxRigCameras, "camera count");
    fuzz::Check(!rig.lidars.empty() && rig.lidars.size() <= io::kMaxRigLidars, "lidar count");
    fuzz::Check(rig.FindCamera(rig.base_frame) != nullptr, "base_frame names a camera");
    for (const CameraInfo& camera : rig.cameras) {
      const CameraModel& model = camera.model;
      fuzz::Check(model.IsValid(), "accepted camera is valid");
      fuzz::Check(std::isfinite(model.fx) && std::isfinite(model.fy) && std::isfinite(model.cx) && std::isfinite(model.cy),
                  "finite intrinsics");
      for (const double k : model.distortion) fuzz::Check(std::isfinite(k), "finite distortion");
      fuzz::Check(fuzz::IsFinite(camera.T_base_camera), "finite T_base_camera");
      if (camera.T_base_camera_sigma) fuzz::Check(camera.T_base_camera_sigma->allFinite(), "finite sigma");
    }
    for (const LidarInfo& lidar : rig.lidars) fuzz::Check(fuzz::IsFinite(lidar.T_base_lidar), "finite T_base_lidar");
  });
}
