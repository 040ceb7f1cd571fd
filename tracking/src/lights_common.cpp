// Option and input checks of lights.h, and the sRGB decoding every estimator shares.
#include <cmath>
#include <string>

#include "lights_internal.h"

namespace mixray::tracking {

namespace {

Status bad(const std::string& message) {
    return {ErrorCode::kInvalidArgument, message};
}

bool finite(const Eigen::Isometry3d& T) {
    const Eigen::Matrix3d R = T.linear();
    return T.matrix().allFinite() &&
           (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() < 1e-6;
}

}  // namespace

Status LightProbe::validate() const {
    if (!std::isfinite(radius_m) || radius_m <= 0)
        return bad("light probe '" + name + "': radius_m must be > 0");
    if (!centre_world.allFinite())
        return bad("light probe '" + name + "': centre_world must be finite");
    return Status::ok();
}

Status ProbeOptions::validate() const {
    if (sphere_samples < 8 || sphere_samples > 4096)
        return bad("probe options: sphere_samples must be 8 to 4096");
    if (max_lights < 1 || max_lights > 8)
        return bad("probe options: max_lights must be 1 to 8");
    if (!(max_luminance_tolerance >= 0 && max_luminance_tolerance < 1))
        return bad("probe options: max_luminance_tolerance must be in [0, 1)");
    if (!(min_visible_fraction >= 0 && min_visible_fraction <= 1))
        return bad("probe options: min_visible_fraction must be in [0, 1]");
    return Status::ok();
}

Status EnvironmentCamera::validate() const {
    MIXRAY_RETURN_IF_ERROR(model.validate().withContext("environment camera"));
    if (!finite(T_world_env))
        return bad("environment camera: T_world_env must be a finite rigid transform");
    if (!std::isfinite(room_radius_m) || room_radius_m < 0)
        return bad("environment camera: room_radius_m must be >= 0");
    if (!std::isfinite(exposure_scale) || exposure_scale <= 0)
        return bad("environment camera: exposure_scale must be > 0");
    return Status::ok();
}

Status EnvironmentLightOptions::validate() const {
    if (!(threshold > 0 && threshold <= 1))
        return bad("environment light options: threshold must be in (0, 1]");
    if (max_lights < 1 || max_lights > 64)
        return bad("environment light options: max_lights must be 1 to 64");
    if (!(min_area_px >= 0) || !std::isfinite(min_area_px))
        return bad("environment light options: min_area_px must be >= 0");
    if (!(max_saturated_fraction > 0 && max_saturated_fraction <= 1))
        return bad("environment light options: max_saturated_fraction must be in (0, 1]");
    if (!(min_mean >= 0 && min_mean < 1))
        return bad("environment light options: min_mean must be in [0, 1)");
    return Status::ok();
}

namespace detail {

Status checkColorImage(const ImageView& image, const char* what) {
    const PixelFormat f = image.desc.format;
    if (f != PixelFormat::kRGB8 && f != PixelFormat::kBGR8 && f != PixelFormat::kMono8)
        return bad(std::string(what) + ": pixel format " + std::string(toString(f)) +
                   " is not rgb8, bgr8 or mono8");
    const int bytes_per_pixel = f == PixelFormat::kMono8 ? 1 : 3;
    if (image.desc.width <= 0 || image.desc.height <= 0 || image.data == nullptr ||
        image.desc.stride_bytes < image.desc.width * bytes_per_pixel ||
        image.size_bytes < image.desc.bufferBytes())
        return bad(std::string(what) + ": empty or truncated image");
    return Status::ok();
}

Status checkColorImage(const ImageView& image, int width, int height, const char* what) {
    MIXRAY_RETURN_IF_ERROR(checkColorImage(image, what));
    if (image.desc.width != width || image.desc.height != height)
        return bad(std::string(what) + " is " + std::to_string(image.desc.width) + "x" +
                   std::to_string(image.desc.height) + ", the camera model " +
                   std::to_string(width) + "x" + std::to_string(height));
    return Status::ok();
}

}  // namespace detail
}  // namespace mixray::tracking
