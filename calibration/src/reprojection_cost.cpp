// The reprojection cost every Ceres solve shares: residual and Jacobians written out for the
// pose chain, pinhole with OpenCV distortion (0/4/5/8) and Kannala–Brandt fish-eye, so solves
// need neither automatic nor numeric differentiation.
#include "reprojection_cost.h"

#include <ceres/cost_function.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cassert>
#include <cmath>
#include <vector>

#include "lens_distortion.h"

namespace mixray::calibration::detail {

namespace {

// Residual of a point the model cannot project: large enough that any step reaching it is
// rejected, constant so that it pulls nowhere.
constexpr double kInvalidResidualPx = 1e4;

// Below this rotation angle the closed forms lose precision; their Taylor series are exact to
// double precision there.
constexpr double kSmallAngleRad = 1e-4;

Eigen::Matrix3d skew(const Eigen::Vector3d& v) {
    Eigen::Matrix3d m;
    m << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
    return m;
}

// R(ω) and the left Jacobian of SO(3), J(ω), for which d(R(ω) q)/dω = −[R(ω) q]× J(ω).
void rotationAndJacobian(const double* rotation_vector, Eigen::Matrix3d* rotation,
                         Eigen::Matrix3d* jacobian) {
    const Eigen::Vector3d w(rotation_vector[0], rotation_vector[1], rotation_vector[2]);
    const double theta2 = w.squaredNorm();
    const double theta = std::sqrt(theta2);
    double a, b, c;  // sin θ / θ, (1 − cos θ) / θ², (θ − sin θ) / θ³
    if (theta < kSmallAngleRad) {
        a = 1 - theta2 / 6;
        b = 0.5 - theta2 / 24;
        c = 1.0 / 6 - theta2 / 120;
    } else {
        a = std::sin(theta) / theta;
        b = (1 - std::cos(theta)) / theta2;
        c = (theta - std::sin(theta)) / (theta2 * theta);
    }
    const Eigen::Matrix3d k = skew(w);
    const Eigen::Matrix3d k2 = k * k;
    *rotation = Eigen::Matrix3d::Identity() + a * k + b * k2;
    *jacobian = Eigen::Matrix3d::Identity() + b * k + c * k2;
}

using Row2 = Eigen::Matrix<double, 2, Eigen::Dynamic, Eigen::RowMajor>;

// A projection and its derivatives with respect to the camera-frame point and to the
// intrinsics (in intrinsicsVector order).
struct Projection {
    bool valid = false;
    Eigen::Vector2d pixel;
    Eigen::Matrix<double, 2, 3> d_point;
    Row2 d_intrinsics;
};

// cv::projectPoints' rational model, k1 k2 p1 p2 k3 k4 k5 k6, with the first `count`
// coefficients present and the rest zero.
Projection projectPinhole(const Eigen::Vector3d& p, const double* intrinsics, int count) {
    Projection out;
    if (!(p.z() > 0))
        return out;
    std::array<double, 8> k{};
    for (int i = 0; i < count; ++i)
        k[i] = intrinsics[4 + i];
    const PinholeCoefficients coefficients{k[0], k[1], k[2], k[3], k[4], k[5], k[6], k[7]};
    const double fx = intrinsics[0], fy = intrinsics[1];
    const double inv_z = 1 / p.z();
    const double x = p.x() * inv_z, y = p.y() * inv_z;
    Eigen::Matrix2d d_distorted;  // d(xd, yd)/d(x, y)
    Eigen::Matrix<double, 2, 8> d_coefficients;
    const Eigen::Vector2d distorted =
        distortPinhole(coefficients, Eigen::Vector2d(x, y), &d_distorted, &d_coefficients);
    out.valid = true;
    out.pixel =
        Eigen::Vector2d(fx * distorted.x() + intrinsics[2], fy * distorted.y() + intrinsics[3]);
    Eigen::Matrix<double, 2, 3> d_normalised;
    d_normalised << inv_z, 0, -x * inv_z, 0, inv_z, -y * inv_z;
    const Eigen::Vector2d focal(fx, fy);
    out.d_point = focal.asDiagonal() * d_distorted * d_normalised;

    out.d_intrinsics.setZero(2, 4 + count);
    out.d_intrinsics(0, 0) = distorted.x();
    out.d_intrinsics(1, 1) = distorted.y();
    out.d_intrinsics(0, 2) = 1;
    out.d_intrinsics(1, 3) = 1;
    out.d_intrinsics.rightCols(count) = focal.asDiagonal() * d_coefficients.leftCols(count);
    return out;
}

// Whether θ_d increases on [0, theta]: CameraModel::project refuses directions past the first
// fold of the polynomial, and the solver must not fit through the folded branch either.
bool fisheyeIncreasingUpTo(const FisheyeCoefficients& k, double theta) {
    constexpr int kSamples = 16;
    for (int i = 1; i <= kSamples; ++i) {
        if (fisheyeThetaDDerivative(k, theta * i / kSamples) <= 0)
            return false;
    }
    return true;
}

// cv::fisheye's Kannala–Brandt model, θ = atan2(ρ, z) as CameraModel::project extends it.
Projection projectFisheye(const Eigen::Vector3d& p, const double* intrinsics) {
    Projection out;
    const FisheyeCoefficients k{intrinsics[4], intrinsics[5], intrinsics[6], intrinsics[7]};
    const double fx = intrinsics[0], fy = intrinsics[1];
    const double rho2 = p.x() * p.x() + p.y() * p.y();
    const double rho = std::sqrt(rho2);
    if (rho == 0 && p.z() <= 0)
        return out;
    const double theta = std::atan2(rho, p.z());
    if (theta > kFisheyeMaxThetaRad || !fisheyeIncreasingUpTo(k, theta))
        return out;
    const double t2 = theta * theta;
    const double theta_d = fisheyeThetaD(k, theta);
    out.valid = true;
    out.d_intrinsics.setZero(2, 8);
    Eigen::Matrix<double, 2, 3> d_distorted;  // d(xd, yd)/d(X, Y, Z)
    double xd, yd;
    // On the axis θ_d/ρ → 1/z; the general form would divide 0 by 0.
    if (rho < 1e-10 * p.z()) {
        const double inv_z = 1 / p.z();
        xd = p.x() * inv_z;
        yd = p.y() * inv_z;
        d_distorted << inv_z, 0, -xd * inv_z, 0, inv_z, -yd * inv_z;
    } else {
        const double u = p.x() / rho, v = p.y() / rho;
        xd = u * theta_d;
        yd = v * theta_d;
        const double n2 = rho2 + p.z() * p.z();
        const Eigen::RowVector3d d_theta(p.z() * u / n2, p.z() * v / n2, -rho / n2);
        const double rho3 = rho2 * rho;
        const Eigen::RowVector3d d_u(p.y() * p.y() / rho3, -p.x() * p.y() / rho3, 0);
        const Eigen::RowVector3d d_v(-p.x() * p.y() / rho3, p.x() * p.x() / rho3, 0);
        const double dtheta_d = fisheyeThetaDDerivative(k, theta);
        d_distorted.row(0) = theta_d * d_u + u * dtheta_d * d_theta;
        d_distorted.row(1) = theta_d * d_v + v * dtheta_d * d_theta;
        double power = theta * t2;  // θ³, θ⁵, θ⁷, θ⁹: d θ_d / d k_i
        for (int i = 0; i < 4; ++i, power *= t2) {
            out.d_intrinsics(0, 4 + i) = fx * u * power;
            out.d_intrinsics(1, 4 + i) = fy * v * power;
        }
    }
    out.pixel = Eigen::Vector2d(fx * xd + intrinsics[2], fy * yd + intrinsics[3]);
    out.d_point = Eigen::Vector2d(fx, fy).asDiagonal() * d_distorted;
    out.d_intrinsics(0, 0) = xd;
    out.d_intrinsics(1, 1) = yd;
    out.d_intrinsics(0, 2) = 1;
    out.d_intrinsics(1, 3) = 1;
    return out;
}

// Any other lens, through CameraModel::project with its intrinsics fixed: the point Jacobian by
// central differences (steps of 1e-7 of the distance keep both the truncation and the rounding
// error near 1e-7 relative for the smooth lens models mrcal has).
Projection projectOther(const CameraModel& model, const Eigen::Vector3d& p) {
    Projection out;
    const auto pixel = model.project(p);
    if (!pixel)
        return out;
    const double h = 1e-7 * std::max(1.0, p.norm());
    for (int i = 0; i < 3; ++i) {
        Eigen::Vector3d plus = p, minus = p;
        plus[i] += h;
        minus[i] -= h;
        const auto a = model.project(plus);
        const auto b = model.project(minus);
        if (!a || !b)
            return out;
        out.d_point.col(i) = (*a - *b) / (2 * h);
    }
    out.valid = true;
    out.pixel = *pixel;
    return out;
}

class ReprojectionCost final : public ceres::CostFunction {
public:
    ReprojectionCost(const CameraModel& model, const Eigen::Vector3d& p_target,
                     const Eigen::Vector2d& observed, double weight, int chain_length,
                     bool intrinsics_free)
        : model_(model),
          lens_(model.lens),
          intrinsics_(intrinsicsVector(model)),
          p_target_(p_target),
          observed_(observed),
          sqrt_weight_(std::sqrt(weight)),
          chain_length_(chain_length),
          intrinsics_free_(intrinsics_free) {
        // The projections index the coefficients directly: callers validate models first.
        assert(lens_ != LensModel::kFisheye || intrinsics_.size() == 8);
        assert(lens_ != LensModel::kPinhole || intrinsics_.size() <= 12);
        // Other lenses are differentiated through CameraModel::project, points only.
        assert(lens_ == LensModel::kPinhole || lens_ == LensModel::kFisheye || !intrinsics_free);
        set_num_residuals(2);
        for (int i = 0; i < chain_length; ++i)
            mutable_parameter_block_sizes()->push_back(6);
        if (intrinsics_free)
            mutable_parameter_block_sizes()->push_back(static_cast<int32_t>(intrinsics_.size()));
    }

    bool Evaluate(double const* const* parameters, double* residuals,
                  double** jacobians) const override {
        const int n = chain_length_;
        // Rotations, their Jacobians and each block's rotated input, from the target end.
        std::vector<Eigen::Matrix3d> rotation(n), rotation_jacobian(n);
        std::vector<Eigen::Vector3d> rotated(n);
        Eigen::Vector3d p = p_target_;
        for (int i = n - 1; i >= 0; --i) {
            rotationAndJacobian(parameters[i], &rotation[i], &rotation_jacobian[i]);
            rotated[i] = rotation[i] * p;
            p = rotated[i] + Eigen::Vector3d(parameters[i][3], parameters[i][4], parameters[i][5]);
        }
        const double* intrinsics = intrinsics_free_ ? parameters[n] : intrinsics_.data();
        const int distortion_count = static_cast<int>(intrinsics_.size()) - 4;
        const Projection projection = lens_ == LensModel::kFisheye ? projectFisheye(p, intrinsics)
                                      : lens_ == LensModel::kPinhole
                                          ? projectPinhole(p, intrinsics, distortion_count)
                                          : projectOther(model_, p);
        if (!projection.valid) {
            residuals[0] = residuals[1] = kInvalidResidualPx * sqrt_weight_;
            if (jacobians) {
                for (int i = 0; i < n + (intrinsics_free_ ? 1 : 0); ++i) {
                    if (jacobians[i]) {
                        std::fill(jacobians[i], jacobians[i] + 2 * parameter_block_sizes()[i], 0.0);
                    }
                }
            }
            return true;
        }
        const Eigen::Vector2d residual = (projection.pixel - observed_) * sqrt_weight_;
        residuals[0] = residual.x();
        residuals[1] = residual.y();
        if (!jacobians)
            return true;
        // d(pixel)/d(point in the frame of block i's output) = d_point · R_0 ⋯ R_{i−1}.
        Eigen::Matrix<double, 2, 3> d_frame = sqrt_weight_ * projection.d_point;
        for (int i = 0; i < n; ++i) {
            if (jacobians[i]) {
                Eigen::Map<Eigen::Matrix<double, 2, 6, Eigen::RowMajor>> j(jacobians[i]);
                j.leftCols<3>() = -d_frame * skew(rotated[i]) * rotation_jacobian[i];
                j.rightCols<3>() = d_frame;
            }
            d_frame = d_frame * rotation[i];
        }
        if (intrinsics_free_ && jacobians[n]) {
            Eigen::Map<Row2> j(jacobians[n], 2, static_cast<Eigen::Index>(intrinsics_.size()));
            j = sqrt_weight_ * projection.d_intrinsics;
        }
        return true;
    }

private:
    CameraModel model_;
    LensModel lens_;
    Eigen::VectorXd intrinsics_;
    Eigen::Vector3d p_target_;
    Eigen::Vector2d observed_;
    double sqrt_weight_;
    int chain_length_;
    bool intrinsics_free_;
};

}  // namespace

ceres::CostFunction* newReprojectionCost(const CameraModel& model, const Eigen::Vector3d& p_target,
                                         const Eigen::Vector2d& observed, double weight,
                                         int chain_length, bool intrinsics_free) {
    return new ReprojectionCost(model, p_target, observed, weight, chain_length, intrinsics_free);
}

Eigen::VectorXd intrinsicsVector(const CameraModel& model) {
    Eigen::VectorXd v(4 + model.distortion.size());
    v.head<4>() << model.fx, model.fy, model.cx, model.cy;
    for (size_t i = 0; i < model.distortion.size(); ++i)
        v[static_cast<Eigen::Index>(4 + i)] = model.distortion[i];
    return v;
}

CameraModel withIntrinsics(const CameraModel& model, const Eigen::VectorXd& parameters) {
    CameraModel out = model;
    out.fx = parameters[0];
    out.fy = parameters[1];
    out.cx = parameters[2];
    out.cy = parameters[3];
    out.distortion.assign(parameters.data() + 4, parameters.data() + parameters.size());
    return out;
}

}  // namespace mixray::calibration::detail
