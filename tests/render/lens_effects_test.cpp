// RT²AR §IV-F's lens effects (render/src/lens_effects.h): glare streak weights and length,
// bloom's spread and energy, and through the Renderer: nothing virtual leaves the camera image
// as it is, a bright virtual sphere glows onto the real image around it, glare only along the
// diagonals.
#include "lens_effects.h"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <numeric>

#include "renderer_test_util.h"

namespace mixray::render::test {
namespace {

using detail::Film;
using detail::PixelBox;
using detail::Vec3;

double total(const std::vector<Vec3>& image) {
    return std::accumulate(image.begin(), image.end(), 0.0,
                           [](double s, const Vec3& v) { return s + v.sum(); });
}

TEST(LensEffects, GlareStreakWeightsArePowersOfTheAttenuationAlongOneDiagonal) {
    constexpr int w = 200, h = 200, c = 120;
    std::vector<Vec3> in(w * h, Vec3::Zero()), out(in.size(), Vec3::Zero());
    in[c * w + c] = Vec3::Ones();
    detail::StreakBuffers buffers;
    const PixelBox box{0, 0, w, h};
    // One pass (b = 1): out(p) gathers in(p + s·(1, 1)), so the light at c lands on c − s·(1, 1)
    // with weight 0.9^s / Σ 0.9^s, and nowhere else.
    detail::addGlareStreak(in, w, box, 1, 1, 1, 0.9f, 1, out, buffers);
    const double norm = 1 + 0.9 + 0.81 + 0.729;
    for (int s = 0; s < 4; ++s)
        EXPECT_NEAR(out[(c - s) * w + (c - s)].x(), std::pow(0.9, s) / norm, 1e-6) << s;
    EXPECT_EQ(out[(c - 4) * w + (c - 4)], Vec3::Zero());
    EXPECT_EQ(out[(c + 1) * w + (c + 1)], Vec3::Zero());
    EXPECT_NEAR(total(out), 3, 1e-5);
    // Three passes (b = 1, 4, 16): a streak 63 pixels long that keeps the light.
    std::fill(out.begin(), out.end(), Vec3::Zero());
    detail::addGlareStreak(in, w, box, 1, 1, 3, 0.9f, 1, out, buffers);
    EXPECT_GT(out[(c - 63) * w + (c - 63)].x(), 0);
    EXPECT_EQ(out[(c - 64) * w + (c - 64)], Vec3::Zero());
    EXPECT_EQ(out[c * w + (c - 10)], Vec3::Zero());  // off the diagonal
    EXPECT_NEAR(total(out), 3, 1e-5);
    // Its weights fall off along the streak.
    EXPECT_GT(out[(c - 5) * w + (c - 5)].x(), out[(c - 50) * w + (c - 50)].x());
}

// A film w x h with one bright virtual square: `radiance` over [x0, x0 + n) x [y0, y0 + n).
Film brightSquare(int w, int h, int x0, int y0, int n, float radiance) {
    Film film;
    film.beginFrame(w, h, 16, false, false);
    for (int y = y0; y < y0 + n; ++y)
        for (int x = x0; x < x0 + n; ++x) {
            const size_t i = static_cast<size_t>(y) * w + x;
            film.mask[i] = 1;
            film.virtual_radiance[i] = Vec3::Constant(radiance);
            film.tile_dirty[static_cast<size_t>((y / 16) * film.tiles_x + x / 16)] = 1;
        }
    return film;
}

TEST(LensEffects, BloomSpreadsTheLightAboveTheThresholdAndKeepsItsEnergy) {
    constexpr int w = 160, h = 120;
    const Film film = brightSquare(w, h, 80, 60, 2, 3);
    // Two thresholds in one pass: 1 passes two thirds of the light, 4 none of it.
    std::array images{detail::BrightImage(1), detail::BrightImage(4)};
    detail::brightPass(film, images);
    const std::vector<Vec3>& bright = images[0].light;
    const PixelBox box = images[0].box;
    EXPECT_TRUE(images[1].box.empty());
    EXPECT_EQ(total(images[1].light), 0);
    EXPECT_EQ(box.x0, 80);
    EXPECT_EQ(box.y1, 62);
    // Luminance 3 over a threshold of 1: two thirds of each pixel's light.
    EXPECT_NEAR(bright[60 * w + 80].x(), 2, 1e-5);
    EXPECT_NEAR(total(bright), 4 * 3 * 2, 1e-4);
    for (const float radius : {1.f, 3.f, 6.f}) {
        std::vector<Vec3> glow(bright.size(), Vec3::Zero());
        const PixelBox added = detail::addBloom(bright, w, h, box, radius, 0.5f, glow);
        EXPECT_NEAR(total(glow), 0.5 * total(bright), 1e-3 * total(bright)) << radius;
        // The light spreads about as far as the Gaussian, and not beyond the box it reports.
        EXPECT_GT(glow[61 * w + 81 + static_cast<int>(2 * radius)].x(), 0) << radius;
        EXPECT_EQ(glow[61 * w + 81 + static_cast<int>(6 * radius) + 12].x(), 0) << radius;
        EXPECT_TRUE(added.contains(81 + static_cast<int>(2 * radius), 61));
    }
    // Nothing above the threshold the next frame: the last frame's light is cleared.
    images[0].threshold = 4;
    detail::brightPass(film, images);
    EXPECT_TRUE(images[0].box.empty());
    EXPECT_EQ(total(images[0].light), 0);
}

SceneDescription brightSphereScene(const LensEffects& effects) {
    SceneDescription scene;
    addGhostFloor(scene);
    scene.materials["white"] = material(MaterialType::kDiffuse, "white");
    scene.materials["white"].albedo = Rgb::Constant(0.9f);
    SceneObject ball =
        object("ball", ObjectRole::kVirtual, ShapeType::kSphere, "white", {0, 0, 0.1});
    ball.shape.radius = 0.1f;
    scene.objects.push_back(ball);
    // The top of the ball: 0.9 · 30 / π ≈ 8.6.
    scene.lights.push_back(directionalLight("sun", {0, 0, -1}, 30));
    scene.lens_effects = effects;
    return scene;
}

// The composite `renderer` makes seen from 2 m above, w x h, over a grey camera image.
Image renderFromAbove(Renderer& renderer, int w = 160, int h = 120) {
    const Image camera = filledImage(w, h, [](int, int) {
        return std::array<uint8_t, 3>{90, 90, 90};
    });
    RenderInputs in;
    in.camera = calibration::CameraModel::pinhole(w, h, 200, 200, (w - 1) / 2.0, (h - 1) / 2.0);
    in.camera_image = camera.view();
    in.T_world_cam = lookDown({0, 0, 2});
    RenderLayers out;
    EXPECT_TRUE(renderer.render(in, out).isOk());
    return std::move(out.composite);
}

Image renderFromAbove(const SceneDescription& scene) {
    auto renderer = Renderer::create(scene, RenderOptions{});
    EXPECT_TRUE(renderer.isOk()) << renderer.status().toString();
    return renderFromAbove(**renderer);
}

LensEffects bloomAndGlare() {
    LensEffects effects;
    effects.bloom = Bloom{};
    effects.glare = Glare{};
    return effects;
}

TEST(LensEffects, AFrameWithNothingVirtualStaysTheCameraImage) {
    // Every pixel of the lit floor would bloom at these thresholds, were it virtual.
    LensEffects effects = bloomAndGlare();
    effects.bloom->threshold = effects.glare->threshold = 1e-3f;
    SceneDescription scene = brightSphereScene(effects);
    scene.objects.back().role = ObjectRole::kGhost;
    const Image camera = filledImage(160, 120, [](int, int) {
        return std::array<uint8_t, 3>{90, 90, 90};
    });
    EXPECT_TRUE(sameImage(renderFromAbove(scene).view(), camera.view()));
    // A virtual object whose marker is not seen this frame.
    scene = brightSphereScene(effects);
    scene.objects.back().anchor = "marker:7";
    EXPECT_TRUE(sameImage(renderFromAbove(scene).view(), camera.view()));
}

TEST(LensEffects, ABrightVirtualSphereGlowsOntoTheRealImageAroundIt) {
    const Image plain = renderFromAbove(brightSphereScene({}));
    LensEffects bloom;
    bloom.bloom = Bloom{};
    const Image bloomed = renderFromAbove(brightSphereScene(bloom));
    // The ball is about 10.5 pixels in radius around (79.5, 59.5).
    const auto grey = [](const Image& image, int x, int y) { return pixelBytes(image, x, y)[0]; };
    EXPECT_GT(grey(bloomed, 79 + 14, 59), grey(plain, 79 + 14, 59));
    EXPECT_GT(grey(bloomed, 79, 59 - 14), grey(plain, 79, 59 - 14));
    EXPECT_GE(grey(bloomed, 79, 59), grey(plain, 79, 59));
    EXPECT_EQ(grey(bloomed, 2, 2), grey(plain, 2, 2));  // far away: the camera pixel

    // Glare alone: along the diagonals, 25 pixels from the centre, and not beside it on the
    // row, which no diagonal through the ball reaches (25 / √2 > 10.5 + 1).
    LensEffects glare;
    glare.glare = Glare{};
    const Image streaked = renderFromAbove(brightSphereScene(glare));
    EXPECT_GT(grey(streaked, 79 + 18, 59 + 18), grey(plain, 79 + 18, 59 + 18));
    EXPECT_GT(grey(streaked, 79 - 18, 59 - 18), grey(plain, 79 - 18, 59 - 18));
    EXPECT_EQ(grey(streaked, 79 + 25, 59), grey(plain, 79 + 25, 59));
    EXPECT_EQ(grey(streaked, 79, 59 + 25), grey(plain, 79, 59 + 25));
}

// The effects keep buffers between frames: a frame of another size (here the same pixel count,
// transposed) comes out as from a fresh renderer.
TEST(LensEffects, AFrameOfAnotherSizeIsAsFromAFreshRenderer) {
    const SceneDescription scene = brightSphereScene(bloomAndGlare());
    auto fresh = Renderer::create(scene, RenderOptions{});
    auto reused = Renderer::create(scene, RenderOptions{});
    ASSERT_TRUE(fresh.isOk() && reused.isOk());
    (void)renderFromAbove(**reused, 160, 120);
    const Image after = renderFromAbove(**reused, 120, 160);
    EXPECT_TRUE(sameImage(after.view(), renderFromAbove(**fresh, 120, 160).view()));
}

}  // namespace
}  // namespace mixray::render::test
