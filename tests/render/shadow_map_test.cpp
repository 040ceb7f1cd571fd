// Shadow maps (render/src/shadow_map.h, Castro et al. §IV) against ray-traced shadows and the
// closed forms of their filters: the hard map agrees with shadow rays but within a texel or so of
// edges, PCF ramps over its kernel, VSM blurs the edge by its Gaussian, the mixed and real maps
// keep the differential, and the 8-bit paths lose the precision their bits say.
#include "shadow_map.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <memory>
#include <vector>

#include "embree_scene.h"
#include "embree_test_util.h"
#include "mixray/render/assets.h"
#include "renderer_test_util.h"

namespace mixray::render::detail {
namespace {

using Eigen::Vector3f;

constexpr float kBallRadius = 0.1f;
const Vector3f kBallCentre{0, 0, 0.3f};

// A ghost floor (z = 0) under a virtual ball, and optionally a real ball above it.
struct BallOverFloor {
    std::vector<ObjectData> objects;
    std::unique_ptr<EmbreeScene> scene;
    std::vector<BoundSphere> casters{{kBallCentre, kBallRadius * 1.001f + 1e-4f}};

    explicit BallOverFloor(bool real_ball_above = false) {
        objects.push_back(test::floorObject(4));
        objects.push_back(test::ballObject(kBallRadius, kBallCentre));
        if (real_ball_above)
            objects.push_back(test::ballObject(kBallRadius, kBallCentre + Vector3f(0, 0, 0.3f),
                                               ObjectRole::kGhost));
        auto built = test::posedScene(objects);
        EXPECT_TRUE(built) << built.status().toString();
        if (built)
            scene = std::move(built).value();
    }
};

LightData directional(const Vector3f& travel) {
    LightData l;
    l.light.type = LightType::kDirectional;
    l.active = true;
    l.direction_world = travel.normalized();
    return l;
}

LightData point(const Vector3f& position) {
    LightData l;
    l.light.type = LightType::kPoint;
    l.active = true;
    l.position_world = position;
    return l;
}

ShadowMapSettings settings(ShadowMapFilter filter, int resolution,
                           ShadowMapStorage storage = ShadowMapStorage::kFloat) {
    ShadowMapSettings s;
    s.filter = filter;
    s.resolution = resolution;
    s.storage = storage;
    return s;
}

const Vector3f kUp{0, 0, 1};

// The direction from floor point q towards the light, and how far the light is.
void towardsLight(const LightData& light, const Vector3f& q, Vector3f& wi, float& dist) {
    if (light.light.type == LightType::kDirectional) {
        wi = -light.direction_world;
        dist = std::numeric_limits<float>::infinity();
    } else {
        wi = (light.position_world - q).normalized();
        dist = (light.position_world - q).norm();
    }
}

// How far the ray from q towards the light passes from the ball's surface, measured across the
// ray at the ball: negative inside its shadow, positive outside.
float edgeDistance(const LightData& light, const Vector3f& q) {
    Vector3f wi;
    float dist;
    towardsLight(light, q, wi, dist);
    const Vector3f c = kBallCentre - q;
    return (c - c.dot(wi) * wi).norm() - kBallRadius;
}

// The hard map against one shadow ray per floor point: where they disagree, the point lies within
// a texel of the shadow's edge (the nearest-texel lookup: up to 0.71 texels diagonally; the
// normal offset and the depth bias move the edge by less than the rest), and they disagree
// nowhere else.
void expectHardMapAgreesWithRays(const LightData& light) {
    BallOverFloor setup;
    ASSERT_TRUE(setup.scene);
    auto map = ShadowMap::render(settings(ShadowMapFilter::kHard, 1024), light, setup.casters,
                                 *setup.scene, setup.objects);
    ASSERT_TRUE(map);
    int points = 0, shadowed = 0, disagree = 0, beyond = 0;
    float worst_texels = 0;
    for (int j = -150; j <= 150; ++j) {
        for (int i = -150; i <= 150; ++i) {
            const Vector3f q(0.003f * static_cast<float>(i), 0.003f * static_cast<float>(j), 0);
            const auto v = map->visibility(q, kUp);
            if (!v)
                continue;
            ++points;
            Vector3f wi;
            float dist;
            towardsLight(light, q, wi, dist);
            const bool lit = !EmbreeScene::occluded(setup.scene->all(), q + 1e-4f * kUp, wi,
                                                    std::isfinite(dist) ? dist * 0.999f : dist);
            shadowed += lit ? 0 : 1;
            EXPECT_EQ(v->r.x(), 1.f) << "the real scene has nothing over the floor";
            if ((v->m.x() > 0.5f) != lit) {
                ++disagree;
                // The ball's distance across the ray, in texels at the ball.
                const float texels = std::abs(edgeDistance(light, q)) / map->texelSize(kBallCentre);
                worst_texels = std::max(worst_texels, texels);
                beyond += texels > 1.f ? 1 : 0;
            }
        }
    }
    std::printf(
        "hard shadow map vs rays: %d of %d floor points disagree (%d in shadow), the "
        "farthest %.2f texels from the edge\n",
        disagree, points, shadowed, worst_texels);
    EXPECT_GT(shadowed, 1000);
    EXPECT_EQ(beyond, 0) << "disagreements farther than a texel from the shadow's edge";
    EXPECT_LT(disagree, points / 100);
}

TEST(ShadowMap, HardMapAgreesWithRaysButAtEdgesDirectional) {
    expectHardMapAgreesWithRays(directional({0.3f, 0.2f, -1}));
}

TEST(ShadowMap, HardMapAgreesWithRaysButAtEdgesPoint) {
    expectHardMapAgreesWithRays(point({-0.4f, 0.3f, 1.5f}));
}

// Visibility along the floor's x axis across the ball's shadow edge (light straight down, so the
// floor is the map's plane), and the distance over which it rises from 10 % to 90 %.
float risingWidth(const ShadowMap& map) {
    float x10 = NAN, x90 = NAN, previous = 0;
    for (int i = 0; i <= 4000; ++i) {
        const float x = 0.08f + 0.00001f * static_cast<float>(i);
        const auto v = map.visibility({x, 0.0005f, 0}, kUp);
        if (!v)
            break;
        const float lit = v->m.x();
        if (std::isnan(x10) && lit >= 0.1f)
            x10 = x - 0.00001f * (lit - 0.1f) / std::max(1e-6f, lit - previous);
        if (std::isnan(x90) && lit >= 0.9f)
            x90 = x - 0.00001f * (lit - 0.9f) / std::max(1e-6f, lit - previous);
        previous = lit;
    }
    return x90 - x10;
}

// PCF's taps are bilinear depth tests a texel apart: across an edge they rise linearly over k
// texels, so 10 % to 90 % takes 0.8 k texels.
TEST(ShadowMap, PcfPenumbraSpansItsKernel) {
    BallOverFloor setup;
    ASSERT_TRUE(setup.scene);
    for (int k : {1, 3, 5, 9}) {
        SCOPED_TRACE("kernel " + std::to_string(k));
        ShadowMapSettings s = settings(ShadowMapFilter::kPcf, 256);
        s.pcf_kernel = k;
        auto map = ShadowMap::render(s, directional({0, 0, -1}), setup.casters, *setup.scene,
                                     setup.objects);
        ASSERT_TRUE(map);
        const float texel = map->texelSize({0, 0, 0});
        const float width = risingWidth(*map) / texel;
        std::printf("PCF %dx%d: penumbra 10-90 %% %.2f texels (expected %.2f)\n", k, k, width,
                    0.8f * static_cast<float>(k));
        EXPECT_NEAR(width, 0.8f * static_cast<float>(k), 0.1f * static_cast<float>(k) + 0.1f);
    }
}

// A VSM's moments of an edge between two depths give Chebyshev's bound exactly the blurred
// fraction of lit texels: the penumbra is the Gaussian's, 2 · 1.2816 σ from 10 % to 90 %.
// Light-bleeding reduction a maps the bound p to (p − a) / (1 − a): narrower.
TEST(ShadowMap, VsmPenumbraIsItsGaussianBlur) {
    BallOverFloor setup;
    ASSERT_TRUE(setup.scene);
    for (float sigma : {2.f, 4.f}) {
        SCOPED_TRACE("sigma " + std::to_string(sigma));
        ShadowMapSettings s = settings(ShadowMapFilter::kVsm, 256);
        s.vsm_blur_texels = sigma;
        s.bleeding_reduction = 0;
        auto map = ShadowMap::render(s, directional({0, 0, -1}), setup.casters, *setup.scene,
                                     setup.objects);
        ASSERT_TRUE(map);
        const float texel = map->texelSize({0, 0, 0});
        const float width = risingWidth(*map) / texel;
        std::printf("VSM sigma %.0f texels: penumbra 10-90 %% %.2f texels (expected %.2f)\n", sigma,
                    width, 2 * 1.2816f * sigma);
        EXPECT_NEAR(width, 2 * 1.2816f * sigma, 0.1f * 2 * 1.2816f * sigma);

        s.bleeding_reduction = 0.3f;
        auto reduced = ShadowMap::render(s, directional({0, 0, -1}), setup.casters, *setup.scene,
                                         setup.objects);
        ASSERT_TRUE(reduced);
        // (p − a)/(1 − a) crosses 10 % and 90 % where p is 37 % and 93 %: 1.807 σ apart.
        const float narrowed = risingWidth(*reduced) / texel;
        EXPECT_NEAR(narrowed, 1.807f * sigma, 0.12f * 1.807f * sigma);
    }
}

// The real map holds the real ball above the virtual one: under both, the real scene is in
// shadow too, so I_m − I_r stays 0 there; only the virtual ball's own shadow differs.
TEST(ShadowMap, RealOccludersShadowTheRealSceneToo) {
    BallOverFloor setup(/*real_ball_above=*/true);
    ASSERT_TRUE(setup.scene);
    for (ShadowMapFilter filter :
         {ShadowMapFilter::kHard, ShadowMapFilter::kPcf, ShadowMapFilter::kVsm}) {
        auto map = ShadowMap::render(settings(filter, 512), directional({0.1f, 0, -1}),
                                     setup.casters, *setup.scene, setup.objects);
        ASSERT_TRUE(map);
        // Under both balls: shadowed in both scenes.
        const auto under = map->visibility({0.03f, 0, 0}, kUp);
        ASSERT_TRUE(under);
        EXPECT_LT(under->m.x(), 0.05f);
        EXPECT_LT(under->r.x(), 0.05f);
        // The virtual ball's top faces the real ball: shadowed in the mixed scene; the real
        // scene has no virtual ball, and its map is looked up there all the same.
        const auto top = map->visibility(kBallCentre + Vector3f(0, 0, kBallRadius), kUp);
        ASSERT_TRUE(top);
        EXPECT_LT(top->m.x(), 0.05f);
    }
}

// Outside the map (where no virtual object can shadow) there is no answer: rays decide there.
// No caster, or a point light among the casters: no map at all.
TEST(ShadowMap, CoversOnlyWhereCastersCanShadow) {
    BallOverFloor setup;
    ASSERT_TRUE(setup.scene);
    auto map = ShadowMap::render(settings(ShadowMapFilter::kPcf, 256), directional({0, 0, -1}),
                                 setup.casters, *setup.scene, setup.objects);
    ASSERT_TRUE(map);
    EXPECT_TRUE(map->visibility({0.05f, 0, 0}, kUp));
    EXPECT_FALSE(map->visibility({0.5f, 0, 0}, kUp));
    EXPECT_FALSE(ShadowMap::render(settings(ShadowMapFilter::kPcf, 256), directional({0, 0, -1}),
                                   {}, *setup.scene, setup.objects));
    EXPECT_FALSE(ShadowMap::render(settings(ShadowMapFilter::kPcf, 256),
                                   point(kBallCentre + Vector3f(0.02f, 0, 0)), setup.casters,
                                   *setup.scene, setup.objects));
}

// Castro et al.'s 8-bit paths: z in one byte loses up to half of a 255th of the depth range
// per texel; their bit-packed RGBA texel keeps z to a 2^32th. Against the float map, texel by
// texel.
TEST(ShadowMap, EightBitPathsLoseWhatTheirBitsSay) {
    BallOverFloor setup;
    ASSERT_TRUE(setup.scene);
    const LightData light = directional({0.3f, 0.2f, -1});
    auto reference = ShadowMap::render(settings(ShadowMapFilter::kHard, 128), light, setup.casters,
                                       *setup.scene, setup.objects);
    ASSERT_TRUE(reference);
    for (ShadowMapStorage storage : {ShadowMapStorage::kEightBit, ShadowMapStorage::kPackedRgba8}) {
        const bool eight = storage == ShadowMapStorage::kEightBit;
        SCOPED_TRACE(eight ? "8-bit" : "RGBA8 packed");
        auto map = ShadowMap::render(settings(ShadowMapFilter::kHard, 128, storage), light,
                                     setup.casters, *setup.scene, setup.objects);
        ASSERT_TRUE(map);
        float worst = 0;
        for (int y = 0; y < 128; ++y)
            for (int x = 0; x < 128; ++x)
                worst = std::max(
                    worst, std::abs(map->storedDepth_m(x, y) - reference->storedDepth_m(x, y)));
        const float step = map->depthStep_m();
        std::printf("%s: step %.3g m, worst error %.3g m\n", eight ? "8-bit z" : "RGBA8-packed z",
                    step, worst);
        EXPECT_LE(worst, 0.5f * step * 1.01f + 2e-5f);
        if (eight) {
            EXPECT_GT(worst, 0.25f * step) << "the 8-bit path should lose precision";
            EXPECT_GT(step, 1e-3f);
        } else {
            EXPECT_LT(step, 1e-9f);
        }
    }
}

// Through the Renderer: a light with a shadow map darkens the ghost floor where shadow rays do
// (composite bytes within two codes of the ray-traced frame but at the shadow's rim), and a
// frame's map time is reported.
TEST(ShadowMap, TheRendererCompositesMapShadowsAsRaysDo) {
    SceneDescription scene;
    test::addGhostFloor(scene);
    scene.materials["white"] = test::material(MaterialType::kDiffuse, "white");
    SceneObject ball = test::object("ball", ObjectRole::kVirtual, ShapeType::kSphere, "white",
                                    kBallCentre.cast<double>());
    ball.shape.radius = kBallRadius;
    scene.objects.push_back(ball);
    scene.lights.push_back(test::directionalLight("sun", {0.2, 0.1, -1}, 3));
    constexpr int kW = 160, kH = 120;
    const Image camera = test::filledImage(kW, kH, [](int, int) {
        return std::array<uint8_t, 3>{150, 140, 130};
    });
    const auto render = [&](const SceneDescription& sc, RenderStats* stats) {
        RenderOptions options;
        options.threads = 2;
        options.soft_shadows = SoftShadowMethod::kHard;
        auto renderer = Renderer::create(sc, options);
        EXPECT_TRUE(renderer.isOk()) << renderer.status().toString();
        RenderInputs in;
        in.camera =
            calibration::CameraModel::pinhole(kW, kH, 150, 150, (kW - 1) / 2.0, (kH - 1) / 2.0);
        in.camera_image = camera.view();
        in.T_world_cam = test::lookDown({0, 0, 1.5});
        RenderLayers out;
        EXPECT_TRUE((*renderer)->render(in, out, stats).isOk());
        return out.composite;
    };
    const Image rays = render(scene, nullptr);
    int shadowed = 0;
    for (int y = 0; y < kH; ++y)
        for (int x = 0; x < kW; ++x)
            shadowed += test::pixelBytes(rays, x, y)[0] < 120 ? 1 : 0;
    EXPECT_GT(shadowed, 50) << "the ray-traced frame shows no shadow";
    for (ShadowMapFilter filter : {ShadowMapFilter::kHard, ShadowMapFilter::kPcf}) {
        SCOPED_TRACE(filter == ShadowMapFilter::kHard ? "hard" : "pcf");
        SceneDescription mapped = scene;
        mapped.lights.back().shadow_map = settings(filter, 1024);
        RenderStats stats;
        const Image map = render(mapped, &stats);
        int differ = 0;
        for (size_t i = 0; i < map.bytes().size(); ++i)
            differ += std::abs(int(map.bytes()[i]) - int(rays.bytes()[i])) > 2 ? 1 : 0;
        std::printf(
            "composite with a shadow map: %d of %zu bytes differ from the rays' by more "
            "than 2 codes; map %.1f ms of %.1f ms\n",
            differ, map.bytes().size(), stats.shadow_map_seconds * 1e3, stats.seconds * 1e3);
        EXPECT_LT(differ, static_cast<int>(map.bytes().size() / 100));
        EXPECT_GT(stats.shadow_map_seconds, 0);
    }
}

}  // namespace
}  // namespace mixray::render::detail
