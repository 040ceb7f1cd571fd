// What the Ceres camera solve (ceres_solver.cpp) and the rig solve (rig.cpp) share: pose
// blocks, the fx = fy manifold, solver settings and covariances.
#pragma once

#include <ceres/manifold.h>
#include <ceres/problem.h>
#include <ceres/solver.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <optional>
#include <vector>

#include "solve_internal.h"

namespace mixray::calibration::detail {

using Vector6d = Eigen::Matrix<double, 6, 1>;

// A pose as the cost's parameter block: [rotation vector, translation].
Vector6d toRt(const Eigen::Isometry3d& T);
Eigen::Isometry3d fromRt(const double* rt);

// Keeps fx = fy in an intrinsics block (fx fy cx cy …): both move by the same step, as
// OpenCV's CALIB_FIX_ASPECT_RATIO with aspect 1.
class EqualFocalManifold final : public ceres::Manifold {
public:
    explicit EqualFocalManifold(int size) : size_(size) {}
    int AmbientSize() const override { return size_; }
    int TangentSize() const override { return size_ - 1; }
    bool Plus(const double* x, const double* delta, double* x_plus_delta) const override;
    bool PlusJacobian(const double* x, double* jacobian) const override;
    bool Minus(const double* y, const double* x, double* y_minus_x) const override;
    bool MinusJacobian(const double* x, double* jacobian) const override;

private:
    int size_;
};

// Levenberg–Marquardt to tight tolerances, one thread (callers share the machine).
ceres::Solver::Options solverOptions();

// (JᵀJ)⁻¹ over `blocks` (in order, each at its ambient size; blocks on a manifold get the
// ambient covariance), unscaled; nullopt when Ceres cannot compute it.
std::optional<Eigen::MatrixXd> covarianceOf(ceres::Problem& problem,
                                            const std::vector<const double*>& blocks);

// solveWithCeres()'s solve alone, without residuals or covariance: the views' poses it ends
// on. The front end's diagnosis when a solve fails (were the views degenerate?).
Result<std::vector<Eigen::Isometry3d>> solvePosesWithCeres(const SolveInput& input,
                                                           const CalibrationOptions& options);

}  // namespace mixray::calibration::detail
