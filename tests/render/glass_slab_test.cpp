// A virtual glass slab in front of a real wall: the wall seen through it (Kán & Kaufmann's
// reprojection of the refracted ray's hit into the camera image) is shifted by the lateral offset
// that Snell's law predicts for each pixel's ray. The expectation is traced here in closed form,
// independently of the renderer's optics code.
#include <gtest/gtest.h>

#include <cmath>
#include <optional>

#include "mixray/render/renderer.h"
#include "renderer_test_util.h"

namespace mixray::render::test {
namespace {

using calibration::CameraModel;
using Eigen::Vector3d;

constexpr int kW = 160, kH = 120;
constexpr double kFocal = 200;
constexpr int kFirstBrightColumn = 80;  // the camera image steps from dark to bright here
constexpr double kIor = 1.5;
constexpr double kThickness = 0.3;
constexpr double kSlabYaw = M_PI / 4;  // about world z: the slab is hit at 45°
const Vector3d kCamera(0, 0, 0.5);
const Vector3d kSlabCentre(0, 1, 0.5);
constexpr double kWallY = 2;

// Snell's law for unit d and a unit normal n facing against d; nullopt beyond the critical angle.
std::optional<Vector3d> snell(const Vector3d& d, const Vector3d& n, double eta) {
    const double cos_i = -n.dot(d);
    const double k = 1 - eta * eta * (1 - cos_i * cos_i);
    if (k < 0)
        return std::nullopt;
    return (eta * d + (eta * cos_i - std::sqrt(k)) * n).normalized();
}

// Where the ray from the camera along d meets the wall after passing through the slab's two
// faces (planes through kSlabCentre ± kThickness/2 along the slab normal).
std::optional<Vector3d> wallPointThroughSlab(const Vector3d& d) {
    const Vector3d normal =
        Eigen::AngleAxisd(kSlabYaw, Vector3d::UnitZ()) * Vector3d::UnitY();  // towards +y
    const auto meetPlane = [&](const Vector3d& o, const Vector3d& dir, double offset) {
        const Vector3d q = kSlabCentre + offset * normal;
        return o + (normal.dot(q - o) / normal.dot(dir)) * dir;
    };
    const Vector3d entry = meetPlane(kCamera, d, -kThickness / 2);
    const auto inside = snell(d, -normal, 1 / kIor);
    if (!inside)
        return std::nullopt;
    const Vector3d exit = meetPlane(entry, *inside, kThickness / 2);
    const auto out = snell(*inside, -normal, kIor);
    if (!out)
        return std::nullopt;
    return exit + ((kWallY - exit.y()) / out->y()) * *out;
}

// The continuous image column at which the ray through (u, v) sees the wall.
double seenColumn(const CameraModel& model, const Eigen::Isometry3d& T_world_cam, double u,
                  double v) {
    const Vector3d d = (T_world_cam.linear() * *model.unproject({u, v})).normalized();
    const auto q = wallPointThroughSlab(d);
    EXPECT_TRUE(q);
    const auto pixel = model.project(T_world_cam.inverse() * *q);
    EXPECT_TRUE(pixel);
    return pixel ? pixel->x() : 0;
}

TEST(Renderer, GlassSlabShiftsTheRealWallByTheAnalyticLateralOffset) {
    SceneDescription scene;
    scene.materials["wall"] = material(MaterialType::kDiffuse, "wall");
    SceneObject wall =
        object("wall", ObjectRole::kGhost, ShapeType::kPlane, "wall", {0, kWallY, 0.5});
    wall.T_anchor_object.rotate(Eigen::AngleAxisd(M_PI / 2, Vector3d::UnitX()));
    wall.shape.size = {10, 4, 0};
    scene.objects.push_back(wall);
    Material glass = material(MaterialType::kGlass, "glass");
    glass.ior = Rgb::Constant(static_cast<float>(kIor));
    glass.transmission = Rgb::Ones();
    scene.materials["glass"] = glass;
    SceneObject slab = object("slab", ObjectRole::kVirtual, ShapeType::kBox, "glass", kSlabCentre);
    slab.T_anchor_object.rotate(Eigen::AngleAxisd(kSlabYaw, Vector3d::UnitZ()));
    slab.shape.size = {1.6f, static_cast<float>(kThickness), 0.8f};
    scene.objects.push_back(slab);

    RenderOptions options;
    options.max_depth = 4;
    auto created = Renderer::create(scene, options);
    ASSERT_TRUE(created.isOk()) << created.status().toString();
    const Image step = filledImage(kW, kH, [](int x, int) {
        const uint8_t v = x < kFirstBrightColumn ? 30 : 220;
        return std::array<uint8_t, 3>{v, v, v};
    });
    RenderInputs inputs;
    inputs.camera = CameraModel::pinhole(kW, kH, kFocal, kFocal, (kW - 1) / 2.0, (kH - 1) / 2.0);
    inputs.camera_image = step.view();
    inputs.T_world_cam = lookAlongY(kCamera);
    RenderLayers out;
    ASSERT_TRUE((*created)->render(inputs, out));

    // The camera image's edge (bilinear in linear light) is half-way at column 79.5; through the
    // slab it shows where the refracted ray sees that column. Solve seenColumn(u) = 79.5 by
    // bisection and find the measured half-way crossing in the composite, row by row.
    const double edge = kFirstBrightColumn - 0.5;
    for (int v = kH / 2 - 20; v <= kH / 2 + 20; v += 10) {
        double lo = 20, hi = kW - 21;
        ASSERT_LT(seenColumn(inputs.camera, inputs.T_world_cam, lo, v), edge);
        ASSERT_GT(seenColumn(inputs.camera, inputs.T_world_cam, hi, v), edge);
        for (int i = 0; i < 60; ++i) {
            const double mid = (lo + hi) / 2;
            (seenColumn(inputs.camera, inputs.T_world_cam, mid, v) < edge ? lo : hi) = mid;
        }
        const double expected = (lo + hi) / 2;
        // The shift is several pixels, so finding the edge unshifted would fail.
        ASSERT_GT(std::abs(expected - edge), 3.0) << "row " << v;

        const float dark = pixelLinear(out.composite, 25, v).x();
        const float bright = pixelLinear(out.composite, kW - 26, v).x();
        ASSERT_GT(bright, 5 * dark) << "row " << v;
        const float half = (dark + bright) / 2;
        std::optional<double> measured;
        for (int x = 20; x + 1 < kW - 20 && !measured; ++x) {
            const float a = pixelLinear(out.composite, x, v).x();
            const float b = pixelLinear(out.composite, x + 1, v).x();
            if (a < half && b >= half)
                measured = x + (half - a) / (b - a);
        }
        ASSERT_TRUE(measured) << "row " << v;
        // A fifth of a pixel covers the 8-bit output's rounding near the crossing (measured
        // bias about 0.08 px); an IOR off by 0.05 moves the edge by about half a pixel.
        EXPECT_NEAR(*measured, expected, 0.2) << "row " << v;
    }
}

}  // namespace
}  // namespace mixray::render::test
