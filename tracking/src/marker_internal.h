// Internals shared by the target fits and the tracker: correspondences of targets and
// detections, and pose refinement.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <optional>
#include <string_view>
#include <vector>

#include "mixray/calibration/camera_model.h"
#include "mixray/graph/image.h"
#include "mixray/graph/result.h"
#include "mixray/tracking/markers.h"

namespace mixray::tracking::detail {

// Reprojection fit of a pose T_camera_points (points in their frame -> camera frame) by
// Levenberg–Marquardt through the lens model. Returns nullopt when a point falls behind the
// camera at the start.
struct PoseFit {
    Eigen::Isometry3d T_camera_points = Eigen::Isometry3d::Identity();
    double rms_px = 0;
};
std::optional<PoseFit> refinePose(const calibration::CameraModel& camera,
                                  const std::vector<Eigen::Vector3d>& points,
                                  const std::vector<Eigen::Vector2d>& pixels,
                                  const Eigen::Isometry3d& T_init);

// Planar target pose from scratch: IPPE (square for one marker: `square` true and the points
// in MarkerTarget::points() order), both IPPE solutions refined, the better kept.
std::optional<PoseFit> planarPose(const calibration::CameraModel& camera,
                                  const std::vector<Eigen::Vector3d>& points,
                                  const std::vector<Eigen::Vector2d>& pixels, bool square);

// The 2D-3D correspondences of one target in one image's detections (ChArUco corners are
// interpolated from `image`, the 8-bit image the detections came from).
struct Correspondences {
    std::vector<Eigen::Vector3d> points;  // target frame
    std::vector<Eigen::Vector2d> pixels;
};
Correspondences correspond(const MarkerTarget& target,
                           const std::vector<MarkerDetection>& detections, const ImageView& image);

}  // namespace mixray::tracking::detail
