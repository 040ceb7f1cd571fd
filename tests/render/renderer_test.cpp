// The Renderer against geometry and the differential-rendering equation: exact copies without
// virtual content, shadow positions and widths, mirrors, glass energy, footprint and errors.
#include "mixray/render/renderer.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <numbers>

#include "mixray/render/assets.h"
#include "mixray/render/bench_seam.h"
#include "renderer_test_util.h"
#include "test_data.h"
#include "watchdog.h"

namespace mixray::render::test {
namespace {

using calibration::CameraModel;

constexpr int kW = 160, kH = 120;

struct Frame {
    Image image;
    RenderInputs inputs;
};

Frame makeFrame(const Eigen::Isometry3d& T_world_cam, Image image, double f = 200) {
    Frame frame{std::move(image), {}};
    frame.inputs.camera = CameraModel::pinhole(kW, kH, f, f, (kW - 1) / 2.0, (kH - 1) / 2.0);
    frame.inputs.camera_image = frame.image.view();
    frame.inputs.T_world_cam = T_world_cam;
    return frame;
}

Image noiseImage() {
    return filledImage(kW, kH, [](int x, int y) {
        const uint32_t h =
            (static_cast<uint32_t>(x) * 73856093u) ^ (static_cast<uint32_t>(y) * 19349663u);
        return std::array<uint8_t, 3>{static_cast<uint8_t>(h), static_cast<uint8_t>(h >> 8),
                                      static_cast<uint8_t>(h >> 16)};
    });
}

Image greyImage(uint8_t v) {
    return filledImage(kW, kH, [v](int, int) { return std::array<uint8_t, 3>{v, v, v}; });
}

std::unique_ptr<Renderer> makeRenderer(const SceneDescription& scene, const RenderOptions& o) {
    auto renderer = Renderer::create(scene, o);
    EXPECT_TRUE(renderer.isOk()) << renderer.status().toString();
    return renderer ? std::move(renderer).value() : nullptr;
}

Light pointLight(const Eigen::Vector3d& position, float intensity) {
    Light light;
    light.name = "point";
    light.type = LightType::kPoint;
    light.position = position;
    light.intensity = Rgb::Constant(intensity);
    return light;
}

TEST(Renderer, WithoutVirtualObjectsTheCompositeIsTheCameraImageBitForBit) {
    SceneDescription scene;
    addGhostFloor(scene);
    Material box = material(MaterialType::kPhong, "box");
    box.reflectance = 0.3f;
    scene.materials["box"] = box;
    scene.objects.push_back(
        object("box", ObjectRole::kGhost, ShapeType::kBox, "box", {0.1, 0, 0.05}));
    scene.lights.push_back(pointLight({0.5, 0.2, 2}, 3));
    for (bool footprint : {true, false}) {
        RenderOptions options;
        options.only_virtual_footprint = footprint;
        auto renderer = makeRenderer(scene, options);
        ASSERT_TRUE(renderer);
        Frame frame = makeFrame(lookDown({0, 0, 2}), noiseImage());
        RenderLayers out;
        RenderStats stats;
        ASSERT_TRUE(renderer->render(frame.inputs, out, &stats));
        EXPECT_TRUE(sameImage(out.composite.view(), frame.image.view()));
        if (footprint) {
            EXPECT_EQ(stats.pixels_traced, 0u);
        }
    }
}

// Issue 14's rule for every effect: each changes the real image only by what the virtual
// content changes. A real mirror ball and a real lacquered box under a shadow-mapped point
// light, a shadow-mapped sphere light and an environment, with caustics, bloom and glare
// (thresholds low enough to catch the real highlights), a wide-open aperture focused away from
// the floor, noise matching and motion blur over a moving shutter: without virtual content (none
// in the scene, or a virtual glass ball whose anchor is not seen this frame) the composite is
// the camera image byte for byte, with the footprint on and off.
TEST(Renderer, WithoutVirtualObjectsEveryEffectLeavesTheCameraImageBitForBit) {
    SceneDescription scene;
    addGhostFloor(scene);
    scene.materials["mirror"] = material(MaterialType::kMirror, "mirror");
    Material lacquer = material(MaterialType::kPhong, "lacquer");
    lacquer.specular = Rgb::Constant(0.8f);
    lacquer.shininess = 200;
    scene.materials["lacquer"] = lacquer;
    SceneObject ball =
        object("mirror_ball", ObjectRole::kGhost, ShapeType::kSphere, "mirror", {-0.1, 0, 0.08});
    ball.shape.radius = 0.08f;
    scene.objects.push_back(ball);
    scene.objects.push_back(
        object("box", ObjectRole::kGhost, ShapeType::kBox, "lacquer", {0.15, 0.05, 0.05}));
    Light point = pointLight({0.5, 0.2, 2}, 3);
    point.shadow_map.emplace();
    point.shadow_map->filter = ShadowMapFilter::kVsm;
    point.shadow_map->resolution = 256;
    scene.lights.push_back(point);
    Light sphere = pointLight({-0.4, 0.3, 1.5}, 2);
    sphere.name = "lamp";
    sphere.type = LightType::kSphere;
    sphere.radius = 0.1f;
    sphere.shadow_map.emplace();
    sphere.shadow_map->resolution = 256;
    scene.lights.push_back(sphere);
    Light sky;
    sky.name = "sky";
    sky.type = LightType::kEnvironment;
    sky.environment = writeEnvironment("every_effect_sky", 32, 16, [](int, int y) {
        return Eigen::Vector3f::Constant(y < 8 ? 0.6f : 0.2f);
    });
    scene.lights.push_back(sky);
    scene.caustics.emplace();
    scene.caustics->photons = 20000;
    scene.caustics->radius_m = 0.01f;
    scene.lens_effects.bloom.emplace();
    scene.lens_effects.bloom->threshold = 0.2f;
    scene.lens_effects.bloom->strength = 0.5f;
    scene.lens_effects.glare.emplace();
    scene.lens_effects.glare->threshold = 0.3f;
    scene.lens_effects.glare->strength = 0.5f;
    scene.camera_matching.noise = 1.0f;
    scene.camera_matching.motion_blur_exposure_ms = 16.0f;
    scene.camera.emplace();
    scene.camera->has_pose = false;
    scene.camera->aperture.emplace();
    scene.camera->aperture->f_number = 1.4f;
    scene.camera->aperture->focal_length_mm = 50;
    scene.camera->aperture->focus_distance_m = 1;

    SceneDescription unseen = scene;
    scene.materials["glass"] = material(MaterialType::kGlass, "glass");
    SceneObject glass =
        object("glass_ball", ObjectRole::kVirtual, ShapeType::kSphere, "glass", {0, -0.15, 0.05});
    glass.shape.radius = 0.05f;
    glass.anchor = "marker:7";
    unseen.materials["glass"] = scene.materials["glass"];
    unseen.objects.push_back(glass);

    for (const SceneDescription* s : {&scene, &unseen})
        for (bool footprint : {true, false}) {
            SCOPED_TRACE(std::string(s == &scene ? "no virtual object" : "its anchor unseen") +
                         (footprint ? ", footprint" : ", every pixel"));
            RenderOptions options;
            options.only_virtual_footprint = footprint;
            options.samples_per_pixel = 4;
            auto renderer = makeRenderer(*s, options);
            ASSERT_TRUE(renderer);
            Frame frame = makeFrame(lookDown({0, 0, 2}), noiseImage());
            frame.inputs.shutter = shutterFromMotion(lookDown({0.02, 0, 2}),
                                                     frame.inputs.T_world_cam, 1 / 30.0, 0.016);
            RenderLayers out;
            RenderStats stats;
            ASSERT_TRUE(renderer->render(frame.inputs, out, &stats));
            EXPECT_TRUE(sameImage(out.composite.view(), frame.image.view()));
        }
}

// A virtual sphere over a real floor lit by two directional lights; the sphere blocks one.
SceneDescription shadowScene(Eigen::Vector3d direction_a, float e_a, float e_b) {
    SceneDescription scene;
    addGhostFloor(scene, 0.6f);
    scene.materials["red"] = material(MaterialType::kDiffuse, "red");
    scene.materials["red"].albedo = {0.7f, 0.1f, 0.1f};
    SceneObject ball = object("ball", ObjectRole::kVirtual, ShapeType::kSphere, "red", {0, 0, 0.5});
    ball.shape.radius = 0.1f;
    scene.objects.push_back(ball);
    scene.lights.push_back(directionalLight("a", direction_a, e_a));
    scene.lights.push_back(directionalLight("b", {0, 0, -1}, e_b));
    return scene;
}

TEST(Renderer, VirtualShadowDarkensTheRealFloorByThePredictedRatio) {
    // Light a travels along (1, 0, -2): the shadow of the ball centre lands at (0.25, 0, 0) and
    // is an ellipse with semi-axes r / cos θ = 0.1118 along x and r = 0.1 along y. Light b comes
    // straight down, so the ball's shadow from b hides under the ball.
    const Eigen::Vector3d dir_a(1, 0, -2);
    const float e_a = 2, e_b = 1, albedo = 0.6f;
    SceneDescription scene = shadowScene(dir_a, e_a, e_b);
    const float cos_a = 2 / std::sqrt(5.f);
    const float lit = albedo / optics::kPi * (e_a * cos_a + e_b);
    const float shadowed = albedo / optics::kPi * e_b;
    const uint8_t grey = optics::encodeSrgb8(lit);  // the camera sees what the model predicts
    RenderOptions options;
    options.soft_shadows = SoftShadowMethod::kHard;
    options.keep_layers = true;
    auto renderer = makeRenderer(scene, options);
    ASSERT_TRUE(renderer);
    Frame frame = makeFrame(lookDown({0, 0, 3}), greyImage(grey));
    RenderLayers out;
    ASSERT_TRUE(renderer->render(frame.inputs, out));

    const double px_per_m = 200 / 3.0, cx = (kW - 1) / 2.0, cy = (kH - 1) / 2.0;
    const int y = static_cast<int>(cy);  // row through the shadow centre (world y ≈ 0)
    const double world_y = -(y - cy) / px_per_m;
    const double half = 0.1118 * std::sqrt(std::max(0.0, 1 - (world_y / 0.1) * (world_y / 0.1)));
    int checked = 0;
    for (int x = static_cast<int>(cx + 0.13 * px_per_m); x < kW; ++x) {
        const double world_x = (x - cx) / px_per_m;
        const double inside = half - std::abs(world_x - 0.25);
        if (std::abs(inside) < 1.5 / px_per_m)
            continue;  // the edge pixel itself
        const float ratio =
            pixelLinear(out.composite, x, y).x() / pixelLinear(frame.image, x, y).x();
        if (inside > 0) {
            EXPECT_NEAR(ratio, shadowed / lit, 0.02) << "x " << x;
            ++checked;
        } else {
            EXPECT_TRUE(pixelBytes(out.composite, x, y)[0] == grey) << "x " << x;
        }
        EXPECT_EQ(out.mask.at(x, y)[0], 0.f);
    }
    EXPECT_GT(checked, 10);
    // The ball itself: masked, and its top lit by both lights.
    EXPECT_EQ(out.mask.at(static_cast<int>(cx), y)[0], 1.f);
}

// Similar triangles: a spherical light of radius R at distance a from an occluder of radius r,
// and the floor at distance b behind it along the same line: the umbra's half-width is
// r − (R − r)·b/a and the penumbra reaches r + (R + r)·b/a.
SceneDescription softShadowScene() {
    SceneDescription scene;
    addGhostFloor(scene, 0.6f);
    scene.materials["grey"] = material(MaterialType::kDiffuse, "grey");
    SceneObject ball = object("ball", ObjectRole::kVirtual, ShapeType::kSphere, "grey", {0, 0, 1});
    ball.shape.radius = 0.12f;
    scene.objects.push_back(ball);
    Light light = pointLight({-1, 0, 2}, 4);
    light.type = LightType::kSphere;
    light.radius = 0.08f;
    scene.lights.push_back(light);
    return scene;
}

TEST(Renderer, SphericalLightGivesUmbraAndPenumbraOfTheSimilarTriangles) {
    const double a = std::sqrt(2.0), b = std::sqrt(2.0), R = 0.08, r = 0.12;
    const double umbra = r - (R - r) * b / a;     // 0.16
    const double penumbra = r + (R + r) * b / a;  // 0.32
    for (SoftShadowMethod method : {SoftShadowMethod::kUniform, SoftShadowMethod::kAdaptive}) {
        RenderOptions options;
        options.soft_shadows = method;
        options.shadow_samples = 64;
        options.shadow_mean_filter = false;
        options.keep_layers = true;
        auto renderer = makeRenderer(softShadowScene(), options);
        ASSERT_TRUE(renderer);
        // Looking down on the shadow centre (1, 0, 0); measure along world y, which is
        // perpendicular to the light-occluder line, so the widths need no projection. A strip
        // of 4 columns is all the test reads.
        const int strip = 4;
        const Image grey = filledImage(strip, kH, [](int, int) {
            return std::array<uint8_t, 3>{128, 128, 128};
        });
        Frame frame = makeFrame(lookDown({1, 0, 3}), grey);
        frame.inputs.camera =
            CameraModel::pinhole(strip, kH, 200, 200, (strip - 1) / 2.0, (kH - 1) / 2.0);
        RenderLayers out;
        ASSERT_TRUE(renderer->render(frame.inputs, out));
        const double px_per_m = 200 / 3.0, cy = (kH - 1) / 2.0;
        const int x = strip / 2;
        for (int y = 0; y < kH; ++y) {
            const double d = std::abs((y - cy) / px_per_m);
            const float visible = out.mixed.at(x, y)[0] / out.real_only.at(x, y)[0];
            if (d < umbra - 0.03) {
                EXPECT_LT(visible, 0.03f) << "y " << y;
            } else if (d > penumbra + 0.03) {
                EXPECT_GT(visible, 0.999f) << "y " << y;
            } else if (d > umbra + 0.03 && d < penumbra - 0.03) {
                EXPECT_GT(visible, 0.02f) << "y " << y;
                EXPECT_LT(visible, 0.98f) << "y " << y;
            }
        }
    }
}

// RT²AR's mean filter smooths an adaptive penumbra's light visibility, not its radiance: a
// finely textured virtual floor lying in the ball's penumbra keeps its texture. The filtered
// adaptive frame stays within 1 % of a 400-sample uniform one, and no further from it than the
// unfiltered one (the filter of the radiance this replaced was 4.3 codes off: it blurred the
// texture).
TEST(Renderer, PenumbraFilterSmoothsTheShadowNotTheTexture) {
    SceneDescription scene = softShadowScene();
    const std::filesystem::path texture = ::mixray::test::tempDir() / "penumbra_texture.png";
    cv::Mat noise(64, 64, CV_8UC3);
    cv::randu(noise, 0, 256);
    ASSERT_TRUE(cv::imwrite(texture.string(), noise));
    Material painted = material(MaterialType::kDiffuse, "painted");
    painted.albedo = Rgb::Ones();
    painted.albedo_texture = texture;
    scene.materials["painted"] = painted;
    SceneObject floor =
        object("painted", ObjectRole::kVirtual, ShapeType::kPlane, "painted", {1, 0, 0.002});
    floor.shape.size = {0.7, 0.7, 0};
    scene.objects.push_back(floor);
    const auto render = [&](SoftShadowMethod method, int samples, bool filter) {
        RenderOptions options;
        options.soft_shadows = method;
        options.shadow_samples = samples;
        options.shadow_mean_filter = filter;
        auto renderer = makeRenderer(scene, options);
        Frame frame = makeFrame(lookDown({1, 0, 3}), greyImage(128), 400);
        RenderLayers out;
        EXPECT_TRUE(renderer && renderer->render(frame.inputs, out));
        return out.composite;
    };
    const Image reference = render(SoftShadowMethod::kUniform, 400, false);
    const auto rmse = [&](const Image& image) {
        double sum = 0;
        for (size_t i = 0; i < image.bytes().size(); ++i)
            sum += std::pow(image.bytes()[i] - reference.bytes()[i], 2);
        return std::sqrt(sum / static_cast<double>(image.bytes().size()));
    };
    const double filtered = rmse(render(SoftShadowMethod::kAdaptive, 20, true));
    const double unfiltered = rmse(render(SoftShadowMethod::kAdaptive, 20, false));
    EXPECT_LT(filtered, 0.01 * 255);
    EXPECT_LE(filtered, unfiltered);
    RecordProperty("rmse_filtered", std::to_string(filtered));
    RecordProperty("rmse_unfiltered", std::to_string(unfiltered));
}

double meanAbsDifference(const Image& a, const Image& b) {
    double sum = 0;
    for (size_t i = 0; i < a.bytes().size(); ++i)
        sum += std::abs(a.bytes()[i] - b.bytes()[i]);
    return sum / static_cast<double>(a.bytes().size());
}

// Soft shadows trace 16-ray occlusion packets; on AMD Zen 4 Embree's AVX-512 coherent packets
// never returned. Every kernel this machine offers renders the same frame, each within a limit.
TEST(Renderer, SoftShadowsRenderTheSameOnEveryEmbreeIsa) {
    Image reference;
    for (const std::string& isa : embreeIsas()) {
        SCOPED_TRACE("isa=" + isa);
        Image composite;
        mixray::test::runWithin(std::chrono::seconds(60), "a soft-shadow frame on isa=" + isa,
                                [&](mixray::test::WatchdogStage& stage) {
                                    RenderOptions options;
                                    options.soft_shadows = SoftShadowMethod::kUniform;
                                    options.shadow_samples = 16;
                                    options.embree_isa = isa;
                                    auto renderer = makeRenderer(softShadowScene(), options);
                                    ASSERT_TRUE(renderer);
                                    Frame frame = makeFrame(lookDown({0.7, 0, 3}), greyImage(150));
                                    RenderLayers out;
                                    stage.set("rendering");
                                    ASSERT_TRUE(renderer->render(frame.inputs, out));
                                    composite = std::move(out.composite);
                                });
        ASSERT_FALSE(composite.bytes().empty());
        if (reference.bytes().empty())
            reference = std::move(composite);
        else
            EXPECT_LT(meanAbsDifference(reference, composite), 0.05);
    }
}

TEST(Renderer, AdaptiveSoftShadowsConvergeToUniformSampling) {
    Image images[2];
    RenderStats stats[2];
    int i = 0;
    for (SoftShadowMethod method : {SoftShadowMethod::kUniform, SoftShadowMethod::kAdaptive}) {
        RenderOptions options;
        options.soft_shadows = method;
        options.shadow_samples = 16;
        options.only_virtual_footprint = false;
        auto renderer = makeRenderer(softShadowScene(), options);
        ASSERT_TRUE(renderer);
        Frame frame = makeFrame(lookDown({0.7, 0, 3}), greyImage(150), 120);
        RenderLayers out;
        ASSERT_TRUE(renderer->render(frame.inputs, out, &stats[i]));
        images[i++] = out.composite;
    }
    EXPECT_LT(meanAbsDifference(images[0], images[1]), 0.5);
    EXPECT_LT(stats[1].shadow_rays, stats[0].shadow_rays / 2);  // adaptive saves rays
}

TEST(Renderer, FootprintTracingGivesTheSameImageAsTracingEverything) {
    SceneDescription scene = softShadowScene();
    scene.materials["mirror"] = material(MaterialType::kMirror, "mirror");
    SceneObject mirror =
        object("mirror", ObjectRole::kVirtual, ShapeType::kBox, "mirror", {1.3, 0.3, 0.1});
    scene.objects.push_back(mirror);
    scene.lights.push_back(directionalLight("sun", {0.3, 0.2, -1}, 1));
    Image images[2];
    RenderStats stats[2];
    for (int i = 0; i < 2; ++i) {
        RenderOptions options;
        options.only_virtual_footprint = i == 0;
        options.samples_per_pixel = 4;
        options.shadow_samples = 8;
        auto renderer = makeRenderer(scene, options);
        ASSERT_TRUE(renderer);
        Frame frame = makeFrame(lookDown({1, 0, 3}), noiseImage(), 120);
        RenderLayers out;
        ASSERT_TRUE(renderer->render(frame.inputs, out, &stats[i]));
        images[i] = out.composite;
    }
    EXPECT_TRUE(sameImage(images[0].view(), images[1].view()));
    EXPECT_LT(stats[0].pixels_traced, stats[1].pixels_traced);
    EXPECT_EQ(stats[1].pixels_traced, static_cast<uint64_t>(kW * kH));
}

TEST(Renderer, VirtualMirrorShowsTheRealWallAsTheCameraSawIt) {
    // Camera 1 m high looking along +y at a real wall at y = 2, over a virtual mirror lying on
    // the ground: mirror pixels show the camera's own pixel of the wall point the reflected ray
    // meets (Kán & Kaufmann's reprojection).
    SceneDescription scene;
    scene.materials["wall"] = material(MaterialType::kDiffuse, "wall");
    SceneObject wall = object("wall", ObjectRole::kGhost, ShapeType::kPlane, "wall", {0, 2, 1});
    wall.T_anchor_object.rotate(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitX()));
    wall.shape.size = {10, 4, 0};
    scene.objects.push_back(wall);
    scene.materials["mirror"] = material(MaterialType::kMirror, "mirror");
    SceneObject mirror =
        object("mirror", ObjectRole::kVirtual, ShapeType::kPlane, "mirror", {0, 0, 0});
    mirror.shape.size = {4, 2, 0};
    scene.objects.push_back(mirror);
    RenderOptions options;
    options.keep_layers = true;
    auto renderer = makeRenderer(scene, options);
    ASSERT_TRUE(renderer);
    const Image gradient = filledImage(kW, kH, [](int x, int y) {
        return std::array<uint8_t, 3>{static_cast<uint8_t>(40 + x), static_cast<uint8_t>(60 + y),
                                      100};
    });
    const Eigen::Vector3d camera(0, -3, 1);
    Frame frame = makeFrame(lookAlongY(camera), gradient, 100);
    RenderLayers out;
    ASSERT_TRUE(renderer->render(frame.inputs, out));
    const CameraModel& model = frame.inputs.camera;
    const Eigen::Isometry3d T_cam_world = frame.inputs.T_world_cam.inverse();
    int checked = 0;
    for (int y = 0; y < kH; ++y)
        for (int x = 0; x < kW; ++x) {
            const Eigen::Vector3d d = frame.inputs.T_world_cam.linear() * *model.unproject({x, y});
            if (d.z() >= 0)
                continue;
            const Eigen::Vector3d p = camera + (-camera.z() / d.z()) * d;  // on the mirror
            if (std::abs(p.x()) > 1.9 || std::abs(p.y()) > 0.95)
                continue;
            EXPECT_EQ(out.mask.at(x, y)[0], 1.f);
            const Eigen::Vector3d r(d.x(), d.y(), -d.z());
            const Eigen::Vector3d q = p + ((2 - p.y()) / r.y()) * r;  // meets the wall
            const auto pixel = model.project(T_cam_world * q);
            ASSERT_TRUE(pixel);
            ASSERT_TRUE(pixel->y() > 0 && pixel->y() < kH - 1) << x << "," << y;
            if (x == 0 || x == kW - 1)
                continue;  // no neighbour to interpolate with
            // The gradient is linear in bytes, so interpolate there for the expectation.
            const double expected_r = 40 + pixel->x(), expected_g = 60 + pixel->y();
            const uint8_t* got = pixelBytes(out.composite, x, y);
            EXPECT_NEAR(got[0], expected_r, 1.5) << x << "," << y;
            EXPECT_NEAR(got[1], expected_g, 1.5) << x << "," << y;
            ++checked;
        }
    EXPECT_GT(checked, 500);
}

TEST(Renderer, GlassSphereInAWhiteFurnaceSplitsEnergyWithoutLoss) {
    SceneDescription scene;
    scene.lights.push_back(environmentLight(
        writeEnvironment("furnace", 32, 16, [](int, int) { return Eigen::Vector3f::Ones(); })));
    Material glass = material(MaterialType::kGlass, "glass");
    scene.materials["glass"] = glass;
    SceneObject ball = object("ball", ObjectRole::kVirtual, ShapeType::kSphere, "glass", {0, 0, 0});
    ball.shape.radius = 0.3f;
    scene.objects.push_back(ball);
    RenderOptions options;
    options.max_depth = 30;  // paths grazing inside the sphere bounce often before leaving
    options.keep_layers = true;
    auto renderer = makeRenderer(scene, options);
    ASSERT_TRUE(renderer);
    Frame frame = makeFrame(lookDown({0, 0, 2}), greyImage(0));
    RenderLayers out;
    ASSERT_TRUE(renderer->render(frame.inputs, out));
    int inside = 0;
    for (int y = 0; y < kH; ++y)
        for (int x = 0; x < kW; ++x) {
            if (out.mask.at(x, y)[0] != 1.f)
                continue;
            ++inside;
            EXPECT_NEAR(out.mixed.at(x, y)[0], 1.f, 2e-3f) << x << "," << y;
        }
    EXPECT_GT(inside, 1000);
}

TEST(Renderer, DispersiveGlassIsTracedPerChannel) {
    // A uniform environment hides dispersion; a split one (red on one side, blue on the other)
    // shows the channels bending differently, while a clear non-dispersive sphere keeps grey.
    SceneDescription scene;
    scene.lights.push_back(environmentLight(writeEnvironment("split", 64, 32, [](int x, int) {
        return Eigen::Vector3f::Constant(x < 32 ? 1.f : 0.2f);
    })));
    Material glass = material(MaterialType::kGlass, "glass");
    glass.ior = {1.45f, 1.5f, 1.6f};
    scene.materials["glass"] = glass;
    SceneObject ball = object("ball", ObjectRole::kVirtual, ShapeType::kSphere, "glass", {0, 0, 0});
    ball.shape.radius = 0.3f;
    scene.objects.push_back(ball);
    RenderOptions options;
    options.keep_layers = true;
    auto renderer = makeRenderer(scene, options);
    ASSERT_TRUE(renderer);
    Frame frame = makeFrame(lookDown({0, 0, 2}), greyImage(0));
    RenderLayers out;
    RenderStats stats;
    ASSERT_TRUE(renderer->render(frame.inputs, out, &stats));
    float max_spread = 0;
    for (int y = 0; y < kH; ++y)
        for (int x = 0; x < kW; ++x)
            if (out.mask.at(x, y)[0] == 1.f)
                max_spread =
                    std::max(max_spread, std::abs(out.mixed.at(x, y)[0] - out.mixed.at(x, y)[2]));
    EXPECT_GT(max_spread, 0.05f);
}

TEST(Renderer, MetalReflectsWithColouredSchlickFresnel) {
    SceneDescription scene;
    scene.lights.push_back(environmentLight(
        writeEnvironment("white", 32, 16, [](int, int) { return Eigen::Vector3f::Ones(); })));
    Material gold = material(MaterialType::kMetal, "gold");
    gold.f0 = {1.0f, 0.71f, 0.29f};
    scene.materials["gold"] = gold;
    SceneObject ball = object("ball", ObjectRole::kVirtual, ShapeType::kSphere, "gold", {0, 0, 0});
    ball.shape.radius = 0.3f;
    scene.objects.push_back(ball);
    RenderOptions options;
    options.keep_layers = true;
    auto renderer = makeRenderer(scene, options);
    ASSERT_TRUE(renderer);
    Frame frame = makeFrame(lookDown({0, 0, 2}), greyImage(0));
    RenderLayers out;
    ASSERT_TRUE(renderer->render(frame.inputs, out));
    // At the centre the view is along the normal: reflectance F0.
    const float* centre = out.mixed.at((kW - 1) / 2, (kH - 1) / 2);
    EXPECT_NEAR(centre[0], 1.0f, 1e-3f);
    EXPECT_NEAR(centre[1], 0.71f, 2e-3f);
    EXPECT_NEAR(centre[2], 0.29f, 2e-3f);
}

TEST(Renderer, MarkerBoundObjectsFollowTheirAnchorAndVanishWithoutIt) {
    SceneDescription scene;
    scene.materials["white"] = material(MaterialType::kDiffuse, "white");
    SceneObject ball = object("ball", ObjectRole::kVirtual, ShapeType::kSphere, "white", {0, 0, 0});
    ball.anchor = "marker:7";
    scene.objects.push_back(ball);
    scene.lights.push_back(pointLight({0, 0, 2}, 5));
    RenderOptions options;
    options.keep_layers = true;
    auto renderer = makeRenderer(scene, options);
    ASSERT_TRUE(renderer);
    Frame frame = makeFrame(lookDown({0, 0, 2}), greyImage(30));
    RenderLayers out;
    ASSERT_TRUE(renderer->render(frame.inputs, out));
    EXPECT_TRUE(sameImage(out.composite.view(), frame.image.view()));
    frame.inputs.T_world_anchor["marker:7"] =
        Eigen::Translation3d(0.3, 0, 0) * Eigen::Isometry3d::Identity();
    ASSERT_TRUE(renderer->render(frame.inputs, out));
    const auto pixel = frame.inputs.camera.project({0.3, 0, 2});
    ASSERT_TRUE(pixel);
    EXPECT_EQ(out.mask.at(static_cast<int>(std::lround(pixel->x())),
                          static_cast<int>(std::lround(pixel->y())))[0],
              1.f);
    EXPECT_EQ(out.mask.at((kW - 1) / 2, (kH - 1) / 2)[0], 0.f);
}

TEST(Renderer, DistortedLensRaysLineUpWithProjection) {
    // The virtual sphere's mask is centred where the lens model projects its centre, even near
    // the border of a strongly distorted image.
    SceneDescription scene;
    scene.materials["white"] = material(MaterialType::kDiffuse, "white");
    SceneObject ball =
        object("ball", ObjectRole::kVirtual, ShapeType::kSphere, "white", {0.55, 0.35, 0});
    ball.shape.radius = 0.06f;
    scene.objects.push_back(ball);
    RenderOptions options;
    options.keep_layers = true;
    options.samples_per_pixel = 4;
    auto renderer = makeRenderer(scene, options);
    ASSERT_TRUE(renderer);
    Frame frame = makeFrame(lookDown({0, 0, 1}), greyImage(30), 90);
    frame.inputs.camera.distortion = {-0.3, 0.08, 0.001, -0.001};
    RenderLayers out;
    ASSERT_TRUE(renderer->render(frame.inputs, out));
    double sx = 0, sy = 0, s = 0;
    for (int y = 0; y < kH; ++y)
        for (int x = 0; x < kW; ++x) {
            const float m = out.mask.at(x, y)[0];
            sx += m * x, sy += m * y, s += m;
        }
    ASSERT_GT(s, 20);
    const Eigen::Isometry3d T_cam_world = frame.inputs.T_world_cam.inverse();
    const auto centre = frame.inputs.camera.project(T_cam_world * Eigen::Vector3d(0.55, 0.35, 0));
    ASSERT_TRUE(centre);
    // A small sphere's image is nearly symmetric: the mask centroid sits on the projection.
    EXPECT_NEAR(sx / s, centre->x(), 0.6);
    EXPECT_NEAR(sy / s, centre->y(), 0.6);
}

TEST(Renderer, RejectsBadOptionsScenesAndInputs) {
    SceneDescription scene = shadowScene({1, 0, -2}, 1, 1);
    RenderOptions options;
    options.samples_per_pixel = 2;
    EXPECT_EQ(Renderer::create(scene, options).status().code(), ErrorCode::kInvalidArgument);
    options = {};
    options.tile_size = 0;
    EXPECT_FALSE(options.validate());
    options = {};
    options.max_depth = -1;
    EXPECT_FALSE(options.validate());
    EXPECT_TRUE(RenderOptions{}.validate());

    SceneDescription bad = scene;
    bad.objects[1].material = "no such material";
    EXPECT_FALSE(Renderer::create(bad, RenderOptions{}).isOk());

    auto renderer = makeRenderer(scene, RenderOptions{});
    ASSERT_TRUE(renderer);
    RenderLayers out;
    Frame frame = makeFrame(lookDown({0, 0, 3}), greyImage(100));
    ASSERT_TRUE(renderer->render(frame.inputs, out));

    Frame nan_pose = makeFrame(lookDown({0, 0, 3}), greyImage(100));
    nan_pose.inputs.T_world_cam.translation().x() = NAN;
    EXPECT_EQ(renderer->render(nan_pose.inputs, out).code(), ErrorCode::kInvalidArgument);

    Frame scaled_pose = makeFrame(lookDown({0, 0, 3}), greyImage(100));
    scaled_pose.inputs.T_world_cam.linear() *= 2;
    EXPECT_EQ(renderer->render(scaled_pose.inputs, out).code(), ErrorCode::kInvalidArgument);

    Frame bad_anchor = makeFrame(lookDown({0, 0, 3}), greyImage(100));
    bad_anchor.inputs.T_world_anchor["marker:1"].matrix().setConstant(INFINITY);
    EXPECT_EQ(renderer->render(bad_anchor.inputs, out).code(), ErrorCode::kInvalidArgument);

    Frame small = makeFrame(lookDown({0, 0, 3}), greyImage(100));
    Image tiny(ImageDesc::packed(PixelFormat::kRGB8, kW / 2, kH));
    small.inputs.camera_image = tiny.view();
    const Status wrong_size = renderer->render(small.inputs, out);
    EXPECT_EQ(wrong_size.code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(wrong_size.message().find("80x120"), std::string::npos) << wrong_size.message();

    Frame mono = makeFrame(lookDown({0, 0, 3}), greyImage(100));
    Image grey(ImageDesc::packed(PixelFormat::kMono8, kW, kH));
    mono.inputs.camera_image = grey.view();
    EXPECT_EQ(renderer->render(mono.inputs, out).code(), ErrorCode::kInvalidArgument);

    Frame depth_format = makeFrame(lookDown({0, 0, 3}), greyImage(100));
    Image depth(ImageDesc::packed(PixelFormat::kMono16, kW, kH));
    depth_format.inputs.depth_mm = depth.view();
    EXPECT_EQ(renderer->render(depth_format.inputs, out).code(), ErrorCode::kInvalidArgument);

    Frame bad_camera = makeFrame(lookDown({0, 0, 3}), greyImage(100));
    bad_camera.inputs.camera.fx = -1;
    EXPECT_EQ(renderer->render(bad_camera.inputs, out).code(), ErrorCode::kInvalidArgument);
}

TEST(Renderer, DepthHidesVirtualObjectsBehindTheMeasuredSurface) {
    // A real wall 1.5 m in front of the camera on the left half of the image only: the virtual
    // sphere 2 m away is hidden where the depth says the wall is, and drawn elsewhere.
    SceneDescription scene;
    scene.materials["white"] = material(MaterialType::kDiffuse, "white");
    SceneObject ball = object("ball", ObjectRole::kVirtual, ShapeType::kSphere, "white", {0, 0, 0});
    ball.shape.radius = 0.3f;
    scene.objects.push_back(ball);
    RenderOptions options;
    options.keep_layers = true;
    auto renderer = makeRenderer(scene, options);
    ASSERT_TRUE(renderer);
    Frame frame = makeFrame(lookDown({0, 0, 2}), greyImage(30));
    Image depth(ImageDesc::packed(PixelFormat::kDepth16, kW, kH));
    for (int y = 0; y < kH; ++y)
        for (int x = 0; x < kW; ++x)
            reinterpret_cast<uint16_t*>(depth.bytes().data())[y * kW + x] = x < kW / 2 ? 1500 : 0;
    frame.inputs.depth_mm = depth.view();
    RenderLayers out;
    ASSERT_TRUE(renderer->render(frame.inputs, out));
    EXPECT_EQ(out.mask.at(kW / 2 - 5, kH / 2)[0], 0.f);
    EXPECT_EQ(out.mask.at(kW / 2 + 5, kH / 2)[0], 1.f);
    for (int y = 0; y < kH; ++y)
        for (int x = 0; x < kW / 2; ++x)
            ASSERT_EQ(pixelBytes(out.composite, x, y)[0], 30) << x << "," << y;
}

// The same wall measured by a depth camera of its own (twice the resolution, 25 mm to the
// side, turned by 1°): with the registration the renderer registers it into the camera and
// hides the sphere exactly where the wall is; without it the image is refused.
TEST(Renderer, DepthFromAnotherCameraIsRegisteredBeforeItOccludes) {
    SceneDescription scene;
    scene.materials["white"] = material(MaterialType::kDiffuse, "white");
    SceneObject ball = object("ball", ObjectRole::kVirtual, ShapeType::kSphere, "white", {0, 0, 0});
    ball.shape.radius = 0.3f;
    scene.objects.push_back(ball);
    RenderOptions options;
    options.keep_layers = true;
    auto renderer = makeRenderer(scene, options);
    ASSERT_TRUE(renderer);
    Frame frame = makeFrame(lookDown({0, 0, 2}), greyImage(30));

    calibration::DepthRegistration registration;
    registration.color = frame.inputs.camera;
    registration.depth =
        CameraModel::pinhole(2 * kW, 2 * kH, 400, 400, (2 * kW - 1) / 2.0, (2 * kH - 1) / 2.0);
    registration.T_color_depth.linear() =
        Eigen::AngleAxisd(1 * std::numbers::pi / 180, Eigen::Vector3d::UnitY()).toRotationMatrix();
    registration.T_color_depth.translation() = Eigen::Vector3d(-0.025, 0, 0);
    // The wall: z = 1.5 m in the colour camera, where x < 0 (the left half of its image).
    Image depth(ImageDesc::packed(PixelFormat::kDepth16, 2 * kW, 2 * kH));
    for (int y = 0; y < 2 * kH; ++y)
        for (int x = 0; x < 2 * kW; ++x) {
            const Eigen::Vector3d ray_depth = *registration.depth.unproject({double(x), double(y)});
            const Eigen::Vector3d o = registration.T_color_depth.translation();
            const Eigen::Vector3d r = registration.T_color_depth.linear() * ray_depth;
            const double t = (1.5 - o.z()) / r.z();
            const Eigen::Vector3d p_color = o + t * r;
            reinterpret_cast<uint16_t*>(depth.bytes().data())[y * 2 * kW + x] =
                p_color.x() < 0 ? static_cast<uint16_t>(std::lround(t * ray_depth.z() * 1e3)) : 0;
        }
    frame.inputs.depth_mm = depth.view();
    RenderLayers out;
    EXPECT_EQ(renderer->render(frame.inputs, out).code(), ErrorCode::kInvalidArgument);
    frame.inputs.depth_registration = &registration;
    ASSERT_TRUE(renderer->render(frame.inputs, out));
    // The wall's edge is the image's centre column (x = 79.5): hidden left of it, drawn right.
    for (int y = kH / 2 - 10; y <= kH / 2 + 10; ++y) {
        EXPECT_EQ(out.mask.at(kW / 2 - 2, y)[0], 0.f) << y;
        EXPECT_EQ(out.mask.at(kW / 2 + 1, y)[0], 1.f) << y;
    }
    for (int y = 0; y < kH; ++y)
        for (int x = 0; x < kW / 2 - 1; ++x)
            ASSERT_EQ(pixelBytes(out.composite, x, y)[0], 30) << x << "," << y;

    // Twice: the registrar is reused, the result the same.
    const std::vector<float> mask = out.mask.pixels;
    ASSERT_TRUE(renderer->render(frame.inputs, out));
    EXPECT_EQ(out.mask.pixels, mask);

    calibration::DepthRegistration other_camera = registration;
    other_camera.color.fx += 1;
    frame.inputs.depth_registration = &other_camera;
    const Status wrong = renderer->render(frame.inputs, out);
    EXPECT_EQ(wrong.code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(wrong.message().find("colour camera"), std::string::npos) << wrong.message();
}

// A ghost floor that the noisy depth map also measures: where the two agree (±2 % noise, less
// than depth_ghost_agreement), the floor is the ghost and receives the virtual shadow exactly as
// without depth; a measurement clearly nearer (a real object the scene does not model) hides it.
TEST(Renderer, DepthThatAgreesWithAGhostKeepsItsVirtualShadow) {
    SceneDescription scene = shadowScene({1, 0, -2}, 2, 1);
    RenderOptions options;
    options.soft_shadows = SoftShadowMethod::kHard;
    auto renderer = makeRenderer(scene, options);
    ASSERT_TRUE(renderer);
    Frame frame = makeFrame(lookDown({0, 0, 3}), greyImage(140));
    RenderLayers without, noisy, nearer;
    ASSERT_TRUE(renderer->render(frame.inputs, without));
    Image depth(ImageDesc::packed(PixelFormat::kDepth16, kW, kH));
    auto* mm = reinterpret_cast<uint16_t*>(depth.bytes().data());
    for (int i = 0; i < kW * kH; ++i)  // the floor 3 m below, ±2 % in a fixed pattern
        mm[i] = static_cast<uint16_t>(3000 + ((i * 7919) % 121) - 60);
    frame.inputs.depth_mm = depth.view();
    ASSERT_TRUE(renderer->render(frame.inputs, noisy));
    EXPECT_TRUE(sameImage(noisy.composite.view(), without.composite.view()));
    // A real object 10 % nearer than the floor everywhere hides the floor's shadow, not the ball
    // (2.5 m away, nearer still).
    for (int i = 0; i < kW * kH; ++i)
        mm[i] = 2700;
    ASSERT_TRUE(renderer->render(frame.inputs, nearer));
    const int shadow_x = static_cast<int>((kW - 1) / 2.0 + 0.25 * 200 / 3.0);
    EXPECT_LT(pixelBytes(without.composite, shadow_x, kH / 2)[0], 130);
    EXPECT_EQ(pixelBytes(nearer.composite, shadow_x, kH / 2)[0], 140);
    EXPECT_NE(pixelBytes(nearer.composite, kW / 2, kH / 2)[0], 140);  // the ball
}

TEST(Renderer, DepthRaysSeeTheMeasuredSurfaceThroughGlass) {
    // Index-1 glass bends nothing: with RT²AR's depth-map traversal, or with the depth mesh, the
    // rays through it find the real wall the depth camera measured and show the camera's pixels;
    // without, the black sky.
    SceneDescription scene;
    Material clear = material(MaterialType::kGlass, "clear");
    clear.ior = {1, 1, 1};
    scene.materials["clear"] = clear;
    SceneObject slab = object("slab", ObjectRole::kVirtual, ShapeType::kBox, "clear", {0, 0, 1});
    slab.shape.size = {0.1f, 0.1f, 0.05f};
    scene.objects.push_back(slab);
    const Image gradient = filledImage(kW, kH, [](int x, int y) {
        return std::array<uint8_t, 3>{static_cast<uint8_t>(40 + x), static_cast<uint8_t>(60 + y),
                                      100};
    });
    Image depth(ImageDesc::packed(PixelFormat::kDepth16, kW, kH));
    for (size_t i = 0; i < static_cast<size_t>(kW) * kH; ++i)
        reinterpret_cast<uint16_t*>(depth.bytes().data())[i] = 2000;
    for (DepthSecondaryRays mode :
         {DepthSecondaryRays::kScreenSpace, DepthSecondaryRays::kMesh, DepthSecondaryRays::kNone}) {
        RenderOptions options;
        options.depth_secondary = mode;
        auto renderer = makeRenderer(scene, options);
        ASSERT_TRUE(renderer);
        Frame frame = makeFrame(Eigen::Isometry3d::Identity(), gradient);
        frame.inputs.depth_mm = depth.view();
        RenderLayers out;
        ASSERT_TRUE(renderer->render(frame.inputs, out));
        const int x = kW / 2, y = kH / 2;
        const uint8_t* got = pixelBytes(out.composite, x, y);
        if (mode != DepthSecondaryRays::kNone) {
            EXPECT_NEAR(got[0], 40 + x, 1) << static_cast<int>(mode);
            EXPECT_NEAR(got[1], 60 + y, 1) << static_cast<int>(mode);
        } else {
            EXPECT_EQ(got[0], 0);
        }
    }
}

TEST(Renderer, GhostsShadowVirtualObjectsAndRealMirrorsReflectThem) {
    // A real box between the sun and a virtual ball darkens the ball's top.
    SceneDescription scene;
    scene.materials["white"] = material(MaterialType::kDiffuse, "white");
    SceneObject ball =
        object("ball", ObjectRole::kVirtual, ShapeType::kSphere, "white", {0, 0, 0.5});
    ball.shape.radius = 0.1f;
    scene.objects.push_back(ball);
    scene.lights.push_back(directionalLight("sun", {1, 0, -1}, 2));
    SceneDescription boxed = scene;
    scene.materials["box"] = material(MaterialType::kDiffuse, "box");
    boxed.materials["box"] = scene.materials["box"];
    SceneObject box = object("box", ObjectRole::kGhost, ShapeType::kBox, "box", {-0.5, 0, 1});
    box.shape.size = {0.3f, 0.3f, 0.3f};
    boxed.objects.push_back(box);
    const int cx = (kW - 1) / 2, cy = (kH - 1) / 2;
    uint8_t top[2];
    for (int i = 0; i < 2; ++i) {
        auto renderer = makeRenderer(i == 0 ? scene : boxed, RenderOptions{});
        ASSERT_TRUE(renderer);
        Frame frame = makeFrame(lookDown({0, 0, 3}), greyImage(90));
        RenderLayers out;
        ASSERT_TRUE(renderer->render(frame.inputs, out));
        top[i] = pixelBytes(out.composite, cx, cy)[0];
    }
    EXPECT_GT(top[0], 100);
    EXPECT_EQ(top[1], 0);

    // A real mirror floor shows the virtual ball lit from below: the composite adds the
    // reflection to the camera image where the mirror is.
    SceneDescription mirrored;
    mirrored.materials["white"] = scene.materials["white"];
    mirrored.objects.push_back(ball);
    mirrored.materials["floor"] = material(MaterialType::kMirror, "floor");
    mirrored.materials["floor"].reflectance = 0.5f;
    SceneObject floor = object("floor", ObjectRole::kGhost, ShapeType::kPlane, "floor", {0, 0, 0});
    floor.shape.size = {20, 20, 0};
    mirrored.objects.push_back(floor);
    mirrored.lights.push_back(pointLight({0, 0, 0.2}, 1));
    RenderOptions options;
    options.keep_layers = true;
    auto renderer = makeRenderer(mirrored, options);
    ASSERT_TRUE(renderer);
    Frame frame = makeFrame(lookDown({1, 0, 3}), greyImage(90));
    RenderLayers out;
    ASSERT_TRUE(renderer->render(frame.inputs, out));
    // The mirror image of the ball centre is (0, 0, -0.5).
    const auto image = frame.inputs.camera.project(frame.inputs.T_world_cam.inverse() *
                                                   Eigen::Vector3d(0, 0, -0.5));
    ASSERT_TRUE(image);
    const int x = static_cast<int>(std::lround(image->x())),
              y = static_cast<int>(std::lround(image->y()));
    EXPECT_EQ(out.mask.at(x, y)[0], 0.f);
    EXPECT_GT(pixelBytes(out.composite, x, y)[0], 95);
    EXPECT_EQ(pixelBytes(out.composite, kW - 5, y)[0], 90);  // the bare mirror: the camera pixel
}

// RT²AR's bench scene in miniature: a metal ball on a slightly reflective real table under a
// spherical lamp, optionally with a second ghost (a diffuse box) so the table is no longer the
// only ghost and reflections of ghosts in ghosts are possible.
SceneDescription reflectiveTableScene(bool second_ghost) {
    SceneDescription scene;
    Material table = material(MaterialType::kDiffuse, "table");
    table.albedo = Rgb::Constant(0.55f);
    table.reflectance = 0.15f;
    scene.materials["table"] = table;
    SceneObject plane = object("table", ObjectRole::kGhost, ShapeType::kPlane, "table", {0, 0, 0});
    plane.shape.size = {3, 2, 0};
    scene.objects.push_back(plane);
    scene.materials["metal"] = material(MaterialType::kMetal, "metal");
    SceneObject ball =
        object("ball", ObjectRole::kVirtual, ShapeType::kSphere, "metal", {0, 0, 0.1});
    ball.shape.radius = 0.1f;
    scene.objects.push_back(ball);
    if (second_ghost) {
        scene.materials["box"] = material(MaterialType::kDiffuse, "box");
        SceneObject box =
            object("box", ObjectRole::kGhost, ShapeType::kBox, "box", {-0.4, 0.3, 0.1});
        box.shape.size = {0.2f, 0.2f, 0.2f};
        scene.objects.push_back(box);
    }
    Light lamp = pointLight({0.6, -0.4, 1.2}, 3);
    lamp.type = LightType::kSphere;
    lamp.radius = 0.08f;
    scene.lights.push_back(lamp);
    return scene;
}

// The screen footprint only skips tiles whose pixels the per-pixel test would not trace, and
// the per-pixel test only skips pixels whose mixed and real radiance agree bit for bit, so
// every switch gives the same bytes.
TEST(Renderer, ScreenFootprintSkipsTilesButNotOnePixelChanges) {
    for (bool second_ghost : {false, true})
        for (SoftShadowMethod method : {SoftShadowMethod::kHard, SoftShadowMethod::kAdaptive})
            for (bool distorted : {false, true}) {
                Image images[3];
                RenderStats stats[3];
                for (int i = 0; i < 3; ++i) {
                    RenderOptions options;
                    options.soft_shadows = method;
                    options.shadow_samples = 8;
                    options.samples_per_pixel = 4;
                    options.tile_size = 8;
                    options.screen_footprint = i == 0;
                    options.only_virtual_footprint = i < 2;
                    auto renderer = makeRenderer(reflectiveTableScene(second_ghost), options);
                    ASSERT_TRUE(renderer);
                    // The distorted camera looks flatter, so tiles cross the table's horizon.
                    Frame frame =
                        distorted
                            ? makeFrame(lookAt({0.4, -1.2, 0.35}, {0, 0, 0.1}), noiseImage(), 120)
                            : makeFrame(lookAt({0.3, -0.9, 0.7}, {0, 0, 0.05}), noiseImage(), 150);
                    if (distorted)
                        frame.inputs.camera.distortion = {-0.15, 0.03, 0.001, -0.001};
                    RenderLayers out;
                    ASSERT_TRUE(renderer->render(frame.inputs, out, &stats[i]));
                    images[i] = out.composite;
                }
                const std::string what =
                    std::string(second_ghost ? "two ghosts" : "lone table") +
                    (method == SoftShadowMethod::kHard ? ", hard" : ", adaptive") +
                    (distorted ? ", distorted lens" : "");
                EXPECT_TRUE(sameImage(images[0].view(), images[1].view())) << what;
                EXPECT_TRUE(sameImage(images[0].view(), images[2].view())) << what;
                EXPECT_FALSE(sameImage(images[0].view(), noiseImage().view())) << what;
                // Tiles without virtual content trace no primary ray at all.
                EXPECT_LT(stats[0].primary_rays, stats[1].primary_rays) << what;
                EXPECT_EQ(stats[1].primary_rays, static_cast<uint64_t>(4 * kW * kH)) << what;
                EXPECT_EQ(stats[0].pixels_traced, stats[1].pixels_traced) << what;
                EXPECT_LT(stats[1].pixels_traced, stats[2].pixels_traced) << what;
            }
}

// Objects that use one mesh (in memory, or one file) at one scale share its triangles and its
// BVH, instanced at each pose; at another scale it is another mesh. Each instance is drawn.
TEST(Renderer, AMeshSeveralObjectsUseIsBuiltOnce) {
    auto box = std::make_shared<TriangleMesh>(makeShapeMesh([] {
        Shape shape;
        shape.type = ShapeType::kBox;
        shape.size = {0.1f, 0.1f, 0.1f};
        return shape;
    }()));
    SceneDescription scene;
    scene.materials["grey"] = material(MaterialType::kDiffuse, "grey");
    for (int i = 0; i < 3; ++i) {
        SceneObject o = object("box" + std::to_string(i), ObjectRole::kVirtual, ShapeType::kMesh,
                               "grey", {-0.2 + 0.2 * i, 0, 0.05});
        o.shape.mesh_data = box;
        o.shape.scale = i < 2 ? 1.f : 0.5f;  // the third is another mesh
        scene.objects.push_back(o);
    }
    scene.lights.push_back(pointLight({0.3, -0.5, 1.0}, 2));
    RenderOptions options;
    options.keep_layers = true;  // the mask shows where each box is
    auto renderer = makeRenderer(scene, options);
    ASSERT_TRUE(renderer);
    const bench::CreationTimes created = bench::creationTimes(*renderer);
    EXPECT_EQ(created.triangles_built, 2 * box->triangles.size());
    EXPECT_GT(created.bvh_s, 0.0);
    EXPECT_GE(created.load_s, 0.0);

    // Two objects of one mesh file: loaded once, built once.
    const std::filesystem::path obj = ::mixray::test::tempDir() / "quad.obj";
    ::mixray::test::writeText(obj,
                              "v 0 0 0\nv 0.1 0 0\nv 0.1 0.1 0\nv 0 0.1 0\nf 1 2 3\nf 1 3 4\n");
    SceneDescription from_file = scene;
    for (SceneObject& o : from_file.objects) {
        o.shape.mesh_data = nullptr;
        o.shape.mesh = obj;
        o.shape.scale = 1;
    }
    auto file_renderer = makeRenderer(from_file, options);
    ASSERT_TRUE(file_renderer);
    EXPECT_EQ(bench::creationTimes(*file_renderer).triangles_built, 2u);

    Frame frame = makeFrame(lookAt({0, -1.0, 0.4}, {0, 0, 0.05}), noiseImage(), 160);
    RenderLayers out;
    ASSERT_TRUE(renderer->render(frame.inputs, out));
    // Each box covers pixels around its own projection.
    for (int i = 0; i < 3; ++i) {
        const auto px = frame.inputs.camera.project(frame.inputs.T_world_cam.inverse() *
                                                    Eigen::Vector3d(-0.2 + 0.2 * i, 0, 0.04));
        ASSERT_TRUE(px);
        const int x = static_cast<int>(px->x()), y = static_cast<int>(px->y());
        EXPECT_EQ(out.mask.pixels[static_cast<size_t>(y) * out.mask.width + x], 1.f) << i;
    }
}

TEST(Renderer, RayLogHoldsExactlyTheRaysTheStatsCount) {
    RenderOptions options;
    options.soft_shadows = SoftShadowMethod::kAdaptive;
    options.shadow_samples = 8;
    auto renderer = makeRenderer(reflectiveTableScene(true), options);
    ASSERT_TRUE(renderer);
    Frame frame = makeFrame(lookAt({0.3, -0.9, 0.7}, {0, 0, 0.05}), noiseImage(), 150);
    RenderLayers plain, logged;
    RenderStats plain_stats, stats;
    ASSERT_TRUE(renderer->render(frame.inputs, plain, &plain_stats));
    bench::RayLog log;
    log.rays.resize(3);  // stale entries from an earlier frame are replaced
    ASSERT_TRUE(bench::renderLoggingRays(*renderer, frame.inputs, logged, &stats, log));
    EXPECT_TRUE(sameImage(plain.composite.view(), logged.composite.view()));
    EXPECT_EQ(stats.rays(), plain_stats.rays());
    EXPECT_GT(stats.secondary_rays, 0u);
    EXPECT_GT(stats.shadow_rays, 0u);
    EXPECT_EQ(log.count(bench::RayLog::Kind::kPrimary), stats.primary_rays);
    EXPECT_EQ(log.count(bench::RayLog::Kind::kSecondary), stats.secondary_rays);
    EXPECT_EQ(log.count(bench::RayLog::Kind::kShadow), stats.shadow_rays);
    EXPECT_EQ(log.rays.size(), stats.rays());
    size_t ghost_rays = 0;
    for (const bench::RayLog::Ray& r : log.rays) {
        const Eigen::Vector3f d(r.direction[0], r.direction[1], r.direction[2]);
        EXPECT_NEAR(d.norm(), 1.f, 1e-4f);
        EXPECT_GT(r.t_far, 0.f);
        ghost_rays += r.ghosts_only ? 1 : 0;
    }
    EXPECT_GT(ghost_rays, 0u);  // real-only rays of the differential pair
    // Bare Embree traces them all on the same BVH.
    const bench::BareTraceTimes bare = bench::traceBare(*renderer, log, 1);
    EXPECT_GT(bare.total(), 0.0);
    EXPECT_FALSE(bare.primary_method.empty());
    EXPECT_FALSE(bare.shadow_method.empty());
    // Every way tried is reported, and the one named for each kind is the fastest of them.
    const auto fastest = [&](bench::RayLog::Kind kind, size_t ways, double seconds,
                             const std::string& method) {
        size_t seen = 0;
        for (const bench::BareTraceTimes::Method& m : bare.tried) {
            if (m.kind != kind)
                continue;
            ++seen;
            EXPECT_GE(m.wall_s, seconds) << m.name;
            if (m.name == method) {
                EXPECT_EQ(m.wall_s, seconds) << m.name;
            }
        }
        EXPECT_EQ(seen, ways);
    };
    fastest(bench::RayLog::Kind::kPrimary, 2, bare.primary_s, bare.primary_method);
    fastest(bench::RayLog::Kind::kSecondary, 3, bare.secondary_s, bare.secondary_method);
    fastest(bench::RayLog::Kind::kShadow, 3, bare.shadow_s, bare.shadow_method);
}

TEST(Renderer, ShadowsCanBeSwitchedOff) {
    SceneDescription scene = shadowScene({1, 0, -2}, 2, 1);
    RenderOptions options;
    options.shadows = false;
    options.soft_shadows = SoftShadowMethod::kHard;
    auto renderer = makeRenderer(scene, options);
    ASSERT_TRUE(renderer);
    const float lit = 0.6f / optics::kPi * (2 * 2 / std::sqrt(5.f) + 1);
    Frame frame = makeFrame(lookDown({0, 0, 3}), greyImage(optics::encodeSrgb8(lit)));
    RenderLayers out;
    RenderStats stats;
    ASSERT_TRUE(renderer->render(frame.inputs, out, &stats));
    EXPECT_EQ(stats.shadow_rays, 0u);
    EXPECT_GT(stats.primary_rays, 0u);
    // Where the shadow of light a would fall, (0.25, 0, 0), the floor is the camera pixel.
    const auto shadow = frame.inputs.camera.project(frame.inputs.T_world_cam.inverse() *
                                                    Eigen::Vector3d(0.25, 0, 0));
    ASSERT_TRUE(shadow);
    const int x = static_cast<int>(std::lround(shadow->x())),
              y = static_cast<int>(std::lround(shadow->y()));
    EXPECT_EQ(pixelBytes(out.composite, x, y)[0], optics::encodeSrgb8(lit));
}

}  // namespace
}  // namespace mixray::render::test

namespace mixray::render::test {
namespace {

// Estimated light changes while the geometry does not: setLights() renders exactly what a
// renderer built with those lights renders, and environment maps from memory are the file's.
TEST(Renderer, ReplacedLightsRenderAsIfBuiltWithThem) {
    const Eigen::Vector3d first(1, 0, -2), second(-1, 0.5, -2);
    RenderOptions options;
    options.soft_shadows = SoftShadowMethod::kHard;
    auto changed = makeRenderer(shadowScene(first, 2, 1), options);
    auto built = makeRenderer(shadowScene(second, 2, 1), options);
    ASSERT_TRUE(changed && built);
    Frame frame = makeFrame(lookDown({0, 0, 3}), greyImage(120));
    RenderLayers before, after, reference;
    ASSERT_TRUE(changed->render(frame.inputs, before));
    ASSERT_TRUE(changed->setLights(shadowScene(second, 2, 1).lights));
    ASSERT_TRUE(changed->render(frame.inputs, after));
    ASSERT_TRUE(built->render(frame.inputs, reference));
    EXPECT_TRUE(sameImage(after.composite.view(), reference.composite.view()));
    EXPECT_FALSE(sameImage(before.composite.view(), after.composite.view()));

    // A bad light is refused and the old ones stay.
    Light bad = directionalLight("bad", {0, 0, -1}, 1);
    bad.direction = Eigen::Vector3d::Zero();
    EXPECT_FALSE(changed->setLights({bad}));
    RenderLayers still;
    ASSERT_TRUE(changed->render(frame.inputs, still));
    EXPECT_TRUE(sameImage(still.composite.view(), reference.composite.view()));

    // An environment map in memory is the same map as from its file.
    const auto radiance = [](int x, int y) {
        return Eigen::Vector3f(0.2f + 0.01f * static_cast<float>(x), 0.5f,
                               0.1f + 0.02f * static_cast<float>(y));
    };
    const Light from_file = environmentLight(writeEnvironment("gradient", 32, 16, radiance));
    // The file's own texels (RGBE rounds the values written).
    auto texture = Texture::load(from_file.environment);
    ASSERT_TRUE(texture) << texture.status().toString();
    auto image = std::make_shared<FloatImage>();
    image->width = texture->width();
    image->height = texture->height();
    for (int y = 0; y < image->height; ++y)
        for (int x = 0; x < image->width; ++x)
            for (int c = 0; c < 3; ++c)
                image->pixels.push_back(texture->texel(x, y)[c]);
    Light in_memory = from_file;
    in_memory.environment.clear();
    in_memory.environment_image = image;
    SceneDescription scene;
    Material chrome = material(MaterialType::kMirror, "chrome");
    chrome.reflectance = 1;
    scene.materials["chrome"] = chrome;
    SceneObject ball =
        object("ball", ObjectRole::kVirtual, ShapeType::kSphere, "chrome", {0, 0, 0});
    ball.shape.radius = 0.3f;
    scene.objects.push_back(ball);
    scene.lights = {from_file};
    auto file_renderer = makeRenderer(scene, options);
    scene.lights = {in_memory};
    auto memory_renderer = makeRenderer(scene, options);
    ASSERT_TRUE(file_renderer && memory_renderer);
    RenderLayers a, b;
    ASSERT_TRUE(file_renderer->render(frame.inputs, a));
    ASSERT_TRUE(memory_renderer->render(frame.inputs, b));
    EXPECT_TRUE(sameImage(a.composite.view(), b.composite.view()));
    // A map of the wrong shape is refused.
    auto square = std::make_shared<FloatImage>(*image);
    square->height = 32;
    square->pixels.resize(32 * 32 * 3, 0.f);
    in_memory.environment_image = square;
    EXPECT_FALSE(file_renderer->setLights({in_memory}));
}

}  // namespace
}  // namespace mixray::render::test
