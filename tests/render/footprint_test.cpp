// The screen footprint's geometric tests: the tapered-segment shadow test against a walk along
// the segment, and tile cones that hold every ray of their tile.
#include "footprint.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "optics.h"

namespace mixray::render::test {
namespace {

// The footprint's shadow test against brute force: a dense walk along the segment.
TEST(Footprint, TaperedSegmentTestMatchesAWalkAlongTheSegment) {
    optics::Rng rng(7);
    const auto u = [&] { return rng.uniform() * 2 - 1; };
    int near = 0, far = 0;
    for (int i = 0; i < 2000; ++i) {
        const Eigen::Vector3f a(u(), u(), u());
        const Eigen::Vector3f dir = Eigen::Vector3f(u(), u(), u()).normalized();
        const float length = 0.4f + rng.uniform();
        // Centres around the segment and beyond its ends; tolerances that widen or narrow by
        // less than the length (steeper tapers are answered "near" without looking).
        const Eigen::Vector3f c = a + (1.4f * rng.uniform() - 0.2f) * length * dir +
                                  0.4f * Eigen::Vector3f(u(), u(), u());
        const float tol_a = 0.3f * rng.uniform(), tol_b = 0.3f * rng.uniform();
        float slack = std::numeric_limits<float>::infinity();  // min of distance − tolerance
        for (int k = 0; k <= 20000; ++k) {
            const float t = length * static_cast<float>(k) / 20000;
            slack =
                std::min(slack, (a + t * dir - c).norm() - (tol_a + (tol_b - tol_a) * t / length));
        }
        if (std::abs(slack) < 1e-4f)
            continue;  // too close to call with a finite walk
        EXPECT_EQ(detail::nearTaperedSegment(c, a, dir, length, tol_a, tol_b), slack < 0) << i;
        (slack < 0 ? near : far) += 1;
    }
    EXPECT_GT(near, 100);
    EXPECT_GT(far, 100);
}

TEST(Footprint, TileConesHoldEveryRayOfTheirTile) {
    auto camera = calibration::CameraModel::pinhole(50, 30, 40, 40, 24.5, 14.5);
    camera.distortion = {-0.2, 0.05, 0, 0};
    const int samples = 4, tile = 8;
    std::vector<Eigen::Vector3f> directions(static_cast<size_t>(50 * 30 * samples));
    optics::Rng rng(3);
    for (int y = 0; y < 30; ++y)
        for (int x = 0; x < 50; ++x)
            for (int k = 0; k < samples; ++k) {
                const auto d = camera.unproject({x + rng.uniform() - 0.5, y + rng.uniform() - 0.5});
                ASSERT_TRUE(d);
                directions[static_cast<size_t>((y * 50 + x) * samples + k)] = d->cast<float>();
            }
    const auto cones = detail::tileCones(camera, directions, samples, tile);
    ASSERT_EQ(cones.size(), 7u * 4u);
    for (int y = 0; y < 30; ++y)
        for (int x = 0; x < 50; ++x) {
            const auto& cone = cones[static_cast<size_t>((y / tile) * 7 + x / tile)];
            EXPECT_FALSE(cone.has_corners);  // distorted: no corner shortcut
            for (int k = 0; k < samples; ++k) {
                const Eigen::Vector3f& d =
                    directions[static_cast<size_t>((y * 50 + x) * samples + k)];
                EXPECT_LE(std::acos(std::min(1.f, cone.axis.dot(d))), cone.half_angle);
            }
        }
    // An undistorted camera's tiles get corners spanning their rays.
    camera.distortion.clear();
    const auto pinhole = detail::tileCones(camera, directions, samples, tile);
    EXPECT_TRUE(pinhole[0].has_corners);
    EXPECT_FLOAT_EQ(pinhole[0].corners[0].x(), (-0.5f - 24.5f) / 40);
    EXPECT_FLOAT_EQ(pinhole[0].corners[3].y(), (7.5f - 14.5f) / 40);
}

}  // namespace
}  // namespace mixray::render::test
