#include "core/rig.hpp"

#include <algorithm>

#include "core/enum_names.hpp"

namespace scenecal {

namespace {
inline constexpr auto kTrajectorySourceNames = MakeEnumNames<TrajectorySource>({
    {TrajectorySource::kExact, "exact"},
    {TrajectorySource::kIns, "ins"},
    {TrajectorySource::kLidarOdometry, "lidar-odometry"},
    {TrajectorySource::kVisualOdometry, "visual-odometry"},
    {TrajectorySource::kUnknown, "unknown"},
});
}  // namespace

const char* TrajectorySourceName(TrajectorySource source) { return EnumName(kTrajectorySourceNames, source); }

bool ParseTrajectorySource(const std::string& name, TrajectorySource* source) {
  return ParseEnumName(kTrajectorySourceNames, name, source);
}

std::string TrajectorySourceChoices() { return EnumNameList(kTrajectorySourceNames); }

const CameraInfo* Rig::FindCamera(const std::string& name) const {
  const auto it = std::find_if(cameras.begin(), cameras.end(), [&](const CameraInfo& c) { return c.name == name; });
  return it == cameras.end() ? nullptr : &*it;
}

const LidarInfo* Rig::FindLidar(const std::string& name) const {
  const auto it = std::find_if(lidars.begin(), lidars.end(), [&](const LidarInfo& l) { return l.name == name; });
  return it == lidars.end() ? nullptr : &*it;
}

bool Rig::HasPushBroomLidar() const {
  return std::any_of(lidars.begin(), lidars.end(), [](const LidarInfo& l) { return l.kind == LidarKind::k2d; });
}

}  // namespace scenecal
