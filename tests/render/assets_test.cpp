// Assets: real meshes through assimp, analytic shape meshes, textures and environment maps.
#include "mixray/render/assets.h"

#include <ImfEnvmap.h>
#include <ImfEnvmapAttribute.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <numbers>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "test_data.h"

namespace mixray::render {
namespace {

namespace fs = std::filesystem;

constexpr float kPi = std::numbers::pi_v<float>;

fs::path modelsDir() {
    return test::sharedDataDir() / "06_models";
}

struct Bounds {
    Eigen::Vector3f min = Eigen::Vector3f::Constant(std::numeric_limits<float>::infinity());
    Eigen::Vector3f max = Eigen::Vector3f::Constant(-std::numeric_limits<float>::infinity());
};

Bounds boundsOf(const std::vector<LoadedMesh>& meshes) {
    Bounds b;
    for (const auto& m : meshes) {
        for (const auto& p : m.mesh.positions) {
            b.min = b.min.cwiseMin(p);
            b.max = b.max.cwiseMax(p);
        }
    }
    return b;
}

size_t vertexCount(const std::vector<LoadedMesh>& meshes) {
    size_t n = 0;
    for (const auto& m : meshes)
        n += m.mesh.positions.size();
    return n;
}

size_t triangleCount(const std::vector<LoadedMesh>& meshes) {
    size_t n = 0;
    for (const auto& m : meshes)
        n += m.mesh.triangles.size();
    return n;
}

// Every mesh is well formed: indices in range, one unit normal per vertex, uvs empty or one
// per vertex.
void expectWellFormed(const TriangleMesh& mesh) {
    ASSERT_FALSE(mesh.empty());
    ASSERT_EQ(mesh.normals.size(), mesh.positions.size());
    EXPECT_TRUE(mesh.uvs.empty() || mesh.uvs.size() == mesh.positions.size());
    for (const auto& t : mesh.triangles) {
        for (uint32_t v : t)
            ASSERT_LT(v, mesh.positions.size());
    }
    for (const auto& n : mesh.normals)
        ASSERT_NEAR(n.norm(), 1.0f, 1e-4f);
    for (const auto& p : mesh.positions)
        ASSERT_TRUE(p.allFinite());
}

// ∮ p·n dA / 3 over a closed, outward-oriented surface is its volume (divergence theorem).
double signedVolume(const TriangleMesh& mesh) {
    double volume = 0;
    for (const auto& t : mesh.triangles) {
        const Eigen::Vector3d a = mesh.positions[t[0]].cast<double>();
        const Eigen::Vector3d b = mesh.positions[t[1]].cast<double>();
        const Eigen::Vector3d c = mesh.positions[t[2]].cast<double>();
        volume += a.dot(b.cross(c)) / 6.0;
    }
    return volume;
}

double area(const TriangleMesh& mesh) {
    double total = 0;
    for (const auto& t : mesh.triangles) {
        const Eigen::Vector3d a = mesh.positions[t[0]].cast<double>();
        const Eigen::Vector3d b = mesh.positions[t[1]].cast<double>();
        const Eigen::Vector3d c = mesh.positions[t[2]].cast<double>();
        total += 0.5 * (b - a).cross(c - a).norm();
    }
    return total;
}

// The geometric normal of every triangle agrees with its vertex normals (winding matches).
void expectWindingMatchesNormals(const TriangleMesh& mesh) {
    for (const auto& t : mesh.triangles) {
        const Eigen::Vector3f face = (mesh.positions[t[1]] - mesh.positions[t[0]])
                                         .cross(mesh.positions[t[2]] - mesh.positions[t[0]]);
        if (face.norm() < 1e-12f)
            continue;
        const Eigen::Vector3f mean = mesh.normals[t[0]] + mesh.normals[t[1]] + mesh.normals[t[2]];
        EXPECT_GT(face.normalized().dot(mean.normalized()), 0.5f);
    }
}

// ---- meshes from files ----

// Faces come out exactly as published (they are all triangles already). Vertices do not:
// assimp keeps only vertices that faces use, and joining identical vertices merges entries
// that repeat a position (the files have no normals or uvs to tell them apart; the normals
// are generated per position). The expected vertex counts are the distinct referenced
// positions, counted from the files with a script.
TEST(LoadMeshFileTest, TeapotHasPublishedCounts) {
    const fs::path path = modelsDir() / "newell_teapot.obj";
    MIXRAY_REQUIRE_SHARED_DATA(path);
    auto meshes = loadMeshFile(path);
    ASSERT_TRUE(meshes.isOk()) << meshes.status().toString();
    ASSERT_EQ(meshes->size(), 1u);
    // 3644 vertices in the file, 403 of them repeat a position along the patch seams.
    EXPECT_EQ(vertexCount(*meshes), 3241u);
    EXPECT_EQ(triangleCount(*meshes), 6320u);
    expectWellFormed((*meshes)[0].mesh);
    const Bounds b = boundsOf(*meshes);
    // A teapot is wider than tall, roughly 6 x 3 x 4 units in the usual modelling.
    const Eigen::Vector3f extent = b.max - b.min;
    EXPECT_GT(extent.maxCoeff(), 1.0f);
    EXPECT_LT(extent.maxCoeff(), 100.0f);
    EXPECT_GT(extent.minCoeff(), 0.2f * extent.maxCoeff());
}

TEST(LoadMeshFileTest, StanfordBunnyObjHasPublishedCounts) {
    const fs::path path = modelsDir() / "stanford-bunny.obj";
    MIXRAY_REQUIRE_SHARED_DATA(path);
    auto meshes = loadMeshFile(path);
    ASSERT_TRUE(meshes.isOk()) << meshes.status().toString();
    // 35947 vertices in the file, 1113 of them used by no face.
    EXPECT_EQ(vertexCount(*meshes), 34834u);
    EXPECT_EQ(triangleCount(*meshes), 69451u);
    for (const auto& m : *meshes)
        expectWellFormed(m.mesh);
    // bun_zipper is ~0.16 m wide in metres.
    const Eigen::Vector3f extent = boundsOf(*meshes).max - boundsOf(*meshes).min;
    EXPECT_GT(extent.maxCoeff(), 0.1f);
    EXPECT_LT(extent.maxCoeff(), 0.3f);
}

// A big mesh's import is kept in the mesh cache: the next load reads it from there and gives
// the same triangles; a changed file is imported again; a broken entry is passed by.
TEST(LoadMeshFileTest, TheMeshCacheGivesTheSameMeshAndFollowsTheFile) {
    const fs::path source = modelsDir() / "opencv_viz_bunny_res3.ply";
    MIXRAY_REQUIRE_SHARED_DATA(source);
    const fs::path dir = test::tempDir();
    const fs::path path = dir / "bunny.ply";
    fs::copy_file(source, path);
    MeshCacheSettings cache;
    cache.dir = dir / "cache";
    cache.min_file_bytes = 0;
    const auto entries = [&] {
        std::vector<fs::path> found;
        if (fs::exists(cache.dir))
            for (const auto& e : fs::directory_iterator(cache.dir))
                found.push_back(e.path());
        return found;
    };
    auto imported = loadMeshFile(path, 2.f, cache);
    ASSERT_TRUE(imported.isOk()) << imported.status().toString();
    ASSERT_EQ(entries().size(), 1u);
    EXPECT_EQ(entries()[0].extension(), ".assbin");
    auto cached = loadMeshFile(path, 2.f, cache);
    ASSERT_TRUE(cached.isOk()) << cached.status().toString();
    ASSERT_EQ(cached->size(), imported->size());
    for (size_t m = 0; m < imported->size(); ++m) {
        EXPECT_EQ((*cached)[m].mesh.triangles, (*imported)[m].mesh.triangles);
        EXPECT_EQ((*cached)[m].mesh.positions, (*imported)[m].mesh.positions);
        EXPECT_EQ((*cached)[m].mesh.normals, (*imported)[m].mesh.normals);
    }
    // A broken entry: imported from the file again, and the entry written anew.
    test::writeText(entries()[0], "not assbin");
    auto repaired = loadMeshFile(path, 2.f, cache);
    ASSERT_TRUE(repaired.isOk()) << repaired.status().toString();
    EXPECT_EQ(triangleCount(*repaired), triangleCount(*imported));
    EXPECT_GT(fs::file_size(entries()[0]), 1000u);
    // The file changes: a second entry, with the new file's triangles.
    test::writeText(path,
                    "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty "
                    "float y\nproperty float z\nelement face 1\nproperty list uchar int "
                    "vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
    auto changed = loadMeshFile(path, 2.f, cache);
    ASSERT_TRUE(changed.isOk()) << changed.status().toString();
    EXPECT_EQ(triangleCount(*changed), 1u);
    EXPECT_EQ(entries().size(), 2u);
    // Small files are not cached, nor files of formats that refer to others (an OBJ's .mtl),
    // nor anything with the cache off.
    const fs::path other = dir / "other.ply";
    fs::copy_file(source, other);
    MeshCacheSettings big_only = cache;
    big_only.min_file_bytes = fs::file_size(other) + 1;
    ASSERT_TRUE(loadMeshFile(other, 1.f, big_only).isOk());
    ASSERT_TRUE(loadMeshFile(other, 1.f, MeshCacheSettings{}).isOk());
    const fs::path obj = dir / "teapot.obj";
    test::writeText(obj, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    ASSERT_TRUE(loadMeshFile(obj, 1.f, cache).isOk());
    EXPECT_EQ(entries().size(), 2u);
}

TEST(LoadMeshFileTest, ViZBunnyPlyHasPublishedCountsAndScales) {
    const fs::path path = modelsDir() / "opencv_viz_bunny_res3.ply";
    MIXRAY_REQUIRE_SHARED_DATA(path);
    auto meshes = loadMeshFile(path);
    ASSERT_TRUE(meshes.isOk()) << meshes.status().toString();
    // 1889 vertices in the file, 2 of them used by no face.
    EXPECT_EQ(vertexCount(*meshes), 1887u);
    EXPECT_EQ(triangleCount(*meshes), 3851u);
    for (const auto& m : *meshes)
        expectWellFormed(m.mesh);
    const Bounds b = boundsOf(*meshes);
    // First vertex of the file, and the same bunny as stanford-bunny.obj at lower resolution.
    EXPECT_NEAR(b.max.y() - b.min.y(), 0.15f, 0.03f);

    auto scaled = loadMeshFile(path, 10.0f);
    ASSERT_TRUE(scaled.isOk());
    const Bounds bs = boundsOf(*scaled);
    EXPECT_NEAR((bs.max - bs.min).norm(), 10.0f * (b.max - b.min).norm(), 1e-4f);
}

TEST(LoadMeshFileTest, GltfCubeWithTextureAndBuffer) {
    const fs::path path = modelsDir() / "gltf_Cube_tinygltf" / "Cube.gltf";
    MIXRAY_REQUIRE_SHARED_DATA(path);
    auto meshes = loadMeshFile(path);
    ASSERT_TRUE(meshes.isOk()) << meshes.status().toString();
    ASSERT_EQ(meshes->size(), 1u);
    const LoadedMesh& cube = (*meshes)[0];
    expectWellFormed(cube.mesh);
    EXPECT_EQ(cube.mesh.triangles.size(), 12u);
    // 6 faces x 4 corners: the 36 listed vertices join into 24 distinct (position, normal, uv).
    EXPECT_EQ(cube.mesh.positions.size(), 24u);
    ASSERT_EQ(cube.mesh.uvs.size(), cube.mesh.positions.size());
    const Bounds b = boundsOf(*meshes);
    EXPECT_TRUE(b.min.isApprox(Eigen::Vector3f(-1, -1, -1), 1e-5f)) << b.min.transpose();
    EXPECT_TRUE(b.max.isApprox(Eigen::Vector3f(1, 1, 1), 1e-5f)) << b.max.transpose();
    // Closed and outward: volume 8.
    EXPECT_NEAR(signedVolume(cube.mesh), 8.0, 1e-4);
    expectWindingMatchesNormals(cube.mesh);
    // The base colour texture sits beside the file; glTF's factors default to 1.
    EXPECT_EQ(cube.material.base_color_texture, path.parent_path() / "Cube_BaseColor.png");
    EXPECT_TRUE(fs::exists(cube.material.base_color_texture));
    EXPECT_FLOAT_EQ(cube.material.metallic, 1.0f);
    EXPECT_FLOAT_EQ(cube.material.roughness, 1.0f);
    EXPECT_TRUE(cube.material.base_color.isApprox(Rgb(1, 1, 1)));
    // glTF's uvs already have v = 0 at the top: they must come out as the file has them,
    // in [-1, 1] and with (1, -1) among them. A stray flip (1 - v) would give v = 2.
    bool has_corner = false;
    for (const auto& uv : cube.mesh.uvs) {
        EXPECT_GE(uv.minCoeff(), -1.0f);
        EXPECT_LE(uv.maxCoeff(), 1.0f);
        has_corner = has_corner || uv.isApprox(Eigen::Vector2f(1, -1));
    }
    EXPECT_TRUE(has_corner);
    auto texture = Texture::load(cube.material.base_color_texture);
    ASSERT_TRUE(texture.isOk()) << texture.status().toString();
    EXPECT_EQ(texture->width(), 512);
    EXPECT_EQ(texture->height(), 512);
}

TEST(LoadMeshFileTest, CornellBoxMaterialsFromMtl) {
    const fs::path path = modelsDir() / "embree_cornell_box.obj";
    MIXRAY_REQUIRE_SHARED_DATA(path);
    auto meshes = loadMeshFile(path);
    ASSERT_TRUE(meshes.isOk()) << meshes.status().toString();
    // 17 quads triangulate into 34 triangles.
    EXPECT_EQ(triangleCount(*meshes), 34u);
    bool red = false, green = false;
    for (const auto& m : *meshes) {
        expectWellFormed(m.mesh);
        red = red || m.material.base_color.isApprox(Rgb(1, 0, 0));
        green = green || m.material.base_color.isApprox(Rgb(0, 1, 0));
    }
    EXPECT_TRUE(red);
    EXPECT_TRUE(green);
    // The measured Cornell box is ~556 mm on a side (in millimetres in this file).
    const Eigen::Vector3f extent = boundsOf(*meshes).max - boundsOf(*meshes).min;
    EXPECT_NEAR(extent.maxCoeff(), 559.2f, 5.0f);
}

TEST(LoadMeshFileTest, MissingAndCorruptFiles) {
    const fs::path missing = test::tempDir() / "nope.obj";
    auto result = loadMeshFile(missing);
    ASSERT_FALSE(result.isOk());
    EXPECT_EQ(result.status().code(), ErrorCode::kNotFound);
    EXPECT_NE(result.status().message().find("nope.obj"), std::string::npos);

    const fs::path corrupt = test::tempDir() / "corrupt.ply";
    std::ofstream(corrupt) << "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n"
                              "end_header\n1\n";
    result = loadMeshFile(corrupt);
    ASSERT_FALSE(result.isOk());
    EXPECT_EQ(result.status().code(), ErrorCode::kCorruptData);
    EXPECT_NE(result.status().message().find("corrupt.ply"), std::string::npos);

    const fs::path garbage = test::tempDir() / "garbage.gltf";
    std::ofstream(garbage) << "{ this is not json";
    result = loadMeshFile(garbage);
    ASSERT_FALSE(result.isOk());
    EXPECT_EQ(result.status().code(), ErrorCode::kCorruptData);
    EXPECT_NE(result.status().message().find("garbage.gltf"), std::string::npos);

    // An OBJ with only points has nothing to trace.
    const fs::path points = test::tempDir() / "points.obj";
    std::ofstream(points) << "v 0 0 0\nv 1 0 0\nv 0 1 0\np 1\np 2\n";
    result = loadMeshFile(points);
    ASSERT_FALSE(result.isOk());
    EXPECT_EQ(result.status().code(), ErrorCode::kCorruptData);

    const fs::path ok = test::tempDir() / "tri.obj";
    std::ofstream(ok) << "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
    EXPECT_EQ(loadMeshFile(ok, 0.0f).status().code(), ErrorCode::kInvalidArgument);
    auto tri = loadMeshFile(ok);
    ASSERT_TRUE(tri.isOk()) << tri.status().toString();
    // Counter-clockwise in the file: the generated normal faces +z.
    EXPECT_TRUE((*tri)[0].mesh.normals[0].isApprox(Eigen::Vector3f(0, 0, 1), 1e-5f));
}

// ---- analytic shapes ----

Shape shapeOf(ShapeType type) {
    Shape shape;
    shape.type = type;
    return shape;
}

TEST(MakeShapeMeshTest, BoxIsClosedAndOutward) {
    Shape box = shapeOf(ShapeType::kBox);
    box.size = {0.2f, 0.3f, 0.5f};
    const TriangleMesh mesh = makeShapeMesh(box);
    expectWellFormed(mesh);
    EXPECT_EQ(mesh.triangles.size(), 12u);
    EXPECT_NEAR(signedVolume(mesh), 0.2 * 0.3 * 0.5, 1e-7);
    EXPECT_NEAR(area(mesh), 2 * (0.2 * 0.3 + 0.3 * 0.5 + 0.2 * 0.5), 1e-6);
    expectWindingMatchesNormals(mesh);
    for (size_t i = 0; i < mesh.positions.size(); ++i) {
        // Flat faces: the normal points away from the centre.
        EXPECT_GT(mesh.normals[i].dot(mesh.positions[i]), 0.0f);
    }
}

TEST(MakeShapeMeshTest, SphereAreaVolumeAndNormals) {
    Shape sphere = shapeOf(ShapeType::kSphere);
    sphere.radius = 0.5f;
    const TriangleMesh mesh = makeShapeMesh(sphere, 128);
    expectWellFormed(mesh);
    ASSERT_EQ(mesh.uvs.size(), mesh.positions.size());
    const double r = 0.5;
    EXPECT_NEAR(area(mesh), 4 * std::numbers::pi * r * r, 4 * std::numbers::pi * r * r * 2e-3);
    EXPECT_NEAR(signedVolume(mesh), 4.0 / 3.0 * std::numbers::pi * r * r * r,
                4.0 / 3.0 * std::numbers::pi * r * r * r * 3e-3);
    expectWindingMatchesNormals(mesh);
    for (size_t i = 0; i < mesh.positions.size(); ++i) {
        EXPECT_NEAR(mesh.positions[i].norm(), 0.5f, 1e-6f);
        EXPECT_TRUE(mesh.normals[i].isApprox(mesh.positions[i] / 0.5f, 1e-5f));
    }
    // Coarse tessellation still closes.
    const TriangleMesh coarse = makeShapeMesh(sphere, 3);
    EXPECT_GT(signedVolume(coarse), 0.0);
    expectWindingMatchesNormals(coarse);
}

TEST(MakeShapeMeshTest, PlaneAndDiskFaceUp) {
    Shape plane = shapeOf(ShapeType::kPlane);
    plane.size = {2.0f, 1.0f, 0.0f};
    const TriangleMesh p = makeShapeMesh(plane);
    expectWellFormed(p);
    EXPECT_NEAR(area(p), 2.0, 1e-6);
    expectWindingMatchesNormals(p);
    for (const auto& n : p.normals)
        EXPECT_TRUE(n.isApprox(Eigen::Vector3f::UnitZ()));
    for (const auto& v : p.positions)
        EXPECT_EQ(v.z(), 0.0f);

    Shape disk = shapeOf(ShapeType::kDisk);
    disk.radius = 0.3f;
    const TriangleMesh d = makeShapeMesh(disk, 256);
    expectWellFormed(d);
    EXPECT_NEAR(area(d), std::numbers::pi * 0.09, 0.09 * 1e-3);
    expectWindingMatchesNormals(d);
    for (const auto& n : d.normals)
        EXPECT_TRUE(n.isApprox(Eigen::Vector3f::UnitZ()));

    EXPECT_TRUE(makeShapeMesh(shapeOf(ShapeType::kMesh)).empty());
}

// ---- textures ----

TEST(TextureTest, DecodesSrgbAndSwapsChannels) {
    const fs::path dir = test::tempDir();
    // One row: pure red, sRGB 128 grey, sRGB 10 (linear segment), white. OpenCV writes BGR.
    cv::Mat image(1, 4, CV_8UC3);
    image.at<cv::Vec3b>(0, 0) = {0, 0, 255};
    image.at<cv::Vec3b>(0, 1) = {128, 128, 128};
    image.at<cv::Vec3b>(0, 2) = {10, 10, 10};
    image.at<cv::Vec3b>(0, 3) = {255, 255, 255};
    ASSERT_TRUE(cv::imwrite((dir / "row.png").string(), image));
    auto texture = Texture::load(dir / "row.png");
    ASSERT_TRUE(texture.isOk()) << texture.status().toString();
    ASSERT_EQ(texture->width(), 4);
    ASSERT_EQ(texture->height(), 1);
    EXPECT_TRUE(texture->texel(0, 0).isApprox(Rgb(1, 0, 0)));
    EXPECT_NEAR(texture->texel(1, 0).x(), 0.2158605f, 1e-6f);  // ((128/255+0.055)/1.055)^2.4
    EXPECT_NEAR(texture->texel(2, 0).x(), 10.0f / 255.0f / 12.92f, 1e-7f);
    EXPECT_NEAR(texture->texel(3, 0).y(), 1.0f, 1e-6f);

    // 16-bit grey: decoded the same way, replicated into R, G, B.
    cv::Mat grey16(1, 2, CV_16UC1);
    grey16.at<uint16_t>(0, 0) = 65535;
    grey16.at<uint16_t>(0, 1) = 32896;  // 128/255 of full scale
    ASSERT_TRUE(cv::imwrite((dir / "grey16.png").string(), grey16));
    auto t16 = Texture::load(dir / "grey16.png");
    ASSERT_TRUE(t16.isOk()) << t16.status().toString();
    EXPECT_TRUE(t16->texel(0, 0).isApprox(Rgb(1, 1, 1)));
    EXPECT_NEAR(t16->texel(1, 0).z(), 0.2158605f, 1e-5f);

    // Radiance HDR is linear already: values above 1 survive (RGBE keeps ~1 % precision).
    cv::Mat hdr(1, 1, CV_32FC3, cv::Scalar(0.5, 2.0, 8.0));  // B, G, R
    ASSERT_TRUE(cv::imwrite((dir / "light.hdr").string(), hdr));
    auto th = Texture::load(dir / "light.hdr");
    ASSERT_TRUE(th.isOk()) << th.status().toString();
    EXPECT_NEAR(th->texel(0, 0).x(), 8.0f, 0.08f);
    EXPECT_NEAR(th->texel(0, 0).y(), 2.0f, 0.02f);
    EXPECT_NEAR(th->texel(0, 0).z(), 0.5f, 0.01f);
}

TEST(TextureTest, MissingAndCorruptFiles) {
    const fs::path dir = test::tempDir();
    auto missing = Texture::load(dir / "absent.png");
    ASSERT_FALSE(missing.isOk());
    EXPECT_EQ(missing.status().code(), ErrorCode::kNotFound);
    EXPECT_NE(missing.status().message().find("absent.png"), std::string::npos);

    std::ofstream(dir / "broken.png") << "\x89PNG\r\n\x1a\n not really";
    auto broken = Texture::load(dir / "broken.png");
    ASSERT_FALSE(broken.isOk());
    EXPECT_EQ(broken.status().code(), ErrorCode::kCorruptData);
    EXPECT_NE(broken.status().message().find("broken.png"), std::string::npos);

    std::ofstream(dir / "broken.exr") << "v/1\x01 definitely not an EXR";
    auto broken_exr = EnvironmentMap::load(dir / "broken.exr");
    ASSERT_FALSE(broken_exr.isOk());
    EXPECT_EQ(broken_exr.status().code(), ErrorCode::kCorruptData);
    EXPECT_NE(broken_exr.status().message().find("broken.exr"), std::string::npos);

    auto broken_hdr = EnvironmentMap::load(dir / "absent.hdr");
    EXPECT_EQ(broken_hdr.status().code(), ErrorCode::kNotFound);
}

TEST(TextureTest, BilinearWrapsUAndClampsV) {
    // 2 x 2: top row black, white; bottom row red, green.
    const Texture t(2, 2, {Rgb(0, 0, 0), Rgb(1, 1, 1), Rgb(1, 0, 0), Rgb(0, 1, 0)});
    // Texel centres return the texel.
    EXPECT_TRUE(t.sample({0.25f, 0.25f}).isApprox(Rgb(0, 0, 0)));
    EXPECT_TRUE(t.sample({0.75f, 0.25f}).isApprox(Rgb(1, 1, 1)));
    EXPECT_TRUE(t.sample({0.25f, 0.75f}).isApprox(Rgb(1, 0, 0)));
    // Halfway between the two top texels.
    EXPECT_TRUE(t.sample({0.5f, 0.25f}).isApprox(Rgb(0.5f, 0.5f, 0.5f)));
    // u = 0 is halfway between the last and the first column (wrap); u = 1.25 == u = 0.25.
    EXPECT_TRUE(t.sample({0.0f, 0.25f}).isApprox(Rgb(0.5f, 0.5f, 0.5f)));
    EXPECT_TRUE(t.sample({1.25f, 0.25f}).isApprox(t.sample({0.25f, 0.25f})));
    EXPECT_TRUE(t.sample({-0.75f, 0.75f}).isApprox(t.sample({0.25f, 0.75f})));
    // v clamps: v = 0 is the top row, v beyond 1 the bottom row.
    EXPECT_TRUE(t.sample({0.25f, 0.0f}).isApprox(Rgb(0, 0, 0)));
    EXPECT_TRUE(t.sample({0.25f, -3.0f}).isApprox(Rgb(0, 0, 0)));
    EXPECT_TRUE(t.sample({0.75f, 7.0f}).isApprox(Rgb(0, 1, 0)));
    // Nothing to sample, or no finite coordinate: black, never a crash.
    EXPECT_TRUE(Texture().sample({0.5f, 0.5f}).isZero());
    EXPECT_TRUE(t.sample({std::nanf(""), 0.5f}).isZero());
    EXPECT_TRUE(t.sample({1e30f, 0.5f}).allFinite());
    // A size that disagrees with the texels makes an empty texture.
    EXPECT_TRUE(Texture(3, 3, {Rgb::Zero()}).empty());
}

// ---- environment maps ----

struct Brightest {
    int x = -1, y = -1;
};

Brightest brightestTexel(const Texture& t) {
    Brightest best;
    float best_luminance = -1;
    for (int y = 0; y < t.height(); ++y) {
        for (int x = 0; x < t.width(); ++x) {
            const Rgb& c = t.texel(x, y);
            const float luminance = 0.2126f * c.x() + 0.7152f * c.y() + 0.0722f * c.z();
            if (luminance > best_luminance) {
                best_luminance = luminance;
                best = {x, y};
            }
        }
    }
    return best;
}

struct EnvCase {
    const char* path;
    int width, height;
    int x, y;  // measured brightest pixel (MANIFEST.md)
};

TEST(EnvironmentMapTest, BrightestPixelsMatchMeasurements) {
    const EnvCase cases[] = {
        {"05_env_exr_latlong_blender/courtyard.exr", 1024, 512, 956, 214},
        {"05_env_exr_latlong_blender/studio.exr", 1024, 512, 709, 234},
        {"05_env_exr_latlong_blender/sunset.exr", 1024, 512, 614, 246},
        {"05_env_hdr_latlong/ennis.hdr", 256, 128, 145, 60},
        {"05_env_hdr_latlong/pisa.hdr", 256, 128, 97, 54},
    };
    for (const EnvCase& c : cases) {
        SCOPED_TRACE(c.path);
        const fs::path path = test::sharedDataDir() / c.path;
        MIXRAY_REQUIRE_SHARED_DATA(path);
        auto env = EnvironmentMap::load(path);
        ASSERT_TRUE(env.isOk()) << env.status().toString();
        ASSERT_EQ(env->texture().width(), c.width);
        ASSERT_EQ(env->texture().height(), c.height);
        const Brightest b = brightestTexel(env->texture());
        EXPECT_LE(std::abs(b.x - c.x), 2) << b.x << "," << b.y;
        EXPECT_LE(std::abs(b.y - c.y), 2) << b.x << "," << b.y;
        // radiance() looks up the texel a direction points at.
        const Eigen::Vector3f d = env->directionOf(Eigen::Vector2f(c.x, c.y));
        const Rgb at = env->texture().texel(c.x, c.y);
        EXPECT_TRUE(env->radiance(d).isApprox(at, 1e-3f));
    }
}

TEST(EnvironmentMapTest, TiledMipMappedExrGivesTopLevel) {
    const fs::path path =
        test::sharedDataDir() / "05_env_exr_latlong_openexr" / "OrientationLatLong.exr";
    MIXRAY_REQUIRE_SHARED_DATA(path);
    auto env = EnvironmentMap::load(path);
    ASSERT_TRUE(env.isOk()) << env.status().toString();
    EXPECT_EQ(env->texture().width(), 1024);
    EXPECT_EQ(env->texture().height(), 512);
}

TEST(EnvironmentMapTest, PixelDirectionRoundTripAndConvention) {
    const EnvironmentMap env(Texture(64, 32, std::vector<Rgb>(64 * 32, Rgb::Zero())));
    for (int y = 0; y < 32; ++y) {
        for (int x = 0; x < 64; ++x) {
            const Eigen::Vector2f pixel(x, y);
            const Eigen::Vector3f d = env.directionOf(pixel);
            ASSERT_NEAR(d.norm(), 1.0f, 1e-5f);
            const Eigen::Vector2f back = env.pixelOf(d);
            // u wraps: compare modulo the width.
            const float dx = std::remainder(back.x() - pixel.x(), 64.0f);
            EXPECT_NEAR(dx, 0.0f, 1e-3f) << x << "," << y;
            EXPECT_NEAR(back.y(), pixel.y(), 1e-3f) << x << "," << y;
        }
    }
    // The documented formula: +x at the centre column, straight up at v = 0, −y at u = 0.75.
    auto uv = [&](const Eigen::Vector3f& d) {
        const Eigen::Vector2f p = env.pixelOf(d);
        return Eigen::Vector2f((p.x() + 0.5f) / 64.0f, (p.y() + 0.5f) / 32.0f);
    };
    EXPECT_TRUE(uv({1, 0, 0}).isApprox(Eigen::Vector2f(0.5f, 0.5f), 1e-6f));
    EXPECT_TRUE(uv({0, -1, 0}).isApprox(Eigen::Vector2f(0.75f, 0.5f), 1e-6f));
    EXPECT_TRUE(uv({0, 1, 0}).isApprox(Eigen::Vector2f(0.25f, 0.5f), 1e-6f));
    EXPECT_NEAR(uv({0, 0, 1}).y(), 0.0f, 1e-6f);
    EXPECT_NEAR(uv({0, 0, -1}).y(), 1.0f, 1e-6f);
    const float u_minus_x = uv({-1, 0, 0}).x();
    EXPECT_TRUE(std::abs(u_minus_x) < 1e-6f || std::abs(u_minus_x - 1) < 1e-6f);
}

// OpenEXR's own lat-long convention (ImfEnvmap.h, y up) against ours (z up): the same pixel
// must give the same direction up to the fixed rotation (X, Y, Z)_exr = (y, z, x)_ours.
// OrientationLatLong.exr is labelled with OpenEXR's axes: its preview shows +X a quarter of
// the way across, +Z at the centre, −X at three quarters, and the Y axis pointing up.
TEST(EnvironmentMapTest, OrientationMatchesOpenExrConvention) {
    const fs::path path =
        test::sharedDataDir() / "05_env_exr_latlong_openexr" / "OrientationLatLong.exr";
    MIXRAY_REQUIRE_SHARED_DATA(path);
    Imath::Box2i window;
    {
        Imf::InputFile file(path.c_str());
        window = file.header().dataWindow();
        const auto* envmap = file.header().findTypedAttribute<Imf::EnvmapAttribute>("envmap");
        ASSERT_NE(envmap, nullptr);
        EXPECT_EQ(envmap->value(), Imf::ENVMAP_LATLONG);
    }
    auto env = EnvironmentMap::load(path);
    ASSERT_TRUE(env.isOk()) << env.status().toString();
    const auto exrToOurs = [](const Imath::V3f& d) { return Eigen::Vector3f(d.z, d.x, d.y); };
    for (int y = 8; y < 512; y += 31) {
        for (int x = 3; x < 1024; x += 37) {
            // OpenEXR maps the outermost pixel centres to ±π, we map the pixel edges; compare
            // away from the poles in directions, allowing for that half-pixel scale.
            const Imath::V3f exr = Imf::LatLongMap::direction(window, Imath::V2f(x, y));
            const Eigen::Vector3f ours = env->directionOf(Eigen::Vector2f(x, y));
            EXPECT_LT((exrToOurs(exr).normalized() - ours).norm(), 2 * kPi / 512) << x << "," << y;
        }
    }
    // The labelled axes: OpenEXR's +X, +Z, −X, −Z along the horizon are our +y, +x, −y, −x.
    const auto columnOf = [&](const Eigen::Vector3f& d) { return env->pixelOf(d).x(); };
    EXPECT_NEAR(columnOf({0, 1, 0}), 255.5f, 0.01f);   // +X_exr
    EXPECT_NEAR(columnOf({1, 0, 0}), 511.5f, 0.01f);   // +Z_exr
    EXPECT_NEAR(columnOf({0, -1, 0}), 767.5f, 0.01f);  // −X_exr

    // The content itself: every face has dark axis arms drawn from its centre, one straight
    // up and one along the horizon towards the neighbouring face. At +Z_exr (our +x) the
    // horizontal arm points at the +X_exr face (our +y); read upside down or mirrored, the
    // arms would be below the horizon or on the other side.
    const auto luminance = [&](const Eigen::Vector3f& d) {
        const Rgb c = env->radiance(d.normalized());
        return 0.2126f * c.x() + 0.7152f * c.y() + 0.0722f * c.z();
    };
    const float a = 10 * kPi / 180;  // along the horizon
    EXPECT_LT(luminance({std::cos(a), std::sin(a), 0}), 0.1f);
    EXPECT_GT(luminance({std::cos(a), -std::sin(a), 0}), 0.5f);
    const float e = 20 * kPi / 180;  // above and below the horizon
    EXPECT_LT(luminance({std::cos(e), 0, std::sin(e)}), 0.1f);
    EXPECT_GT(luminance({std::cos(e), 0, -std::sin(e)}), 0.5f);
}

TEST(EnvironmentMapTest, MirrorUpperIntoLower) {
    const int w = 8, h = 6;
    std::vector<Rgb> texels;
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x)
            texels.emplace_back(float(x), float(y), float(x * y));
    }
    EnvironmentMap env(Texture(w, h, texels));
    env.mirrorUpperIntoLower();
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            // Upper rows unchanged; row v and row 1 − v equal.
            if (y < h / 2) {
                EXPECT_EQ(env.texture().texel(x, y), texels[y * w + x]);
            }
            EXPECT_EQ(env.texture().texel(x, y), env.texture().texel(x, h - 1 - y));
        }
    }
    // The radiance from below mirrors the radiance from above.
    const Eigen::Vector3f up = Eigen::Vector3f(0.3f, -0.2f, 0.6f).normalized();
    const Eigen::Vector3f down(up.x(), up.y(), -up.z());
    EXPECT_TRUE(env.radiance(up).isApprox(env.radiance(down), 1e-5f));
    // Odd heights keep their middle row.
    EnvironmentMap odd(Texture(
        2, 3,
        {Rgb(1, 1, 1), Rgb(1, 1, 1), Rgb(2, 2, 2), Rgb(2, 2, 2), Rgb(3, 3, 3), Rgb(3, 3, 3)}));
    odd.mirrorUpperIntoLower();
    EXPECT_EQ(odd.texture().texel(0, 1), Rgb(2, 2, 2));
    EXPECT_EQ(odd.texture().texel(1, 2), Rgb(1, 1, 1));
}

}  // namespace
}  // namespace mixray::render
