// Test helpers for calibration targets: antialiased ray-cast renders of printed chessboards,
// ChArUco boards and AprilGrids through a lens model, so the true corners are known exactly.
#pragma once

#include <Eigen/Geometry>
#include <vector>

#include "mixray/calibration/camera_model.h"
#include "mixray/calibration/target.h"
#include "mixray/graph/image.h"

namespace mixray::calibration::synth {

// A mono8 sRGB image of `target` (printed with a white margin of one square or tag, on a light
// grey table) seen from a camera at T_camera_board: `samples`² rays per pixel averaged in
// linear light; Gaussian noise of `noise` grey levels (fixed seed).
Image renderTarget(const CameraModel& camera, const CalibrationTarget& target,
                   const Eigen::Isometry3d& T_camera_board, int samples = 4, double noise = 1.0);

// Where every target point projects (point-id order); points behind the camera at (-1e9, -1e9).
std::vector<Eigen::Vector2d> projectPoints(const CameraModel& camera,
                                           const CalibrationTarget& target,
                                           const Eigen::Isometry3d& T_camera_board);

// The board's centre `distance_m` in front of the camera, its front towards the camera and
// upright, turned by `tilt_deg` about the board's x axis and `yaw_deg` about its y axis.
Eigen::Isometry3d boardPose(const CalibrationTarget& target, double distance_m, double tilt_deg,
                            double yaw_deg);

// The pinhole the synthetic tests use: 640x480, f = 600 px, mild OpenCV5 distortion.
CameraModel testCamera();

}  // namespace mixray::calibration::synth
