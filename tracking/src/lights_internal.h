// Shared by the light estimators: reading 8-bit colour pixels as sRGB-decoded linear values, and
// the per-pixel geometry of a fish-eye environment camera (computed once, reused per frame).
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "mixray/graph/image.h"
#include "mixray/graph/result.h"
#include "mixray/graph/srgb.h"
#include "mixray/tracking/lights.h"

namespace mixray::tracking::detail {

// kInvalidArgument unless `image` is kRGB8, kBGR8 or kMono8 with data for its size.
Status checkColorImage(const ImageView& image, const char* what);
// The same, and that it is width x height (its camera model's size), naming both otherwise.
Status checkColorImage(const ImageView& image, int width, int height, const char* what);

// The pixel's three code values as R, G, B (mono repeated).
inline std::array<uint8_t, 3> codesAt(const ImageView& image, int x, int y) {
    const uint8_t* row = image.row<uint8_t>(y);
    switch (image.desc.format) {
        case PixelFormat::kBGR8:
            return {row[3 * x + 2], row[3 * x + 1], row[3 * x]};
        case PixelFormat::kMono8:
            return {row[x], row[x], row[x]};
        default:
            return {row[3 * x], row[3 * x + 1], row[3 * x + 2]};
    }
}

// The linear radiance (sRGB decoded) at (x, y) in [0, width − 1] x [0, height − 1], bilinear
// between pixel centres: interpolated in linear light, where averaging light is meaningful.
inline std::array<double, 3> linearRadianceAt(const ImageView& image, double x, double y) {
    const auto& table = srgbToLinearTable();
    const int w = image.desc.width, h = image.desc.height;
    const int x0 = std::min(static_cast<int>(x), w - 1), y0 = std::min(static_cast<int>(y), h - 1);
    const int x1 = std::min(x0 + 1, w - 1), y1 = std::min(y0 + 1, h - 1);
    const double ax = x - x0, ay = y - y0;
    const auto c00 = codesAt(image, x0, y0), c10 = codesAt(image, x1, y0);
    const auto c01 = codesAt(image, x0, y1), c11 = codesAt(image, x1, y1);
    std::array<double, 3> out{};
    for (size_t c = 0; c < 3; ++c)
        out[c] = (1 - ay) * ((1 - ax) * table[c00[c]] + ax * table[c10[c]]) +
                 ay * ((1 - ax) * table[c01[c]] + ax * table[c11[c]]);
    return out;
}

// Rec. 709 luminance weights, applied to linear RGB.
inline double luminance(const Eigen::Vector3d& rgb) {
    return 0.2126 * rgb.x() + 0.7152 * rgb.y() + 0.0722 * rgb.z();
}

// Where every pixel of the environment camera looks (world frame) and the solid angle it covers.
struct FisheyeGeometry {
    int width = 0;
    int height = 0;
    std::vector<Eigen::Vector3f> to_world;  // unit; NaN where the lens model has no ray
    std::vector<float> solid_angle_sr;      // 0 where there is no ray

    static Result<FisheyeGeometry> build(const EnvironmentCamera& camera);
    bool valid(size_t i) const { return solid_angle_sr[i] > 0; }
};

Result<std::vector<EstimatedLight>> environmentLights(const ImageView& env,
                                                      const EnvironmentCamera& camera,
                                                      const FisheyeGeometry& geometry,
                                                      const EnvironmentLightOptions& options);

}  // namespace mixray::tracking::detail
