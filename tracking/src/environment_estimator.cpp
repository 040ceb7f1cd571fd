// EnvironmentEstimator: environment lights and map from one fish-eye image after another.
#include <memory>
#include <optional>
#include <string>

#include "lights_internal.h"

namespace mixray::tracking {

struct EnvironmentEstimator::Geometry {
    Result<detail::FisheyeGeometry> fisheye;
};

EnvironmentEstimator::EnvironmentEstimator(EnvironmentCamera camera,
                                           EnvironmentLightOptions options, int map_width)
    : camera_(std::move(camera)), options_(options), map_width_(map_width) {}

EnvironmentEstimator::~EnvironmentEstimator() = default;

const Estimate<EnvironmentEstimate>& EnvironmentEstimator::estimate(const ImageView& env,
                                                                    int64_t stamp_ns) {
    if (const Status ok = detail::checkColorImage(env, "environment image"); !ok) {
        latest_.keep(ok.message(), stamp_ns);
        return latest_;
    }
    if (!geometry_)
        geometry_ = std::make_unique<Geometry>(Geometry{detail::FisheyeGeometry::build(camera_)});
    if (!geometry_->fisheye) {
        latest_.keep(geometry_->fisheye.status().message(), stamp_ns);
        return latest_;
    }
    auto lights = detail::environmentLights(env, camera_, *geometry_->fisheye, options_);
    if (!lights) {
        latest_.keep(lights.status().message(), stamp_ns);
        return latest_;
    }
    auto map = environmentMapFromFisheye(env, camera_, map_width_);
    if (!map) {
        latest_.keep(map.status().message(), stamp_ns);
        return latest_;
    }
    latest_.update(
        {std::move(lights).value(), std::make_shared<const FloatImage>(std::move(map).value())},
        stamp_ns);
    return latest_;
}

}  // namespace mixray::tracking
