// projectionUncertainty(): mrcal's projection uncertainty (mrcal docs "Projection uncertainty",
// mrcal 2.2's "mean-frames" reference) from CameraCalibration::covariance, whichever back end
// solved it.
#include <Eigen/Dense>
#include <cmath>
#include <optional>
#include <vector>

#include "mixray/calibration/calibrate.h"
#include "mrcal_lens.h"

namespace mixray::calibration {
namespace {

using Vector6d = Eigen::Matrix<double, 6, 1>;

Vector6d rtFromIsometry(const Eigen::Isometry3d& T) {
    const Eigen::AngleAxisd aa(T.rotation());
    Vector6d rt;
    rt.head<3>() = aa.axis() * aa.angle();
    rt.tail<3>() = T.translation();
    return rt;
}

// dq/dintrinsics (2 × n, model order) and dq/dp (2 × 3) at p: mrcal's analytic gradients for the
// lenses it has, central differences otherwise (Kannala–Brandt).
bool projectionGradients(const CameraModel& model, const Eigen::Vector3d& p,
                         Eigen::MatrixXd& dq_dintrinsics, Eigen::Matrix<double, 2, 3>& dq_dp) {
    const size_t n = 4 + model.distortion.size();
    dq_dintrinsics.resize(2, static_cast<Eigen::Index>(n));
    if (const std::optional<mrcal_lensmodel_t> lens = detail::mrcalLensModel(model)) {
        const std::vector<double> intrinsics = detail::mrcalIntrinsics(model);
        mrcal_point3_t point;
        point.x = p.x();
        point.y = p.y();
        point.z = p.z();
        mrcal_point2_t q;
        mrcal_point3_t gradient_p[2];
        std::vector<double> gradient_intrinsics(2 * n);
        if (!mrcal_project(&q, gradient_p, gradient_intrinsics.data(), &point, 1, &*lens,
                           intrinsics.data()))
            return false;
        for (int row = 0; row < 2; ++row) {
            for (int k = 0; k < 3; ++k)
                dq_dp(row, k) = gradient_p[row].xyz[k];
            for (size_t k = 0; k < n; ++k)
                dq_dintrinsics(row, static_cast<Eigen::Index>(k)) =
                    gradient_intrinsics[row * n + k];
        }
        return dq_dintrinsics.allFinite() && dq_dp.allFinite();
    }
    // Steps scaled to each parameter: relative for the core, absolute for the coefficients,
    // both near the cube root of the double epsilon times the value's size.
    auto parameter = [&](CameraModel& m, size_t k) -> double& {
        switch (k) {
            case 0:
                return m.fx;
            case 1:
                return m.fy;
            case 2:
                return m.cx;
            case 3:
                return m.cy;
            default:
                return m.distortion[k - 4];
        }
    };
    for (size_t k = 0; k < n; ++k) {
        CameraModel plus = model, minus = model;
        const double h = 1e-6 * std::max(1.0, std::abs(parameter(plus, k)));
        parameter(plus, k) += h;
        parameter(minus, k) -= h;
        const auto qp = plus.project(p), qm = minus.project(p);
        if (!qp || !qm)
            return false;
        dq_dintrinsics.col(static_cast<Eigen::Index>(k)) = (*qp - *qm) / (2 * h);
    }
    const double h = 1e-6 * std::max(1.0, p.norm());
    for (int k = 0; k < 3; ++k) {
        Eigen::Vector3d plus = p, minus = p;
        plus[k] += h;
        minus[k] -= h;
        const auto qp = model.project(plus), qm = model.project(minus);
        if (!qp || !qm)
            return false;
        dq_dp.col(k) = (*qp - *qm) / (2 * h);
    }
    return true;
}

// The largest axis of a 2 × 2 covariance's 1σ ellipse (mrcal.worst_direction_stdev).
double worstDirectionStddev(const Eigen::Matrix2d& cov) {
    const double a = cov(0, 0), b = cov(1, 0), c = cov(1, 1);
    return std::sqrt(std::max(0.0, (a + c) / 2 + std::sqrt((a - c) * (a - c) / 4 + b * b)));
}

}  // namespace

Result<UncertaintyMap> projectionUncertainty(const CameraCalibration& calibration, double step_px,
                                             double distance_m) {
    const CameraModel& model = calibration.model;
    if (Status valid = model.validate(); !valid.isOk())
        return Status(ErrorCode::kInvalidArgument, "projection uncertainty: " + valid.message());
    if (!(step_px > 0) || !(distance_m >= 0) || !std::isfinite(distance_m)) {
        return Status(ErrorCode::kInvalidArgument,
                      "projection uncertainty: step_px must be > 0 and distance_m >= 0 (0: at "
                      "infinity)");
    }
    const Eigen::Index nintrinsics = 4 + static_cast<Eigen::Index>(model.distortion.size());
    const size_t nviews = calibration.views.size();
    const Eigen::Index nstate = nintrinsics + 6 * static_cast<Eigen::Index>(nviews);
    if (nviews == 0 || calibration.covariance.rows() != nstate ||
        calibration.covariance.cols() != nstate) {
        return Status(ErrorCode::kInvalidArgument,
                      "projection uncertainty: the covariance is " +
                          std::to_string(calibration.covariance.rows()) + "x" +
                          std::to_string(calibration.covariance.cols()) + ", expected " +
                          std::to_string(nstate) + " square (" + std::to_string(nintrinsics) +
                          " intrinsics and 6 per each of " + std::to_string(nviews) + " views)");
    }

    UncertaintyMap map;
    map.step_px = step_px;
    map.distance_m = distance_m;
    map.cols = static_cast<int>(std::floor((model.width - 1) / step_px)) + 1;
    map.rows = static_cast<int>(std::floor((model.height - 1) / step_px)) + 1;
    map.stddev_px.assign(static_cast<size_t>(map.cols) * static_cast<size_t>(map.rows), NAN);

    std::vector<Vector6d> rt_camera_target;
    std::vector<Eigen::Isometry3d> T_target_camera;
    for (const ViewFit& view : calibration.views) {
        rt_camera_target.push_back(rtFromIsometry(view.T_camera_target));
        T_target_camera.push_back(view.T_camera_target.inverse());
    }
    const bool at_infinity = distance_m == 0;
    const double inv_n = 1.0 / static_cast<double>(nviews);

    Eigen::MatrixXd dq_db(2, nstate);
    Eigen::MatrixXd dq_dintrinsics;
    Eigen::Matrix<double, 2, 3> dq_dp;
    for (int row = 0; row < map.rows; ++row) {
        for (int col = 0; col < map.cols; ++col) {
            const Eigen::Vector2d pixel(col * step_px, row * step_px);
            const std::optional<Eigen::Vector3d> ray = model.unproject(pixel);
            if (!ray)
                continue;
            const Eigen::Vector3d p_cam = at_infinity ? *ray : Eigen::Vector3d(*ray * distance_m);
            if (!projectionGradients(model, p_cam, dq_dintrinsics, dq_dp))
                continue;
            dq_db.setZero();
            dq_db.leftCols(nintrinsics) = dq_dintrinsics;
            // The reference frame is the mean of the frames the boards define: the point, taken
            // into each board's frame and back through that board's pose, averaged. Perturbing
            // a pose moves the point by 1/N of that pose's effect.
            for (size_t v = 0; v < nviews; ++v) {
                Eigen::Matrix<double, 3, 6, Eigen::RowMajor> dp_drt =
                    Eigen::Matrix<double, 3, 6, Eigen::RowMajor>::Zero();
                double moved[3];
                if (at_infinity) {
                    const Eigen::Vector3d p_target = T_target_camera[v].linear() * p_cam;
                    Eigen::Matrix<double, 3, 3, Eigen::RowMajor> dp_dr;
                    mrcal_rotate_point_r(moved, dp_dr.data(), nullptr, rt_camera_target[v].data(),
                                         p_target.data());
                    dp_drt.leftCols<3>() = dp_dr;
                } else {
                    const Eigen::Vector3d p_target = T_target_camera[v] * p_cam;
                    mrcal_transform_point_rt(moved, dp_drt.data(), nullptr,
                                             rt_camera_target[v].data(), p_target.data());
                }
                dq_db.middleCols<6>(nintrinsics + 6 * static_cast<Eigen::Index>(v)) =
                    dq_dp * dp_drt * inv_n;
            }
            const Eigen::Matrix2d cov = dq_db * calibration.covariance * dq_db.transpose();
            map.stddev_px[static_cast<size_t>(row) * map.cols + col] =
                static_cast<float>(worstDirectionStddev(cov));
        }
    }
    return map;
}

}  // namespace mixray::calibration
