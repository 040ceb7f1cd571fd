// alignEnvironmentCamera()'s stages, given the board's points (CalibrationTarget::points()):
// the per-key seeding and the joint solve, for tests that bring their own board geometry.
#pragma once

#include <vector>

#include "mixray/calibration/environment_alignment.h"

namespace mixray::calibration::detail {

// One key seen by all three: the seeds of its poses.
struct AlignmentKey {
    int64_t key = 0;
    const TargetView* main_view = nullptr;
    const TargetView* env_view = nullptr;
    const MarkerView* marker = nullptr;  // null: the pose is known (options.main_poses)
    Eigen::Isometry3d T_main_world = Eigen::Isometry3d::Identity();  // = T_main_marker
    Eigen::Isometry3d T_world_board = Eigen::Isometry3d::Identity();
    Eigen::Isometry3d T_env_world = Eigen::Isometry3d::Identity();  // this key's own
};

struct AlignmentSeed {
    std::vector<AlignmentKey> keys;
    Eigen::Isometry3d T_env_world = Eigen::Isometry3d::Identity();  // the keys' average
    double spread_deg = 0;
};

// A camera's pose relative to planar points by PnP on the unprojected corners (any lens
// model; corners more than ~78° off the axis are left out). nullopt with fewer than 4 usable.
std::optional<Eigen::Isometry3d> poseFromCorners(const CameraModel& camera,
                                                 const std::vector<Eigen::Vector3d>& points,
                                                 const std::vector<Eigen::Vector2d>& pixels,
                                                 bool square_marker);

Result<AlignmentSeed> seedEnvironmentAlignment(const CameraModel& main, const CameraModel& env,
                                               const std::vector<Eigen::Vector3d>& board_points,
                                               const CameraViews& main_board,
                                               const CameraViews& env_board,
                                               const std::vector<MarkerView>& marker,
                                               const EnvironmentAlignmentOptions& options);

Result<EnvironmentAlignment> alignEnvironmentCamera(
    const CameraModel& main, const CameraModel& env,
    const std::vector<Eigen::Vector3d>& board_points, const CameraViews& main_board,
    const CameraViews& env_board, const std::vector<MarkerView>& marker,
    const EnvironmentAlignmentOptions& options);

}  // namespace mixray::calibration::detail
