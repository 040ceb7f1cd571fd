// The integrator's batches against its one-hit functions, in the SIMD lanes of every instruction
// set this machine runs: surfacesAt() against surfaceAt() (the same bits for every hit, invalid
// hits left alone, on meshes with and without normals and uvs, rotated instances, degenerate
// triangles, zero normals and exact spheres), and ghostsInfluenced() against ghostInfluenced()
// (the same answer for every ghost hit, on every material, light kind and footprint shortcut);
// and the direct-light batch's hard shadow rays, traced as 16-ray occlusion packets
// (ShadowRays::hardVisibilities), against visibility()'s one ray at a time.
#include "integrator.h"

#include <gtest/gtest.h>
#include <hwy/targets.h>

#include <cstdio>
#include <cstring>
#include <random>

#include "embree_test_util.h"
#include "shadow_rays.h"

namespace mixray::render::detail {
namespace {

// Triangles with random vertices and normals; some triangles degenerate (zero area) and some
// normals zero, the cases surfaceAt() treats apart.
TriangleMesh soup(std::mt19937& rng, bool normals, bool uvs) {
    std::uniform_real_distribution<float> coord(-1, 1);
    TriangleMesh mesh;
    for (int i = 0; i < 60; ++i) {
        mesh.positions.emplace_back(coord(rng), coord(rng), coord(rng));
        if (normals)
            mesh.normals.push_back(i % 7 == 0 ? Vec3::Zero()
                                              : Vec3(coord(rng), coord(rng), coord(rng)));
        if (uvs)
            mesh.uvs.emplace_back(coord(rng), coord(rng));
    }
    for (uint32_t i = 0; i + 2 < 60; ++i)
        mesh.triangles.push_back({i, i + 1, i % 9 == 0 ? i : i + 2});
    return mesh;
}

ObjectData meshObject(TriangleMesh mesh, const Eigen::Matrix3f& R, const Vec3& t) {
    ObjectData object;
    object.name = "soup";
    object.role = ObjectRole::kGhost;
    object.shape = ShapeType::kMesh;
    object.meshes->push_back(std::move(mesh));
    object.R_world_object = R;
    object.t_world_object = t;
    object.bound_radius = 2;
    return object;
}

bool sameBits(const Vec3& a, const Vec3& b) {
    return std::memcmp(a.data(), b.data(), sizeof(float) * 3) == 0;
}

TEST(Integrator, BatchedSurfacesAreSurfaceAtsBitForBit) {
    std::mt19937 rng(7);
    const Eigen::Matrix3f turned =
        Eigen::AngleAxisf(0.7f, Vec3(1, 2, 3).normalized()).toRotationMatrix();
    std::vector<ObjectData> objects;
    objects.push_back(meshObject(soup(rng, true, true), turned, {0.1f, -0.2f, 0.3f}));
    objects.push_back(
        meshObject(soup(rng, false, false), Eigen::Matrix3f::Identity(), Vec3::Zero()));
    objects.push_back(meshObject(soup(rng, true, false), turned.transpose(), {1, 1, 1}));
    objects.push_back(test::ballObject(0.3f, {0, 0, 2}));
    auto scene = EmbreeScene::build(objects);
    ASSERT_TRUE(scene) << scene.status().message();
    const std::vector<MaterialData> materials(1);
    const RenderOptions options;
    const DifferentialIntegrator integrator(options, materials, objects, **scene, std::nullopt);

    // Hits on every object, some invalid, in an order that mixes them; more than a lane group.
    std::uniform_real_distribution<float> unit(0, 1), coord(-1, 1);
    std::vector<Hit> hits;
    std::vector<Vec3> origins, dirs;
    for (int i = 0; i < 203; ++i) {
        Hit hit;
        hit.valid = i % 5 != 3;
        hit.object = static_cast<unsigned>(i % objects.size());
        hit.prim = static_cast<unsigned>(rng() % 58);
        hit.u = unit(rng);
        hit.v = unit(rng) * (1 - hit.u);
        hit.t = 0.5f + unit(rng);
        hits.push_back(hit);
        origins.emplace_back(coord(rng), coord(rng), coord(rng));
        dirs.push_back(Vec3(coord(rng), coord(rng), coord(rng)).normalized());
    }
    Surface untouched;
    untouched.p = untouched.n_geometric = untouched.n_shading = Vec3::Constant(42);
    const std::vector<int64_t> targets = hwy::SupportedAndGeneratedTargets();
    ASSERT_FALSE(targets.empty());
    for (const int64_t target : targets) {
        SCOPED_TRACE(hwy::TargetName(target));
        hwy::SetSupportedTargetsForTest(target);
        std::vector<Surface> batched(hits.size(), untouched);
        integrator.surfacesAt(hits.data(), origins.data(), dirs.data(), hits.size(),
                              batched.data());
        int compared = 0;
        for (size_t i = 0; i < hits.size(); ++i) {
            if (!hits[i].valid) {
                EXPECT_TRUE(sameBits(batched[i].p, untouched.p)) << i;
                continue;
            }
            const Surface one = integrator.surfaceAt(hits[i], origins[i], dirs[i]);
            const Surface& b = batched[i];
            EXPECT_EQ(b.object, one.object) << i;
            EXPECT_EQ(b.material, one.material) << i;
            EXPECT_TRUE(sameBits(b.p, one.p))
                << i << ": " << b.p.transpose() << " vs " << one.p.transpose();
            EXPECT_TRUE(sameBits(b.n_geometric, one.n_geometric))
                << i << ": " << b.n_geometric.transpose() << " vs " << one.n_geometric.transpose();
            EXPECT_TRUE(sameBits(b.n_shading, one.n_shading))
                << i << ": " << b.n_shading.transpose() << " vs " << one.n_shading.transpose();
            EXPECT_EQ(std::memcmp(b.uv.data(), one.uv.data(), sizeof(float) * 2), 0) << i;
            ++compared;
        }
        EXPECT_GT(compared, 150);
    }
    hwy::SetSupportedTargetsForTest(0);  // back to what the CPU has
    std::printf("batched surfaces compared on %zu instruction sets\n", targets.size());
}

TEST(Integrator, BatchedFootprintTestIsGhostInfluencedsOnEveryHit) {
    std::mt19937 rng(11);
    std::uniform_real_distribution<float> unit(0, 1), coord(-1, 1);
    const auto randomDir = [&] { return Vec3(coord(rng), coord(rng), coord(rng)).normalized(); };
    // Ghost materials of every kind the test tells apart.
    std::vector<MaterialData> materials(6);
    materials[0].material.type = MaterialType::kDiffuse;
    materials[1].material.type = MaterialType::kDiffuse;
    materials[1].material.reflectance = 0.15f;
    materials[2].material.type = MaterialType::kPhong;
    materials[3].material.type = MaterialType::kMirror;
    materials[4].material.type = MaterialType::kMetal;
    materials[5].material.type = MaterialType::kGlass;
    std::vector<ObjectData> objects;
    objects.push_back(test::floorObject(4));
    auto scene = EmbreeScene::build(objects);
    ASSERT_TRUE(scene) << scene.status().message();
    // Lights of each kind, near and far from the points; balls as virtual bounds.
    std::vector<LightData> lights(4);
    lights[0].light.type = LightType::kPoint;
    lights[0].position_world = {0.3f, 0.2f, 1.5f};
    lights[1].light.type = LightType::kSphere;
    lights[1].light.radius = 0.2f;
    lights[1].position_world = {-0.8f, 0.4f, 0.9f};
    lights[2].light.type = LightType::kDirectional;
    lights[2].direction_world = Vec3(0.3f, -0.2f, -1).normalized();
    lights[3].light.type = LightType::kPoint;
    lights[3].position_world = {0.5f, 0.5f, 0.5f};  // among the points: zero lengths nearby
    std::vector<Hit> hits;
    std::vector<Surface> surfaces;
    std::vector<Vec3> dirs;
    for (int i = 0; i < 997; ++i) {
        Surface s;
        s.p = {coord(rng), coord(rng), 0.5f * coord(rng)};
        if (i % 97 == 0)
            s.p = lights[3].position_world;  // at a light
        s.n_geometric = randomDir();
        s.n_shading = (s.n_geometric + 0.3f * randomDir()).normalized();
        s.object = &objects[0];
        s.material = &materials[static_cast<size_t>(i) % materials.size()];
        surfaces.push_back(s);
        dirs.push_back(randomDir());
    }
    std::vector<uint32_t> samples;
    for (uint32_t i = 0; i < surfaces.size(); ++i)
        if (i % 11 != 4)  // some left out: their answers must stay as they were
            samples.push_back(i);
    const std::vector<int64_t> targets = hwy::SupportedAndGeneratedTargets();
    int cases = 0;
    for (const bool shadows : {true, false})
        for (const bool lone_flat_ghost : {true, false})
            for (const int n_lights : {0, 1, 4}) {
                RenderOptions options;
                options.shadows = shadows;
                const DifferentialIntegrator integrator(options, materials, objects, **scene,
                                                        std::nullopt);
                Frame f;
                f.lone_flat_ghost = lone_flat_ghost;
                f.virtual_bounds = {{{0.1f, 0.1f, 0.4f}, 0.15f},
                                    {{-0.5f, 0.3f, 0.2f}, 0.05f},
                                    {{0.6f, -0.6f, 0.1f}, 0.3f}};
                for (int l = 0; l < n_lights; ++l)
                    f.lights.push_back(&lights[static_cast<size_t>(l)]);
                std::vector<uint8_t> expected(surfaces.size(), 7);
                int yes = 0;
                for (const uint32_t i : samples) {
                    expected[i] = integrator.ghostInfluenced(f, surfaces[i], dirs[i]) ? 1 : 0;
                    yes += expected[i];
                }
                for (const int64_t target : targets) {
                    SCOPED_TRACE(::testing::Message()
                                 << hwy::TargetName(target) << ", shadows " << shadows
                                 << ", lone flat ghost " << lone_flat_ghost << ", " << n_lights
                                 << " lights");
                    hwy::SetSupportedTargetsForTest(target);
                    std::vector<uint8_t> batched(surfaces.size(), 7);
                    integrator.ghostsInfluenced(f, surfaces.data(), dirs.data(), samples.data(),
                                                samples.size(), batched.data());
                    int differ = 0;
                    for (size_t i = 0; i < surfaces.size(); ++i)
                        differ += batched[i] != expected[i];
                    EXPECT_EQ(differ, 0) << yes << " of " << samples.size() << " influenced";
                }
                hwy::SetSupportedTargetsForTest(0);
                // Both answers occur, so the comparison can fail either way.
                if (yes > 50 && yes < static_cast<int>(samples.size()) - 50)
                    ++cases;
            }
    EXPECT_GE(cases, 6) << "too few configurations give both answers";
}

TEST(Integrator, PacketsOfHardShadowRaysAreVisibilitysAnswers) {
    // A ghost floor, a real ball on it and virtual balls: rays blocked in both scenes, in the
    // mixed one only, and in neither.
    std::vector<ObjectData> objects;
    objects.push_back(test::floorObject(4));
    objects.push_back(test::ballObject(0.25f, {0.2f, -0.3f, 0.25f}, ObjectRole::kGhost));
    objects.push_back(test::ballObject(0.2f, {-0.3f, 0.2f, 0.4f}));
    objects.push_back(test::ballObject(0.15f, {0.4f, 0.4f, 0.6f}));
    auto scene = test::posedScene(objects);
    ASSERT_TRUE(scene) << scene.status().message();
    const RenderOptions options;
    const ShadowRays shadows(options, **scene);
    LightData point;
    point.light.type = LightType::kPoint;

    std::mt19937 rng(5);
    std::uniform_real_distribution<float> coord(-1, 1), unit(0, 1);
    // More than a packet, not a multiple of one; every mode, finite and infinite lengths.
    std::vector<HardShadowQuery> queries;
    std::vector<float> dists;
    for (int i = 0; i < 203; ++i) {
        const Vec3 origin(coord(rng), coord(rng), 0.01f + 0.3f * unit(rng));
        const Vec3 light(0.6f * coord(rng), 0.6f * coord(rng), 1.2f + unit(rng));
        const bool far = i % 11 == 4;
        const Vec3 to_light =
            far ? Vec3(coord(rng), coord(rng), 1).normalized() : (light - origin).normalized();
        const float dist = far ? kInf : (light - origin).norm();
        queries.push_back(ShadowRays::hardQuery(origin, to_light, dist, static_cast<Mode>(i % 3)));
        dists.push_back(dist);
    }

    Counters batch_counters;
    std::vector<Pair> batched(queries.size());
    shadows.hardVisibilities(queries.data(), queries.size(), batch_counters, nullptr,
                             batched.data());
    Counters one_counters;
    SampleState st;
    st.counters = &one_counters;
    int blocked_m = 0, blocked_r = 0, lit_both = 0;
    for (size_t i = 0; i < queries.size(); ++i) {
        const HardShadowQuery& q = queries[i];
        const Pair one = shadows.visibility(point, q.origin, q.dir, dists[i], q.mode, st);
        const bool want_m = q.mode != Mode::kReal, want_r = q.mode != Mode::kMixed;
        if (want_m) {
            EXPECT_EQ(batched[i].m.x(), one.m.x()) << i;
            blocked_m += one.m.x() == 0;
        }
        if (want_r) {
            EXPECT_EQ(batched[i].r.x(), one.r.x()) << i;
            blocked_r += one.r.x() == 0;
        }
        lit_both += want_m && want_r && one.m.x() == 1 && one.r.x() == 1;
    }
    EXPECT_EQ(batch_counters.shadow, one_counters.shadow);
    // Every outcome occurs, so the comparison can fail either way.
    EXPECT_GT(blocked_m, 10);
    EXPECT_GT(blocked_r, 5);
    EXPECT_GT(lit_both, 10);
    std::printf("%zu hard tests: %d blocked in the mixed scene, %d in the real one\n",
                queries.size(), blocked_m, blocked_r);
}

}  // namespace
}  // namespace mixray::render::detail
