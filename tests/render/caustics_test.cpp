// Caustics by photon mapping (render/src/caustics.h, Kán & Kaufmann §3.2): a glass ball focuses
// a beam where the ball-lens formula puts the focus; photons conserve the power a generator
// intercepts and carry its Fresnel transmission through; the kernel estimate integrates to the
// photons' power; through the Renderer a virtual glass ball's caustic brightens a real floor,
// the screen footprint holds it, and a frame with nothing virtual is still the camera image.
#include "caustics.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <memory>
#include <vector>

#include "embree_scene.h"
#include "embree_test_util.h"
#include "integrator.h"
#include "optics.h"
#include "renderer_test_util.h"

namespace mixray::render::detail {
namespace {

using Eigen::Vector3f;

constexpr float kRadius = 0.05f;
constexpr float kIor = 1.5f;

MaterialData materialOf(MaterialType type) {
    MaterialData m;
    m.material.type = type;
    m.material.ior = Rgb::Constant(kIor);
    m.material.albedo = Rgb::Constant(0.5f);
    return m;
}

// A glass ball (material 1) above a diffuse ghost floor (material 0) at z = 0, and optionally a
// diffuse ghost sphere around everything (inside facing), so that no photon escapes.
struct GlassBall {
    std::vector<MaterialData> materials{materialOf(MaterialType::kDiffuse),
                                        materialOf(MaterialType::kGlass)};
    std::vector<ObjectData> objects;
    std::unique_ptr<EmbreeScene> scene;
    RenderOptions options;
    std::optional<DifferentialIntegrator> integrator;

    GlassBall(const Vector3f& centre, bool enclosed) {
        objects.push_back(test::floorObject(20));
        objects.push_back(test::ballObject(kRadius, centre));
        objects.back().material = 1;
        if (enclosed) {
            objects.push_back(test::ballObject(3, {0, 0, 0}, ObjectRole::kGhost));
            objects.back().name = "room";
        }
        auto built = test::posedScene(objects);
        EXPECT_TRUE(built) << built.status().toString();
        if (!built)
            return;
        scene = std::move(built).value();
        integrator.emplace(options, materials, objects, *scene, std::nullopt);
    }
};

LightData pointLight(float intensity, const Vector3f& position) {
    LightData light;
    light.light.type = LightType::kPoint;
    light.light.intensity = Rgb::Constant(intensity);
    light.active = true;
    light.position_world = position;
    return light;
}

// A beam along −z at impact parameter b lands on the floor (z = 0) at a signed distance from the
// axis that shrinks to 0 at the focus: two ball heights give the line, its zero the focus. The
// ball-lens formula: a paraxial focus nR / (2(n − 1)) from the centre.
TEST(Caustics, AGlassBallFocusesWhereTheBallLensFormulaSays) {
    const float b = 0.04f * kRadius;  // paraxial
    std::vector<float> heights = {1.2f * kRadius, 3.f * kRadius};
    std::vector<float> landed;
    for (float height : heights) {
        GlassBall ball({0, 0, height}, false);
        ASSERT_TRUE(ball.scene);
        optics::Rng rng(3);
        float sum = 0;
        int n = 0;
        for (int i = 0; i < 200; ++i) {
            std::vector<Photon> out;
            CausticMaps::tracePhoton({b, 0, height + 1}, {0, 0, -1}, Vec3::Ones(),
                                     ball.scene->all(), *ball.integrator, rng, out);
            // Refracted twice lands near the axis; the few Fresnel reflections land far off.
            for (const Photon& ph : out)
                if (std::abs(ph.p.x()) < 4 * b && std::abs(ph.p.y()) < 1e-4f) {
                    sum += ph.p.x();
                    ++n;
                }
        }
        ASSERT_GT(n, 150);
        landed.push_back(sum / static_cast<float>(n));
    }
    // x(h) is linear in the floor's distance below the centre, h: zero where h is the focus.
    const float focus =
        heights[0] - landed[0] * (heights[1] - heights[0]) / (landed[1] - landed[0]);
    const float expected = kIor * kRadius / (2 * (kIor - 1));
    std::printf(
        "glass ball (n %.2f, R %.0f mm): focus %.3f mm from the centre (ball-lens formula "
        "%.3f mm)\n",
        kIor, kRadius * 1e3, focus * 1e3, expected * 1e3);
    EXPECT_NEAR(focus, expected, 0.01f * expected);
}

// Inside a closed diffuse room every photon lands somewhere: the stored power is what the ball
// intercepts of a point light, I·Ω. The photons refracted into the ball and out again carry that
// times the mean two-interface Fresnel transmission over the ball's disk.
TEST(Caustics, PowerIsWhatTheBallInterceptsTimesTheFresnelTransmission) {
    const Vector3f centre(0, 0, 0.5f);
    GlassBall ball(centre, true);
    ASSERT_TRUE(ball.scene);
    const LightData light = pointLight(2, {0, 0, 1.5f});
    Frame f;
    f.lights.push_back(&light);
    CausticSettings settings;
    settings.photons = 200000;
    settings.radius_m = 0.01f;
    CausticMaps maps(settings, ball.objects, ball.materials);
    ASSERT_TRUE(maps.any());
    maps.update(f, *ball.scene, *ball.integrator);
    const float dist = (centre - light.position_world).norm();
    const float cos_half = std::sqrt(1 - (kRadius / dist) * (kRadius / dist));
    const float intercepted = 2 * 2 * optics::kPi * (1 - cos_half);  // I·Ω
    const Vec3 stored = maps.mixed().totalPower();
    std::printf("stored %.6f W of %.6f W intercepted (%zu photons)\n", stored.x(), intercepted,
                maps.mixed().photons().size());
    EXPECT_NEAR(stored.x(), intercepted, 0.01f * intercepted);

    // The mean of T_in · T_out over the disk the ball shows the light (uniform in area: the
    // light is far compared to the ball).
    double mean = 0;
    const int steps = 20000;
    for (int i = 0; i < steps; ++i) {
        const double s = (i + 0.5) / steps;  // (b/R)², uniform over the disk's area
        const float cos_i = static_cast<float>(std::sqrt(1 - s));
        const float sin_t = static_cast<float>(std::sqrt(s)) / kIor;
        const float cos_t = std::sqrt(1 - sin_t * sin_t);
        mean += (1 - optics::dielectricReflectance(cos_i, 1, kIor)) *
                (1 - optics::dielectricReflectance(cos_t, kIor, 1));
    }
    mean /= steps;
    float through = 0;
    for (const Photon& ph : maps.mixed().photons())
        if (ph.specular_events == 2)
            through += ph.power.x();
    std::printf(
        "refracted in and out: %.6f W; intercepted x mean Fresnel transmission %.4f: "
        "%.6f W\n",
        through, mean, intercepted * mean);
    EXPECT_NEAR(through, intercepted * mean, 0.02f * intercepted * mean);

    // The kernel estimate integrates to the photons' power: over the floor under the ball.
    double floor_power = 0, estimated = 0;
    for (const Photon& ph : maps.mixed().photons())
        if (std::abs(ph.p.z()) < 1e-4f && std::abs(ph.p.x()) < 0.4f && std::abs(ph.p.y()) < 0.4f)
            floor_power += ph.power.x();
    const float cell = 0.002f;
    for (float y = -0.4f; y < 0.4f; y += cell)
        for (float x = -0.4f; x < 0.4f; x += cell)
            estimated += maps.mixed().irradiance({x + cell / 2, y + cell / 2, 0}, {0, 0, 1}).x() *
                         cell * cell;
    std::printf("floor: photons %.6f W, kernel estimate integrated %.6f W\n", floor_power,
                estimated);
    EXPECT_NEAR(estimated, floor_power, 0.03 * floor_power + 1e-6);
}

// The caustic under a glass ball converges to a brute-force light-tracing reference as photons
// grow: the reference shoots plain random photons into a cone twice the ball's, unstratified,
// and counts the power landing in 1 cm cells of the floor; the maps' kernel estimate, averaged
// over each cell, comes nearer to it with 4x and 16x the photons.
TEST(Caustics, ConvergeToALightTracingReferenceAsPhotonsGrow) {
    const Vector3f centre(0, 0, 0.2f);
    GlassBall ball(centre, false);
    ASSERT_TRUE(ball.scene);
    const LightData light = pointLight(1, {0.05f, 0, 1.2f});
    constexpr float kCell = 0.01f, kHalf = 0.06f;
    constexpr int kCells = static_cast<int>(2 * kHalf / kCell + 0.5f);
    const auto cellOf = [&](const Vec3& p) -> int {
        const int x = static_cast<int>(std::floor((p.x() + kHalf) / kCell));
        const int y = static_cast<int>(std::floor((p.y() + kHalf) / kCell));
        return x >= 0 && y >= 0 && x < kCells && y < kCells && std::abs(p.z()) < 1e-4f
                   ? y * kCells + x
                   : -1;
    };
    // Reference: I·Ω_cone / N per photon, directions uniform in the cone.
    std::vector<double> reference(kCells * kCells, 0);
    const Vec3 axis = (centre - light.position_world).normalized();
    const Vec3 u = axis.unitOrthogonal(), v = axis.cross(u);
    const float dist = (centre - light.position_world).norm();
    const float cos_max = std::cos(2 * std::asin(kRadius / dist));
    const int n_reference = 400000;
    const double omega = 2 * optics::kPi * (1 - cos_max);
    optics::Rng rng(11);
    std::vector<Photon> out;
    for (int i = 0; i < n_reference; ++i) {
        const float cos_t = 1 - rng.uniform() * (1 - cos_max);
        const float sin_t = std::sqrt(1 - cos_t * cos_t);
        const float phi = 2 * optics::kPi * rng.uniform();
        const Vec3 d = sin_t * std::cos(phi) * u + sin_t * std::sin(phi) * v + cos_t * axis;
        out.clear();
        CausticMaps::tracePhoton(light.position_world, d.normalized(),
                                 Vec3::Constant(static_cast<float>(omega / n_reference)),
                                 ball.scene->all(), *ball.integrator, rng, out);
        for (const Photon& ph : out)
            if (const int c = cellOf(ph.p); c >= 0)
                reference[static_cast<size_t>(c)] += ph.power.x() / (kCell * kCell);
    }
    double reference_total = 0;
    for (double e : reference)
        reference_total += e;
    ASSERT_GT(reference_total, 0);
    Frame f;
    f.lights.push_back(&light);
    std::vector<double> errors;
    for (int photons : {10000, 40000, 160000}) {
        CausticSettings settings;
        settings.photons = photons;
        settings.radius_m = 0.003f;
        CausticMaps maps(settings, ball.objects, ball.materials);
        maps.update(f, *ball.scene, *ball.integrator);
        double error = 0;
        for (int c = 0; c < kCells * kCells; ++c) {
            double estimate = 0;
            for (int j = 0; j < 5; ++j)
                for (int i = 0; i < 5; ++i) {
                    const Vec3 p(-kHalf + ((c % kCells) + (i + 0.5f) / 5) * kCell,
                                 -kHalf + ((c / kCells) + (j + 0.5f) / 5) * kCell, 0);
                    estimate += maps.mixed().irradiance(p, {0, 0, 1}).x() / 25;
                }
            error += std::abs(estimate - reference[static_cast<size_t>(c)]);
        }
        errors.push_back(error / reference_total);
        std::printf("%6d photons: relative L1 error against the light-tracing reference %.3f\n",
                    photons, errors.back());
    }
    EXPECT_LT(errors[1], errors[0]);
    EXPECT_LT(errors[2], errors[1]);
    EXPECT_LT(errors[2], 0.15);
}

SceneDescription glassBallScene(bool with_caustics) {
    SceneDescription scene;
    test::addGhostFloor(scene);
    Material glass = test::material(MaterialType::kGlass, "glass");
    glass.ior = Rgb::Constant(kIor);
    scene.materials["glass"] = glass;
    SceneObject ball =
        test::object("ball", ObjectRole::kVirtual, ShapeType::kSphere, "glass", {0, 0, 0.1});
    ball.shape.radius = kRadius;
    scene.objects.push_back(ball);
    Light lamp;
    lamp.type = LightType::kPoint;
    lamp.position = {0.05, 0.02, 0.8};
    lamp.intensity = Rgb::Constant(1.5f);
    scene.lights.push_back(lamp);
    if (with_caustics) {
        CausticSettings caustics;
        caustics.photons = 100000;
        caustics.radius_m = 0.004f;
        scene.caustics = caustics;
    }
    return scene;
}

Image renderGlassBall(const SceneDescription& scene, bool footprint, bool virtual_active,
                      RenderStats* stats = nullptr) {
    RenderOptions options;
    options.threads = 2;
    options.screen_footprint = footprint;
    options.only_virtual_footprint = footprint;
    SceneDescription s = scene;
    if (!virtual_active)
        s.objects.back().anchor = "marker:7";  // never tracked: inactive
    auto renderer = Renderer::create(s, options);
    EXPECT_TRUE(renderer.isOk()) << renderer.status().toString();
    constexpr int kW = 120, kH = 90;
    const Image camera = test::filledImage(kW, kH, [](int x, int y) {
        return std::array<uint8_t, 3>{static_cast<uint8_t>(100 + x / 4),
                                      static_cast<uint8_t>(90 + y / 4), 80};
    });
    RenderInputs in;
    in.camera = calibration::CameraModel::pinhole(kW, kH, 110, 110, (kW - 1) / 2.0, (kH - 1) / 2.0);
    in.camera_image = camera.view();
    in.T_world_cam = test::lookDown({0, 0, 0.6});
    RenderLayers out;
    EXPECT_TRUE((*renderer)->render(in, out, stats).isOk());
    if (!virtual_active) {
        EXPECT_EQ(std::vector<uint8_t>(out.composite.bytes().begin(), out.composite.bytes().end()),
                  std::vector<uint8_t>(camera.bytes().begin(), camera.bytes().end()))
            << "with nothing virtual the composite must be the camera image";
    }
    return out.composite;
}

// Through the Renderer: the caustic brightens the real floor under the ball (the composite is
// brighter there with caustics than without), the screen footprint shades every pixel it
// reaches (the same bytes as tracing every pixel), and with the ball absent the composite is
// the camera image.
TEST(Caustics, AVirtualGlassBallsCausticBrightensTheRealFloor) {
    const Image with = renderGlassBall(glassBallScene(true), true, true);
    const Image without = renderGlassBall(glassBallScene(false), true, true);
    int brighter = 0;
    for (size_t i = 0; i < with.bytes().size(); ++i)
        brighter += with.bytes()[i] > without.bytes()[i] + 8 ? 1 : 0;
    std::printf("the caustic brightens %d bytes by more than 8 codes\n", brighter);
    EXPECT_GT(brighter, 30);
    const Image everywhere = renderGlassBall(glassBallScene(true), false, true);
    EXPECT_EQ(std::vector<uint8_t>(with.bytes().begin(), with.bytes().end()),
              std::vector<uint8_t>(everywhere.bytes().begin(), everywhere.bytes().end()))
        << "the screen footprint misses pixels the caustic reaches";
    renderGlassBall(glassBallScene(true), true, false);
}

// A real mirror ball beside the virtual glass ball throws its own caustic over the floor; it is
// in the camera image already, so it must cancel: the screen footprint shades only what the
// virtual ball changes (photons the two scenes share are left out of it), and still gives the
// same bytes as tracing every pixel.
TEST(Caustics, ARealMirrorsCausticCancelsAndLeavesTheFootprintAlone) {
    SceneDescription scene = glassBallScene(true);
    scene.materials["chrome"] = test::material(MaterialType::kMirror, "chrome");
    SceneObject mirror = test::object("mirror", ObjectRole::kGhost, ShapeType::kSphere, "chrome",
                                      {-0.12, 0.05, 0.06});
    mirror.shape.radius = 0.06f;
    scene.objects.insert(scene.objects.begin() + 1, mirror);  // the glass ball stays last
    RenderStats alone, beside, everywhere_stats;
    renderGlassBall(glassBallScene(true), true, true, &alone);
    const Image with = renderGlassBall(scene, true, true, &beside);
    const Image everywhere = renderGlassBall(scene, false, true, &everywhere_stats);
    std::printf(
        "pixels traced: glass ball alone %llu, beside a real mirror ball %llu, every pixel "
        "%llu; photons %llu\n",
        static_cast<unsigned long long>(alone.pixels_traced),
        static_cast<unsigned long long>(beside.pixels_traced),
        static_cast<unsigned long long>(everywhere_stats.pixels_traced),
        static_cast<unsigned long long>(beside.caustic_photons));
    EXPECT_EQ(std::vector<uint8_t>(with.bytes().begin(), with.bytes().end()),
              std::vector<uint8_t>(everywhere.bytes().begin(), everywhere.bytes().end()))
        << "the screen footprint misses pixels the caustics change";
    EXPECT_LT(beside.pixels_traced, 2 * alone.pixels_traced)
        << "the real mirror's own caustic spread the footprint";
    renderGlassBall(scene, true, false);  // nothing virtual: the camera image
}

}  // namespace
}  // namespace mixray::render::detail
