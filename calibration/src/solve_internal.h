// Between calibrateCamera()'s front end (input checks, seeding, outlier loop: calibrate.cpp) and
// its two back ends (Ceres: ceres_solver.cpp, mrcal: mrcal_solver.cpp).
#pragma once

#include <Eigen/Geometry>
#include <optional>
#include <utility>
#include <vector>

#include "mixray/calibration/calibrate.h"

namespace mixray::calibration::detail {

// What a solve that does not converge returns (calibrate.h).
constexpr ErrorCode kNotConverged = ErrorCode::kInternal;

// One camera's problem, checked and seeded.
struct SolveInput {
    const CameraViews* views = nullptr;
    std::vector<size_t> used;               // indices of the views to solve with
    std::vector<std::vector<bool>> inlier;  // per used view, per corner: still in the solve
    CameraModel seed;                       // the model to fit, its parameters seeded
    std::vector<Eigen::Isometry3d> T_camera_target;  // per used view, seeded
};

// Each back end minimises the weighted reprojection error over the inliers and fills every
// field of CameraCalibration (residuals for all corners of the used views, the covariance in
// calibrate.h's layout). kNotConverged when it does not converge.
Result<CameraCalibration> solveWithCeres(const SolveInput& input,
                                         const CalibrationOptions& options);
Result<CameraCalibration> solveWithMrcal(const SolveInput& input,
                                         const CalibrationOptions& options);

// What both back ends report after their solve: out.views, out.residuals, out.outliers and
// out.rms_px for every corner of the used views, projected through out.model at
// T_camera_target (per used view); `points` are the target's points by corner id. The RMS
// values are over the inliers that project. Returns the first inlier that does not project,
// as (index into input.used, index into that view's corners), or nullopt.
std::optional<std::pair<size_t, size_t>> fillResiduals(
    const SolveInput& input, const std::vector<Eigen::Isometry3d>& T_camera_target,
    const std::vector<Eigen::Vector3d>& points, CameraCalibration& out);

// Whether mrcal has the model named by CalibrationOptions::model.
bool mrcalHasModel(std::string_view model);

}  // namespace mixray::calibration::detail
