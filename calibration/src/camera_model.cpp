// Lens models: names, validation, projection and unprojection (pinhole+OpenCV distortion,
// Kannala–Brandt fish-eye), matching cv::projectPoints and cv::fisheye::projectPoints; mrcal's
// stereographic and splined stereographic models through mrcal_project/mrcal_unproject.
#include "mixray/calibration/camera_model.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <string>

#include "lens_distortion.h"
#include "mrcal_lens.h"

namespace mixray::calibration {

namespace {

using detail::FisheyeCoefficients;
using detail::fisheyeThetaD;
using detail::fisheyeThetaDDerivative;
using detail::kFisheyeMaxThetaRad;
using detail::PinholeCoefficients;

// Iteration limits for unproject(). Newton converges in a handful of steps for real lenses;
// the generous cap leaves room for damped steps near the image corners.
constexpr int kMaxIterations = 100;
// Convergence threshold on the reprojection residual, in pixels: far below the 1e-6 px the
// header promises, and well above double rounding noise for images up to ~10^4 px.
constexpr double kResidualTolerancePx = 1e-9;
// How close mrcal_unproject()'s ray must reproject onto its pixel: the header's promise.
constexpr double kUnprojectCheckPx = 1e-6;

double coefficient(const std::vector<double>& d, size_t i) {
    return i < d.size() ? d[i] : 0.0;
}

bool allFinite(const std::vector<double>& values) {
    return std::all_of(values.begin(), values.end(), [](double v) { return std::isfinite(v); });
}

// ---- pinhole (OpenCV rational model) ----

PinholeCoefficients pinholeCoefficients(const std::vector<double>& d) {
    return {coefficient(d, 0), coefficient(d, 1), coefficient(d, 2), coefficient(d, 3),
            coefficient(d, 4), coefficient(d, 5), coefficient(d, 6), coefficient(d, 7)};
}

// ---- fish-eye (Kannala–Brandt as cv::fisheye) ----

FisheyeCoefficients fisheyeCoefficients(const std::vector<double>& d) {
    return {coefficient(d, 0), coefficient(d, 1), coefficient(d, 2), coefficient(d, 3)};
}

// True when θ_d surely increases on [0, theta]: a lower bound of its derivative, keeping only
// the negative terms at their worst, stays positive. Cheap, so it runs before any scan.
bool fisheyeSurelyMonotonicUpTo(const FisheyeCoefficients& c, double theta) {
    const double s = theta * theta;
    const double lower = 1 + std::min(0.0, 3 * c.k1) * s + std::min(0.0, 5 * c.k2) * s * s +
                         std::min(0.0, 7 * c.k3) * s * s * s +
                         std::min(0.0, 9 * c.k4) * s * s * s * s;
    return lower > 0;
}

// The largest θ the fish-eye model is used for: kFisheyeMaxThetaRad, or less where θ_d(θ)
// stops increasing (there the model folds over and has no unique inverse).
double fisheyeMaxTheta(const FisheyeCoefficients& c) {
    if (fisheyeSurelyMonotonicUpTo(c, kFisheyeMaxThetaRad))
        return kFisheyeMaxThetaRad;
    // The derivative is a quartic in θ²: a coarse scan finds its first sign change (real lens
    // models have no dip narrower than a step), bisection then pins it down.
    constexpr int kSteps = 64;
    double previous = 0;
    for (int i = 1; i <= kSteps; ++i) {
        const double theta = kFisheyeMaxThetaRad * i / kSteps;
        if (fisheyeThetaDDerivative(c, theta) <= 0) {
            double lo = previous, hi = theta;
            for (int k = 0; k < 44; ++k) {
                const double mid = 0.5 * (lo + hi);
                (fisheyeThetaDDerivative(c, mid) > 0 ? lo : hi) = mid;
            }
            return lo;
        }
        previous = theta;
    }
    return kFisheyeMaxThetaRad;
}

// An upper end for the search of θ_d(θ) = theta_d on which θ_d surely increases and that
// brackets the root: shrinks from the field-of-view limit while the cheap bound fails, and
// falls back to the exact limit only for pixels far out on a folding lens.
double fisheyeSearchLimit(const FisheyeCoefficients& c, double theta_d) {
    double limit = kFisheyeMaxThetaRad;
    for (int i = 0; i < 24 && !fisheyeSurelyMonotonicUpTo(c, limit); ++i)
        limit *= 0.9;
    if (fisheyeSurelyMonotonicUpTo(c, limit) && fisheyeThetaD(c, limit) >= theta_d)
        return limit;
    return fisheyeMaxTheta(c);
}

// Solves θ_d(θ) = theta_d for θ in [0, theta_max] by Newton with a bisection fallback; θ_d is
// increasing on that interval, so the bracket always holds the root.
std::optional<double> solveFisheyeTheta(const FisheyeCoefficients& c, double theta_d,
                                        double theta_max, double tolerance) {
    if (theta_d <= 0)
        return 0.0;
    if (theta_d > fisheyeThetaD(c, theta_max))
        return std::nullopt;
    double lo = 0, hi = theta_max;
    double theta = std::min(theta_d, theta_max);
    for (int i = 0; i < kMaxIterations; ++i) {
        const double f = fisheyeThetaD(c, theta) - theta_d;
        if (std::abs(f) < tolerance)
            return theta;
        if (f > 0) {
            hi = theta;
        } else {
            lo = theta;
        }
        const double step = f / fisheyeThetaDDerivative(c, theta);
        double next = theta - step;
        if (!(next > lo && next < hi))
            next = 0.5 * (lo + hi);
        theta = next;
    }
    return std::nullopt;
}

// ---- mrcal's stereographic models ----

// Where a splined model's control points define it, in stereographic u (mrcal's
// _splined_stereographic_domain()): cubic splines one knot in from the outermost, quadratic
// ones half a segment; beyond it mrcal extrapolates the outermost polynomial segment.
struct SplineDomain {
    double x0, x1, y0, y1;
    bool contains(const Eigen::Vector2d& u) const {
        return u.x() >= x0 && u.x() <= x1 && u.y() >= y0 && u.y() <= y1;
    }
};

SplineDomain splineDomain(const mrcal_lensmodel_t& lens, const SplineConfig& c) {
    std::vector<double> ux(static_cast<size_t>(c.nx)), uy(static_cast<size_t>(c.ny));
    mrcal_knots_for_splined_models(ux.data(), uy.data(), &lens);
    const size_t nx = ux.size(), ny = uy.size();
    if (c.order == 3)
        return {ux[1], ux[nx - 2], uy[1], uy[ny - 2]};
    return {0.5 * (ux[0] + ux[1]), 0.5 * (ux[nx - 2] + ux[nx - 1]), 0.5 * (uy[0] + uy[1]),
            0.5 * (uy[ny - 2] + uy[ny - 1])};
}

// The stereographic u of a direction; nullopt straight back (and for the zero vector).
std::optional<Eigen::Vector2d> stereographicU(const Eigen::Vector3d& p) {
    const double denominator = p.norm() + p.z();
    if (!(denominator > 0))
        return std::nullopt;
    return Eigen::Vector2d(2 * p.x() / denominator, 2 * p.y() / denominator);
}

bool insideMrcalDomain(const CameraModel& m, const mrcal_lensmodel_t& lens,
                       const Eigen::Vector3d& p) {
    const std::optional<Eigen::Vector2d> u = stereographicU(p);
    if (!u)
        return false;
    return m.lens != LensModel::kSplinedStereographic || splineDomain(lens, m.spline).contains(*u);
}

std::optional<Eigen::Vector2d> projectMrcal(const CameraModel& m, const Eigen::Vector3d& p) {
    const std::optional<mrcal_lensmodel_t> lens = detail::mrcalLensModel(m);
    if (!lens || !p.allFinite() || !insideMrcalDomain(m, *lens, p))
        return std::nullopt;
    const std::vector<double> intrinsics = detail::mrcalIntrinsics(m);
    if (intrinsics.size() != static_cast<size_t>(mrcal_lensmodel_num_params(&*lens)))
        return std::nullopt;
    mrcal_point3_t point;
    point.x = p.x();
    point.y = p.y();
    point.z = p.z();
    mrcal_point2_t q;
    if (!mrcal_project(&q, nullptr, nullptr, &point, 1, &*lens, intrinsics.data()))
        return std::nullopt;
    const Eigen::Vector2d pixel(q.x, q.y);
    if (!pixel.allFinite())
        return std::nullopt;
    return pixel;
}

std::optional<Eigen::Vector3d> unprojectMrcal(const CameraModel& m, const Eigen::Vector2d& pixel) {
    const std::optional<mrcal_lensmodel_t> lens = detail::mrcalLensModel(m);
    if (!lens)
        return std::nullopt;
    const std::vector<double> intrinsics = detail::mrcalIntrinsics(m);
    if (intrinsics.size() != static_cast<size_t>(mrcal_lensmodel_num_params(&*lens)))
        return std::nullopt;
    mrcal_point2_t q;
    q.x = pixel.x();
    q.y = pixel.y();
    mrcal_point3_t v;
    if (!mrcal_unproject(&v, &q, 1, &*lens, intrinsics.data()))
        return std::nullopt;
    Eigen::Vector3d ray(v.x, v.y, v.z);
    if (!ray.allFinite() || !(ray.norm() > 0))
        return std::nullopt;
    ray.normalize();
    if (!insideMrcalDomain(m, *lens, ray))
        return std::nullopt;
    // mrcal's solver stops at its own tolerance, and for pixels the spline cannot reach it
    // returns its best effort: only rays that reproject onto the pixel are the pixel's ray.
    const std::optional<Eigen::Vector2d> back = projectMrcal(m, ray);
    if (!back || (*back - pixel).norm() > kUnprojectCheckPx)
        return std::nullopt;
    return ray;
}

}  // namespace

std::string_view toString(LensModel model) {
    switch (model) {
        case LensModel::kPinhole:
            return "pinhole";
        case LensModel::kFisheye:
            return "fisheye";
        case LensModel::kStereographic:
            return "stereographic";
        case LensModel::kSplinedStereographic:
            return "splined_stereographic";
    }
    return "unknown";
}

std::optional<LensModel> lensModelFromString(std::string_view name) {
    if (name == "pinhole")
        return LensModel::kPinhole;
    if (name == "fisheye")
        return LensModel::kFisheye;
    if (name == "stereographic" || name == "LENSMODEL_STEREOGRAPHIC")
        return LensModel::kStereographic;
    if (name == "splined_stereographic" || name.starts_with("LENSMODEL_SPLINED_STEREOGRAPHIC_"))
        return LensModel::kSplinedStereographic;
    return std::nullopt;
}

std::string toString(const SplineConfig& c) {
    return "LENSMODEL_SPLINED_STEREOGRAPHIC_order=" + std::to_string(c.order) +
           "_Nx=" + std::to_string(c.nx) + "_Ny=" + std::to_string(c.ny) +
           "_fov_x_deg=" + std::to_string(c.fov_x_deg);
}

std::optional<SplineConfig> splineConfigFromString(std::string_view name) {
    mrcal_lensmodel_t lens = detail::makeMrcalLensModel(MRCAL_LENSMODEL_INVALID);
    const std::string terminated(name);
    if (!mrcal_lensmodel_from_name(&lens, terminated.c_str()) ||
        lens.type != MRCAL_LENSMODEL_SPLINED_STEREOGRAPHIC)
        return std::nullopt;
    const auto& config = lens.LENSMODEL_SPLINED_STEREOGRAPHIC__config;
    const SplineConfig parsed{config.order, config.Nx, config.Ny, config.fov_x_deg};
    // mrcal's scanf-based parser accepts trailing text; the name must be exactly the model's.
    if (toString(parsed) != name)
        return std::nullopt;
    return parsed;
}

std::string CameraModel::lensName() const {
    if (lens == LensModel::kSplinedStereographic)
        return toString(spline);
    return std::string(toString(lens));
}

CameraModel CameraModel::pinhole(int width, int height, double fx, double fy, double cx,
                                 double cy) {
    CameraModel model;
    model.lens = LensModel::kPinhole;
    model.width = width;
    model.height = height;
    model.fx = fx;
    model.fy = fy;
    model.cx = cx;
    model.cy = cy;
    return model;
}

Status CameraModel::validate() const {
    auto invalid = [](std::string message) {
        return Status(ErrorCode::kInvalidArgument, "camera model: " + std::move(message));
    };
    if (width <= 0 || height <= 0) {
        return invalid("width and height must be > 0, got " + std::to_string(width) + "x" +
                       std::to_string(height));
    }
    // The ranges mixray's own calibration file reads (camera_model_yaml.cpp), so that a model
    // accepted from any format can be written and read back (found by calibration_file_fuzz: a
    // Kalibr principal point of 2462049 px).
    constexpr int kMaxSide = 65535;
    constexpr double kMaxPixels = 1e6;
    if (width > kMaxSide || height > kMaxSide)
        return invalid("width and height must be at most " + std::to_string(kMaxSide));
    if (!std::isfinite(fx) || fx <= 0 || fx > kMaxPixels)
        return invalid("fx must be finite, > 0 and at most 1e6");
    if (!std::isfinite(fy) || fy <= 0 || fy > kMaxPixels)
        return invalid("fy must be finite, > 0 and at most 1e6");
    if (!std::isfinite(cx) || std::abs(cx) > kMaxPixels)
        return invalid("cx must be finite and within ±1e6");
    if (!std::isfinite(cy) || std::abs(cy) > kMaxPixels)
        return invalid("cy must be finite and within ±1e6");
    for (double d : distortion) {
        if (!std::isfinite(d) || std::abs(d) > kMaxPixels)
            return invalid("distortion coefficients must be finite and within ±1e6");
    }
    const size_t n = distortion.size();
    if (lens == LensModel::kPinhole) {
        if (n != 0 && n != 4 && n != 5 && n != 8) {
            return invalid("distortion: pinhole takes 0, 4, 5 or 8 coefficients, got " +
                           std::to_string(n));
        }
    } else if (lens == LensModel::kFisheye) {
        if (n != 4) {
            return invalid("distortion: fisheye takes 4 coefficients (k1 k2 k3 k4), got " +
                           std::to_string(n));
        }
    } else if (lens == LensModel::kStereographic) {
        if (n != 0)
            return invalid("distortion: stereographic takes none, got " + std::to_string(n));
    } else if (lens == LensModel::kSplinedStereographic) {
        const SplineConfig& c = spline;
        if (c.order != 2 && c.order != 3)
            return invalid("spline: order must be 2 or 3, got " + std::to_string(c.order));
        // mrcal needs a segment of support beyond the valid region on each side.
        if (c.nx < 4 || c.ny < 4 || c.nx > 1000 || c.ny > 1000) {
            return invalid("spline: Nx and Ny must be in 4..1000, got " + std::to_string(c.nx) +
                           "x" + std::to_string(c.ny));
        }
        if (c.fov_x_deg <= 0 || c.fov_x_deg >= 360)
            return invalid("spline: fov_x_deg must be in 1..359, got " +
                           std::to_string(c.fov_x_deg));
        const size_t expected = 2 * static_cast<size_t>(c.nx) * static_cast<size_t>(c.ny);
        if (n != expected) {
            return invalid("distortion: " + toString(c) +
                           " takes 2*Nx*Ny = " + std::to_string(expected) +
                           " control-point values, got " + std::to_string(n));
        }
    } else {
        return invalid("lens: unknown lens model");
    }
    if (!allFinite(distortion))
        return invalid("distortion: coefficients must be finite");
    return Status::ok();
}

std::optional<Eigen::Vector2d> CameraModel::project(const Eigen::Vector3d& p_cam) const {
    if (lens == LensModel::kStereographic || lens == LensModel::kSplinedStereographic)
        return projectMrcal(*this, p_cam);
    if (lens == LensModel::kFisheye) {
        const FisheyeCoefficients c = fisheyeCoefficients(distortion);
        const double rho = std::hypot(p_cam.x(), p_cam.y());
        if (rho == 0 && p_cam.z() <= 0)
            return std::nullopt;
        // atan2 instead of OpenCV's atan(r) extends the model behind the image plane (z <= 0);
        // for z > 0 both give the same θ.
        const double theta = std::atan2(rho, p_cam.z());
        if (theta > kFisheyeMaxThetaRad ||
            (!fisheyeSurelyMonotonicUpTo(c, theta) && theta > fisheyeMaxTheta(c)))
            return std::nullopt;
        const double theta_d = fisheyeThetaD(c, theta);
        // OpenCV scales a = X/Z by θ_d/r; for r ~ 0 it uses 1, i.e. the point itself.
        double xd, yd;
        if (p_cam.z() > 0) {
            const double a = p_cam.x() / p_cam.z();
            const double b = p_cam.y() / p_cam.z();
            const double r = std::sqrt(a * a + b * b);
            const double inv_r = r > 1e-8 ? 1.0 / r : 1.0;
            const double cdist = r > 1e-8 ? theta_d * inv_r : 1.0;
            xd = a * cdist;
            yd = b * cdist;
        } else {
            xd = p_cam.x() / rho * theta_d;
            yd = p_cam.y() / rho * theta_d;
        }
        return Eigen::Vector2d(fx * xd + cx, fy * yd + cy);
    }
    if (p_cam.z() <= 0)
        return std::nullopt;
    const Eigen::Vector2d xy(p_cam.x() / p_cam.z(), p_cam.y() / p_cam.z());
    const Eigen::Vector2d d = detail::distortPinhole(pinholeCoefficients(distortion), xy, nullptr);
    return Eigen::Vector2d(fx * d.x() + cx, fy * d.y() + cy);
}

std::optional<Eigen::Vector3d> CameraModel::unproject(const Eigen::Vector2d& pixel) const {
    if (!(fx > 0) || !(fy > 0) || !pixel.allFinite())
        return std::nullopt;
    if (lens == LensModel::kStereographic || lens == LensModel::kSplinedStereographic)
        return unprojectMrcal(*this, pixel);
    const Eigen::Vector2d target((pixel.x() - cx) / fx, (pixel.y() - cy) / fy);
    // Residual tolerance in normalised units, from the pixel tolerance and the larger focal
    // length (the one that magnifies errors most).
    const double tolerance = kResidualTolerancePx / std::max(fx, fy);

    if (lens == LensModel::kFisheye) {
        const FisheyeCoefficients c = fisheyeCoefficients(distortion);
        const double theta_d = target.norm();
        if (theta_d == 0)
            return Eigen::Vector3d(0, 0, 1);
        const std::optional<double> theta =
            solveFisheyeTheta(c, theta_d, fisheyeSearchLimit(c, theta_d), tolerance);
        if (!theta)
            return std::nullopt;
        const double s = std::sin(*theta) / theta_d;
        return Eigen::Vector3d(target.x() * s, target.y() * s, std::cos(*theta));
    }

    if (distortion.empty())
        return Eigen::Vector3d(target.x(), target.y(), 1).normalized();
    const PinholeCoefficients c = pinholeCoefficients(distortion);
    // Damped Newton from the distorted point: it starts close for real lenses, and halving a
    // step that does not reduce the residual keeps it from jumping to the far fold of the
    // polynomial near the image corners.
    Eigen::Vector2d xy = target;
    Eigen::Matrix2d jacobian;
    Eigen::Vector2d residual = detail::distortPinhole(c, xy, &jacobian) - target;
    double residual_norm = residual.norm();
    for (int i = 0; i < kMaxIterations && residual_norm >= tolerance; ++i) {
        const double det = jacobian.determinant();
        if (!std::isfinite(det) || std::abs(det) < 1e-300)
            return std::nullopt;
        const Eigen::Vector2d step = jacobian.inverse() * residual;
        double scale = 1.0;
        bool improved = false;
        for (int halvings = 0; halvings < 30; ++halvings, scale *= 0.5) {
            const Eigen::Vector2d candidate = xy - scale * step;
            Eigen::Matrix2d candidate_jacobian;
            const Eigen::Vector2d candidate_residual =
                detail::distortPinhole(c, candidate, &candidate_jacobian) - target;
            const double candidate_norm = candidate_residual.norm();
            if (std::isfinite(candidate_norm) && candidate_norm < residual_norm) {
                xy = candidate;
                residual = candidate_residual;
                residual_norm = candidate_norm;
                jacobian = candidate_jacobian;
                improved = true;
                break;
            }
        }
        if (!improved)
            break;
    }
    // A root where the distortion map is orientation-reversing lies beyond the fold of the
    // polynomial: it reprojects, but it is not the ray a real lens imaged there.
    if (!(residual_norm < tolerance) || !(jacobian.determinant() > 0))
        return std::nullopt;
    return Eigen::Vector3d(xy.x(), xy.y(), 1).normalized();
}

CameraModel CameraModel::scaled(double scale) const {
    CameraModel out = *this;
    out.width = static_cast<int>(std::lround(width * scale));
    out.height = static_cast<int>(std::lround(height * scale));
    out.fx = fx * scale;
    out.fy = fy * scale;
    // Pixel centres sit at integer coordinates, so the image edge is at -0.5: scale about it.
    out.cx = (cx + 0.5) * scale - 0.5;
    out.cy = (cy + 0.5) * scale - 0.5;
    return out;
}

}  // namespace mixray::calibration
