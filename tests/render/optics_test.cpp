// Closed-form optics of the integrator against the textbook formulas.
#include "optics.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstring>
#include <limits>

namespace mixray::render::optics {
namespace {

TEST(Optics, FresnelAtNormalIncidenceIsSquaredIndexRatio) {
    for (float n : {1.33f, 1.5f, 2.4f}) {
        const float expected = ((n - 1) / (n + 1)) * ((n - 1) / (n + 1));
        EXPECT_NEAR(dielectricReflectance(1.f, 1.f, n), expected, 1e-6f);
        EXPECT_NEAR(dielectricReflectance(1.f, n, 1.f), expected, 1e-6f);  // leaving the glass
    }
    EXPECT_NEAR(fresnelR0(1.f, 1.5f), 0.04f, 1e-6f);
}

TEST(Optics, FresnelTendsToOneAtGrazingIncidence) {
    EXPECT_NEAR(dielectricReflectance(0.f, 1.f, 1.5f), 1.f, 1e-6f);
    EXPECT_GT(dielectricReflectance(0.05f, 1.f, 1.5f), 0.7f);
    // Monotonic from normal to grazing.
    float previous = 0;
    for (float c = 1.f; c >= 0.f; c -= 0.05f) {
        const float r = dielectricReflectance(c, 1.f, 1.5f);
        EXPECT_GE(r, previous - 1e-6f);
        previous = r;
    }
}

TEST(Optics, RefractionFollowsSnell) {
    const Eigen::Vector3f n(0, 0, 1);
    for (float deg : {0.f, 10.f, 30.f, 60.f, 85.f}) {
        const float theta = deg * kPi / 180;
        const Eigen::Vector3f d(std::sin(theta), 0, -std::cos(theta));
        const auto t = refract(d, n, 1.f / 1.5f);
        ASSERT_TRUE(t.has_value());
        EXPECT_NEAR(t->norm(), 1.f, 1e-6f);
        EXPECT_NEAR(t->x(), std::sin(theta) / 1.5f, 1e-6f);  // sin θt = sin θi / n
        EXPECT_LT(t->z(), 0);
    }
}

TEST(Optics, TotalInternalReflectionBeyondTheCriticalAngle) {
    const float critical = std::asin(1.f / 1.5f);
    const Eigen::Vector3f n(0, 0, -1);  // inside the glass, facing the ray
    const auto direction = [](float theta) {
        return Eigen::Vector3f(std::sin(theta), 0, std::cos(theta));
    };
    EXPECT_TRUE(refract(direction(critical - 0.01f), n, 1.5f).has_value());
    EXPECT_FALSE(refract(direction(critical + 0.01f), n, 1.5f).has_value());
    EXPECT_EQ(dielectricReflectance(std::cos(critical + 0.01f), 1.5f, 1.f), 1.f);
    EXPECT_LT(dielectricReflectance(std::cos(critical - 0.2f), 1.5f, 1.f), 0.5f);
}

TEST(Optics, GlassSlabShiftsARayByTheAnalyticLateralOffset) {
    // Through a slab of thickness t: the ray leaves parallel, shifted by
    // t·sin(θ − θt)/cos θt perpendicular to itself.
    const float t = 0.02f, ior = 1.5f;
    for (float deg : {15.f, 40.f, 70.f}) {
        const float theta = deg * kPi / 180;
        const Eigen::Vector3f d(std::sin(theta), 0, -std::cos(theta));
        const Eigen::Vector3f entry(0, 0, 0);
        const auto inside = refract(d, {0, 0, 1}, 1.f / ior);
        ASSERT_TRUE(inside);
        const Eigen::Vector3f exit_point = entry + (t / -inside->z()) * *inside;
        const auto out = refract(*inside, {0, 0, 1}, ior);
        ASSERT_TRUE(out);
        EXPECT_NEAR((*out - d).norm(), 0.f, 1e-5f);
        const Eigen::Vector3f straight = entry + (t / std::cos(theta)) * d;
        const float offset = (exit_point - straight).cross(d).norm();
        const float theta_t = std::asin(std::sin(theta) / ior);
        EXPECT_NEAR(offset, t * std::sin(theta - theta_t) / std::cos(theta_t), 1e-6f);
    }
}

TEST(Optics, SrgbRoundTripsEveryByte) {
    for (int i = 0; i < 256; ++i)
        EXPECT_EQ(encodeSrgb8(srgbToLinear(i / 255.f)), i);
}

// The table encoder gives the formula's byte: at every code's threshold and the floats either
// side of it, through (0, 1] in steps of 4099 floats, and outside [0, 1].
TEST(Optics, SrgbEncoderGivesTheFormulasByteForEveryFloat) {
    const auto bits = [](float v) {
        uint32_t b;
        std::memcpy(&b, &v, sizeof b);
        return b;
    };
    const auto value = [](uint32_t b) {
        float v;
        std::memcpy(&v, &b, sizeof v);
        return v;
    };
    int checked = 0;
    for (uint32_t b = 0; b <= bits(1.f); b += 4099, ++checked)
        ASSERT_EQ(encodeSrgb8(value(b)), encodeSrgb8ByFormula(value(b))) << value(b);
    for (int code = 1; code < 256; ++code) {
        const float at = srgbToLinear((code - 0.5f) / 255.f);
        for (uint32_t b = bits(at) - 64; b <= bits(at) + 64; ++b, ++checked)
            ASSERT_EQ(encodeSrgb8(value(b)), encodeSrgb8ByFormula(value(b))) << value(b);
    }
    for (float v : {-1.f, -0.f, 0.f, 1.f, 1.5f, 1e30f, std::numeric_limits<float>::infinity(),
                    -std::numeric_limits<float>::infinity(), std::numeric_limits<float>::min(),
                    std::numeric_limits<float>::denorm_min()})
        EXPECT_EQ(encodeSrgb8(v), encodeSrgb8ByFormula(v)) << v;
    EXPECT_GT(checked, 250000);
}

TEST(Optics, DiscSamplesCoverTheDiscEvenly) {
    const int n = 400;
    int inner = 0;
    Eigen::Vector2f mean = Eigen::Vector2f::Zero();
    for (int k = 0; k < n; ++k) {
        const Eigen::Vector2f q = discSample(k, n, 0.5f, 0.3f);
        EXPECT_LE(q.norm(), 1.f + 1e-6f);
        inner += q.norm() < std::sqrt(0.5f) ? 1 : 0;
        mean += q / n;
    }
    EXPECT_EQ(inner, n / 2);  // half the area inside radius sqrt(1/2)
    EXPECT_LT(mean.norm(), 0.02f);
}

}  // namespace
}  // namespace mixray::render::optics
