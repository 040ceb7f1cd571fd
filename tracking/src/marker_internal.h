// Internals shared by the marker detector, the target fits and the tracker: image conversion,
// detection with an optional lens model for the edge fit, and pose refinement.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <opencv2/aruco/dictionary.hpp>
#include <opencv2/core.hpp>
#include <optional>
#include <string_view>
#include <vector>

#include "mixray/calibration/camera_model.h"
#include "mixray/graph/image.h"
#include "mixray/graph/result.h"
#include "mixray/tracking/markers.h"

namespace mixray::tracking::detail {

// docs/conventions.md puts pixel (0,0) at the centre of the top-left pixel. Measured on
// antialiased synthetic markers (tests/tracking/marker_detect_test.cpp): OpenCV's aruco corners
// already follow it (mean offset < 0.05 px), libapriltag's are 0.5 px larger in x and y (it
// puts (0,0) at the top-left pixel's corner), and interpolateCornersCharuco's ChArUco corners
// are 0.5 px larger too.
constexpr double kOpenCvArucoOffsetPx = 0.0;
constexpr double kAprilTagOffsetPx = 0.5;
constexpr double kCharucoOffsetPx = 0.5;

// OpenCV's predefined dictionary of that name ("DICT_6X6_250"); nullopt for others.
std::optional<cv::aruco::PREDEFINED_DICTIONARY_NAME> arucoDictionaryId(std::string_view name);

// An 8-bit grey copy of a kMono8, kRGB8 or kBGR8 image; kInvalidArgument for anything else.
Result<cv::Mat> toGrey(const ImageView& image);

// detectMarkers() on a grey image. With `camera`, the refinement fits the marker's edges as
// straight lines in undistorted coordinates (straight in the world, curved in the image).
Result<std::vector<MarkerDetection>> detectGrey(const cv::Mat& grey, std::string_view dictionary,
                                                const DetectorOptions& options,
                                                const calibration::CameraModel* camera);

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
// interpolated from `grey`).
struct Correspondences {
    std::vector<Eigen::Vector3d> points;  // target frame
    std::vector<Eigen::Vector2d> pixels;
};
Correspondences correspond(const MarkerTarget& target,
                           const std::vector<MarkerDetection>& detections, const cv::Mat& grey);

}  // namespace mixray::tracking::detail
