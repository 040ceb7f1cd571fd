// Camera matching (render/src/sensor_noise.h): the camera's noise measured as a function of
// brightness, on smooth shading and across edges, and through the Renderer: virtual pixels
// carry the same noise as the real ones around them, and a frame with nothing virtual stays the
// camera image.
#include "sensor_noise.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "renderer_test_util.h"

namespace mixray::render::test {
namespace {

// An image w x h of `value(x, y)` plus Gaussian noise of σ `sigma(value)`, rounded and clamped.
Image noisyImage(int w, int h, const std::function<double(int, int)>& value,
                 const std::function<double(double)>& sigma, uint32_t seed = 7) {
    std::mt19937 rng(seed);
    std::normal_distribution<double> normal;
    return filledImage(w, h, [&](int x, int y) {
        std::array<uint8_t, 3> c{};
        const double v = value(x, y);
        for (uint8_t& ch : c)
            ch =
                static_cast<uint8_t>(std::clamp(std::lround(v + sigma(v) * normal(rng)), 0L, 255L));
        return c;
    });
}

TEST(SensorNoise, MeasuredNoiseFollowsBrightnessOnSmoothShading) {
    // A ramp from code 10 to 245, and noise that grows with brightness as shot noise does.
    const auto sigma = [](double v) { return 1.0 + 0.02 * v; };
    const Image image = noisyImage(
        480, 360, [](int x, int y) { return 10 + 235.0 * x / 479 + 3 * std::sin(y * 0.02); },
        sigma);
    const detail::NoiseProfile profile = detail::measureNoise(image.view(), 1);
    for (const double code : {40.0, 120.0, 200.0})
        EXPECT_NEAR(profile.at(static_cast<float>(code)), sigma(code), 0.1 * sigma(code))
            << "code " << code;
    EXPECT_LT(profile.at(40), profile.at(200));
}

TEST(SensorNoise, EdgesMoveTheMeasureLittle) {
    // A chessboard of 8-pixel squares: a third of the pixels touch an edge.
    const Image image = noisyImage(
        320, 240, [](int x, int y) { return ((x / 8 + y / 8) & 1) ? 180.0 : 60.0; },
        [](double) { return 2.5; });
    const detail::NoiseProfile profile = detail::measureNoise(image.view(), 1);
    EXPECT_NEAR(profile.at(60), 2.5, 0.15 * 2.5);
    EXPECT_NEAR(profile.at(180), 2.5, 0.15 * 2.5);
}

TEST(SensorNoise, NothingToMeasureIsNoNoise) {
    const Image flat = filledImage(64, 48, [](int, int) { return std::array<uint8_t, 3>{}; });
    EXPECT_EQ(detail::measureNoise(flat.view()).at(0), 0);
    detail::Grain grain;
    grain.update(flat.view());
    EXPECT_EQ(grain.add(100, 1, 0), 100);
}

constexpr int kWidth = 160, kHeight = 120;

// A white virtual box under a sun, seen from 2 m above over a noisy grey camera image.
Image renderBox(std::optional<float> noise, bool with_box = true) {
    SceneDescription scene;
    addGhostFloor(scene);
    scene.materials["white"] = material(MaterialType::kDiffuse, "white");
    scene.materials["white"].albedo = Rgb::Constant(0.5f);
    if (with_box) {
        SceneObject box =
            object("box", ObjectRole::kVirtual, ShapeType::kBox, "white", {0, 0, 0.05});
        box.shape.size = {0.6f, 0.6f, 0.1f};
        scene.objects.push_back(box);
    }
    scene.lights.push_back(directionalLight("sun", {0, 0, -1}, 1.5f));
    scene.camera_matching.noise = noise;
    RenderOptions options;
    options.threads = 2;
    auto renderer = Renderer::create(scene, options);
    EXPECT_TRUE(renderer.isOk()) << renderer.status().toString();
    const Image camera = noisyImage(
        kWidth, kHeight, [](int, int) { return 110.0; }, [](double) { return 3.0; });
    RenderInputs in;
    in.camera = calibration::CameraModel::pinhole(kWidth, kHeight, 200, 200, (kWidth - 1) / 2.0,
                                                  (kHeight - 1) / 2.0);
    in.camera_image = camera.view();
    in.T_world_cam = lookDown({0, 0, 2});
    RenderLayers out;
    EXPECT_TRUE((*renderer)->render(in, out).isOk());
    if (!with_box) {
        EXPECT_TRUE(sameImage(out.composite.view(), camera.view()));
    }
    return std::move(out.composite);
}

// The standard deviation of the red channel over [x0, x0 + n) x [y0, y0 + n).
double blockStddev(const Image& image, int x0, int y0, int n) {
    double s = 0, ss = 0;
    for (int y = y0; y < y0 + n; ++y)
        for (int x = x0; x < x0 + n; ++x) {
            const double v = pixelBytes(image, x, y)[0];
            s += v;
            ss += v * v;
        }
    const double count = static_cast<double>(n) * n;
    return std::sqrt(std::max(0.0, ss / count - (s / count) * (s / count)));
}

TEST(SensorNoise, VirtualPixelsCarryTheCamerasNoise) {
    // The box's top spans pixels 48..111 across; its middle is flat virtual light.
    const Image clean = renderBox(std::nullopt);
    const Image matched = renderBox(1.0f);
    const double real = blockStddev(matched, 4, 4, 30);  // the camera's own floor
    EXPECT_NEAR(real, 3.0, 0.3);
    EXPECT_LT(blockStddev(clean, 60, 40, 40), 0.6);  // virtual light is clean without matching
    EXPECT_NEAR(blockStddev(matched, 60, 40, 40), real, 0.15 * real);
    // Nothing virtual: the camera image byte for byte with matching on (checked inside).
    renderBox(1.0f, /*with_box=*/false);
}

}  // namespace
}  // namespace mixray::render::test
