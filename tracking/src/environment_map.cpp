// An equirectangular environment map from one fish-eye image, in the renderer's lat-long
// convention (docs/conventions.md): u = 0.5 − atan2(d.y, d.x) / 2π, v = acos(d.z) / π, pixel
// centres at (i + 0.5) / size, world frame +z up. The fish-eye sees the upper hemisphere; the
// lower one is its mirror image (Kán & Kaufmann 2012, §4), as the renderer's
// EnvironmentMap::mirrorUpperIntoLower() does.
#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>
#include <vector>

#include "lights_internal.h"

namespace mixray::tracking {

Result<FloatImage> environmentMapFromFisheye(const ImageView& env, const EnvironmentCamera& camera,
                                             int width) {
    MIXRAY_RETURN_IF_ERROR(camera.validate());
    MIXRAY_RETURN_IF_ERROR(
        detail::checkColorImage(env, camera.model.width, camera.model.height, "environment image"));
    if (width < 16 || width > 8192 || width % 2 != 0)
        return Status(ErrorCode::kInvalidArgument,
                      "environment map width must be even, 16 to 8192");
    FloatImage map;
    map.width = width;
    map.height = width / 2;
    map.channels = 3;
    map.pixels.assign(static_cast<size_t>(map.width) * map.height * 3, 0.f);
    // Rows whose centre is at or above the horizon come from the image (an odd height's middle
    // row lies on it).
    const int upper_rows = (map.height + 1) / 2;
    const Eigen::Matrix3d R_env_world = camera.T_world_env.linear().transpose();
    const int iw = env.desc.width, ih = env.desc.height;
    const float scale = static_cast<float>(camera.exposure_scale);
    std::vector<char> seen(static_cast<size_t>(map.width) * upper_rows, 0);
    for (int y = 0; y < upper_rows; ++y) {
        const double theta = std::numbers::pi * (y + 0.5) / map.height;
        for (int x = 0; x < map.width; ++x) {
            const double phi = (0.5 - (x + 0.5) / map.width) * 2 * std::numbers::pi;
            const Eigen::Vector3d d_world(std::sin(theta) * std::cos(phi),
                                          std::sin(theta) * std::sin(phi), std::cos(theta));
            const auto px = camera.model.project(R_env_world * d_world);
            if (!px || !(px->x() >= 0 && px->y() >= 0 && px->x() <= iw - 1 && px->y() <= ih - 1))
                continue;
            const std::array<double, 3> radiance = detail::linearRadianceAt(env, px->x(), px->y());
            float* out = map.at(x, y);
            for (size_t c = 0; c < 3; ++c)
                out[c] = scale * static_cast<float>(radiance[c]);
            seen[static_cast<size_t>(y) * map.width + x] = 1;
        }
    }
    // Upper directions the lens misses (a tilted camera's low rim) take the nearest seen value
    // in their column: first from above, then, for a column unseen at the top, from below.
    for (int x = 0; x < map.width; ++x) {
        for (int y = 1; y < upper_rows; ++y)
            if (!seen[static_cast<size_t>(y) * map.width + x] &&
                seen[static_cast<size_t>(y - 1) * map.width + x]) {
                std::copy_n(map.at(x, y - 1), 3, map.at(x, y));
                seen[static_cast<size_t>(y) * map.width + x] = 1;
            }
        for (int y = upper_rows - 2; y >= 0; --y)
            if (!seen[static_cast<size_t>(y) * map.width + x] &&
                seen[static_cast<size_t>(y + 1) * map.width + x]) {
                std::copy_n(map.at(x, y + 1), 3, map.at(x, y));
                seen[static_cast<size_t>(y) * map.width + x] = 1;
            }
    }
    for (int y = upper_rows; y < map.height; ++y)
        std::copy_n(map.at(0, map.height - 1 - y), static_cast<size_t>(map.width) * 3,
                    map.at(0, y));
    return map;
}

}  // namespace mixray::tracking
