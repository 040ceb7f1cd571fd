// Lights from the fish-eye environment image (Kán & Kaufmann 2012, §5): threshold, blobs by
// connected components, the biggest blobs as lights, each blob's direction through the lens
// model and the camera's alignment with the world, its intensity the radiance integrated over
// its solid angle.
#include <algorithm>
#include <cmath>
#include <numbers>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <string>
#include <vector>

#include "lights_internal.h"

namespace mixray::tracking {

namespace detail {

Result<FisheyeGeometry> FisheyeGeometry::build(const EnvironmentCamera& camera) {
    MIXRAY_RETURN_IF_ERROR(camera.validate());
    FisheyeGeometry g;
    g.width = camera.model.width;
    g.height = camera.model.height;
    const size_t count = static_cast<size_t>(g.width) * g.height;
    const Eigen::Matrix3f R = camera.T_world_env.linear().cast<float>();
    g.to_world.assign(count, Eigen::Vector3f::Constant(NAN));
    g.solid_angle_sr.assign(count, 0.f);
    std::vector<char> has(count, 0);
    for (int y = 0; y < g.height; ++y)
        for (int x = 0; x < g.width; ++x) {
            const auto d = camera.model.unproject(Eigen::Vector2d(x, y));
            if (!d)
                continue;
            const size_t i = static_cast<size_t>(y) * g.width + x;
            g.to_world[i] = R * d->cast<float>();
            has[i] = 1;
        }
    // A pixel's solid angle from the directions of its neighbours (central differences, one
    // sided at the edge of what the lens sees).
    auto at = [&](int x, int y) { return static_cast<size_t>(y) * g.width + x; };
    for (int y = 0; y < g.height; ++y)
        for (int x = 0; x < g.width; ++x) {
            const size_t i = at(x, y);
            if (!has[i])
                continue;
            const int xl = x > 0 && has[at(x - 1, y)] ? x - 1 : x;
            const int xr = x + 1 < g.width && has[at(x + 1, y)] ? x + 1 : x;
            const int yu = y > 0 && has[at(x, y - 1)] ? y - 1 : y;
            const int yd = y + 1 < g.height && has[at(x, y + 1)] ? y + 1 : y;
            if (xl == xr || yu == yd)
                continue;
            const Eigen::Vector3f dx =
                (g.to_world[at(xr, y)] - g.to_world[at(xl, y)]) / static_cast<float>(xr - xl);
            const Eigen::Vector3f dy =
                (g.to_world[at(x, yd)] - g.to_world[at(x, yu)]) / static_cast<float>(yd - yu);
            g.solid_angle_sr[i] = dx.cross(dy).norm();
        }
    return g;
}

Result<std::vector<EstimatedLight>> environmentLights(const ImageView& env,
                                                      const EnvironmentCamera& camera,
                                                      const FisheyeGeometry& geometry,
                                                      const EnvironmentLightOptions& options) {
    MIXRAY_RETURN_IF_ERROR(options.validate());
    MIXRAY_RETURN_IF_ERROR(checkColorImage(env, "environment image"));
    if (env.desc.width != geometry.width || env.desc.height != geometry.height)
        return Status(ErrorCode::kInvalidArgument,
                      "environment image is " + std::to_string(env.desc.width) + "x" +
                          std::to_string(env.desc.height) + ", the camera model " +
                          std::to_string(geometry.width) + "x" + std::to_string(geometry.height));
    const auto& table = srgbToLinearTable();
    const int w = geometry.width, h = geometry.height;
    cv::Mat mask(h, w, CV_8U, cv::Scalar(0));
    size_t seen = 0, clipped = 0, above = 0;
    double sum = 0, brightest = 0;
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const size_t i = static_cast<size_t>(y) * w + x;
            if (!geometry.valid(i))
                continue;
            const auto c = codesAt(env, x, y);
            const double Y = luminance({table[c[0]], table[c[1]], table[c[2]]});
            ++seen;
            sum += Y;
            brightest = std::max(brightest, Y);
            clipped += std::min({c[0], c[1], c[2]}) >= 250;
            if (Y >= options.threshold) {
                mask.at<uint8_t>(y, x) = 1;
                ++above;
            }
        }
    auto percent = [](double f) { return std::to_string(static_cast<int>(std::lround(100 * f))); };
    if (seen == 0)
        return Status(ErrorCode::kInvalidArgument, "environment camera model sees no pixel");
    const double mean = sum / static_cast<double>(seen);
    const double clipped_fraction = static_cast<double>(clipped) / static_cast<double>(seen);
    const double above_fraction = static_cast<double>(above) / static_cast<double>(seen);
    if (clipped_fraction > options.max_saturated_fraction ||
        above_fraction > options.max_saturated_fraction)
        return Status(ErrorCode::kNotFound,
                      "environment image over-exposed (" +
                          percent(std::max(clipped_fraction, above_fraction)) +
                          "% of it at or above the light threshold)");
    if (mean < options.min_mean)
        return Status(ErrorCode::kNotFound,
                      "environment image black (mean " + std::to_string(mean) + " of full scale)");

    cv::Mat labels, stats, centroids;
    int count = 0;
    try {
        count = cv::connectedComponentsWithStats(mask, labels, stats, centroids, 8, CV_32S);
    } catch (const cv::Exception& e) {
        return Status(ErrorCode::kInternal, std::string("environment blobs: ") + e.what());
    }
    std::vector<int> blobs;
    for (int label = 1; label < count; ++label)
        if (stats.at<int>(label, cv::CC_STAT_AREA) >= options.min_area_px)
            blobs.push_back(label);
    if (blobs.empty())
        return Status(ErrorCode::kNotFound,
                      "environment image featureless: no light (nothing of " +
                          std::to_string(static_cast<int>(options.min_area_px)) +
                          " px or more above " + percent(options.threshold) +
                          "% of full scale; brightest " + percent(brightest) + "%)");
    std::stable_sort(blobs.begin(), blobs.end(), [&](int a, int b) {
        return stats.at<int>(a, cv::CC_STAT_AREA) > stats.at<int>(b, cv::CC_STAT_AREA);
    });
    if (static_cast<int>(blobs.size()) > options.max_lights)
        blobs.resize(static_cast<size_t>(options.max_lights));

    std::vector<EstimatedLight> lights;
    for (int label : blobs) {
        const int x0 = stats.at<int>(label, cv::CC_STAT_LEFT);
        const int y0 = stats.at<int>(label, cv::CC_STAT_TOP);
        const int bw = stats.at<int>(label, cv::CC_STAT_WIDTH);
        const int bh = stats.at<int>(label, cv::CC_STAT_HEIGHT);
        Eigen::Vector3d direction = Eigen::Vector3d::Zero(), energy = Eigen::Vector3d::Zero();
        double solid_angle = 0;
        for (int y = y0; y < y0 + bh; ++y)
            for (int x = x0; x < x0 + bw; ++x) {
                if (labels.at<int>(y, x) != label)
                    continue;
                const size_t i = static_cast<size_t>(y) * w + x;
                const auto c = codesAt(env, x, y);
                const Eigen::Vector3d radiance(table[c[0]], table[c[1]], table[c[2]]);
                const double omega = geometry.solid_angle_sr[i];
                // Radiance-weighted over the sphere, not over pixels: the fish-eye squeezes
                // solid angle towards its rim.
                direction += omega * luminance(radiance) * geometry.to_world[i].cast<double>();
                energy += omega * radiance;
                solid_angle += omega;
            }
        if (direction.norm() <= 0)
            continue;
        EstimatedLight light;
        light.source = LightSource::kEnvironment;
        light.to_light_world = direction.normalized();
        light.intensity = energy * camera.exposure_scale;
        light.angular_radius_rad =
            std::acos(std::clamp(1 - solid_angle / (2 * std::numbers::pi), -1.0, 1.0));
        if (camera.room_radius_m > 0)
            light.position_world =
                camera.T_world_env.translation() + camera.room_radius_m * light.to_light_world;
        light.weight = stats.at<int>(label, cv::CC_STAT_AREA);
        lights.push_back(light);
    }
    return lights;
}

}  // namespace detail

Result<std::vector<EstimatedLight>> estimateEnvironmentLights(
    const ImageView& env, const EnvironmentCamera& camera, const EnvironmentLightOptions& options) {
    MIXRAY_RETURN_IF_ERROR(options.validate());
    MIXRAY_RETURN_IF_ERROR(detail::checkColorImage(env, "environment image"));
    auto geometry = detail::FisheyeGeometry::build(camera);
    if (!geometry)
        return geometry.status();
    return detail::environmentLights(env, camera, *geometry, options);
}

}  // namespace mixray::tracking
