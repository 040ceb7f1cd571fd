// The Ceres cost every mixray solve shares: a target point seen through a chain of rigid poses
// and a lens model, with analytic Jacobians.
#pragma once

#include <Eigen/Core>

#include "mixray/calibration/camera_model.h"

namespace ceres {
class CostFunction;
}

namespace mixray::calibration::detail {

// Residual: (project(T(rt_0) · T(rt_1) · … · T(rt_{n-1}) · p_target) − observed) · √weight,
// 2 values. Each rt block is 6 doubles, [rotation vector, translation] of T_a_b (p_a = R p_b
// + t). Parameter blocks: the n rt blocks in order, then, when `intrinsics_free`, the model's
// parameters (fx fy cx cy, then distortion: pinhole OpenCV 4/5/8 or Kannala–Brandt fish-eye);
// otherwise the model's own values are used and fixed. Other lenses (mrcal's stereographic and
// splined models) only with fixed intrinsics, differentiated through CameraModel::project by
// central differences. Points the model cannot project give a large constant residual with
// zero Jacobians (the solver steps back). Owned by the caller (ceres::Problem takes
// ownership).
ceres::CostFunction* newReprojectionCost(const CameraModel& model, const Eigen::Vector3d& p_target,
                                         const Eigen::Vector2d& observed, double weight,
                                         int chain_length, bool intrinsics_free);

// The model's parameters in the cost's order, and back.
Eigen::VectorXd intrinsicsVector(const CameraModel& model);
CameraModel withIntrinsics(const CameraModel& model, const Eigen::VectorXd& parameters);

}  // namespace mixray::calibration::detail
