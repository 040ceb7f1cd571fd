// Cancelling Renderer::render() through RenderInputs::stop: a frame stops within about one
// tile's time, is dropped whole, and the renderer's next frame is exact.
#include <gtest/gtest.h>

#include <chrono>
#include <stop_token>
#include <thread>

#include "mixray/render/renderer.h"
#include "renderer_test_util.h"

namespace mixray::render::test {
namespace {

using calibration::CameraModel;
using Clock = std::chrono::steady_clock;

constexpr int kW = 320, kH = 240;

// A grey ball bound to marker 1 over a ghost floor under a spherical light, seen from above:
// the ball and its soft shadow cover most of the image, so every shadow sample counts.
SceneDescription ballScene() {
    SceneDescription scene;
    addGhostFloor(scene, 0.6f);
    scene.materials["grey"] = material(MaterialType::kDiffuse, "grey");
    SceneObject ball = object("ball", ObjectRole::kVirtual, ShapeType::kSphere, "grey", {0, 0, 0});
    ball.anchor = "marker:1";
    ball.shape.radius = 0.3f;
    scene.objects.push_back(ball);
    Light light;
    light.name = "key";
    light.type = LightType::kSphere;
    light.position = {0.4, 0.2, 2};
    light.radius = 0.3f;
    light.intensity = Rgb::Constant(4);
    scene.lights.push_back(light);
    return scene;
}

struct Shot {
    Image image = filledImage(kW, kH, [](int x, int y) {
        return std::array<uint8_t, 3>{static_cast<uint8_t>(x), static_cast<uint8_t>(y), 90};
    });
    RenderInputs inputs;
    Shot() {
        inputs.camera_image = image.view();
        inputs.camera = CameraModel::pinhole(kW, kH, 240, 240, (kW - 1) / 2.0, (kH - 1) / 2.0);
        inputs.T_world_cam = lookDown({0, 0, 1.6});
        inputs.T_world_anchor["marker:1"] =
            Eigen::Translation3d(0, 0, 0.3) * Eigen::Isometry3d::Identity();
    }
};

// Soft shadows from 7 rays per sample: fewer than 8, so single rays, not Embree's 16-ray packets.
RenderOptions uniformShadows(int samples_per_pixel) {
    RenderOptions options;
    options.soft_shadows = SoftShadowMethod::kUniform;
    options.shadow_samples = 7;
    options.samples_per_pixel = samples_per_pixel;
    options.threads = 2;
    return options;
}

std::unique_ptr<Renderer> makeRenderer(const RenderOptions& options) {
    auto renderer = Renderer::create(ballScene(), options);
    EXPECT_TRUE(renderer.isOk()) << renderer.status().toString();
    return renderer ? std::move(renderer).value() : nullptr;
}

// Renders `shot` on a thread, requests the stop after `delay`, and returns the render's status
// and how long it took to return after the request.
std::pair<Status, double> renderAndStopAfter(Renderer& renderer, Shot& shot,
                                             std::chrono::milliseconds delay, RenderLayers& out,
                                             RenderStats& stats) {
    std::stop_source stop;
    shot.inputs.stop = stop.get_token();
    Status status;
    Clock::time_point returned;
    std::thread worker([&] {
        status = renderer.render(shot.inputs, out, &stats);
        returned = Clock::now();
    });
    std::this_thread::sleep_for(delay);
    const Clock::time_point requested = Clock::now();
    stop.request_stop();
    worker.join();
    shot.inputs.stop = {};
    return {status, std::chrono::duration<double>(returned - requested).count()};
}

TEST(RendererCancel, AStopFromAnotherThreadEndsTheFrameWithinATile) {
    // 64 samples per pixel, each with 7 shadow rays: ten million rays, seconds for the frame; a
    // 4x4 tile is about 1/1500 of it.
    RenderOptions options = uniformShadows(64);
    options.tile_size = 4;
    auto renderer = makeRenderer(options);
    ASSERT_TRUE(renderer);
    Shot shot;
    RenderLayers out;
    const Image sentinel = filledImage(kW, kH, [](int, int) {
        return std::array<uint8_t, 3>{7, 7, 7};
    });
    out.composite = sentinel;
    RenderStats stats;
    const auto [status, latency_s] =
        renderAndStopAfter(*renderer, shot, std::chrono::milliseconds(300), out, stats);
    EXPECT_EQ(status.code(), ErrorCode::kCancelled) << status.toString();
    EXPECT_LT(latency_s, 2.0) << "the frame took " << latency_s << " s to stop";
    // Dropped whole: neither the composite nor the statistics hold a part of the frame.
    EXPECT_EQ(out.composite.bytes(), sentinel.bytes());
    EXPECT_EQ(stats.rays(), 0u);
    EXPECT_EQ(stats.seconds, 0);

    // The next frame, without the ball (its marker is not seen), is the camera image bit for
    // bit: no tile the cancelled frame shaded leaks into it.
    shot.inputs.T_world_anchor.clear();
    ASSERT_TRUE(renderer->render(shot.inputs, out, &stats));
    EXPECT_EQ(out.composite.bytes(), shot.image.bytes());
}

TEST(RendererCancel, AStopRequestedBeforeTheFrameReturnsAtOnce) {
    auto renderer = makeRenderer({});
    ASSERT_TRUE(renderer);
    Shot shot;
    std::stop_source stop;
    stop.request_stop();
    shot.inputs.stop = stop.get_token();
    RenderLayers out;
    const Status status = renderer->render(shot.inputs, out);
    EXPECT_EQ(status.code(), ErrorCode::kCancelled);
    EXPECT_NE(status.message().find("stopped on request"), std::string::npos) << status.message();
    EXPECT_TRUE(out.composite.bytes().empty());
}

TEST(RendererCancel, TheFrameAfterACancelledOneIsTheSameAsAFreshRenderersFrame) {
    const RenderOptions options = uniformShadows(4);
    auto fresh = makeRenderer(options);
    auto reused = makeRenderer(options);
    ASSERT_TRUE(fresh && reused);
    Shot shot;
    RenderLayers expected;
    ASSERT_TRUE(fresh->render(shot.inputs, expected));

    // Stop the reused renderer at a few points of a frame of a moved camera (different tiles
    // dirty), then render the shot itself.
    Shot moved;
    moved.inputs.T_world_cam = lookDown({0.2, -0.1, 1.4});
    int cancelled = 0;
    for (int delay_ms : {5, 40, 120}) {
        RenderLayers out;
        RenderStats stats;
        const Status status =
            renderAndStopAfter(*reused, moved, std::chrono::milliseconds(delay_ms), out, stats)
                .first;
        ASSERT_TRUE(status.isOk() || status.code() == ErrorCode::kCancelled) << status.toString();
        cancelled += status.code() == ErrorCode::kCancelled;
        RenderLayers again;
        ASSERT_TRUE(reused->render(shot.inputs, again));
        EXPECT_EQ(again.composite.bytes(), expected.composite.bytes()) << delay_ms << " ms";
    }
    // At least the earliest stop lands inside a frame (a frame takes far longer than 5 ms).
    EXPECT_GT(cancelled, 0);
}

}  // namespace
}  // namespace mixray::render::test
