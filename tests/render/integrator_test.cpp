// The integrator's batched surfaces (DifferentialIntegrator::surfacesAt, render/src/integrator.h)
// against its one-hit surfaceAt(): the same bits for every hit, invalid hits left alone, on
// meshes with and without normals and uvs, rotated instances, degenerate triangles, zero normals
// and exact spheres, in the SIMD lanes of every instruction set this machine runs.
#include "integrator.h"

#include <gtest/gtest.h>
#include <hwy/targets.h>

#include <cstdio>
#include <cstring>
#include <random>

#include "embree_test_util.h"

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
    objects.push_back(meshObject(soup(rng, false, false), Eigen::Matrix3f::Identity(), {}));
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

}  // namespace
}  // namespace mixray::render::detail
