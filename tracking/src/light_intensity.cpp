// Light intensities from a diffuse probe's shading (light_intensity.h).
#include "mixray/tracking/light_intensity.h"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>

#include "mixray/graph/srgb.h"

namespace mixray::tracking {
namespace {

// Non-negative least squares for a handful of unknowns: solve, drop the most negative
// coefficient, repeat (an active-set method that is exact for the small systems here).
Eigen::VectorXd nonNegativeLeastSquares(const Eigen::MatrixXd& A, const Eigen::VectorXd& b) {
    const Eigen::Index n = A.cols();
    std::vector<bool> active(static_cast<size_t>(n), true);
    Eigen::VectorXd x = Eigen::VectorXd::Zero(n);
    for (Eigen::Index round = 0; round < n; ++round) {
        std::vector<Eigen::Index> columns;
        for (Eigen::Index j = 0; j < n; ++j)
            if (active[static_cast<size_t>(j)])
                columns.push_back(j);
        if (columns.empty())
            break;
        Eigen::MatrixXd sub(A.rows(), static_cast<Eigen::Index>(columns.size()));
        for (size_t k = 0; k < columns.size(); ++k)
            sub.col(static_cast<Eigen::Index>(k)) = A.col(columns[k]);
        const Eigen::VectorXd solved = sub.colPivHouseholderQr().solve(b);
        Eigen::Index worst = -1;
        double worst_value = 0;
        for (size_t k = 0; k < columns.size(); ++k) {
            if (solved[static_cast<Eigen::Index>(k)] < worst_value) {
                worst_value = solved[static_cast<Eigen::Index>(k)];
                worst = columns[k];
            }
        }
        if (worst < 0) {
            x.setZero();
            for (size_t k = 0; k < columns.size(); ++k)
                x[columns[k]] = solved[static_cast<Eigen::Index>(k)];
            return x;
        }
        active[static_cast<size_t>(worst)] = false;
    }
    return x;
}

}  // namespace

Status IntensityFitOptions::validate() const {
    const auto bad = [](const std::string& what) {
        return Status(ErrorCode::kInvalidArgument, "intensity fit options: " + what);
    };
    if (!(albedo > 0 && albedo <= 1))
        return bad("albedo must be in (0, 1]");
    if (max_samples < 16)
        return bad("max_samples must be at least 16");
    if (!(edge_margin_px >= 0 && edge_margin_px < 1e4))
        return bad("edge_margin_px must be 0 or more");
    if (saturated_code < 1 || saturated_code > 256)
        return bad("saturated_code must be 1 to 256");
    return Status::ok();
}

Result<IntensityFit> fitLightIntensities(const ImageView& color,
                                         const calibration::CameraModel& camera,
                                         const Eigen::Isometry3d& T_world_camera,
                                         const LightProbe& probe,
                                         const std::vector<Eigen::Vector3d>& to_light_world,
                                         const IntensityFitOptions& options) {
    MIXRAY_RETURN_IF_ERROR(options.validate());
    MIXRAY_RETURN_IF_ERROR(camera.validate());
    MIXRAY_RETURN_IF_ERROR(probe.validate());
    const PixelFormat format = color.desc.format;
    if (format != PixelFormat::kRGB8 && format != PixelFormat::kBGR8)
        return Status(ErrorCode::kInvalidArgument, "intensity fit: needs an rgb8 or bgr8 image");
    if (!color.data || color.size_bytes < static_cast<size_t>(color.desc.stride_bytes) *
                                              static_cast<size_t>(color.desc.height))
        return Status(ErrorCode::kInvalidArgument, "intensity fit: an empty or truncated image");
    if (color.desc.width != camera.width || color.desc.height != camera.height)
        return Status(ErrorCode::kInvalidArgument,
                      "intensity fit: the image size differs from the camera model's");
    if (to_light_world.empty())
        return Status(ErrorCode::kInvalidArgument, "intensity fit: no light directions");
    for (const Eigen::Vector3d& l : to_light_world)
        if (!l.allFinite() || l.norm() < 1e-9)
            return Status(ErrorCode::kInvalidArgument, "intensity fit: a zero light direction");

    // The probe's bounding box in the image: project points on its silhouette.
    const Eigen::Isometry3d T_camera_world = T_world_camera.inverse();
    const Eigen::Vector3d c_cam = T_camera_world * probe.centre_world;
    const double distance = c_cam.norm();
    if (!(c_cam.z() > probe.radius_m && distance > probe.radius_m * 1.01))
        return Status(ErrorCode::kNotFound,
                      "probe " + probe.name + " is not in front of the camera");
    const Eigen::Vector3d axis = c_cam / distance;
    const Eigen::Vector3d u = axis.unitOrthogonal();
    const Eigen::Vector3d v = axis.cross(u);
    double x0 = 1e18, y0 = 1e18, x1 = -1e18, y1 = -1e18;
    for (int k = 0; k < 64; ++k) {
        const double a = 2 * std::numbers::pi * k / 64;
        const Eigen::Vector3d rim = c_cam + probe.radius_m * (std::cos(a) * u + std::sin(a) * v);
        const auto px = camera.project(rim);
        if (!px)
            return Status(ErrorCode::kNotFound, "probe " + probe.name + " is out of view");
        x0 = std::min(x0, px->x());
        y0 = std::min(y0, px->y());
        x1 = std::max(x1, px->x());
        y1 = std::max(y1, px->y());
    }
    const int ix0 = std::max(0, static_cast<int>(std::floor(x0)));
    const int iy0 = std::max(0, static_cast<int>(std::floor(y0)));
    const int ix1 = std::min(camera.width - 1, static_cast<int>(std::ceil(x1)));
    const int iy1 = std::min(camera.height - 1, static_cast<int>(std::ceil(y1)));
    if (ix0 > ix1 || iy0 > iy1)
        return Status(ErrorCode::kNotFound, "probe " + probe.name + " is out of view");
    const long area = static_cast<long>(ix1 - ix0 + 1) * (iy1 - iy0 + 1);
    const int step =
        std::max(1, static_cast<int>(std::sqrt(static_cast<double>(area) / options.max_samples)));

    std::vector<Eigen::Vector3d> lights_cam;
    for (const Eigen::Vector3d& l : to_light_world)
        lights_cam.push_back((T_camera_world.linear() * l).normalized());
    const Eigen::Index unknowns =
        static_cast<Eigen::Index>(lights_cam.size()) + (options.ambient ? 1 : 0);
    std::vector<Eigen::VectorXd> shading;
    std::vector<Eigen::Vector3d> values;
    const int channel_r = format == PixelFormat::kRGB8 ? 0 : 2;
    const double r2 = probe.radius_m * probe.radius_m;
    const double margin_m = options.edge_margin_px * distance / std::max(camera.fx, camera.fy);
    for (int y = iy0; y <= iy1; y += step) {
        const uint8_t* row = color.row<uint8_t>(y);
        for (int x = ix0; x <= ix1; x += step) {
            const auto ray = camera.unproject(Eigen::Vector2d(x, y));
            if (!ray)
                continue;
            // Ray-sphere intersection in the camera frame; keep pixels clear of the outline.
            const double b = ray->dot(c_cam);
            const double disc = b * b - (c_cam.squaredNorm() - r2);
            if (disc <= 0)
                continue;
            const double miss = std::sqrt(std::max(0.0, c_cam.squaredNorm() - b * b));
            if (miss > probe.radius_m - margin_m)
                continue;
            const Eigen::Vector3d p = (b - std::sqrt(disc)) * *ray;
            const Eigen::Vector3d n = (p - c_cam) / probe.radius_m;
            const uint8_t* px = row + static_cast<size_t>(x) * 3;
            const int r = px[channel_r], g = px[1], bl = px[2 - channel_r];
            if (r >= options.saturated_code || g >= options.saturated_code ||
                bl >= options.saturated_code)
                continue;
            Eigen::VectorXd terms(unknowns);
            for (size_t k = 0; k < lights_cam.size(); ++k)
                terms[static_cast<Eigen::Index>(k)] =
                    options.albedo / std::numbers::pi * std::max(0.0, n.dot(lights_cam[k]));
            if (options.ambient)
                terms[unknowns - 1] = options.albedo;
            shading.push_back(std::move(terms));
            const auto& linear = srgbToLinearTable();
            values.emplace_back(linear[static_cast<size_t>(r)], linear[static_cast<size_t>(g)],
                                linear[static_cast<size_t>(bl)]);
        }
    }
    if (static_cast<Eigen::Index>(shading.size()) < 4 * unknowns + 8)
        return Status(ErrorCode::kNotFound, "probe " + probe.name +
                                                " shows too few unclipped pixels (" +
                                                std::to_string(shading.size()) + ")");
    const Eigen::Index m = static_cast<Eigen::Index>(shading.size());
    Eigen::MatrixXd A(m, unknowns);
    for (Eigen::Index i = 0; i < m; ++i)
        A.row(i) = shading[static_cast<size_t>(i)].transpose();
    IntensityFit fit;
    fit.samples = static_cast<int>(m);
    fit.irradiance.assign(lights_cam.size(), Eigen::Vector3d::Zero());
    double squared = 0;
    for (int c = 0; c < 3; ++c) {
        Eigen::VectorXd b(m);
        for (Eigen::Index i = 0; i < m; ++i)
            b[i] = values[static_cast<size_t>(i)][c];
        const Eigen::VectorXd x = nonNegativeLeastSquares(A, b);
        for (size_t k = 0; k < lights_cam.size(); ++k)
            fit.irradiance[k][c] = x[static_cast<Eigen::Index>(k)];
        if (options.ambient)
            fit.ambient[c] = x[unknowns - 1];
        squared += (A * x - b).squaredNorm();
    }
    fit.rms = std::sqrt(squared / static_cast<double>(3 * m));
    return fit;
}

}  // namespace mixray::tracking
