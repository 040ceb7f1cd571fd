// Embree's packet kernels as the renderer calls them (EmbreeScene::intersect16, occluded16) on
// every instruction set this CPU and Embree offer, against single rays, under a watchdog: on AMD
// Zen 4, Embree 3.13.5's AVX-512 coherent occlusion packets never returned.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <numbers>
#include <random>

#include "embree_scene.h"
#include "embree_test_util.h"
#include "mixray/render/assets.h"
#include "mixray/render/renderer.h"
#include "watchdog.h"

namespace mixray::render::detail {
namespace {

using Eigen::Vector3f;

// Long enough for a slow kernel under ASan on a loaded machine; short enough that a hang fails
// within the test's ctest timeout.
constexpr std::chrono::seconds kPerIsaLimit{30};

using test::ballObject;
using test::floorObject;

// Shadow rays from a grid of points on the floor towards a spherical light.
struct ShadowSetup {
    std::vector<ObjectData> objects;
    Vector3f light;
    float light_radius;
    Vector3f grid_centre;
    float grid_step;
};

// The renderer test's soft-shadow scene (a 20 m floor, a ball of 12 cm floating 1 m above it,
// a light of 8 cm), origins over its shadow: the packets that never returned on Zen 4.
ShadowSetup floatingBall() {
    ShadowSetup s{
        {floorObject(20), ballObject(0.12f, {0, 0, 1})}, {-1, 0, 2}, 0.08f, {1, 0, 0}, 0.04f};
    return s;
}

// A ball resting on a smaller floor and a rotated box beside it: instanced exact spheres and
// triangle meshes together, shadows that start right beside the occluders.
ShadowSetup tabletop() {
    ShadowSetup s{{floorObject(4), ballObject(0.12f, {0, 0, 0.12f})},
                  {-0.8f, 0.3f, 1.6f},
                  0.15f,
                  {0.2f, 0, 0},
                  0.05f};
    Shape box;
    box.type = ShapeType::kBox;
    box.size = {0.2f, 0.15f, 0.3f};
    ObjectData b;
    b.name = "box";
    b.shape = ShapeType::kBox;
    b.meshes->push_back(makeShapeMesh(box));
    b.t_world_object = {0.35f, 0.1f, 0.15f};
    b.R_world_object = Eigen::AngleAxisf(0.4f, Vector3f::UnitZ()).toRotationMatrix();
    s.objects.push_back(std::move(b));
    return s;
}

struct Mismatches {
    int shadow = 0, shadow_rays = 0;
    int camera = 0, camera_rays = 0;
};

// Soft-shadow packets as lightVisibility() makes them: from points on the floor, 16 directions
// towards points on a spherical light, tnear 0, tfar just short of the light; camera packets of
// 4x4 pixels from above. Each lane against the single-ray call.
Mismatches compareWithSingleRays(EmbreeScene& scene, const ShadowSetup& setup,
                                 mixray::test::WatchdogStage& stage) {
    Mismatches m;
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> uniform(0.f, 1.f);
    for (int oy = -12; oy <= 12; ++oy) {
        for (int ox = -12; ox <= 12; ++ox) {
            const Vector3f origin =
                setup.grid_centre + Vector3f(setup.grid_step * static_cast<float>(ox),
                                             setup.grid_step * static_cast<float>(oy), 1e-4f);
            const Vector3f w = (setup.light - origin).normalized();
            const Vector3f u = w.unitOrthogonal(), v = w.cross(u);
            Vector3f dirs[16];
            float lengths[16];
            for (int i = 0; i < 16; ++i) {
                const float r = setup.light_radius * std::sqrt(uniform(rng));
                const float phi = 2 * std::numbers::pi_v<float> * uniform(rng);
                const Vector3f target = setup.light + r * (std::cos(phi) * u + std::sin(phi) * v);
                dirs[i] = (target - origin).normalized();
                lengths[i] = (target - origin).norm() * 0.99f;
            }
            bool packet[16];
            stage.set("rtcOccluded16 from (" + std::to_string(origin.x()) + ", " +
                      std::to_string(origin.y()) + ", " + std::to_string(origin.z()) + ")");
            EmbreeScene::occluded16(scene.all(), origin, dirs, lengths, nullptr, 16, packet);
            stage.set("rtcOccluded1");
            for (int i = 0; i < 16; ++i) {
                ++m.shadow_rays;
                m.shadow +=
                    packet[i] != EmbreeScene::occluded(scene.all(), origin, dirs[i], lengths[i]);
            }
        }
    }
    const Vector3f eye = setup.grid_centre + Vector3f(-0.1f, -0.2f, 2.5f);
    for (int by = 0; by < 16; ++by) {
        for (int bx = 0; bx < 16; ++bx) {
            Vector3f dirs[16];
            for (int i = 0; i < 16; ++i) {
                const float px = static_cast<float>(bx * 4 + i % 4) / 64.f - 0.5f;
                const float py = static_cast<float>(by * 4 + i / 4) / 64.f - 0.5f;
                dirs[i] = Vector3f(px, py, -1.f).normalized();
            }
            Hit packet[16];
            stage.set("rtcIntersect16");
            EmbreeScene::intersect16(scene.all(), eye, dirs, 16, packet);
            stage.set("rtcIntersect1");
            for (int i = 0; i < 16; ++i) {
                const Hit single = EmbreeScene::intersect(scene.all(), eye, dirs[i],
                                                          std::numeric_limits<float>::infinity());
                ++m.camera_rays;
                const bool same =
                    packet[i].valid == single.valid &&
                    (!single.valid || (packet[i].object == single.object &&
                                       std::abs(packet[i].t - single.t) < 1e-4f * single.t));
                m.camera += same ? 0 : 1;
            }
        }
    }
    return m;
}

TEST(EmbreeIsas, ListsWhatThisCpuRuns) {
    const std::vector<std::string> isas = embreeIsas();
    ASSERT_FALSE(isas.empty());
    EXPECT_EQ(isas.front(), "sse2");  // every x86-64 CPU
    __builtin_cpu_init();
    if (__builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512vl") &&
        __builtin_cpu_supports("avx512bw") && __builtin_cpu_supports("avx512dq") &&
        __builtin_cpu_supports("avx512cd")) {
        EXPECT_EQ(isas.back(), "avx512");
    } else if (__builtin_cpu_supports("avx2")) {
        EXPECT_NE(std::find(isas.begin(), isas.end(), "avx2"), isas.end());
    }
    std::string listed;
    for (const std::string& isa : isas)
        listed += isa + " ";
    std::printf("Embree ISAs on this machine: %s\n", listed.c_str());
}

TEST(EmbreeIsas, UnknownOrUnavailableIsasAreRefused) {
    RenderOptions options;
    options.embree_isa = "avx1024";
    const Status status = options.validate();
    EXPECT_FALSE(status);
    EXPECT_NE(status.message().find("avx1024"), std::string::npos) << status.toString();
    std::vector<ObjectData> objects = tabletop().objects;
    auto built = EmbreeScene::build(objects, "avx1024");
    ASSERT_FALSE(built);
    EXPECT_NE(built.status().message().find("not available"), std::string::npos)
        << built.status().toString();
}

TEST(EmbreePackets, AgreeWithSingleRaysOnEveryIsa) {
    for (const std::string& isa : embreeIsas()) {
        for (const auto& [name, make] :
             {std::pair{"floating ball", &floatingBall}, std::pair{"tabletop", &tabletop}}) {
            SCOPED_TRACE("isa=" + isa + ", " + name);
            mixray::test::runWithin(
                kPerIsaLimit, "Embree packets on isa=" + isa + " (" + name + ")",
                [&, make = make](mixray::test::WatchdogStage& stage) {
                    ShadowSetup setup = make();
                    stage.set("building the scene");
                    auto built = test::posedScene(setup.objects, isa);
                    ASSERT_TRUE(built) << built.status().toString();
                    EmbreeScene& scene = **built;
                    const Mismatches m = compareWithSingleRays(scene, setup, stage);
                    // Packet and single-ray kernels may differ on a ray that grazes an
                    // edge; anything more is a wrong answer.
                    EXPECT_LE(m.shadow, m.shadow_rays / 1000)
                        << m.shadow << " of " << m.shadow_rays << " shadow rays";
                    EXPECT_LE(m.camera, m.camera_rays / 1000)
                        << m.camera << " of " << m.camera_rays << " camera rays";
                    std::printf("isa=%s, %s: %d/%d shadow, %d/%d camera lanes differ\n",
                                isa.c_str(), name, m.shadow, m.shadow_rays, m.camera,
                                m.camera_rays);
                });
        }
    }
}

}  // namespace
}  // namespace mixray::render::detail
