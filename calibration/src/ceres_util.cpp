// Pose blocks, the fx = fy manifold, solver settings and covariances for the Ceres solves.
#include "ceres_util.h"

#include <ceres/covariance.h>
#include <ceres/rotation.h>

namespace mixray::calibration::detail {

namespace {

// Above this many parameters the dense SVD's cubic cost outweighs its tolerance of rank
// deficiency; the sparse QR then does the work.
constexpr int kDenseCovarianceMaxParameters = 1500;

}  // namespace

Vector6d toRt(const Eigen::Isometry3d& T) {
    const Eigen::Matrix3d R = T.linear();
    Vector6d rt;
    ceres::RotationMatrixToAngleAxis(R.data(), rt.data());
    rt.tail<3>() = T.translation();
    return rt;
}

Eigen::Isometry3d fromRt(const double* rt) {
    Eigen::Matrix3d R;
    ceres::AngleAxisToRotationMatrix(rt, R.data());
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = R;
    T.translation() = Eigen::Vector3d(rt[3], rt[4], rt[5]);
    return T;
}

bool EqualFocalManifold::Plus(const double* x, const double* delta, double* x_plus_delta) const {
    x_plus_delta[0] = x[0] + delta[0];
    x_plus_delta[1] = x[1] + delta[0];
    for (int i = 2; i < size_; ++i)
        x_plus_delta[i] = x[i] + delta[i - 1];
    return true;
}

bool EqualFocalManifold::PlusJacobian(const double*, double* jacobian) const {
    Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>> j(
        jacobian, size_, size_ - 1);
    j.setZero();
    j(0, 0) = 1;
    j(1, 0) = 1;
    for (int i = 2; i < size_; ++i)
        j(i, i - 1) = 1;
    return true;
}

bool EqualFocalManifold::Minus(const double* y, const double* x, double* y_minus_x) const {
    y_minus_x[0] = y[0] - x[0];
    for (int i = 2; i < size_; ++i)
        y_minus_x[i - 1] = y[i] - x[i];
    return true;
}

bool EqualFocalManifold::MinusJacobian(const double*, double* jacobian) const {
    Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>> j(
        jacobian, size_ - 1, size_);
    j.setZero();
    j(0, 0) = 1;
    for (int i = 2; i < size_; ++i)
        j(i - 1, i) = 1;
    return true;
}

ceres::Solver::Options solverOptions() {
    ceres::Solver::Options options;
    options.linear_solver_type = ceres::DENSE_SCHUR;
    options.max_num_iterations = 500;
    options.function_tolerance = 1e-12;
    options.gradient_tolerance = 1e-14;
    options.parameter_tolerance = 1e-12;
    options.num_threads = 1;
    options.logging_type = ceres::SILENT;
    return options;
}

std::optional<Eigen::MatrixXd> covarianceOf(ceres::Problem& problem,
                                            const std::vector<const double*>& blocks) {
    int total = 0;
    for (const double* block : blocks)
        total += problem.ParameterBlockSize(block);
    ceres::Covariance::Options options;
    options.num_threads = 1;
    if (problem.NumParameters() <= kDenseCovarianceMaxParameters)
        options.algorithm_type = ceres::DENSE_SVD;
    ceres::Covariance covariance(options);
    std::vector<std::pair<const double*, const double*>> pairs;
    for (size_t i = 0; i < blocks.size(); ++i) {
        for (size_t j = i; j < blocks.size(); ++j)
            pairs.emplace_back(blocks[i], blocks[j]);
    }
    if (!covariance.Compute(pairs, &problem))
        return std::nullopt;
    Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> out(total, total);
    if (!covariance.GetCovarianceMatrix(blocks, out.data()))
        return std::nullopt;
    return Eigen::MatrixXd(out);
}

}  // namespace mixray::calibration::detail
