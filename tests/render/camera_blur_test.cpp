// The camera's own blur, sampled with the pixel (render/src/camera_rays.h). Depth of field from
// the real lens's aperture (Kán & Kaufmann §3.1): a virtual point away from the plane of focus
// spreads over the circle of confusion the thin-lens formula gives, a virtual object on the
// plane of focus renders as through a pinhole. Motion blur over the exposure (camera matching):
// a point smears along the image path the camera's travel or turn gives it. In both, the screen
// footprint still holds every pixel the blur reaches.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "camera_rays.h"
#include "mixray/render/ar_pipeline.h"
#include "renderer_test_util.h"

namespace mixray::render::test {
namespace {

constexpr int kWidth = 96, kHeight = 72;
constexpr double kFocal_px = 400;

LensAperture aperture(float focus_distance_m) {
    LensAperture a;
    a.f_number = 2;
    a.focal_length_mm = 50;  // 25 mm across
    a.focus_distance_m = focus_distance_m;
    return a;
}

// A grey ghost floor 2 m below the camera, one small white virtual `shape` 1 m below it, a sun.
SceneDescription smallObjectScene(ShapeType shape, std::optional<LensAperture> lens) {
    SceneDescription scene;
    addGhostFloor(scene);
    scene.materials["white"] = material(MaterialType::kDiffuse, "white");
    SceneObject o = object("thing", ObjectRole::kVirtual, shape, "white", {0, 0, 1});
    o.shape.radius = shape == ShapeType::kSphere ? 0.005f : 0.05f;
    scene.objects.push_back(o);
    scene.lights.push_back(directionalLight("sun", {0.2, 0.1, -1}, 3));
    if (lens) {
        scene.camera.emplace();
        scene.camera->has_pose = false;
        scene.camera->aperture = lens;
    }
    return scene;
}

// `distortion`: OpenCV coefficients of the camera's lens; none: a pinhole.
RenderLayers renderFromAbove(const SceneDescription& scene, RenderOptions options,
                             std::vector<double> distortion = {},
                             std::optional<RenderInputs::ShutterPoses> shutter = {}) {
    options.threads = 2;
    auto renderer = Renderer::create(scene, options);
    EXPECT_TRUE(renderer.isOk()) << renderer.status().toString();
    const Image camera = filledImage(kWidth, kHeight, [](int x, int y) {
        return std::array<uint8_t, 3>{static_cast<uint8_t>(60 + x), static_cast<uint8_t>(40 + y),
                                      90};
    });
    RenderInputs in;
    in.camera = calibration::CameraModel::pinhole(kWidth, kHeight, kFocal_px, kFocal_px,
                                                  (kWidth - 1) / 2.0, (kHeight - 1) / 2.0);
    in.camera.distortion = std::move(distortion);
    in.camera_image = camera.view();
    in.T_world_cam = lookDown({0, 0, 2});
    in.shutter = shutter;
    RenderLayers out;
    EXPECT_TRUE((*renderer)->render(in, out).isOk());
    return out;
}

struct Spread {
    double total = 0;  // the mask's sum: the object's area in pixels
    double var_x = 0, var_y = 0;
};

Spread maskSpread(const FloatImage& mask) {
    Spread s;
    double sx = 0, sy = 0, sxx = 0, syy = 0;
    for (int y = 0; y < mask.height; ++y)
        for (int x = 0; x < mask.width; ++x) {
            const double m = mask.at(x, y)[0];
            s.total += m;
            sx += m * x;
            sy += m * y;
            sxx += m * x * x;
            syy += m * y * y;
        }
    s.var_x = sxx / s.total - (sx / s.total) * (sx / s.total);
    s.var_y = syy / s.total - (sy / s.total) * (sy / s.total);
    return s;
}

// Enough samples for a point's spread to be measured from its mask, and no shadows to trace.
RenderOptions spreadOptions() {
    RenderOptions options;
    options.samples_per_pixel = 64;
    options.keep_layers = true;
    options.shadows = false;
    return options;
}

TEST(DepthOfField, APointSpreadsOverTheThinLensCircleOfConfusion) {
    const RenderOptions options = spreadOptions();
    const Spread pinhole =
        maskSpread(renderFromAbove(smallObjectScene(ShapeType::kSphere, {}), options).mask);
    // A disk of diameter D has variance D²/16 along an axis; the blurred image is the pinhole
    // image convolved with the circle of confusion, so their variances add.
    for (const float focus : {0.5f, 2.0f, 4.0f}) {
        const Spread blurred = maskSpread(
            renderFromAbove(smallObjectScene(ShapeType::kSphere, aperture(focus)), options).mask);
        const double expected = kFocal_px * 0.025 * std::abs(1 / 1.0 - 1 / focus);
        for (const double var : {blurred.var_x, blurred.var_y}) {
            const double measured = 4 * std::sqrt(var - pinhole.var_x);
            EXPECT_NEAR(measured, expected, 0.05 * expected) << "focus " << focus;
        }
        // Blur moves coverage and keeps it: the object covers as many pixels in all.
        EXPECT_NEAR(blurred.total, pinhole.total, 0.03 * pinhole.total) << "focus " << focus;
    }
}

TEST(DepthOfField, InFocusTheImageIsThePinholeImage) {
    // A disk facing the camera on the plane of focus: every ray through the aperture meets it
    // where the pinhole ray through the calibrated lens model (barrel distortion here) does.
    RenderOptions options;
    options.samples_per_pixel = 16;
    options.keep_layers = true;
    const std::vector<double> barrel = {-0.2, 0.05, 0.001, -0.001, 0};
    const RenderLayers pinhole =
        renderFromAbove(smallObjectScene(ShapeType::kDisk, {}), options, barrel);
    const RenderLayers lens =
        renderFromAbove(smallObjectScene(ShapeType::kDisk, aperture(1.0f)), options, barrel);
    int mask_differs = 0;
    for (int y = 0; y < kHeight; ++y)
        for (int x = 0; x < kWidth; ++x) {
            if (pinhole.mask.at(x, y)[0] != lens.mask.at(x, y)[0])
                ++mask_differs;
            if (pinhole.mask.at(x, y)[0] != 1)
                continue;
            for (int c = 0; c < 3; ++c)
                EXPECT_EQ(pixelBytes(pinhole.composite, x, y)[c],
                          pixelBytes(lens.composite, x, y)[c])
                    << x << "," << y;
        }
    // Rays meeting the rim exactly may round either way.
    EXPECT_LE(mask_differs, 2);
    // The disk is there: about π·(400·0.05)² pixels.
    EXPECT_NEAR(maskSpread(lens.mask).total, M_PI * 20 * 20, 0.03 * M_PI * 20 * 20);
}

TEST(DepthOfField, TheScreenFootprintHoldsEveryPixelTheBlurReaches) {
    // Focused 0.4 m away: the object 1 m away blurs over 15 pixels, its shadow on the floor over
    // 20; the footprint's tiles (of pinhole rays, grown by the blur) must lose none of it.
    RenderOptions options;
    options.samples_per_pixel = 16;
    options.tile_size = 8;
    const SceneDescription scene = smallObjectScene(ShapeType::kSphere, aperture(0.4f));
    options.screen_footprint = false;
    const Image every_pixel = renderFromAbove(scene, options).composite;
    options.screen_footprint = true;
    const Image footprint = renderFromAbove(scene, options).composite;
    int changed = 0;
    for (int y = 0; y < kHeight; ++y)
        for (int x = 0; x < kWidth; ++x)
            for (int c = 0; c < 3; ++c) {
                EXPECT_EQ(pixelBytes(footprint, x, y)[c], pixelBytes(every_pixel, x, y)[c])
                    << x << "," << y;
                changed += pixelBytes(every_pixel, x, y)[c] != 90 && c == 2;
            }
    EXPECT_GT(changed, 150);  // the blur is there to be lost
}

TEST(DepthOfField, AFrameWithNothingVirtualIsTheCameraImage) {
    SceneDescription scene = smallObjectScene(ShapeType::kSphere, aperture(0.4f));
    scene.objects.pop_back();  // the ghost floor alone
    RenderOptions options;
    options.samples_per_pixel = 16;
    const Image composite = renderFromAbove(scene, options).composite;
    for (int y = 0; y < kHeight; ++y)
        for (int x = 0; x < kWidth; ++x) {
            ASSERT_EQ(pixelBytes(composite, x, y)[0], 60 + x);
            ASSERT_EQ(pixelBytes(composite, x, y)[1], 40 + y);
            ASSERT_EQ(pixelBytes(composite, x, y)[2], 90);
        }
}

TEST(DepthOfField, BlurRadiusIsHalfTheLargestCircleOfConfusion) {
    const detail::ThinLens lens{0.01f, 1.0f};
    // Nearest 0.5 m: |1/0.5 − 1| = 1 > 1/focus = 1; nearest 0.25 m: 3.
    EXPECT_NEAR(lens.blurRadiusPx(500, 0.5f), 500 * 0.01 * 1, 1e-4);
    EXPECT_NEAR(lens.blurRadiusPx(500, 0.25f), 500 * 0.01 * 3, 1e-3);
    // Far objects: at most the blur of a point at infinity.
    EXPECT_NEAR(lens.blurRadiusPx(500, 100.f), 500 * 0.01 * 1, 1e-4);
    EXPECT_EQ(detail::ThinLens{}.blurRadiusPx(500, 0.1f), 0);
}

// The exposure of a camera 2 m above the floor that moves by `travel` (world) or turns by
// `turn_rad` about the image's vertical axis while the shutter is open; the image's pose is the
// middle one.
RenderInputs::ShutterPoses shutterPoses(const Eigen::Vector3d& travel, double turn_rad = 0) {
    RenderInputs::ShutterPoses s;
    s.T_world_cam_open = lookDown(Eigen::Vector3d(0, 0, 2) - travel / 2);
    s.T_world_cam_close = lookDown(Eigen::Vector3d(0, 0, 2) + travel / 2);
    s.T_world_cam_open.linear() =
        s.T_world_cam_open.linear() * Eigen::AngleAxisd(-turn_rad / 2, Eigen::Vector3d::UnitY());
    s.T_world_cam_close.linear() =
        s.T_world_cam_close.linear() * Eigen::AngleAxisd(turn_rad / 2, Eigen::Vector3d::UnitY());
    return s;
}

// The calibration file's lens settings give the scene's camera its aperture (the pose stays
// tracking's), and the scene's own aperture wins over them.
TEST(DepthOfField, TheCalibratedLensSetsTheApertureUnlessTheSceneDoes) {
    calibration::CalibratedCamera camera;
    camera.name = "kinect/color";
    camera.lens = calibration::LensSettings{2, 50, 0.86};
    SceneDescription scene = smallObjectScene(ShapeType::kSphere, {});
    applyCalibratedLens(camera, scene);
    ASSERT_TRUE(scene.camera && scene.camera->aperture);
    EXPECT_FALSE(scene.camera->has_pose);
    EXPECT_FLOAT_EQ(scene.camera->aperture->f_number, 2);
    EXPECT_FLOAT_EQ(scene.camera->aperture->focal_length_mm, 50);
    EXPECT_FLOAT_EQ(scene.camera->aperture->focus_distance_m, 0.86f);
    // Rendered, the point blurs as with the same aperture from the scene file.
    const Spread from_calibration = maskSpread(renderFromAbove(scene, spreadOptions()).mask);
    const Spread from_scene = maskSpread(
        renderFromAbove(smallObjectScene(ShapeType::kSphere, aperture(0.86f)), spreadOptions())
            .mask);
    EXPECT_GT(from_calibration.var_x, 0);
    EXPECT_EQ(from_calibration.total, from_scene.total);
    EXPECT_EQ(from_calibration.var_x, from_scene.var_x);
    SceneDescription own = smallObjectScene(ShapeType::kSphere, aperture(3));
    applyCalibratedLens(camera, own);
    EXPECT_FLOAT_EQ(own.camera->aperture->focus_distance_m, 3);
    camera.lens.reset();
    SceneDescription none = smallObjectScene(ShapeType::kSphere, {});
    applyCalibratedLens(camera, none);
    EXPECT_FALSE(none.camera);
}

TEST(MotionBlur, APointSmearsAlongTheImagePathOfTheCamerasTravelOrTurn) {
    const RenderOptions options = spreadOptions();
    const SceneDescription scene = smallObjectScene(ShapeType::kSphere, {});
    const Spread still = maskSpread(renderFromAbove(scene, options).mask);
    // A box blur of length L adds L²/12 to the variance along it, nothing across it. Moving
    // 2 cm sideways past a point 1 m away: L = 400 · 0.02 / 1 = 8 px; turning by 0.02 rad about
    // the image's vertical axis near its centre: L = 400 · 0.02 = 8 px, both along x.
    for (const auto& [name, shutter] :
         {std::pair{"travel", shutterPoses({0.02, 0, 0})},
          std::pair{"turn", shutterPoses(Eigen::Vector3d::Zero(), 0.02)}}) {
        const Spread blurred = maskSpread(renderFromAbove(scene, options, {}, shutter).mask);
        EXPECT_NEAR(std::sqrt(12 * (blurred.var_x - still.var_x)), 8, 0.05 * 8) << name;
        EXPECT_NEAR(blurred.var_y, still.var_y, 0.05 * 64 / 12) << name;
        EXPECT_NEAR(blurred.total, still.total, 0.03 * still.total) << name;
    }
}

TEST(MotionBlur, TheScreenFootprintHoldsEveryPixelTheSmearReaches) {
    // 10 cm of travel and a turn: the object smears over 40 pixels, its shadow on the floor
    // over 20, both along paths that leave their pinhole tiles.
    RenderOptions options;
    options.samples_per_pixel = 16;
    options.tile_size = 8;
    const SceneDescription scene = smallObjectScene(ShapeType::kSphere, {});
    const auto shutter = shutterPoses({0.1, 0.03, 0}, 0.03);
    options.screen_footprint = false;
    const Image every_pixel = renderFromAbove(scene, options, {}, shutter).composite;
    options.screen_footprint = true;
    const Image footprint = renderFromAbove(scene, options, {}, shutter).composite;
    int changed = 0;
    for (int y = 0; y < kHeight; ++y)
        for (int x = 0; x < kWidth; ++x) {
            for (int c = 0; c < 3; ++c)
                EXPECT_EQ(pixelBytes(footprint, x, y)[c], pixelBytes(every_pixel, x, y)[c])
                    << x << "," << y;
            changed += pixelBytes(every_pixel, x, y)[2] != 90;
        }
    EXPECT_GT(changed, 100);  // the smear is there to be lost
}

TEST(MotionBlur, ShutterPosesMustBeRigid) {
    RenderOptions options;
    options.threads = 1;
    auto renderer = Renderer::create(smallObjectScene(ShapeType::kSphere, {}), options);
    ASSERT_TRUE(renderer.isOk());
    const Image camera = filledImage(kWidth, kHeight, [](int, int) {
        return std::array<uint8_t, 3>{90, 90, 90};
    });
    RenderInputs in;
    in.camera = calibration::CameraModel::pinhole(kWidth, kHeight, kFocal_px, kFocal_px,
                                                  (kWidth - 1) / 2.0, (kHeight - 1) / 2.0);
    in.camera_image = camera.view();
    in.T_world_cam = lookDown({0, 0, 2});
    in.shutter = shutterPoses({0.01, 0, 0});
    in.shutter->T_world_cam_close.linear()(0, 0) = 2;
    RenderLayers out;
    const Status status = (*renderer)->render(in, out);
    EXPECT_EQ(status.code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(status.toString().find("T_world_cam_close"), std::string::npos) << status.toString();
}

}  // namespace
}  // namespace mixray::render::test
