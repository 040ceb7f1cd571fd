// The depth half of the Kinect calibration on a generated Kinect: IR corners give the board
// poses (PnP, as the IR solve would), depth images made with scale 1.02, offset −8 mm and a
// radial Herrera term give the correction back, and the recovered registration maps a scene's
// depth into the colour camera within a pixel of the true registration.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <numbers>
#include <random>

#include "depth_test_scene.h"
#include "environment_alignment_internal.h"
#include "mixray/calibration/depth_registration.h"

namespace mixray::calibration {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

struct Kinect {
    DepthRegistration truth;  // IR as the depth camera, colour, T_color_ir, correction
};

Kinect trueKinect() {
    Kinect k;
    DepthRegistration& r = k.truth;
    r.depth = CameraModel::pinhole(640, 480, 580, 580, 314.5, 245.5);
    r.depth.distortion = {-0.06, 0.12, 3e-4, 2e-4, 0};
    r.color = CameraModel::pinhole(640, 480, 524.8, 525.4, 318.6, 241.9);
    r.color.distortion = {0.045, -0.11, 6e-4, -4e-4, 0.04};
    r.T_color_depth.linear() = (Eigen::AngleAxisd(0.3 * kDeg, Eigen::Vector3d::UnitX()) *
                                Eigen::AngleAxisd(-0.15 * kDeg, Eigen::Vector3d::UnitY()))
                                   .toRotationMatrix();
    r.T_color_depth.translation() = Eigen::Vector3d(-0.0251, 3e-4, 8e-4);
    DepthCorrection& c = r.correction;
    c.scale = 1.02;
    c.offset_m = -0.008;
    c.alpha1 = 0.6;
    c.alpha0 = 0.9;
    c.distortion.resize(static_cast<size_t>(r.depth.width) * r.depth.height);
    for (int y = 0; y < r.depth.height; ++y)
        for (int x = 0; x < r.depth.width; ++x) {
            const double rx = (x - r.depth.cx) / r.depth.width;
            const double ry = (y - r.depth.cy) / r.depth.width;
            c.distortion[static_cast<size_t>(y) * r.depth.width + x] =
                static_cast<float>(0.012 * (rx * rx + ry * ry - 0.12));
        }
    return k;
}

using test::boardPoints;

struct Session {
    CameraViews ir;
    std::vector<Image> images;
    std::vector<KeyedDepth> depth;
    RigCalibration rig;  // as calibrateRig would give it: true models, PnP board poses
};

// `count` board poses over 0.7–2.6 m, seen by the IR camera (corners with 0.1 px noise) and
// measured by the depth camera (raw readings through the true correction's inverse, 1 mm
// noise, 1 mm steps).
Session session(const Kinect& k, int count, uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(-1, 1);
    std::normal_distribution<double> noise(0, 1);
    const CameraModel& ir = k.truth.depth;
    const auto points = boardPoints();
    Session s;
    s.ir.camera = "kinect/ir";
    s.ir.width = ir.width;
    s.ir.height = ir.height;
    s.ir.target = test::depthBoard();
    CameraCalibration color_cal, ir_cal;
    color_cal.camera = "kinect/color";
    color_cal.model = k.truth.color;
    ir_cal.camera = "kinect/ir";
    ir_cal.model = ir;
    for (int i = 0; i < count; ++i) {
        const double z = 0.7 + 1.9 * (i % 7) / 6.0 + 0.05 * u(rng);
        const Eigen::Vector3d centre(0.45 * z * u(rng), 0.33 * z * u(rng), z);
        Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
        T.linear() = (Eigen::AngleAxisd(35 * kDeg * u(rng), Eigen::Vector3d::UnitX()) *
                      Eigen::AngleAxisd(35 * kDeg * u(rng), Eigen::Vector3d::UnitY()))
                         .toRotationMatrix();
        T.translation() = centre - T.linear() * Eigen::Vector3d(0.24, 0.15, 0);
        TargetView view;
        view.key = 1000 + i;
        std::vector<Eigen::Vector3d> seen;
        std::vector<Eigen::Vector2d> pixels;
        for (size_t p = 0; p < points.size(); ++p) {
            const auto px = ir.project(T * points[p]);
            if (!px || px->x() < 0 || px->y() < 0 || px->x() > ir.width - 1 ||
                px->y() > ir.height - 1)
                continue;
            const Eigen::Vector2d observed = *px + 0.1 * Eigen::Vector2d(noise(rng), noise(rng));
            view.corners.push_back({static_cast<int>(p), observed, 1.0});
            seen.push_back(points[p]);
            pixels.push_back(observed);
        }
        const auto pose = detail::poseFromCorners(ir, seen, pixels, false);
        if (seen.size() < 20 || !pose)
            continue;
        ViewFit fit;
        fit.view = s.ir.views.size();
        fit.corners = static_cast<int>(seen.size());
        fit.T_camera_target = *pose;
        ir_cal.views.push_back(fit);
        s.ir.views.push_back(view);

        test::Scene scene;
        scene.planes.push_back({T.linear().col(2), T.linear().col(2).dot(T.translation())});
        Image image = test::depthImage(test::render(scene, ir, Eigen::Isometry3d::Identity()),
                                       &k.truth.correction);
        const MutableImageView v = image.mutableView();
        for (int y = 0; y < ir.height; ++y)
            for (int x = 0; x < ir.width; ++x) {
                uint16_t& d = v.row<uint16_t>(y)[x];
                if (d)
                    d = static_cast<uint16_t>(std::max(1L, std::lround(d + noise(rng))));
            }
        s.images.push_back(std::move(image));
    }
    for (size_t i = 0; i < s.images.size(); ++i)
        s.depth.push_back({s.ir.views[i].key, s.images[i].view()});
    s.rig.reference = "kinect/color";
    s.rig.cameras = {color_cal, ir_cal};
    s.rig.T_ref_camera = {Eigen::Isometry3d::Identity(), k.truth.T_color_depth};
    return s;
}

TEST(KinectCalibration, RecoversTheCorrectionAndRegistersWithinAPixel) {
    const Kinect k = trueKinect();
    Session s = session(k, 28, 5);
    ASSERT_GE(s.ir.views.size(), 24u);
    // A depth image nobody asked for is ignored.
    Image stray(ImageDesc::packed(PixelFormat::kDepth16, 640, 480));
    s.depth.push_back({5, stray.view()});
    DepthCorrectionOptions options;
    options.per_pixel = true;
    auto kinect =
        kinectCalibrationFromRig(s.rig, "kinect/color", s.ir, s.depth, boardPoints(), options);
    ASSERT_TRUE(kinect) << kinect.status().toString();
    const DepthCorrection& c = kinect->registration.correction;
    std::printf("Kinect: scale %.5f offset %.2f mm alpha1 %.3f, rms %.2f -> %.2f mm over %d\n",
                c.scale, c.offset_m * 1e3, c.alpha1, kinect->depth_fit.rms_before_m * 1e3,
                kinect->depth_fit.rms_after_m * 1e3, kinect->depth_fit.samples);
    EXPECT_NEAR(c.scale, 1.02, 0.003);
    EXPECT_NEAR(c.offset_m, -0.008, 0.002);
    // With board poses from noisy corners (PnP), α1 is poorly determined (it trades against D
    // and the poses' plane errors); the correction as a whole is what must agree: over the
    // pixels the boards covered, at 0.8–2.5 m.
    double sum = 0, worst = 0;
    int n = 0;
    const CameraModel& ir = k.truth.depth;
    for (int y = 8; y < ir.height - 8; y += 8)
        for (int x = 8; x < ir.width - 8; x += 8) {
            bool covered = false;
            for (const auto& fit : s.rig.cameras[1].views) {
                const Eigen::Isometry3d& T = fit.T_camera_target;
                const Eigen::Vector3d dir = *ir.unproject({double(x), double(y)});
                const Eigen::Vector3d normal = T.linear().col(2);
                const double t = normal.dot(T.translation()) / normal.dot(dir);
                const Eigen::Vector3d q = T.inverse() * (dir * t);
                covered = covered || (q.x() > 0.02 && q.y() > 0.02 && q.x() < 0.46 && q.y() < 0.28);
            }
            if (!covered)
                continue;
            for (double z = 0.8; z <= 2.5; z += 0.1) {
                const double d = correctedDepth(c, z, x, y, ir.width) -
                                 correctedDepth(k.truth.correction, z, x, y, ir.width);
                sum += d * d;
                worst = std::max(worst, std::abs(d));
                ++n;
            }
        }
    const double rms = std::sqrt(sum / n);
    std::printf("correction vs truth: rms %.2f mm, max %.2f mm over %d samples\n", rms * 1e3,
                worst * 1e3, n);
    EXPECT_LT(rms, 0.001);
    EXPECT_LT(worst, 0.004);
    EXPECT_LT(kinect->depth_fit.rms_after_m, 0.0015);
    EXPECT_EQ(kinect->registration.T_color_depth.matrix(), k.truth.T_color_depth.matrix());

    // A box before a wall registered by the recovered calibration and by the true one.
    test::Scene scene;
    scene.planes.push_back({Eigen::Vector3d(0.1, 0, 1).normalized(), 2.0});
    test::Scene::Box box;
    box.T_ref_box.linear() =
        Eigen::AngleAxisd(25 * kDeg, Eigen::Vector3d::UnitY()).toRotationMatrix();
    box.T_ref_box.translation() = Eigen::Vector3d(0.05, -0.02, 1.1);
    box.half = Eigen::Vector3d(0.16, 0.12, 0.1);
    scene.boxes.push_back(box);
    const Image raw = test::depthImage(test::render(scene, k.truth.depth, k.truth.T_color_depth),
                                       &k.truth.correction);
    auto mine = registerDepth(kinect->registration, raw.view());
    auto exact = registerDepth(k.truth, raw.view());
    ASSERT_TRUE(mine && exact);
    const int W = k.truth.color.width, H = k.truth.color.height;
    const auto at = [](const Image& image, int x, int y) {
        return static_cast<int>(image.view().row<uint16_t>(y)[x]);
    };
    // A pixel within 1 px of a change of surface (a jump of > 2 cm, or reading / none) in the
    // exact registration.
    const auto nearEdge = [&](int x, int y) {
        const int z = at(*exact, x, y);
        for (int dy = -1; dy <= 1; ++dy)
            for (int dx = -1; dx <= 1; ++dx) {
                const int u = std::clamp(x + dx, 0, W - 1), v = std::clamp(y + dy, 0, H - 1);
                const int q = at(*exact, u, v);
                if ((q == 0) != (z == 0) || std::abs(q - z) > 20)
                    return true;
            }
        return false;
    };
    int both = 0, within_1mm = 0, off_surface_inside = 0, max_mm = 0;
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) {
            const int a = at(*mine, x, y), b = at(*exact, x, y);
            const bool edge = nearEdge(x, y);
            if ((a == 0) != (b == 0) || std::abs(a - b) > 20) {
                off_surface_inside += !edge;
                continue;
            }
            if (a == 0 || edge)
                continue;
            ++both;
            within_1mm += std::abs(a - b) <= 1;
            max_mm = std::max(max_mm, std::abs(a - b));
        }
    std::printf(
        "registered: %d px compared, %.4f within 1 mm, max %d mm, %d off-surface "
        "away from edges\n",
        both, static_cast<double>(within_1mm) / both, max_mm, off_surface_inside);
    EXPECT_GT(both, W * H / 2);
    // Silhouettes and shadow edges within 1 px of the exact registration's.
    EXPECT_EQ(off_surface_inside, 0);
    EXPECT_GT(static_cast<double>(within_1mm) / both, 0.99);
    EXPECT_LE(max_mm, 3);
}

TEST(KinectCalibration, ClearErrors) {
    const Kinect k = trueKinect();
    Session s = session(k, 3, 6);
    auto r = kinectCalibrationFromRig(s.rig, "kinect/rgb", s.ir, s.depth, boardPoints());
    ASSERT_FALSE(r);
    EXPECT_NE(r.status().message().find("kinect/rgb"), std::string::npos);
    RigCalibration ir_reference = s.rig;
    ir_reference.reference = "kinect/ir";
    EXPECT_EQ(kinectCalibrationFromRig(ir_reference, "kinect/color", s.ir, s.depth, boardPoints())
                  .status()
                  .code(),
              ErrorCode::kInvalidArgument);
    std::vector<KeyedDepth> unmatched = s.depth;
    for (auto& d : unmatched)
        d.key += 7;
    r = kinectCalibrationFromRig(s.rig, "kinect/color", s.ir, unmatched, boardPoints());
    ASSERT_FALSE(r);
    EXPECT_NE(r.status().message().find("no depth image"), std::string::npos)
        << r.status().message();
}

}  // namespace
}  // namespace mixray::calibration
