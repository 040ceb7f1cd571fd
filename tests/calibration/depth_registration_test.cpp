// Registrar: depth images of generated scenes registered into the colour camera against the
// depth rendered directly in it — planes within 1 mm, silhouettes within 1 px, no holes where
// the depth camera saw the surface, and surfaces the colour camera cannot see never win.
#include "mixray/calibration/depth_registration.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <string>

#include "depth_test_scene.h"

namespace mixray::calibration {
namespace {

using test::Rendered;
using test::Scene;

constexpr double kDeg = std::numbers::pi / 180.0;

struct Rig {
    std::string name;
    DepthRegistration registration;
};

// A Kinect v1 (the simulator's IR and colour cameras, 25 mm apart) and an Azure Kinect
// (NFOV depth 640x576, colour 1280x720: about 1.2 colour pixels per depth pixel, so
// footprints must meet without cracks).
std::vector<Rig> rigs() {
    Rig v1{"kinect_v1", {}};
    v1.registration.depth = CameraModel::pinhole(640, 480, 580, 580, 314.5, 245.5);
    v1.registration.depth.distortion = {-0.06, 0.12, 3e-4, 2e-4, 0};
    v1.registration.color = CameraModel::pinhole(640, 480, 524.8, 525.4, 318.6, 241.9);
    v1.registration.color.distortion = {0.045, -0.11, 6e-4, -4e-4, 0.04};
    v1.registration.T_color_depth.linear() =
        (Eigen::AngleAxisd(0.3 * kDeg, Eigen::Vector3d::UnitX()) *
         Eigen::AngleAxisd(-0.15 * kDeg, Eigen::Vector3d::UnitY()))
            .toRotationMatrix();
    v1.registration.T_color_depth.translation() = Eigen::Vector3d(-0.0251, 3e-4, 8e-4);

    Rig azure{"azure_kinect", {}};
    azure.registration.depth = CameraModel::pinhole(640, 576, 504.0, 504.1, 321.6, 330.9);
    azure.registration.depth.distortion = {0.3, -0.05, 1e-4, -5e-5, 0.0, 0.65, -0.02, -0.01};
    azure.registration.color = CameraModel::pinhole(1280, 720, 612.0, 612.3, 637.3, 366.2);
    azure.registration.color.distortion = {0.33, -2.49, -1.6e-4, -1.3e-4, 1.45, 0.21, -2.30, 1.38};
    azure.registration.T_color_depth.linear() =
        Eigen::AngleAxisd(-6 * kDeg, Eigen::Vector3d::UnitX()).toRotationMatrix();
    azure.registration.T_color_depth.translation() = Eigen::Vector3d(-0.032, -0.0022, 0.0039);
    return {v1, azure};
}

Scene slantedPlane() {
    Scene scene;
    scene.planes.push_back({Eigen::Vector3d(0.35, -0.2, 1).normalized(), 1.4});
    return scene;
}

Scene boxBeforeWall() {
    Scene scene;
    scene.planes.push_back({Eigen::Vector3d(0.1, 0, 1).normalized(), 2.0});
    Scene::Box box;
    box.T_ref_box.linear() =
        Eigen::AngleAxisd(25 * kDeg, Eigen::Vector3d::UnitY()).toRotationMatrix();
    box.T_ref_box.translation() = Eigen::Vector3d(0.05, -0.02, 1.1);
    box.half = Eigen::Vector3d(0.16, 0.12, 0.1);
    scene.boxes.push_back(box);
    return scene;
}

// Whether the depth camera sees the surface point behind colour pixel (x, y) (no other
// surface in front, inside its image by a pixel).
bool seenByDepth(const Scene& scene, const DepthRegistration& r, const Rendered& color, int x,
                 int y) {
    const double z = color.at(x, y);
    if (z <= 0)
        return false;
    const auto dir = r.color.unproject({double(x), double(y)});
    const Eigen::Vector3d p_color = *dir * (z / dir->z());
    const Eigen::Vector3d p_depth = r.T_color_depth.inverse() * p_color;
    const auto px = r.depth.project(p_depth);
    if (!px || px->x() < 1 || px->y() < 1 || px->x() > r.depth.width - 2 ||
        px->y() > r.depth.height - 2)
        return false;
    const auto hit = scene.hit(r.T_color_depth.translation(),
                               (p_color - r.T_color_depth.translation()).normalized());
    return hit && std::abs(hit->first - p_depth.norm()) < 1e-4;
}

// A colour pixel within 1 px of a change of visible surface (or face) in the truth, or of
// the outline of what the depth camera sees (`seen`): where a silhouette or a shadow edge
// passes.
bool nearEdge(const Rendered& color, const std::vector<uint8_t>& seen, int x, int y,
              int radius = 1) {
    const size_t i = static_cast<size_t>(y) * color.width + x;
    for (int dy = -radius; dy <= radius; ++dy)
        for (int dx = -radius; dx <= radius; ++dx) {
            const int u = x + dx, v = y + dy;
            if (u < 0 || v < 0 || u >= color.width || v >= color.height)
                continue;
            const size_t j = static_cast<size_t>(v) * color.width + u;
            if (color.id[j] != color.id[i] || seen[j] != seen[i])
                return true;
        }
    return false;
}

struct Errors {
    int compared = 0;         // pixels seen by both cameras, away from silhouettes
    double max_plane_m = 0;   // |registered − true| over them
    int holes = 0;            // of them, registered 0
    int wrong_surface = 0;    // registered off the visible surface by > 5 mm, away from edges
    int background_wins = 0;  // registered behind the visible surface by > 5 mm, anywhere
    int background_wins_near_edge = 0;
    int max_mm_diff = 0;        // depth16 output vs the true depth in mm
    int occluded_in_color = 0;  // depth pixels whose surface the colour camera cannot see
    int disoccluded = 0;        // colour pixels the depth camera cannot see
};

Errors compare(const Scene& scene, const DepthRegistration& r, const DepthCorrection* raw_of) {
    const Rendered depth_truth = test::render(scene, r.depth, r.T_color_depth);
    const Rendered color_truth = test::render(scene, r.color, Eigen::Isometry3d::Identity());
    const Image depth = test::depthImage(depth_truth, raw_of);
    auto registrar = Registrar::create(r);
    EXPECT_TRUE(registrar) << registrar.status().toString();
    Image out(ImageDesc::packed(PixelFormat::kDepth16, r.color.width, r.color.height));
    EXPECT_TRUE(registrar->registerDepth(depth.view(), out.mutableView()));
    const std::vector<float>& z = registrar->colorDepth();

    std::vector<uint8_t> seen_by_depth(color_truth.z.size());
    for (int y = 0; y < r.color.height; ++y)
        for (int x = 0; x < r.color.width; ++x)
            seen_by_depth[static_cast<size_t>(y) * r.color.width + x] =
                seenByDepth(scene, r, color_truth, x, y);

    // Colour pixels per depth pixel, rounded up.
    const int footprint_px = static_cast<int>(std::ceil(r.color.fx / r.depth.fx));
    Errors e;
    for (int y = 0; y < r.color.height; ++y) {
        for (int x = 0; x < r.color.width; ++x) {
            const double truth = color_truth.at(x, y);
            const double reg = z[static_cast<size_t>(y) * r.color.width + x];
            const bool seen = seen_by_depth[static_cast<size_t>(y) * r.color.width + x];
            const bool edge = nearEdge(color_truth, seen_by_depth, x, y);
            if (truth > 0 && !seen)
                ++e.disoccluded;
            if (reg > 0 && truth > 0 && reg > truth + 5e-3) {
                ++e.background_wins;
                if (edge)
                    ++e.background_wins_near_edge;
            }
            if (!seen || edge)
                continue;
            ++e.compared;
            if (reg <= 0) {
                ++e.holes;
                continue;
            }
            if (std::abs(reg - truth) > 5e-3) {
                ++e.wrong_surface;
                continue;
            }
            // Within one depth pixel's footprint of a crease the footprints blend the two
            // faces (their shared corners are averaged): planes are compared beyond it.
            if (nearEdge(color_truth, seen_by_depth, x, y, footprint_px))
                continue;
            e.max_plane_m = std::max(e.max_plane_m, std::abs(reg - truth));
            const int mm = out.view().row<uint16_t>(y)[x];
            e.max_mm_diff =
                std::max(e.max_mm_diff, static_cast<int>(std::abs(mm - std::lround(truth * 1e3))));
        }
    }
    // Depth pixels whose surface point is hidden from the colour camera.
    for (int y = 0; y < r.depth.height; y += 2) {
        for (int x = 0; x < r.depth.width; x += 2) {
            const double zd = depth_truth.at(x, y);
            if (zd <= 0)
                continue;
            const auto dir = r.depth.unproject({double(x), double(y)});
            const Eigen::Vector3d p_color = r.T_color_depth * (*dir * (zd / dir->z()));
            const auto hit = scene.hit(Eigen::Vector3d::Zero(), p_color.normalized());
            if (hit && hit->first < p_color.norm() - 1e-3)
                ++e.occluded_in_color;
        }
    }
    return e;
}

class DepthRegistrationTest : public ::testing::TestWithParam<Rig> {};

TEST_P(DepthRegistrationTest, PlaneWithinOneMillimetreAndNoHoles) {
    const DepthRegistration& r = GetParam().registration;
    const Errors e = compare(slantedPlane(), r, nullptr);
    EXPECT_GT(e.compared, r.color.width * r.color.height / 2);
    EXPECT_EQ(e.holes, 0);
    EXPECT_EQ(e.wrong_surface, 0);
    EXPECT_LT(e.max_plane_m, 1e-3);
    EXPECT_LE(e.max_mm_diff, 1);
}

TEST_P(DepthRegistrationTest, BoxBeforeWallEdgesWithinOnePixelBackgroundNeverWins) {
    const DepthRegistration& r = GetParam().registration;
    const Errors e = compare(boxBeforeWall(), r, nullptr);
    // The scene exercises occlusion both ways: wall the colour camera cannot see behind the
    // box (the z-buffer must reject it) and wall only the colour camera sees (left empty).
    EXPECT_GT(e.occluded_in_color, 50);
    EXPECT_GT(e.disoccluded, 50);
    EXPECT_GT(e.compared, r.color.width * r.color.height / 2);
    EXPECT_EQ(e.holes, 0);
    // Every pixel off the true surface is within 1 px of a true silhouette.
    EXPECT_EQ(e.wrong_surface, 0);
    EXPECT_EQ(e.background_wins, e.background_wins_near_edge);
    EXPECT_LT(e.max_plane_m, 1e-3);
    EXPECT_LE(e.max_mm_diff, 1);
}

TEST_P(DepthRegistrationTest, AppliesTheDepthCorrection) {
    DepthRegistration r = GetParam().registration;
    r.correction.scale = 1.02;
    r.correction.offset_m = -0.008;
    r.correction.alpha0 = 0.5;
    r.correction.alpha1 = 0.4;
    r.correction.distortion.resize(static_cast<size_t>(r.depth.width) * r.depth.height);
    for (int y = 0; y < r.depth.height; ++y)
        for (int x = 0; x < r.depth.width; ++x) {
            const double rx = (x - r.depth.cx) / r.depth.width;
            const double ry = (y - r.depth.cy) / r.depth.width;
            r.correction.distortion[static_cast<size_t>(y) * r.depth.width + x] =
                static_cast<float>(0.01 * (rx * rx + ry * ry));
        }
    const Errors e = compare(boxBeforeWall(), r, &r.correction);
    EXPECT_EQ(e.holes, 0);
    EXPECT_EQ(e.wrong_surface, 0);
    EXPECT_LT(e.max_plane_m, 1e-3);

    // Without the correction the same readings land centimetres off.
    DepthRegistration uncorrected = r;
    uncorrected.correction = {};
    const Rendered depth_truth = test::render(boxBeforeWall(), r.depth, r.T_color_depth);
    const Image raw = test::depthImage(depth_truth, &r.correction);
    auto corrected = registerDepth(r, raw.view());
    auto plain = registerDepth(uncorrected, raw.view());
    ASSERT_TRUE(corrected && plain);
    const int cx = r.color.width / 2, cy = r.color.height / 2;
    EXPECT_GT(
        std::abs(corrected->view().row<uint16_t>(cy)[cx] - plain->view().row<uint16_t>(cy)[cx]),
        10);
}

INSTANTIATE_TEST_SUITE_P(Rigs, DepthRegistrationTest, ::testing::ValuesIn(rigs()),
                         [](const auto& param_info) { return param_info.param.name; });

TEST(DepthRegistration, IdentityRegistrationReproducesTheImage) {
    DepthRegistration r;
    r.depth = r.color = CameraModel::pinhole(160, 120, 150, 150, 79.5, 59.5);
    EXPECT_TRUE(r.isIdentity());
    const Rendered truth = test::render(boxBeforeWall(), r.depth, Eigen::Isometry3d::Identity());
    const Image depth = test::depthImage(truth);
    auto out = registerDepth(r, depth.view());
    ASSERT_TRUE(out) << out.status().toString();
    int differ = 0;
    for (int y = 0; y < 120; ++y)
        for (int x = 0; x < 160; ++x)
            differ +=
                std::abs(out->view().row<uint16_t>(y)[x] - depth.view().row<uint16_t>(y)[x]) > 1;
    EXPECT_EQ(differ, 0);
}

TEST(DepthRegistration, RejectsBadInput) {
    DepthRegistration r = rigs()[0].registration;
    auto registrar = Registrar::create(r);
    ASSERT_TRUE(registrar);
    Image small(ImageDesc::packed(PixelFormat::kDepth16, 320, 240));
    Image out(ImageDesc::packed(PixelFormat::kDepth16, 640, 480));
    Status s = registrar->registerDepth(small.view(), out.mutableView());
    EXPECT_EQ(s.code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(s.message().find("640x480"), std::string::npos) << s.message();
    Image depth(ImageDesc::packed(PixelFormat::kDepth16, 640, 480));
    Image rgb(ImageDesc::packed(PixelFormat::kRGB8, 640, 480));
    EXPECT_EQ(registrar->registerDepth(depth.view(), rgb.mutableView()).code(),
              ErrorCode::kInvalidArgument);

    DepthRegistration bad = r;
    bad.correction.distortion.assign(10, 0.f);
    auto created = Registrar::create(bad);
    ASSERT_FALSE(created);
    EXPECT_NE(created.status().message().find("distortion map"), std::string::npos);
    bad = r;
    bad.T_color_depth.linear() *= 2;
    EXPECT_FALSE(Registrar::create(bad));
    bad = r;
    bad.correction.scale = 0;
    EXPECT_FALSE(Registrar::create(bad));
}

}  // namespace
}  // namespace mixray::calibration
