// The OpenCV lens polynomials CameraModel::project/unproject (camera_model.cpp) and the Ceres
// cost's analytic Jacobians (reprojection_cost.cpp) both evaluate: one definition, so that the
// solver fits exactly the model the library projects with.
#pragma once

#include <Eigen/Core>
#include <numbers>

namespace mixray::calibration::detail {

// The fish-eye model is used up to 100° off the optical axis (a 200° field of view). Beyond
// that the polynomial is extrapolated far past any calibration data, so such directions are
// treated as outside the field of view.
inline constexpr double kFisheyeMaxThetaRad = 100.0 * std::numbers::pi / 180.0;

// cv::projectPoints' rational model; absent coefficients are zero.
struct PinholeCoefficients {
    double k1 = 0, k2 = 0, p1 = 0, p2 = 0, k3 = 0, k4 = 0, k5 = 0, k6 = 0;
};

// Distorts normalised coordinates (x, y) = (X/Z, Y/Z) as cv::projectPoints does, with the
// same operation order so results agree to the last bits. Optionally returns the Jacobians
// with respect to (x, y) and to the coefficients (columns k1 k2 p1 p2 k3 k4 k5 k6).
inline Eigen::Vector2d distortPinhole(const PinholeCoefficients& c, const Eigen::Vector2d& xy,
                                      Eigen::Matrix2d* d_xy,
                                      Eigen::Matrix<double, 2, 8>* d_coefficients = nullptr) {
    const double x = xy.x(), y = xy.y();
    const double r2 = x * x + y * y;
    const double r4 = r2 * r2;
    const double r6 = r4 * r2;
    const double a1 = 2 * x * y;
    const double a2 = r2 + 2 * x * x;
    const double a3 = r2 + 2 * y * y;
    const double num = 1 + c.k1 * r2 + c.k2 * r4 + c.k3 * r6;
    const double den = 1 + c.k4 * r2 + c.k5 * r4 + c.k6 * r6;
    const double inv_den = 1 / den;
    const double radial = num * inv_den;
    const Eigen::Vector2d out(x * radial + c.p1 * a1 + c.p2 * a2,
                              y * radial + c.p1 * a3 + c.p2 * a1);
    if (d_xy) {
        // d(radial)/d(r2) by the quotient rule; d(r2)/dx = 2x.
        const double dnum = c.k1 + 2 * c.k2 * r2 + 3 * c.k3 * r4;
        const double dden = c.k4 + 2 * c.k5 * r2 + 3 * c.k6 * r4;
        const double dradial_dr2 = (dnum * den - num * dden) * inv_den * inv_den;
        const double drdx = dradial_dr2 * 2 * x;
        const double drdy = dradial_dr2 * 2 * y;
        (*d_xy)(0, 0) = radial + x * drdx + 2 * c.p1 * y + 6 * c.p2 * x;
        (*d_xy)(0, 1) = x * drdy + 2 * c.p1 * x + 2 * c.p2 * y;
        (*d_xy)(1, 0) = y * drdx + 2 * c.p1 * x + 2 * c.p2 * y;
        (*d_xy)(1, 1) = radial + y * drdy + 6 * c.p1 * y + 2 * c.p2 * x;
    }
    if (d_coefficients) {
        const double num_den2 = num * inv_den * inv_den;
        *d_coefficients << x * r2 * inv_den, x * r4 * inv_den, a1, a2, x * r6 * inv_den,
            -x * r2 * num_den2, -x * r4 * num_den2, -x * r6 * num_den2,  //
            y * r2 * inv_den, y * r4 * inv_den, a3, a1, y * r6 * inv_den, -y * r2 * num_den2,
            -y * r4 * num_den2, -y * r6 * num_den2;
    }
    return out;
}

// cv::fisheye's Kannala–Brandt model: θ_d = θ (1 + k1 θ² + k2 θ⁴ + k3 θ⁶ + k4 θ⁸).
struct FisheyeCoefficients {
    double k1 = 0, k2 = 0, k3 = 0, k4 = 0;
};

inline double fisheyeThetaD(const FisheyeCoefficients& c, double theta) {
    const double t2 = theta * theta;
    const double t4 = t2 * t2;
    const double t6 = t4 * t2;
    const double t8 = t4 * t4;
    return theta * (1 + c.k1 * t2 + c.k2 * t4 + c.k3 * t6 + c.k4 * t8);
}

inline double fisheyeThetaDDerivative(const FisheyeCoefficients& c, double theta) {
    const double t2 = theta * theta;
    return 1 + t2 * (3 * c.k1 + t2 * (5 * c.k2 + t2 * (7 * c.k3 + t2 * 9 * c.k4)));
}

}  // namespace mixray::calibration::detail
