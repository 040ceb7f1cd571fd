// One-Euro pose smoothing (tracking/src/pose_filter.cpp): jitter drops on a still pose, lag
// stays small on a fast one, and the filter restarts where it must.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include "mixray/tracking/markers.h"

namespace mixray::tracking {
namespace {

using Eigen::Isometry3d;
using Eigen::Vector3d;

constexpr int64_t kFrameNs = 33'333'333;  // 30 Hz

Isometry3d pose(const Vector3d& t, const Vector3d& rotvec) {
    Isometry3d T = Isometry3d::Identity();
    if (rotvec.norm() > 0)
        T.linear() = Eigen::AngleAxisd(rotvec.norm(), rotvec.normalized()).toRotationMatrix();
    T.translation() = t;
    return T;
}

double rotationDeg(const Isometry3d& a, const Isometry3d& b) {
    return Eigen::AngleAxisd(a.linear().transpose() * b.linear()).angle() * 180 / M_PI;
}

TEST(PoseFilter, JitterOfAStillPoseDrops) {
    // A tracked pose at rest with 1 mm and 0.1 degree of noise, as a marker fit gives.
    std::mt19937 rng(7);
    std::normal_distribution<double> mm(0, 1e-3), rad(0, 0.1 * M_PI / 180);
    const Isometry3d still = pose(Vector3d(0.1, -0.2, 0.6), Vector3d(0.3, -0.2, 0.1));
    PoseFilter filter;
    double raw_t = 0, out_t = 0, raw_r = 0, out_r = 0;
    int n = 0;
    for (int i = 0; i < 300; ++i) {
        const Isometry3d raw = still * pose(Vector3d(mm(rng), mm(rng), mm(rng)),
                                            Vector3d(rad(rng), rad(rng), rad(rng)));
        const Isometry3d out = filter.filter(raw, i * kFrameNs);
        if (i < 30)
            continue;  // the first second settles
        raw_t += (raw.translation() - still.translation()).squaredNorm();
        out_t += (out.translation() - still.translation()).squaredNorm();
        raw_r += std::pow(rotationDeg(raw, still), 2);
        out_r += std::pow(rotationDeg(out, still), 2);
        ++n;
    }
    const double ratio_t = std::sqrt(out_t / raw_t), ratio_r = std::sqrt(out_r / raw_r);
    std::printf("One-Euro on a still pose: jitter std ratio translation %.3f, rotation %.3f\n",
                ratio_t, ratio_r);
    EXPECT_LT(ratio_t, 0.6);
    EXPECT_LT(ratio_r, 0.6);
}

TEST(PoseFilter, FastMotionLagsLittle) {
    // 1 m/s along a line while turning at 1 rad/s, noise-free: after the speed estimate has
    // settled the output trails the input by little, where a fixed 1 Hz low-pass trails by
    // 16 cm.
    const SmoothingOptions options;
    PoseFilter filter(options);
    double lag_m = 0, lag_deg = 0;
    for (int i = 0; i <= 45; ++i) {
        const double t = i * kFrameNs * 1e-9;
        const Isometry3d raw = pose(Vector3d(t, 0.5 * t, 0.4), Vector3d(0, 0, t));
        const Isometry3d out = filter.filter(raw, i * kFrameNs);
        lag_m = (out.translation() - raw.translation()).norm();
        lag_deg = rotationDeg(out, raw);
    }
    const double fixed_alpha = 1 / (1 + 1 / (2 * M_PI * options.min_cutoff_hz * kFrameNs * 1e-9));
    const double fixed_lag_m =
        std::hypot(1, 0.5) * kFrameNs * 1e-9 * (1 - fixed_alpha) / fixed_alpha;
    std::printf(
        "One-Euro at 1.1 m/s and 1 rad/s after 1.5 s: lag %.2f mm, %.3f deg (a fixed %.0f Hz "
        "low-pass: %.0f mm)\n",
        1e3 * lag_m, lag_deg, options.min_cutoff_hz, 1e3 * fixed_lag_m);
    EXPECT_LT(lag_m, 0.005);
    EXPECT_LT(lag_m, 0.05 * fixed_lag_m);
    EXPECT_LT(lag_deg, 0.3);
}

TEST(PoseFilter, RestartsOnResetOnOldStampsAndWhenDisabled) {
    PoseFilter filter;
    const Isometry3d a = pose(Vector3d(0, 0, 1), Vector3d::Zero());
    const Isometry3d b = pose(Vector3d(0.5, 0, 1), Vector3d(0, 0.5, 0));
    EXPECT_TRUE(filter.filter(a, 0).isApprox(a));
    EXPECT_FALSE(filter.filter(b, kFrameNs).isApprox(b, 1e-3));  // smoothed towards b
    EXPECT_TRUE(filter.filter(b, kFrameNs).isApprox(b));         // same stamp: restart
    filter.reset();
    EXPECT_TRUE(filter.filter(a, 5 * kFrameNs).isApprox(a));
    SmoothingOptions off;
    off.enabled = false;
    PoseFilter passthrough(off);
    EXPECT_TRUE(passthrough.filter(a, 0).isApprox(a));
    EXPECT_TRUE(passthrough.filter(b, kFrameNs).isApprox(b));
}

}  // namespace
}  // namespace mixray::tracking
