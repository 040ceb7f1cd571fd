// Generated calibration views for the Ceres solver tests: a chessboard seen through a known
// lens model at random tilted poses, its corners projected exactly and then perturbed by
// Gaussian noise.
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "mixray/calibration/camera_model.h"
#include "mixray/calibration/target.h"

namespace mixray::calibration::test {

CalibrationTarget chessboard(int cols, int rows, double square_m);

// The fraction of the target's points that project inside the image.
double visibleFraction(const CameraModel& model, const CalibrationTarget& target,
                       const Eigen::Isometry3d& T_camera_target);

// A board pose in the camera frame: centred on a random pixel, spanning 40–70 % of the image
// width, tilted 20–50° and turned up to 30° in its plane, with ≥ 80 % of its points in view.
Eigen::Isometry3d randomBoardPose(const CameraModel& model, const CalibrationTarget& target,
                                  std::mt19937& rng);

// The corners that land in the image, each with N(0, noise_px²) added per coordinate.
TargetView observe(const CameraModel& model, const CalibrationTarget& target,
                   const Eigen::Isometry3d& T_camera_target, double noise_px, std::mt19937& rng,
                   int64_t key, const std::string& source);

// `count` views at randomBoardPose()s; their poses in `poses` when given.
CameraViews generateViews(const std::string& camera, const CameraModel& model,
                          const CalibrationTarget& target, int count, double noise_px,
                          std::mt19937& rng, std::vector<Eigen::Isometry3d>* poses = nullptr);

// Angle of the rotation between two poses, degrees.
double rotationErrorDeg(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b);

}  // namespace mixray::calibration::test
