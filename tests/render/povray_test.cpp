// POV-Ray as the renderer's peer (mixray/render/povray.h): the scene it is given, the
// statistics read from it, and the same frame rendered by both, which must look alike.
#include "mixray/render/povray.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>

#include "mixray/render/output.h"
#include "mixray/render/renderer.h"
#include "renderer_test_util.h"
#include "test_data.h"

namespace mixray::render {
namespace {

using test::lookAt;
using test::material;
using test::object;

// A diffuse floor that mirrors a little, a red diffuse sphere that mirrors more, a mirror box
// and a point light: every material and shape kind the export writes.
SceneDescription peerScene() {
    SceneDescription scene;
    Material floor = material(MaterialType::kDiffuse, "floor");
    floor.albedo = {0.6f, 0.6f, 0.55f};
    floor.reflectance = 0.2f;
    Material red = material(MaterialType::kDiffuse, "red");
    red.albedo = {0.8f, 0.2f, 0.15f};
    red.reflectance = 0.4f;
    Material mirror = material(MaterialType::kMirror, "mirror");
    mirror.reflectance = 0.9f;
    scene.materials = {{"floor", floor}, {"red", red}, {"mirror", mirror}};
    SceneObject plane =
        object("floor", ObjectRole::kVirtual, ShapeType::kPlane, "floor", {0, 0, 0});
    plane.shape.size = {1.5f, 1.5f, 0};
    scene.objects.push_back(plane);
    SceneObject ball = object("ball", ObjectRole::kVirtual, ShapeType::kSphere, "red", {0, 0, 0.1});
    ball.shape.radius = 0.1f;
    scene.objects.push_back(ball);
    SceneObject box =
        object("box", ObjectRole::kVirtual, ShapeType::kBox, "mirror", {0.22, 0.12, 0.08});
    box.shape.size = {0.12f, 0.12f, 0.16f};
    box.T_anchor_object.rotate(Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitZ()));
    scene.objects.push_back(box);
    Light lamp;
    lamp.name = "lamp";
    lamp.type = LightType::kPoint;
    lamp.position = {0.5, -0.4, 0.9};
    lamp.intensity = Rgb::Constant(1.2f);
    scene.lights.push_back(lamp);
    return scene;
}

PovrayView peerView(int w, int h) {
    PovrayView view;
    view.camera =
        calibration::CameraModel::pinhole(w, h, 0.9 * w, 0.9 * w, (w - 1) / 2.0, (h - 1) / 2.0);
    view.T_world_cam = lookAt({0.35, -0.75, 0.45}, {0.05, 0, 0.08});
    return view;
}

TEST(Povray, SceneHoldsTheCameraLightsAndEveryObject) {
    const auto text = povrayScene(peerScene(), peerView(160, 120));
    ASSERT_TRUE(text) << text.status().toString();
    EXPECT_NE(text->find("max_trace_level 4"), std::string::npos);
    // right = width / fx, up = height / fy: the pinhole's field of view.
    EXPECT_NE(text->find("right <1.11111111,0,0> up <0,0.833333333,0>"), std::string::npos);
    EXPECT_NE(text->find("fade_power 2"), std::string::npos);
    EXPECT_EQ(text->find("shadowless"), std::string::npos);
    EXPECT_NE(text->find("sphere {"), std::string::npos);
    size_t meshes = 0;
    for (size_t at = text->find("mesh2"); at != std::string::npos; at = text->find("mesh2", at + 1))
        ++meshes;
    EXPECT_EQ(meshes, 2u);  // the floor and the box
    PovrayView flat = peerView(160, 120);
    flat.shadows = false;
    flat.max_depth = 0;
    const auto primary = povrayScene(peerScene(), flat);
    ASSERT_TRUE(primary);
    EXPECT_NE(primary->find("shadowless"), std::string::npos);
    EXPECT_NE(primary->find("max_trace_level 1"), std::string::npos);
}

TEST(Povray, RefusesWhatPovrayWouldRenderDifferently) {
    for (MaterialType type : {MaterialType::kPhong, MaterialType::kMetal, MaterialType::kGlass}) {
        SceneDescription scene = peerScene();
        scene.materials["red"].type = type;
        const auto text = povrayScene(scene, peerView(64, 48));
        EXPECT_EQ(text.status().code(), ErrorCode::kUnsupported);
        EXPECT_NE(text.status().message().find("'red'"), std::string::npos);
    }
    SceneDescription soft = peerScene();
    soft.lights[0].type = LightType::kSphere;
    EXPECT_EQ(povrayScene(soft, peerView(64, 48)).status().code(), ErrorCode::kUnsupported);
    SceneDescription anchored = peerScene();
    anchored.objects[1].anchor = "marker:3";
    EXPECT_EQ(povrayScene(anchored, peerView(64, 48)).status().code(), ErrorCode::kUnsupported);
    PovrayView distorted = peerView(64, 48);
    distorted.camera.distortion = {0.1, 0, 0, 0, 0};
    EXPECT_EQ(povrayScene(peerScene(), distorted).status().code(), ErrorCode::kInvalidArgument);
}

// POV-Ray 3.7.0.10's statistics for a 320x240 frame, as it printed them.
constexpr const char* kStats = R"(Parser Time
  Parse Time:       0 hours  0 minutes  0 seconds (0.012 seconds)
              using 1 thread(s) with 0.000 CPU-seconds total
Render Statistics
Image Resolution 320 x 240
Pixels:            76800   Samples:               0   Smpls/Pxl: 0.00
Rays:              81972   Saved:                 0   Max Level: 2/2
Shadow Ray Tests:             38189   Succeeded:                   835
Shadow Cache Hits:              831
Reflected Rays:                5172
Render Time:
  Photon Time:      No photons
  Radiosity Time:   No radiosity
  Trace Time:       0 hours  0 minutes  1 seconds (1.021 seconds)
              using 2 thread(s) with 0.031 CPU-seconds total
POV-Ray finished
)";

TEST(Povray, StatisticsAreRead) {
    const auto stats = parsePovrayStats(kStats);
    ASSERT_TRUE(stats) << stats.status().toString();
    EXPECT_DOUBLE_EQ(stats->parse_s, 0.012);
    EXPECT_DOUBLE_EQ(stats->trace_s, 1.021);
    EXPECT_EQ(stats->pixels, 76800u);
    EXPECT_EQ(stats->rays, 81972u);
    EXPECT_EQ(stats->shadow_rays, 38189u);
    EXPECT_EQ(stats->threads, 2);
    const std::string text = kStats;
    // A render cut short has no trace time.
    EXPECT_EQ(parsePovrayStats(text.substr(0, text.find("Render Time"))).status().code(),
              ErrorCode::kCorruptData);
    EXPECT_EQ(parsePovrayStats("").status().code(), ErrorCode::kCorruptData);
}

// The same frame from both renderers: every pixel traced by mixray (all objects virtual, the
// footprint off, one ray per pixel) and by POV-Ray, at every trace depth, with and without
// shadows. They differ only where a pixel's one ray falls either side of an edge (the two
// renderers' triangles and spheres are intersected in different floating-point steps) and by
// 8-bit rounding.
TEST(Povray, BothRenderersDrawTheSameFrame) {
    const SceneDescription scene = peerScene();
    const int w = 160, h = 120;
    const std::filesystem::path dir = ::mixray::test::tempDir();
    for (const auto& [depth, shadows] : {std::pair{0, false}, {0, true}, {3, true}}) {
        SCOPED_TRACE("max_depth " + std::to_string(depth) + (shadows ? ", shadows" : ""));
        PovrayView view = peerView(w, h);
        view.max_depth = depth;
        view.shadows = shadows;
        const auto text = povrayScene(scene, view);
        ASSERT_TRUE(text) << text.status().toString();
        const std::filesystem::path work =
            dir / ("depth" + std::to_string(depth) + (shadows ? "_shadows" : ""));
        std::filesystem::create_directories(work);
        const auto pov = renderWithPovray(*text, w, h, 2, work);
        if (!pov && pov.status().code() == ErrorCode::kNotFound)
            GTEST_SKIP() << pov.status().toString();
        ASSERT_TRUE(pov) << pov.status().toString();
        EXPECT_EQ(pov->stats.pixels, static_cast<uint64_t>(w * h));
        EXPECT_GE(pov->stats.rays, static_cast<uint64_t>(w * h));
        EXPECT_EQ(pov->stats.shadow_rays > 0, shadows);

        RenderOptions options;
        options.max_depth = depth;
        options.shadows = shadows;
        options.soft_shadows = SoftShadowMethod::kHard;
        options.only_virtual_footprint = false;
        options.threads = 2;
        options.cut_paths_see_environment = false;  // black, as POV-Ray past max_trace_level
        auto renderer = Renderer::create(scene, options);
        ASSERT_TRUE(renderer) << renderer.status().toString();
        Image black(ImageDesc::packed(PixelFormat::kRGB8, w, h));
        RenderInputs inputs;
        inputs.camera = view.camera;
        inputs.camera_image = black.view();
        inputs.T_world_cam = view.T_world_cam;
        RenderLayers out;
        ASSERT_TRUE((*renderer)->render(inputs, out));

        auto difference = compareImages(out.composite.view(), pov->image.view(), 24);
        ASSERT_TRUE(difference);
        int lit = 0;
        const auto a = out.composite.bytes();
        for (size_t i = 0; i < a.size(); i += 3)
            lit += a[i] + a[i + 1] + a[i + 2] > 30 ? 1 : 0;
        EXPECT_GT(lit, w * h / 4);  // a frame with something in it
        EXPECT_LT(difference->rmse, 2.0);
        EXPECT_LT(difference->pixels_far_off, static_cast<uint64_t>(w * h / 500));  // edges
        std::printf("RMSE %.3f codes, %llu pixels more than 24 codes apart\n", difference->rmse,
                    static_cast<unsigned long long>(difference->pixels_far_off));
        if (HasFailure()) {
            (void)writePng(out.composite.view(), work / "mixray.png");
            ADD_FAILURE() << "the two images are in " << work;
        }
    }
}

}  // namespace
}  // namespace mixray::render
