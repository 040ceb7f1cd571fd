// The fish-eye environment camera's pose in the world (marker) frame, from simultaneous views
// of a board by the main camera and the environment camera, and the marker seen by the main
// camera: Kán & Kaufmann's light estimation needs the environment image aligned to the marker.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <vector>

#include "mixray/calibration/camera_model.h"
#include "mixray/calibration/target.h"
#include "mixray/graph/result.h"

namespace mixray::calibration {

// The world marker as the main camera saw it at one key: its four corners in ArUco's order
// (the printed marker's top-left, top-right, bottom-right, bottom-left), docs/conventions.md
// pixels. In the marker (world) frame they lie at (∓s/2, ±s/2, 0): (−s/2, s/2), (s/2, s/2),
// (s/2, −s/2), (−s/2, −s/2), s the marker's side.
struct MarkerView {
    int64_t key = 0;
    std::array<Eigen::Vector2d, 4> corners;
};

// The main camera's pose in the world at one key, known from elsewhere (the marker tracker, a
// recording's pose stream): used, held fixed, at keys where the main camera does not see the
// marker (a board held over the environment camera often hides it or leaves the view).
struct KnownMainPose {
    int64_t key = 0;
    Eigen::Isometry3d T_world_main = Eigen::Isometry3d::Identity();
};

struct EnvironmentAlignmentOptions {
    double marker_size_m = 0.1;  // the marker's side (its black square)
    // Keys where the environment camera and the main camera both see the board and the main
    // camera's pose is known (it sees the marker, or main_poses has it); fewer:
    // kInvalidArgument.
    int min_views = 2;
    int min_corners = 6;  // board corners a view needs to take part
    // Corners whose residual exceeds this many times the RMS of all residuals are dropped and
    // the solve repeated (mislabelled or badly interpolated corners), until none are.
    double outlier_sigma = 3.0;
    // Main-camera poses for keys without a marker view (see KnownMainPose); empty: none.
    std::vector<KnownMainPose> main_poses;
};

struct EnvironmentAlignment {
    Eigen::Isometry3d T_world_env = Eigen::Isometry3d::Identity();  // = T_marker_env
    // Covariance of T_world_env as [rotation vector (rad), translation (m)], σ² (JᵀJ)⁻¹ with
    // σ the observed residual noise.
    Eigen::Matrix<double, 6, 6> covariance = Eigen::Matrix<double, 6, 6>::Zero();
    double rms_px = 0;  // all corners but the outliers
    int outliers = 0;
    double env_rms_px = 0, main_rms_px = 0, marker_rms_px = 0;
    std::vector<int64_t> keys;     // the keys used
    int keys_with_known_pose = 0;  // of them, linked through options.main_poses
    // The per-key seeds' spread about the seed (largest angle, degrees): how far the views
    // agreed before the joint solve.
    double seed_spread_deg = 0;
};

// Joint solve (Ceres, the shared reprojection cost) of T_env_world, and per key T_main_world
// and T_world_board: the environment camera sees the board through T_env_world ·
// T_world_board(key), the main camera sees it through T_main_world(key) · T_world_board(key)
// and the marker through T_main_world(key) (at keys without a marker view but with a known
// pose, T_main_world(key) is that pose, fixed). Intrinsics are fixed. Seeded per key by PnP
// (the board in both cameras, the marker in the main camera) and averaged. kInvalidArgument naming
// the cause: too few keys seen by all three, invalid models, views of another target or image
// size than the models, a pose the views do not determine; kInternal when Ceres does not
// converge.
Result<EnvironmentAlignment> alignEnvironmentCamera(
    const CameraModel& main, const CameraModel& env, const CameraViews& main_board,
    const CameraViews& env_board, const std::vector<MarkerView>& marker,
    const EnvironmentAlignmentOptions& options = {});

}  // namespace mixray::calibration
