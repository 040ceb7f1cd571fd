// Scene files: the fixtures parse into the expected structs; every malformed input is
// kCorruptData naming the line and field path; validate() checks scenes built in code.
#include "mixray/render/scene_file.h"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <iterator>
#include <limits>
#include <random>
#include <string>

#include "mixray/render/compositor_node.h"
#include "test_data.h"

namespace mixray::render {
namespace {

namespace fs = std::filesystem;

constexpr double kPi = 3.14159265358979323846;

// The message of a failed parse; the test fails when the parse succeeds.
std::string parseError(const std::string& text, ErrorCode code = ErrorCode::kCorruptData) {
    auto scene = parseScene(text, "s.yaml");
    EXPECT_FALSE(scene.isOk()) << text;
    if (scene.isOk())
        return {};
    EXPECT_EQ(scene.status().code(), code) << scene.status().toString();
    return scene.status().message();
}

// Expects "s.yaml:LINE:COL: PATH: ..." (column not checked) and `what` in the message.
void expectError(const std::string& text, int line, const std::string& path,
                 const std::string& what = {}) {
    const std::string message = parseError(text);
    const std::string prefix = "s.yaml:" + std::to_string(line) + ":";
    EXPECT_EQ(message.rfind(prefix, 0), 0u) << "message: " << message << "\ntext:\n" << text;
    if (!path.empty()) {
        EXPECT_NE(message.find(": " + path + ": "), std::string::npos)
            << "message: " << message << "\nwanted path " << path;
    }
    if (!what.empty()) {
        EXPECT_NE(message.find(what), std::string::npos) << "message: " << message;
    }
}

const char* kHeader = R"(materials:
  m:
    type: diffuse
objects:
)";

TEST(SceneFileTest, TeapotChessboardFixture) {
    const fs::path file = test::fixturesDir() / "scenes" / "teapot_chessboard.yaml";
    auto scene = loadScene(file);
    ASSERT_TRUE(scene.isOk()) << scene.status().toString();
    ASSERT_EQ(scene->materials.size(), 2u);
    const Material& metal = scene->materials.at("teapot_metal");
    EXPECT_EQ(metal.type, MaterialType::kMetal);
    EXPECT_TRUE(metal.f0.isApprox(Rgb(0.95f, 0.93f, 0.88f)));
    const Material& table = scene->materials.at("table");
    EXPECT_EQ(table.type, MaterialType::kDiffuse);
    EXPECT_TRUE(table.albedo.isApprox(Rgb::Constant(0.55f)));
    EXPECT_FLOAT_EQ(table.reflectance, 0.15f);

    ASSERT_EQ(scene->objects.size(), 2u);
    const SceneObject& teapot = scene->objects[0];
    EXPECT_EQ(teapot.name, "teapot");
    EXPECT_EQ(teapot.role, ObjectRole::kVirtual);
    EXPECT_EQ(teapot.shape.type, ShapeType::kMesh);
    EXPECT_FLOAT_EQ(teapot.shape.scale, 0.02f);
    // Relative to the scene file's folder, made absolute: the shared folder beside the repo.
    const fs::path mesh = (test::sourceDir() / "../shared/data/06_models/newell_teapot.obj");
    EXPECT_EQ(teapot.shape.mesh, fs::absolute(mesh).lexically_normal());
    EXPECT_TRUE(teapot.shape.mesh.is_absolute());
    EXPECT_EQ(teapot.material, "teapot_metal");
    EXPECT_EQ(teapot.anchor, "world");
    EXPECT_TRUE(teapot.T_anchor_object.translation().isApprox(Eigen::Vector3d(0.125, 0.0875, 0)));
    // 90 degrees about x: the file's +y (up) becomes world +z.
    EXPECT_TRUE((teapot.T_anchor_object.linear() * Eigen::Vector3d::UnitY())
                    .isApprox(Eigen::Vector3d::UnitZ(), 1e-12));
    EXPECT_EQ(teapot.where.line, 16);

    const SceneObject& ghost = scene->objects[1];
    EXPECT_EQ(ghost.role, ObjectRole::kGhost);
    EXPECT_EQ(ghost.shape.type, ShapeType::kPlane);
    EXPECT_FLOAT_EQ(ghost.shape.size.x(), 1.2f);
    EXPECT_FLOAT_EQ(ghost.shape.size.y(), 0.8f);

    ASSERT_EQ(scene->lights.size(), 1u);
    const Light& lamp = scene->lights[0];
    EXPECT_EQ(lamp.type, LightType::kPoint);
    EXPECT_EQ(lamp.name, "lamp");
    EXPECT_TRUE(lamp.position.isApprox(Eigen::Vector3d(0.4, -0.3, 0.8)));
    EXPECT_TRUE(lamp.intensity.isApprox(Rgb::Constant(2.0f)));
    EXPECT_FALSE(scene->camera.has_value());
    EXPECT_EQ(scene->source_path, file);
}

TEST(SceneFileTest, DemoFixture) {
    auto scene = loadScene(test::fixturesDir() / "scenes" / "demo.yaml");
    ASSERT_TRUE(scene.isOk()) << scene.status().toString();
    ASSERT_EQ(scene->materials.size(), 4u);
    const Material& glass = scene->materials.at("glass");
    EXPECT_EQ(glass.type, MaterialType::kGlass);
    EXPECT_TRUE(glass.ior.isApprox(Rgb(1.51f, 1.52f, 1.53f)));
    EXPECT_TRUE(glass.transmission.isApprox(Rgb(0.98f, 0.99f, 0.98f)));
    const Material& plastic = scene->materials.at("red_plastic");
    EXPECT_EQ(plastic.type, MaterialType::kPhong);
    EXPECT_FLOAT_EQ(plastic.shininess, 64);
    EXPECT_TRUE(plastic.specular.isApprox(Rgb::Constant(0.04f)));

    ASSERT_EQ(scene->objects.size(), 4u);
    EXPECT_EQ(scene->objects[0].shape.type, ShapeType::kSphere);
    EXPECT_FLOAT_EQ(scene->objects[0].shape.radius, 0.05f);
    EXPECT_EQ(scene->objects[0].anchor, "marker:0");
    const SceneObject& teapot = scene->objects[1];
    EXPECT_TRUE((teapot.T_anchor_object.linear() * Eigen::Vector3d::UnitY())
                    .isApprox(Eigen::Vector3d::UnitZ(), 1e-6));
    const SceneObject& crate = scene->objects[2];
    EXPECT_EQ(crate.shape.type, ShapeType::kBox);
    EXPECT_TRUE(crate.shape.size.isApprox(Eigen::Vector3f::Constant(0.06f)));
    const Eigen::Vector3d x_rotated = crate.T_anchor_object.linear() * Eigen::Vector3d::UnitX();
    EXPECT_NEAR(x_rotated.x(), std::cos(kPi / 6), 1e-12);
    EXPECT_NEAR(x_rotated.y(), std::sin(kPi / 6), 1e-12);
    EXPECT_EQ(scene->objects[3].role, ObjectRole::kGhost);

    ASSERT_EQ(scene->lights.size(), 1u);
    EXPECT_EQ(scene->lights[0].type, LightType::kSphere);
    EXPECT_FLOAT_EQ(scene->lights[0].radius, 0.1f);
    EXPECT_EQ(scene->lights[0].anchor, "marker:0");
    EXPECT_TRUE(scene->lights[0].intensity.isApprox(Rgb(3.0f, 2.9f, 2.7f)));
}

TEST(SceneFileTest, EveryFeature) {
    const std::string text = R"(version: 1
objects:
  - name: disk
    shape: { disk: { radius: 0.2 } }
    material: chrome
    anchor: marker:007
    pose: { rotation_deg: [0, 90, 0] }
materials:
  chrome: { type: mirror }
  dim_mirror: { type: mirror, reflectance: 0.5 }
  painted:
    type: phong
    albedo_texture: tex/wood.png
    reflectance_map: /abs/map.png
lights:
  - { type: directional, direction: [0, 0, -2], irradiance: [1, 2, 3] }
  - type: environment
    file: env/courtyard.exr
    scale: 0.5
    mirror_lower_hemisphere: true
    rotation: { rotation_deg: [0, 0, 90] }
camera:
  pose: { translation: [0, -1, 0.5], quaternion: [1, 0, 0, 0] }
  model:
    lens: fisheye
    width: 1280
    height: 960
    fx: 400
    fy: 401
    cx: 639.5
    cy: 479.5
    distortion: [0.1, -0.01, 0.001, 0]
)";
    auto scene = parseScene(text, "dir/s.yaml");
    ASSERT_TRUE(scene.isOk()) << scene.status().toString();
    EXPECT_EQ(scene->objects[0].shape.type, ShapeType::kDisk);
    EXPECT_EQ(scene->objects[0].anchor, "marker:7");  // canonical spelling
    EXPECT_TRUE((scene->objects[0].T_anchor_object.linear() * Eigen::Vector3d::UnitZ())
                    .isApprox(Eigen::Vector3d::UnitX(), 1e-12));
    EXPECT_EQ(scene->materials.at("chrome").type, MaterialType::kMirror);
    EXPECT_FLOAT_EQ(scene->materials.at("chrome").reflectance, 1.0f);
    EXPECT_FLOAT_EQ(scene->materials.at("dim_mirror").reflectance, 0.5f);
    EXPECT_EQ(scene->materials.at("painted").albedo_texture, fs::path("dir/tex/wood.png"));
    EXPECT_EQ(scene->materials.at("painted").reflectance_map, fs::path("/abs/map.png"));
    EXPECT_EQ(scene->materials.at("painted").where, (SourceLocation{"dir/s.yaml", 11, 3}));

    ASSERT_EQ(scene->lights.size(), 2u);
    EXPECT_EQ(scene->lights[0].type, LightType::kDirectional);
    EXPECT_TRUE(scene->lights[0].direction.isApprox(Eigen::Vector3d(0, 0, -1)));
    EXPECT_TRUE(scene->lights[0].intensity.isApprox(Rgb(1, 2, 3)));
    const Light& env = scene->lights[1];
    EXPECT_EQ(env.type, LightType::kEnvironment);
    EXPECT_EQ(env.environment, fs::path("dir/env/courtyard.exr"));
    EXPECT_FLOAT_EQ(env.environment_scale, 0.5f);
    EXPECT_TRUE(env.mirror_lower_hemisphere);
    EXPECT_TRUE((env.T_world_environment.linear() * Eigen::Vector3d::UnitX())
                    .isApprox(Eigen::Vector3d::UnitY(), 1e-12));

    ASSERT_TRUE(scene->camera.has_value());
    EXPECT_TRUE(scene->camera->T_world_cam.translation().isApprox(Eigen::Vector3d(0, -1, 0.5)));
    ASSERT_TRUE(scene->camera->model.has_value());
    const calibration::CameraModel& model = *scene->camera->model;
    EXPECT_EQ(model.lens, calibration::LensModel::kFisheye);
    EXPECT_EQ(model.width, 1280);
    EXPECT_EQ(model.height, 960);
    EXPECT_DOUBLE_EQ(model.fy, 401);
    EXPECT_DOUBLE_EQ(model.cx, 639.5);
    EXPECT_EQ(model.distortion.size(), 4u);
}

TEST(SceneFileTest, EmptyListsAreAScene) {
    auto scene = parseScene("materials: {}\nobjects: []\nlights: []\n", "s.yaml");
    ASSERT_TRUE(scene.isOk()) << scene.status().toString();
    EXPECT_TRUE(scene->objects.empty());
}

TEST(SceneFileTest, MalformedObjects) {
    const std::string h = kHeader;
    // Unknown key with a hint.
    expectError(h + "  - name: a\n    shape: { sphere: { radius: 1 } }\n    material: m\n"
                    "    materal: m\n",
                8, "objects[0].materal", "did you mean material?");
    // Negative and zero sizes, NaN, wrong types.
    expectError(h + "  - name: a\n    shape:\n      sphere: { radius: -1 }\n    material: m\n", 7,
                "objects[0].shape.sphere.radius", "above 0");
    expectError(h + "  - name: a\n    shape: { box: { size: [1, 0, 1] } }\n    material: m\n", 6,
                "objects[0].shape.box.size[1]");
    expectError(h + "  - name: a\n    shape: { plane: { size: [1, 1, 1] } }\n    material: m\n", 6,
                "objects[0].shape.plane.size", "[x, y]");
    expectError(h + "  - name: a\n    shape: { disk: { radius: .nan } }\n    material: m\n", 6,
                "objects[0].shape.disk.radius", "finite");
    expectError(h + "  - name: a\n    shape: { sphere: { radius: big } }\n    material: m\n", 6,
                "objects[0].shape.sphere.radius");
    expectError(h + "  - name: a\n    shape: { cone: { radius: 1 } }\n    material: m\n", 6,
                "objects[0].shape.cone");
    expectError(h + "  - name: a\n    shape: { sphere: { radius: 1 }, disk: { radius: 1 } }\n"
                    "    material: m\n",
                6, "objects[0].shape", "exactly one");
    expectError(h + "  - name: a\n    shape: { mesh: { scale: 2 } }\n    material: m\n", 6,
                "objects[0].shape.mesh.file", "missing");
    expectError(h + "  - name: a\n    shape: { mesh: { file: x.obj, scale: 0 } }\n"
                    "    material: m\n",
                6, "objects[0].shape.mesh.scale");
    // Unknown material, with a hint; duplicate names; bad anchors and roles.
    expectError(h + "  - name: a\n    shape: { sphere: { radius: 1 } }\n    material: mm\n", 7,
                "objects[0].material", "unknown material \"mm\" (did you mean m?)");
    expectError(h + "  - name: a\n    shape: { sphere: { radius: 1 } }\n    material: m\n"
                    "  - name: a\n    shape: { sphere: { radius: 1 } }\n    material: m\n",
                8, "objects[1].name", "duplicate object name \"a\" (first at s.yaml:5:");
    expectError(h + "  - name: a\n    shape: { sphere: { radius: 1 } }\n    material: m\n"
                    "    anchor: marker:x\n",
                8, "objects[0].anchor", "marker:<id>");
    expectError(h + "  - name: a\n    shape: { sphere: { radius: 1 } }\n    material: m\n"
                    "    anchor: table\n",
                8, "objects[0].anchor");
    expectError(h + "  - name: a\n    shape: { sphere: { radius: 1 } }\n    material: m\n"
                    "    role: real\n",
                8, "objects[0].role", "virtual or ghost");
    expectError(h + "  - name: a b\n    shape: { sphere: { radius: 1 } }\n    material: m\n", 5,
                "objects[0].name");
    expectError(h + "  - name: a\n    material: m\n", 5, "objects[0].shape", "missing");
    // Poses.
    expectError(h + "  - name: a\n    shape: { sphere: { radius: 1 } }\n    material: m\n"
                    "    pose: { rotation_deg: [0, 0, 0], quaternion: [1, 0, 0, 0] }\n",
                8, "objects[0].pose.quaternion", "give one of");
    expectError(h + "  - name: a\n    shape: { sphere: { radius: 1 } }\n    material: m\n"
                    "    pose: { quaternion: [1, 1, 0, 0] }\n",
                8, "objects[0].pose.quaternion", "unit quaternion");
    expectError(h + "  - name: a\n    shape: { sphere: { radius: 1 } }\n    material: m\n"
                    "    pose:\n      translation: [0, 0]\n",
                9, "objects[0].pose.translation", "[x, y, z]");
    expectError(h + "  - name: a\n    shape: { sphere: { radius: 1 } }\n    material: m\n"
                    "    pose:\n      translation: [0, 0, .inf]\n",
                9, "objects[0].pose.translation[2]", "finite");
    expectError(h + "  - name: a\n    shape: { sphere: { radius: 1 } }\n    material: m\n"
                    "    pose:\n      rotation: [0, 0, 1]\n",
                9, "objects[0].pose.rotation", "did you mean rotation_deg?");
}

TEST(SceneFileTest, MalformedMaterials) {
    expectError("materials:\n  g:\n    type: glass\n    ior: 0.9\n", 4, "materials.g.ior",
                "from 1 to");
    expectError("materials:\n  g:\n    type: glass\n    ior: [1.5, 0.5, 1.5]\n", 4,
                "materials.g.ior[1]");
    expectError("materials:\n  g:\n    type: glas\n", 3, "materials.g.type", "did you mean glass?");
    expectError("materials:\n  g:\n    type: metal\n    ior: 1.5\n", 4, "materials.g.ior",
                "does not apply to a metal material");
    expectError("materials:\n  g:\n    albedo: [0.5, 0.5]\n", 3, "materials.g.albedo", "[r, g, b]");
    expectError("materials:\n  g:\n    albedo: -0.1\n", 3, "materials.g.albedo");
    expectError("materials:\n  g:\n    albdo: 0.5\n", 3, "materials.g.albdo",
                "did you mean albedo?");
    expectError("materials:\n  g:\n    type: phong\n    shininess: 0\n", 4,
                "materials.g.shininess");
    expectError("materials:\n  g:\n    reflectance: 1.5\n", 3, "materials.g.reflectance");
    expectError("materials:\n  g: {}\n  g: {}\n", 3, "materials.g", "duplicate key");
    expectError("materials:\n  \"a b\": {}\n", 2, "materials.\"a b\"", "material name");
    expectError("materials:\n  g: diffuse\n", 2, "materials.g", "a material mapping");
}

TEST(SceneFileTest, MalformedLightsAndCamera) {
    expectError("lights:\n  - type: point\n    intensity: 1\n", 2, "lights[0].position", "missing");
    expectError("lights:\n  - type: spot\n    position: [0, 0, 1]\n", 2, "lights[0].type",
                "point, sphere, directional, environment");
    expectError("lights:\n  - type: point\n    position: [0, 0, 1]\n    radius: 1\n", 4,
                "lights[0].radius", "does not apply to a point light");
    expectError("lights:\n  - type: sphere\n    position: [0, 0, 1]\n    radius: 0\n", 4,
                "lights[0].radius");
    expectError("lights:\n  - type: point\n    position: [0, 0, 1]\n    intensity: -1\n", 4,
                "lights[0].intensity");
    expectError("lights:\n  - type: directional\n    direction: [0, 0, 0]\n", 3,
                "lights[0].direction", "zero");
    expectError(
        "lights:\n  - { name: a, type: point, position: [0, 0, 1] }\n"
        "  - { name: a, type: point, position: [0, 0, 1] }\n",
        3, "lights[1].name", "duplicate light name");
    expectError(
        "lights:\n  - type: environment\n    file: e.exr\n"
        "    mirror_lower_hemisphere: yes please\n",
        4, "lights[0].mirror_lower_hemisphere", "true or false");
    expectError("lights:\n  - type: environment\n    file: e.exr\n    rotation: [0, 0, 1]\n", 4,
                "lights[0].rotation");
    expectError(
        "camera:\n  model:\n    lens: orthographic\n    width: 1\n    height: 1\n"
        "    fx: 1\n    fy: 1\n    cx: 0\n    cy: 0\n",
        3, "camera.model.lens", "pinhole, fisheye, stereographic or a configured");
    expectError(
        "camera:\n  model:\n    width: 0\n    height: 1\n    fx: 1\n    fy: 1\n"
        "    cx: 0\n    cy: 0\n",
        3, "camera.model.width");
    expectError(
        "camera:\n  model:\n    width: 640\n    height: 480\n    fx: 1\n    fy: 1\n"
        "    cx: 0\n    cy: 0\n    distortion: [1, 2, 3]\n",
        9, "camera.model.distortion", "4, 5 or 8");
    expectError(
        "camera:\n  model:\n    width: 640\n    height: 480\n    fx: 1\n    fy: 1\n"
        "    cx: 0\n",
        3, "camera.model.cy", "missing");
    expectError("depth_surface:\n  reflectance: 1.5\n", 2, "depth_surface.reflectance");
    expectError("depth_surface:\n  albedo: 0.5\n", 2, "depth_surface.albedo", "unknown field");
    expectError("depth_surface: 0.2\n", 1, "depth_surface", "reflectance:");
    auto parsed = parseScene("depth_surface: { reflectance: 0.25 }\n", "s.yaml");
    ASSERT_TRUE(parsed.isOk()) << parsed.status().toString();
    EXPECT_FLOAT_EQ(parsed->depth_surface.reflectance, 0.25f);
    auto plain = parseScene("objects: []\n", "s.yaml");
    ASSERT_TRUE(plain.isOk());
    EXPECT_EQ(plain->depth_surface.reflectance, 0.f);
    EXPECT_FALSE(plain->lens_effects.any());
}

TEST(SceneFileTest, LensEffects) {
    auto parsed = parseScene(
        "lens_effects:\n  bloom: { threshold: 2, strength: 0.5, radius_px: 4 }\n"
        "  glare: { passes: 2, attenuation: 0.85 }\n",
        "s.yaml");
    ASSERT_TRUE(parsed.isOk()) << parsed.status().toString();
    ASSERT_TRUE(parsed->lens_effects.bloom && parsed->lens_effects.glare);
    EXPECT_FLOAT_EQ(parsed->lens_effects.bloom->threshold, 2);
    EXPECT_FLOAT_EQ(parsed->lens_effects.bloom->strength, 0.5f);
    EXPECT_FLOAT_EQ(parsed->lens_effects.bloom->radius_px, 4);
    EXPECT_EQ(parsed->lens_effects.glare->passes, 2);
    EXPECT_FLOAT_EQ(parsed->lens_effects.glare->attenuation, 0.85f);
    EXPECT_FLOAT_EQ(parsed->lens_effects.glare->threshold, Glare{}.threshold);  // the default
    auto bloom_only = parseScene("lens_effects: { bloom: {} }\n", "s.yaml");
    ASSERT_TRUE(bloom_only.isOk()) << bloom_only.status().toString();
    EXPECT_TRUE(bloom_only->lens_effects.bloom && !bloom_only->lens_effects.glare);

    expectError("lens_effects:\n  bloom: { threshold: 0 }\n", 2, "lens_effects.bloom.threshold");
    expectError("lens_effects:\n  bloom: { radius_px: 100 }\n", 2, "lens_effects.bloom.radius_px");
    expectError("lens_effects:\n  glare: { passes: 2.5 }\n", 2, "lens_effects.glare.passes",
                "whole number");
    expectError("lens_effects:\n  glare: { passes: 9 }\n", 2, "lens_effects.glare.passes");
    expectError("lens_effects:\n  glare: { attenuation: 1 }\n", 2,
                "lens_effects.glare.attenuation");
    expectError("lens_effects:\n  flare: {}\n", 2, "lens_effects.flare", "unknown field");
    expectError("lens_effects: 1\n", 1, "lens_effects", "bloom:");
}

TEST(SceneFileTest, CameraAperture) {
    auto parsed = parseScene(
        "camera:\n  aperture: { f_number: 1.8, focal_length_mm: 35, focus_distance_m: 1.2 }\n",
        "s.yaml");
    ASSERT_TRUE(parsed.isOk()) << parsed.status().toString();
    ASSERT_TRUE(parsed->camera && parsed->camera->aperture);
    EXPECT_FALSE(parsed->camera->has_pose);  // the pose still comes from tracking
    EXPECT_FLOAT_EQ(parsed->camera->aperture->f_number, 1.8f);
    EXPECT_FLOAT_EQ(parsed->camera->aperture->diameter_m(), 0.035f / 1.8f);
    EXPECT_FLOAT_EQ(parsed->camera->aperture->focus_distance_m, 1.2f);
    auto default_f =
        parseScene("camera: { aperture: { focal_length_mm: 6, focus_distance_m: 2 } }\n", "s.yaml");
    ASSERT_TRUE(default_f.isOk()) << default_f.status().toString();
    EXPECT_FLOAT_EQ(default_f->camera->aperture->f_number, LensAperture{}.f_number);

    expectError("camera:\n  aperture: { focus_distance_m: 2 }\n", 2, "camera.aperture",
                "focal_length_mm is required");
    expectError("camera:\n  aperture: { focal_length_mm: 6 }\n", 2, "camera.aperture",
                "focus_distance_m is required");
    expectError("camera:\n  aperture: { focal_length_mm: 6, focus_distance_m: 0 }\n", 2,
                "camera.aperture.focus_distance_m");
    expectError("camera:\n  aperture: { f_number: 0.2, focal_length_mm: 6, focus_distance_m: 1 }\n",
                2, "camera.aperture.f_number");
    expectError("camera:\n  aperture: { iris: 2 }\n", 2, "camera.aperture.iris", "unknown field");
}

TEST(SceneFileTest, CameraMatching) {
    auto parsed = parseScene("camera_matching: { noise: 0.8 }\n", "s.yaml");
    ASSERT_TRUE(parsed.isOk()) << parsed.status().toString();
    ASSERT_TRUE(parsed->camera_matching.noise);
    EXPECT_FLOAT_EQ(*parsed->camera_matching.noise, 0.8f);
    auto off = parseScene("camera_matching: {}\n", "s.yaml");
    ASSERT_TRUE(off.isOk()) << off.status().toString();
    EXPECT_FALSE(off->camera_matching.any());
    expectError("camera_matching:\n  noise: 11\n", 2, "camera_matching.noise");
    auto blur = parseScene("camera_matching: { motion_blur: { exposure_ms: 8 } }\n", "s.yaml");
    ASSERT_TRUE(blur.isOk()) << blur.status().toString();
    EXPECT_FLOAT_EQ(blur->camera_matching.motion_blur_exposure_ms.value_or(-1), 8);
    EXPECT_FALSE(blur->camera_matching.noise);
    auto own = parseScene("camera_matching: { motion_blur: {} }\n", "s.yaml");
    ASSERT_TRUE(own.isOk()) << own.status().toString();
    EXPECT_EQ(own->camera_matching.motion_blur_exposure_ms, 0.f);  // the frames' own only
    expectError("camera_matching:\n  motion_blur: { exposure_ms: -1 }\n", 2,
                "camera_matching.motion_blur.exposure_ms");
    expectError("camera_matching:\n  blur: 1\n", 2, "camera_matching.blur", "unknown field");
}

TEST(SceneFileTest, MalformedFiles) {
    expectError("", 1, "", "empty");
    expectError("objects: []\nfoo: 1\n", 2, "foo", "unknown field");
    expectError("version: 2\n", 1, "version", "version 2");
    expectError("objects: {}\n", 1, "objects", "a list of objects");
    expectError("- 1\n- 2\n", 1, "", "a mapping");
    expectError("objects: []\n---\nobjects: []\n", 2, "", "second YAML document");
    expectError("objects: [\n", 2, "", "YAML syntax error");
    expectError(", objects: []\n", 1, "", "unexpected ','");
    expectError("objects:\n\t- name: a\n", 2, "", "tab in indentation");
    expectError(std::string("objects: [] \x01\n"), 1, "", "control character");
    std::string deep = "objects: ";
    for (int i = 0; i < 40; ++i)
        deep += "[";
    expectError(deep + "\n", 1, "", "nesting deeper");
    EXPECT_NE(parseError(std::string(kMaxSceneFileBytes + 1, ' ')).find("at most"),
              std::string::npos);
}

// A light's shadow map: every setting read, and bad ones named with where they are.
TEST(SceneFileTest, ShadowMapSettings) {
    auto scene = parseScene(
        "lights:\n  - type: point\n    position: [0, 0, 1]\n    shadow_map:\n"
        "      filter: pcf\n      resolution: 512\n      kernel: 5\n      storage: rgba8\n"
        "  - type: directional\n    direction: [0, 0, -1]\n    shadow_map: { filter: hard, "
        "storage: 8bit }\n",
        "scene.yaml");
    ASSERT_TRUE(scene.isOk()) << scene.status().toString();
    ASSERT_TRUE(scene->lights[0].shadow_map);
    const ShadowMapSettings& pcf = *scene->lights[0].shadow_map;
    EXPECT_EQ(pcf.filter, ShadowMapFilter::kPcf);
    EXPECT_EQ(pcf.resolution, 512);
    EXPECT_EQ(pcf.pcf_kernel, 5);
    EXPECT_EQ(pcf.storage, ShadowMapStorage::kPackedRgba8);
    EXPECT_EQ(scene->lights[1].shadow_map->filter, ShadowMapFilter::kHard);
    EXPECT_EQ(scene->lights[1].shadow_map->storage, ShadowMapStorage::kEightBit);
    const std::vector<std::pair<std::string, std::string>> bad = {
        {"    shadow_map: { filter: pfc }\n", "expected one of hard, pcf, vsm (did you mean pcf?)"},
        {"    shadow_map: { resolution: 8 }\n", "resolution"},
        {"    shadow_map: { kernel: 16 }\n", "kernel"},
        {"    shadow_map: { bleeding_reduction: 1 }\n", "bleeding_reduction"},
        {"    shadow_map: { storage: 16bit }\n", "expected one of float, 8bit, rgba8"},
        {"    shadow_map: { blur: 2 }\n", "blur"},
    };
    for (const auto& [text, message] : bad) {
        SCOPED_TRACE(text);
        auto refused =
            parseScene("lights:\n  - type: point\n    position: [0, 0, 1]\n" + text, "s.yaml");
        ASSERT_FALSE(refused.isOk());
        EXPECT_NE(refused.status().message().find(message), std::string::npos)
            << refused.status().toString();
        EXPECT_NE(refused.status().message().find("s.yaml:4"), std::string::npos)
            << refused.status().toString();
    }
    auto environment = parseScene(
        "lights:\n  - type: environment\n    file: e.hdr\n    shadow_map: {}\n", "s.yaml");
    ASSERT_FALSE(environment.isOk());
    EXPECT_NE(environment.status().message().find("does not apply to a environment light"),
              std::string::npos)
        << environment.status().toString();
}

// The lights tracking estimates take the scene's estimated_lights settings: a shadow map for
// each point, sphere and directional estimate, none for the environment map.
TEST(SceneFileTest, EstimatedLightSettings) {
    auto scene = parseScene(
        "estimated_lights:\n  shadow_map: { filter: vsm, resolution: 256, blur_texels: 3 }\n",
        "scene.yaml");
    ASSERT_TRUE(scene.isOk()) << scene.status().toString();
    ASSERT_TRUE(scene->estimated_lights.shadow_map);
    EXPECT_EQ(scene->estimated_lights.shadow_map->filter, ShadowMapFilter::kVsm);
    EXPECT_EQ(scene->estimated_lights.shadow_map->resolution, 256);
    EXPECT_FLOAT_EQ(scene->estimated_lights.shadow_map->vsm_blur_texels, 3);
    EXPECT_FALSE(parseScene("version: 1\n", "s.yaml")->estimated_lights.shadow_map);

    tracking::EstimatedLight sun;
    sun.to_light_world = {0, 0, 1};
    tracking::EstimatedLight lamp = sun;
    lamp.position_world = Eigen::Vector3d(0, 0, 2);
    lamp.angular_radius_rad = 0.05;
    FloatImage room;
    room.width = 8;
    room.height = 4;
    room.pixels.assign(8 * 4 * 3, 0.5f);
    const auto map = std::make_shared<const FloatImage>(std::move(room));
    const std::vector<Light> lights =
        lightsFromEstimates({sun, lamp}, map, scene->estimated_lights);
    ASSERT_EQ(lights.size(), 3u);
    EXPECT_EQ(lights[0].type, LightType::kDirectional);
    EXPECT_EQ(lights[1].type, LightType::kSphere);
    EXPECT_EQ(lights[2].type, LightType::kEnvironment);
    EXPECT_TRUE(lights[0].shadow_map && lights[1].shadow_map);
    EXPECT_FALSE(lights[2].shadow_map);
    EXPECT_FALSE(lightsFromEstimates({sun}, nullptr)[0].shadow_map);

    for (const auto& [text, message] : std::vector<std::pair<std::string, std::string>>{
             {"estimated_lights: { shadow_map: { kernel: 16 } }\n", "kernel"},
             {"estimated_lights: { shadows: {} }\n", "shadows"},
             {"estimated_lights: 3\n", "an estimated_lights mapping"}}) {
        auto refused = parseScene(text, "s.yaml");
        ASSERT_FALSE(refused.isOk()) << text;
        EXPECT_NE(refused.status().message().find(message), std::string::npos)
            << refused.status().toString();
        EXPECT_NE(refused.status().message().find("s.yaml:1"), std::string::npos)
            << refused.status().toString();
    }
}

// Caustics: both settings read, defaults kept, bad values named.
TEST(SceneFileTest, CausticSettings) {
    auto scene = parseScene("caustics: { photons: 50000 }\n", "scene.yaml");
    ASSERT_TRUE(scene.isOk()) << scene.status().toString();
    ASSERT_TRUE(scene->caustics);
    EXPECT_EQ(scene->caustics->photons, 50000);
    EXPECT_FLOAT_EQ(scene->caustics->radius_m, 0.005f);
    EXPECT_FALSE(parseScene("lights: []\n", "scene.yaml")->caustics);
    for (const auto& [text, message] : std::vector<std::pair<std::string, std::string>>{
             {"caustics: { photons: 10 }\n", "photons"},
             {"caustics: { radius_m: 0 }\n", "radius_m"},
             {"caustics: { radius: 0.01 }\n", "radius"},
             {"caustics: 3\n", "caustics"}}) {
        auto bad = parseScene(text, "s.yaml");
        ASSERT_FALSE(bad.isOk()) << text;
        EXPECT_NE(bad.status().message().find(message), std::string::npos)
            << bad.status().toString();
        EXPECT_NE(bad.status().message().find("s.yaml:1"), std::string::npos)
            << bad.status().toString();
    }
}

// The complete example in docs/scene-format.md parses, and the messages it shows are real.
TEST(SceneFileTest, DocumentationExamples) {
    std::ifstream in(test::sourceDir() / "docs" / "scene-format.md");
    const std::string doc((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const size_t start = doc.find("```yaml\n");
    ASSERT_NE(start, std::string::npos);
    const size_t end = doc.find("```\n", start + 8);
    auto scene = parseScene(doc.substr(start + 8, end - start - 8), "docs/scene.yaml");
    ASSERT_TRUE(scene.isOk()) << scene.status().toString();
    EXPECT_EQ(scene->materials.size(), 5u);
    EXPECT_EQ(scene->objects.size(), 5u);
    EXPECT_EQ(scene->lights.size(), 4u);
    ASSERT_TRUE(scene->camera && scene->camera->model);
    EXPECT_EQ(scene->camera->model->distortion.size(), 5u);
    ASSERT_TRUE(scene->camera->aperture);
    EXPECT_FLOAT_EQ(scene->camera->aperture->focus_distance_m, 0.8f);
    EXPECT_EQ(scene->materials.at("red_plastic").albedo_texture,
              fs::path("docs/textures/plastic.png"));
    EXPECT_FLOAT_EQ(scene->depth_surface.reflectance, 0.1f);
    ASSERT_TRUE(scene->lens_effects.bloom && scene->lens_effects.glare);
    EXPECT_FLOAT_EQ(scene->lens_effects.glare->attenuation, 0.9f);
    ASSERT_TRUE(scene->camera_matching.noise);
    EXPECT_FLOAT_EQ(*scene->camera_matching.noise, 1.0f);
    ASSERT_TRUE(scene->lights[2].shadow_map);
    EXPECT_EQ(scene->lights[2].shadow_map->filter, ShadowMapFilter::kVsm);
    EXPECT_EQ(scene->lights[2].shadow_map->resolution, 1024);
    EXPECT_FALSE(scene->lights[0].shadow_map);
    ASSERT_TRUE(scene->caustics);
    EXPECT_EQ(scene->caustics->photons, 150000);
    EXPECT_FLOAT_EQ(scene->caustics->radius_m, 0.005f);

    const std::string h = kHeader;
    const std::vector<std::string> inputs = {
        h + "  - name: a\n    shape: { sphere: { radius: 1 } }\n    material: m\n"
            "    materal: m\n",
        h + "  - name: a\n    shape:\n      sphere: { radius: -1 }\n    material: m\n",
        h + "  - name: a\n    shape: { sphere: { radius: 1 } }\n    material: mm\n",
        "materials:\n  g:\n    type: glass\n    ior: 0.9\n",
        "materials:\n  g:\n    type: metal\n    ior: 1.5\n",
    };
    for (const std::string& input : inputs) {
        auto bad = parseScene(input, "scene.yaml");
        ASSERT_FALSE(bad.isOk());
        EXPECT_NE(doc.find(bad.status().message() + "\n"), std::string::npos)
            << "not in the documentation: " << bad.status().message();
    }
}

// Mutated fixtures (fixed seed): every parse returns, either a scene that validates or
// kCorruptData naming the file. A quick, deterministic stand-in for fuzzing.
TEST(SceneFileTest, MutatedInputsNeverCrash) {
    std::ifstream in(test::fixturesDir() / "scenes" / "demo.yaml");
    const std::string original((std::istreambuf_iterator<char>(in)),
                               std::istreambuf_iterator<char>());
    ASSERT_FALSE(original.empty());
    constexpr std::string_view kBytes = " \n:-,[]{}#&*!|>'\"%@`0123456789.eE+-abcxyz\t\x01";
    std::mt19937 random(12345);
    int failures = 0;
    for (int i = 0; i < 1500; ++i) {
        std::string text = original;
        const int edits = 1 + static_cast<int>(random() % 4);
        for (int e = 0; e < edits && !text.empty(); ++e) {
            const size_t at = random() % text.size();
            switch (random() % 4) {
                case 0:
                    text[at] = kBytes[random() % kBytes.size()];
                    break;
                case 1:
                    text.erase(at, 1 + random() % 8);
                    break;
                case 2:
                    text.insert(at, 1, kBytes[random() % kBytes.size()]);
                    break;
                default:
                    text.resize(at);
                    break;
            }
        }
        auto scene = parseScene(text, "m.yaml");
        if (scene.isOk()) {
            EXPECT_TRUE(scene->validate().isOk());
        } else {
            ++failures;
            EXPECT_EQ(scene.status().code(), ErrorCode::kCorruptData) << scene.status().toString();
            EXPECT_EQ(scene.status().message().rfind("m.yaml", 0), 0u) << scene.status().message();
        }
    }
    EXPECT_GT(failures, 500);  // the mutations do break things
}

TEST(SceneFileTest, LoadErrors) {
    auto missing = loadScene(test::tempDir() / "no_such_scene.yaml");
    ASSERT_FALSE(missing.isOk());
    EXPECT_EQ(missing.status().code(), ErrorCode::kNotFound);
    EXPECT_NE(missing.status().message().find("no_such_scene.yaml"), std::string::npos);

    auto directory = loadScene(test::tempDir());
    ASSERT_FALSE(directory.isOk());
    EXPECT_EQ(directory.status().code(), ErrorCode::kInvalidArgument);

    // Content errors name the file as given.
    const fs::path bad = test::tempDir() / "bad.yaml";
    std::ofstream(bad) << "objects:\n  - name: x\n";
    auto corrupt = loadScene(bad);
    ASSERT_FALSE(corrupt.isOk());
    EXPECT_EQ(corrupt.status().code(), ErrorCode::kCorruptData);
    EXPECT_EQ(corrupt.status().message().rfind(bad.string() + ":2:", 0), 0u)
        << corrupt.status().message();
}

// mixray demo and run composite virtual objects into a session's modelled real scene: the real
// objects become ghosts whatever their role in the file, the real lights and camera are left to
// tracking, and a missing mesh is replaced by a sphere with a note instead of failing the run.
TEST(SceneFileTest, ComposeArSceneMakesTheRealSceneGhostsUnderTheVirtualObjects) {
    const fs::path dir = test::tempDir() / "compose_ar_scene";
    fs::create_directories(dir / "objects");
    const fs::path real = dir / "room.scene.yaml";
    std::ofstream(real) << R"(version: 1
materials:
  wood: { type: diffuse, albedo: [0.5, 0.4, 0.3] }
objects:
  - { name: table, role: ghost, shape: { plane: { size: [1, 1] } }, material: wood }
  - { name: lamp, role: virtual, shape: { sphere: { radius: 0.1 } }, material: wood }
lights:
  - { name: sun, type: directional, direction: [0, 0, -1], irradiance: [1, 1, 1] }
)";
    const fs::path objects = dir / "objects" / "virtual.yaml";
    std::ofstream(objects) << R"(version: 1
materials:
  clay: { type: diffuse, albedo: [0.7, 0.35, 0.2] }
objects:
  - { name: box, shape: { box: { size: [0.1, 0.1, 0.1] } }, material: clay }
  - name: pot
    shape: { mesh: { file: missing/pot.obj } }
    material: clay
    pose: { translation: [0.1, 0.2, 0] }
lens_effects: { glare: { passes: 2 } }
caustics: { photons: 20000 }
)";
    auto composed = composeArScene(real, objects);
    ASSERT_TRUE(composed.isOk()) << composed.status().toString();
    const SceneDescription& scene = composed->scene;
    ASSERT_EQ(scene.objects.size(), 4u);
    EXPECT_EQ(scene.objects[0].name, "table");
    EXPECT_EQ(scene.objects[0].role, ObjectRole::kGhost);
    EXPECT_EQ(scene.objects[1].name, "lamp");
    EXPECT_EQ(scene.objects[1].role, ObjectRole::kGhost);
    EXPECT_EQ(scene.objects[2].role, ObjectRole::kVirtual);
    EXPECT_TRUE(scene.lights.empty());
    EXPECT_FALSE(scene.camera.has_value());
    // The objects file says how its objects pass the lens.
    ASSERT_TRUE(scene.lens_effects.glare.has_value());
    EXPECT_EQ(scene.lens_effects.glare->passes, 2);
    EXPECT_FALSE(scene.lens_effects.bloom.has_value());
    ASSERT_TRUE(scene.caustics.has_value());
    EXPECT_EQ(scene.caustics->photons, 20000);
    EXPECT_EQ(scene.materials.size(), 2u);
    // The missing mesh: a sphere of its material on the same spot, raised by its radius.
    const SceneObject& pot = scene.objects[3];
    EXPECT_EQ(pot.shape.type, ShapeType::kSphere);
    EXPECT_FLOAT_EQ(pot.shape.radius, 0.04f);
    EXPECT_EQ(pot.material, "clay");
    EXPECT_NEAR(pot.T_anchor_object.translation().z(), 0.04, 1e-12);
    EXPECT_NEAR(pot.T_anchor_object.translation().y(), 0.2, 1e-12);
    ASSERT_EQ(composed->notes.size(), 1u);
    EXPECT_NE(composed->notes[0].find("pot.obj"), std::string::npos) << composed->notes[0];
    EXPECT_NE(composed->notes[0].find("pot"), std::string::npos);
    // The inserted part is the virtual objects alone, with their own materials.
    ASSERT_EQ(composed->inserted.objects.size(), 2u);
    EXPECT_EQ(composed->inserted.objects[0].name, "box");
    EXPECT_EQ(composed->inserted.materials.count("clay"), 1u);
    EXPECT_EQ(composed->inserted.materials.count("wood"), 0u);

    // A material defined in both files is refused, naming both files.
    const fs::path clash = dir / "clash.yaml";
    std::ofstream(clash) << R"(version: 1
materials:
  wood: { type: diffuse, albedo: [0.1, 0.1, 0.1] }
objects:
  - { name: block, shape: { box: { size: [0.1, 0.1, 0.1] } }, material: wood }
)";
    auto refused = composeArScene(real, clash);
    ASSERT_FALSE(refused.isOk());
    EXPECT_EQ(refused.status().code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(refused.status().message().find("clash.yaml"), std::string::npos);
    EXPECT_NE(refused.status().message().find("room.scene.yaml"), std::string::npos);
    // Either file missing: its load error.
    EXPECT_EQ(composeArScene(dir / "none.yaml", objects).status().code(), ErrorCode::kNotFound);
    EXPECT_EQ(composeArScene(real, dir / "none.yaml").status().code(), ErrorCode::kNotFound);
}

// The demo's own files compose (the session's real scene and the demo objects).
TEST(SceneFileTest, ComposeArSceneOnTheDemoFixtures) {
    auto composed = composeArScene(test::fixturesDir() / "sessions/sim_tabletop.scene.yaml",
                                   test::fixturesDir() / "scenes/sim_tabletop_demo.yaml");
    ASSERT_TRUE(composed.isOk()) << composed.status().toString();
    EXPECT_EQ(composed->inserted.objects.size(), 3u);
    EXPECT_EQ(composed->scene.objects.size(), 9u);
    for (const SceneObject& o : composed->scene.objects)
        EXPECT_EQ(o.role, o.name == "teapot" || o.name == "glass_ball" || o.name == "clay_box"
                              ? ObjectRole::kVirtual
                              : ObjectRole::kGhost)
            << o.name;
    EXPECT_TRUE(composed->scene.lights.empty());
}

// The lens-effects demo objects compose onto the session's real scene and bring their effects.
TEST(SceneFileTest, ComposeArSceneOnTheLensEffectsFixture) {
    auto composed = composeArScene(test::fixturesDir() / "sessions/sim_tabletop.scene.yaml",
                                   test::fixturesDir() / "scenes/sim_tabletop_glow.yaml");
    ASSERT_TRUE(composed.isOk()) << composed.status().toString();
    EXPECT_EQ(composed->inserted.objects.size(), 2u);
    const LensEffects& lens = composed->scene.lens_effects;
    ASSERT_TRUE(lens.bloom && lens.glare);
    EXPECT_LT(lens.bloom->threshold, lens.glare->threshold);
    EXPECT_EQ(lens.glare->passes, 3);
}

// The depth-of-field, all-effects and caustics demo objects compose too, bringing the lens's
// aperture (the pose still from tracking), the camera matching and the caustics.
TEST(SceneFileTest, ComposeArSceneOnTheEffectsFixtures) {
    for (const char* objects :
         {"scenes/sim_tabletop_dof.yaml", "scenes/sim_tabletop_effects.yaml"}) {
        auto composed = composeArScene(test::fixturesDir() / "sessions/sim_tabletop.scene.yaml",
                                       test::fixturesDir() / objects);
        ASSERT_TRUE(composed.isOk()) << composed.status().toString();
        ASSERT_TRUE(composed->scene.camera && composed->scene.camera->aperture) << objects;
        EXPECT_FALSE(composed->scene.camera->has_pose) << objects;
        EXPECT_FLOAT_EQ(composed->scene.camera->aperture->f_number, 1.4f) << objects;
    }
    auto effects = composeArScene(test::fixturesDir() / "sessions/sim_tabletop.scene.yaml",
                                  test::fixturesDir() / "scenes/sim_tabletop_effects.yaml");
    ASSERT_TRUE(effects.isOk());
    EXPECT_TRUE(effects->scene.lens_effects.bloom && effects->scene.lens_effects.glare);
    EXPECT_TRUE(effects->scene.camera_matching.noise);
    ASSERT_TRUE(effects->scene.caustics);
    EXPECT_EQ(effects->scene.caustics->photons, 100000);
    ASSERT_TRUE(effects->scene.estimated_lights.shadow_map);
    EXPECT_EQ(effects->scene.estimated_lights.shadow_map->filter, ShadowMapFilter::kPcf);
    auto caustics = composeArScene(test::fixturesDir() / "sessions/sim_tabletop.scene.yaml",
                                   test::fixturesDir() / "scenes/sim_tabletop_caustics.yaml");
    ASSERT_TRUE(caustics.isOk()) << caustics.status().toString();
    ASSERT_TRUE(caustics->scene.caustics);
    EXPECT_EQ(caustics->scene.caustics->photons, 150000);
    EXPECT_EQ(caustics->inserted.objects.size(), 2u);
}

TEST(SceneFileTest, ValidateScenesBuiltInCode) {
    SceneDescription scene;
    scene.materials["m"].name = "m";
    SceneObject object;
    object.name = "a";
    object.material = "m";
    object.where = {"code", 3, 0};
    scene.objects.push_back(object);
    EXPECT_TRUE(scene.validate().isOk()) << scene.validate().toString();

    auto expectInvalid = [](const SceneDescription& s, const std::string& path) {
        const Status status = s.validate();
        EXPECT_EQ(status.code(), ErrorCode::kCorruptData);
        EXPECT_NE(status.message().find(path), std::string::npos) << status.message();
    };
    SceneDescription s = scene;
    s.objects[0].material = "nope";
    expectInvalid(s, "code:3: objects[0].material: unknown material");
    s = scene;
    s.objects.push_back(object);
    expectInvalid(s, "objects[1].name: duplicate");
    s = scene;
    s.objects[0].anchor = "marker:";
    expectInvalid(s, "objects[0].anchor");
    s = scene;
    s.objects[0].shape.radius = std::nanf("");
    expectInvalid(s, "objects[0].shape.radius");
    s = scene;
    s.objects[0].shape.type = ShapeType::kBox;
    s.objects[0].shape.size.z() = -1;
    expectInvalid(s, "objects[0].shape.size");
    s = scene;
    s.objects[0].T_anchor_object.linear() *= 2;
    expectInvalid(s, "objects[0].pose");
    s = scene;
    s.materials["m"].ior.y() = 0.9f;
    expectInvalid(s, "materials.m.ior");
    s = scene;
    s.materials["m"].name = "other";
    expectInvalid(s, "materials.m");
    s = scene;
    s.lights.push_back(Light{});
    s.lights[0].intensity.x() = std::numeric_limits<float>::infinity();
    expectInvalid(s, "lights[0].intensity");
    s = scene;
    s.camera.emplace();
    calibration::CameraModel model;
    model.width = 640;
    model.height = 480;
    model.fx = model.fy = 500;
    model.distortion = {1, 2};
    s.camera->model = model;
    expectInvalid(s, "camera.model.distortion");
    s = scene;
    s.depth_surface.reflectance = std::nanf("");
    expectInvalid(s, "depth_surface.reflectance");
}

}  // namespace
}  // namespace mixray::render
