// Small scenes, cameras and images for the Renderer tests.
#pragma once

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <filesystem>
#include <functional>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <string>

#include "mixray/render/renderer.h"
#include "optics.h"

namespace mixray::render::test {

// Camera at `position` looking straight down (world −z), image +x = world +x.
inline Eigen::Isometry3d lookDown(const Eigen::Vector3d& position) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() << 1, 0, 0, 0, -1, 0, 0, 0, -1;
    T.translation() = position;
    return T;
}

// Camera at `position` looking along world +y with world +z up in the image.
inline Eigen::Isometry3d lookAlongY(const Eigen::Vector3d& position) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() << 1, 0, 0, 0, 0, 1, 0, -1, 0;
    T.translation() = position;
    return T;
}

// A camera at `eye` looking at `target`, the world's z up in the image.
inline Eigen::Isometry3d lookAt(const Eigen::Vector3d& eye, const Eigen::Vector3d& target) {
    const Eigen::Vector3d forward = (target - eye).normalized();
    const Eigen::Vector3d right = forward.cross(Eigen::Vector3d::UnitZ()).normalized();
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear().col(0) = right;
    T.linear().col(1) = forward.cross(right);
    T.linear().col(2) = forward;
    T.translation() = eye;
    return T;
}

inline Image filledImage(int w, int h, const std::function<std::array<uint8_t, 3>(int, int)>& f) {
    Image image(ImageDesc::packed(PixelFormat::kRGB8, w, h));
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const auto c = f(x, y);
            uint8_t* p = image.bytes().data() + (static_cast<size_t>(y) * w + x) * 3;
            p[0] = c[0], p[1] = c[1], p[2] = c[2];
        }
    return image;
}

inline Eigen::Vector3f pixelLinear(const Image& image, int x, int y) {
    const uint8_t* p = image.bytes().data() + (static_cast<size_t>(y) * image.desc().width + x) * 3;
    return {optics::srgbToLinear(p[0] / 255.f), optics::srgbToLinear(p[1] / 255.f),
            optics::srgbToLinear(p[2] / 255.f)};
}

inline const uint8_t* pixelBytes(const Image& image, int x, int y) {
    return image.bytes().data() + (static_cast<size_t>(y) * image.desc().width + x) * 3;
}

inline Material material(MaterialType type, const std::string& name) {
    Material m;
    m.name = name;
    m.type = type;
    return m;
}

inline SceneObject object(const std::string& name, ObjectRole role, ShapeType shape,
                          const std::string& material_name, const Eigen::Vector3d& position) {
    SceneObject o;
    o.name = name;
    o.role = role;
    o.shape.type = shape;
    o.material = material_name;
    o.T_anchor_object = Eigen::Translation3d(position) * Eigen::Isometry3d::Identity();
    return o;
}

// A large ghost floor (plane z = 0) with a diffuse material named "floor".
inline void addGhostFloor(SceneDescription& scene, float albedo = 0.5f) {
    Material floor = material(MaterialType::kDiffuse, "floor");
    floor.albedo = Rgb::Constant(albedo);
    scene.materials["floor"] = floor;
    SceneObject plane = object("floor", ObjectRole::kGhost, ShapeType::kPlane, "floor", {0, 0, 0});
    plane.shape.size = {20, 20, 0};
    scene.objects.push_back(plane);
}

// Writes a w x h equirectangular Radiance .hdr with radiance(x, y) per texel; returns its path.
inline std::filesystem::path writeEnvironment(
    const std::string& name, int w, int h,
    const std::function<Eigen::Vector3f(int, int)>& radiance) {
    cv::Mat bgr(h, w, CV_32FC3);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const Eigen::Vector3f c = radiance(x, y);
            bgr.at<cv::Vec3f>(y, x) = cv::Vec3f(c.z(), c.y(), c.x());
        }
    const std::filesystem::path path =
        std::filesystem::path(::testing::TempDir()) / ("mixray_render_" + name + ".hdr");
    EXPECT_TRUE(cv::imwrite(path.string(), bgr));
    return path;
}

inline Light directionalLight(const std::string& name, const Eigen::Vector3d& direction,
                              float irradiance) {
    Light light;
    light.name = name;
    light.type = LightType::kDirectional;
    light.direction = direction.normalized();
    light.intensity = Rgb::Constant(irradiance);
    return light;
}

inline Light environmentLight(const std::filesystem::path& path) {
    Light light;
    light.name = "environment";
    light.type = LightType::kEnvironment;
    light.environment = path;
    return light;
}

}  // namespace mixray::render::test
