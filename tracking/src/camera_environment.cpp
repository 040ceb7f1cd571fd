// The environment from the camera's own frames (camera_environment.h).
#include "mixray/tracking/camera_environment.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>

#include "lights_internal.h"

namespace mixray::tracking {

Status CameraEnvironmentOptions::validate() const {
    if (width < 16 || width > 8192 || width % 2 != 0)
        return Status(ErrorCode::kInvalidArgument,
                      "camera environment: width must be even, 16 to 8192");
    if (!(radius_m >= 0) || !std::isfinite(radius_m))
        return Status(ErrorCode::kInvalidArgument,
                      "camera environment: radius_m must be finite and >= 0 (0: at infinity)");
    if (!centre.allFinite())
        return Status(ErrorCode::kInvalidArgument, "camera environment: centre must be finite");
    return Status::ok();
}

CameraEnvironment::CameraEnvironment(const CameraEnvironmentOptions& options)
    : options_(options), width_(options.width) {
    const int h = height();
    directions_.resize(static_cast<size_t>(width_) * h);
    // Texel centres: u = 0.5 − atan2(d.y, d.x)/2π, v = acos(d.z)/π (lights.h).
    for (int y = 0; y < h; ++y) {
        const double theta = std::numbers::pi * (y + 0.5) / h;
        for (int x = 0; x < width_; ++x) {
            const double phi = (0.5 - (x + 0.5) / width_) * 2 * std::numbers::pi;
            directions_[static_cast<size_t>(y) * width_ + x] = Eigen::Vector3d(
                std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta));
        }
    }
    sum_.assign(directions_.size() * 3, 0.0);
    weight_.assign(directions_.size(), 0.0);
}

Result<CameraEnvironment> CameraEnvironment::create(const CameraEnvironmentOptions& options) {
    MIXRAY_RETURN_IF_ERROR(options.validate());
    return CameraEnvironment(options);
}

Status CameraEnvironment::add(const ImageView& color, const calibration::CameraModel& camera,
                              const Eigen::Isometry3d& T_world_cam) {
    MIXRAY_RETURN_IF_ERROR(detail::checkColorImage(color, camera.width, camera.height,
                                                   "camera environment: the colour image"));
    if (!T_world_cam.matrix().allFinite() ||
        !T_world_cam.linear().isUnitary(1e-6))  // a rotation: its inverse is its transpose
        return Status(ErrorCode::kInvalidArgument,
                      "camera environment: the pose must be a finite rigid transform");
    const Eigen::Matrix3d R_cam_world = T_world_cam.linear().transpose();
    const Eigen::Vector3d t_cam_world = -(R_cam_world * T_world_cam.translation());
    const int iw = camera.width, ih = camera.height;
    for (size_t i = 0; i < directions_.size(); ++i) {
        const Eigen::Vector3d p_cam =
            options_.radius_m > 0
                ? Eigen::Vector3d(R_cam_world *
                                      (options_.centre + options_.radius_m * directions_[i]) +
                                  t_cam_world)
                : Eigen::Vector3d(R_cam_world * directions_[i]);
        if (!(p_cam.z() > 0))
            continue;
        const auto px = camera.project(p_cam);
        if (!px || !(px->x() >= 0 && px->y() >= 0 && px->x() <= iw - 1 && px->y() <= ih - 1))
            continue;
        const std::array<double, 3> radiance = detail::linearRadianceAt(color, px->x(), px->y());
        for (size_t c = 0; c < 3; ++c)
            sum_[3 * i + c] += radiance[c];
        weight_[i] += 1;
    }
    ++frames_;
    return Status::ok();
}

FloatImage CameraEnvironment::map() const {
    // One pyramid level: each texel's radiance sum and weight.
    struct Level {
        int w = 0, h = 0;
        std::vector<double> sum, weight;
    };
    std::vector<Level> levels(1);
    levels[0] = {width_, height(), sum_, weight_};
    while (levels.back().w > 1 || levels.back().h > 1) {
        const Level& fine = levels.back();
        Level coarse;
        coarse.w = (fine.w + 1) / 2;
        coarse.h = (fine.h + 1) / 2;
        coarse.sum.assign(static_cast<size_t>(coarse.w) * coarse.h * 3, 0.0);
        coarse.weight.assign(static_cast<size_t>(coarse.w) * coarse.h, 0.0);
        for (int y = 0; y < fine.h; ++y)
            for (int x = 0; x < fine.w; ++x) {
                const size_t f = static_cast<size_t>(y) * fine.w + x;
                const size_t c = static_cast<size_t>(y / 2) * coarse.w + x / 2;
                coarse.weight[c] += fine.weight[f];
                for (size_t k = 0; k < 3; ++k)
                    coarse.sum[3 * c + k] += fine.sum[3 * f + k];
            }
        levels.push_back(std::move(coarse));
    }
    // Pull: from the top down, each level's seen texels keep their mean and the others take
    // the level above's (already filled) means, bilinear between its texel centres.
    std::vector<double> above;  // the filled means of the level above, 3 per texel
    for (size_t l = levels.size(); l-- > 0;) {
        const Level& level = levels[l];
        std::vector<double> mean(static_cast<size_t>(level.w) * level.h * 3, 0.0);
        const int aw = l + 1 < levels.size() ? levels[l + 1].w : 0;
        const int ah = l + 1 < levels.size() ? levels[l + 1].h : 0;
        for (int y = 0; y < level.h; ++y)
            for (int x = 0; x < level.w; ++x) {
                const size_t i = static_cast<size_t>(y) * level.w + x;
                if (level.weight[i] > 0) {
                    for (size_t k = 0; k < 3; ++k)
                        mean[3 * i + k] = level.sum[3 * i + k] / level.weight[i];
                    continue;
                }
                if (above.empty())
                    continue;
                // Texel (x, y)'s centre in the level above's texel coordinates.
                const double u = std::clamp((x + 0.5) / 2 - 0.5, 0.0, aw - 1.0);
                const double v = std::clamp((y + 0.5) / 2 - 0.5, 0.0, ah - 1.0);
                const int u0 = static_cast<int>(u), v0 = static_cast<int>(v);
                const int u1 = std::min(u0 + 1, aw - 1), v1 = std::min(v0 + 1, ah - 1);
                const double fu = u - u0, fv = v - v0;
                for (size_t k = 0; k < 3; ++k) {
                    const auto at = [&](int uu, int vv) {
                        return above[3 * (static_cast<size_t>(vv) * aw + uu) + k];
                    };
                    mean[3 * i + k] = (1 - fv) * ((1 - fu) * at(u0, v0) + fu * at(u1, v0)) +
                                      fv * ((1 - fu) * at(u0, v1) + fu * at(u1, v1));
                }
            }
        above = std::move(mean);
    }
    FloatImage out;
    out.width = width_;
    out.height = height();
    out.channels = 3;
    out.pixels.resize(above.size());
    std::transform(above.begin(), above.end(), out.pixels.begin(),
                   [](double v) { return static_cast<float>(v); });
    return out;
}

double CameraEnvironment::coverage() const {
    // Texels of row y cover sin θ of the sphere's solid angle, in proportion.
    double seen_area = 0, total = 0;
    const int h = height();
    for (int y = 0; y < h; ++y) {
        const double area = std::sin(std::numbers::pi * (y + 0.5) / h);
        for (int x = 0; x < width_; ++x) {
            total += area;
            if (weight_[static_cast<size_t>(y) * width_ + x] > 0)
                seen_area += area;
        }
    }
    return total > 0 ? seen_area / total : 0;
}

}  // namespace mixray::tracking
