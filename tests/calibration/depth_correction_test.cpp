// fitDepthCorrection on generated board views: depth images made with a known correction
// (scale 1.02, offset −8 mm, a radial Herrera term) are corrected back onto the board planes.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <numbers>
#include <random>

#include "depth_test_scene.h"
#include "mixray/calibration/depth_registration.h"

namespace mixray::calibration {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

CameraModel irCamera() {
    CameraModel ir = CameraModel::pinhole(640, 480, 580, 580, 314.5, 245.5);
    ir.distortion = {-0.06, 0.12, 3e-4, 2e-4, 0};
    return ir;
}

using test::boardPoints;

// Board poses spread over the image and over 0.7–2.6 m, tilted up to 35°.
std::vector<Eigen::Isometry3d> boardPoses(int count, uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(-1, 1);
    std::vector<Eigen::Isometry3d> poses;
    for (int i = 0; i < count; ++i) {
        const double z = 0.7 + 1.9 * (i % 7) / 6.0 + 0.05 * u(rng);
        const Eigen::Vector3d centre(0.45 * z * u(rng), 0.33 * z * u(rng), z);
        Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
        T.linear() = (Eigen::AngleAxisd(35 * kDeg * u(rng), Eigen::Vector3d::UnitX()) *
                      Eigen::AngleAxisd(35 * kDeg * u(rng), Eigen::Vector3d::UnitY()) *
                      Eigen::AngleAxisd(10 * kDeg * u(rng), Eigen::Vector3d::UnitZ()))
                         .toRotationMatrix();
        T.translation() = centre - T.linear() * Eigen::Vector3d(0.24, 0.15, 0);
        poses.push_back(T);
    }
    return poses;
}

// The true correction: scale 1.02, offset −8 mm and, when `radial`, D(u, v) = 12 mm ·
// (r² − 0.12) with r the distance from the principal point over the image width (about
// −1.4 mm at the centre, +3 mm in the corners at α's reference depth), α1 = 0.6/m.
DepthCorrection trueCorrection(const CameraModel& ir, bool radial) {
    DepthCorrection c;
    c.scale = 1.02;
    c.offset_m = -0.008;
    if (!radial)
        return c;
    c.alpha1 = 0.6;
    c.alpha0 = 0.6 * 1.5;
    c.distortion.resize(static_cast<size_t>(ir.width) * ir.height);
    for (int y = 0; y < ir.height; ++y)
        for (int x = 0; x < ir.width; ++x) {
            const double rx = (x - ir.cx) / ir.width, ry = (y - ir.cy) / ir.width;
            c.distortion[static_cast<size_t>(y) * ir.width + x] =
                static_cast<float>(0.012 * (rx * rx + ry * ry - 0.12));
        }
    return c;
}

struct Views {
    std::vector<Image> images;
    std::vector<DepthPlaneView> views;
};

// Raw depth images of each board pose, as the true correction's inverse, with Gaussian noise
// of `noise_m` before the 1 mm quantisation.
Views makeViews(const CameraModel& ir, const std::vector<Eigen::Isometry3d>& poses,
                const DepthCorrection& truth, double noise_m, uint32_t seed) {
    std::mt19937 rng(seed);
    std::normal_distribution<double> noise(0, noise_m);
    Views out;
    for (const auto& T : poses) {
        test::Scene scene;
        scene.planes.push_back({T.linear().col(2), T.linear().col(2).dot(T.translation())});
        test::Rendered rendered = test::render(scene, ir, Eigen::Isometry3d::Identity());
        Image image = test::depthImage(rendered, &truth);
        const MutableImageView v = image.mutableView();
        for (int y = 0; y < ir.height; ++y)
            for (int x = 0; x < ir.width; ++x) {
                uint16_t& d = v.row<uint16_t>(y)[x];
                if (d != 0 && noise_m > 0)
                    d = static_cast<uint16_t>(std::max(1L, std::lround(d + noise(rng) * 1e3)));
            }
        out.images.push_back(std::move(image));
    }
    for (size_t i = 0; i < poses.size(); ++i)
        out.views.push_back({poses[i], out.images[i].view()});
    return out;
}

// RMS and largest difference of two corrections over pixels and depths 0.8–2.5 m, on the
// pixels `covered` marks.
std::pair<double, double> difference(const DepthCorrection& a, const DepthCorrection& b,
                                     const CameraModel& ir, const std::vector<uint8_t>& covered) {
    double sum = 0, worst = 0;
    int n = 0;
    for (int y = 0; y < ir.height; y += 4)
        for (int x = 0; x < ir.width; x += 4) {
            if (!covered[static_cast<size_t>(y) * ir.width + x])
                continue;
            for (double z = 0.8; z <= 2.5; z += 0.1) {
                const double d =
                    correctedDepth(a, z, x, y, ir.width) - correctedDepth(b, z, x, y, ir.width);
                sum += d * d;
                worst = std::max(worst, std::abs(d));
                ++n;
            }
        }
    return {std::sqrt(sum / std::max(n, 1)), worst};
}

// Pixels inside some board's outline.
std::vector<uint8_t> coveredPixels(const CameraModel& ir,
                                   const std::vector<Eigen::Isometry3d>& poses) {
    std::vector<uint8_t> covered(static_cast<size_t>(ir.width) * ir.height, 0);
    const std::vector<Eigen::Vector3d> rays = test::pixelRays(ir);
    for (const auto& T : poses) {
        const Eigen::Isometry3d T_board_ir = T.inverse();
        const Eigen::Vector3d n = T.linear().col(2);
        for (int y = 0; y < ir.height; ++y)
            for (int x = 0; x < ir.width; ++x) {
                const Eigen::Vector3d& dir = rays[static_cast<size_t>(y) * ir.width + x];
                const double t = n.dot(T.translation()) / n.dot(dir);
                const Eigen::Vector3d q = T_board_ir * (dir * t);
                if (t > 0 && q.x() > 0.01 && q.y() > 0.01 && q.x() < 0.47 && q.y() < 0.29)
                    covered[static_cast<size_t>(y) * ir.width + x] = 1;
            }
    }
    return covered;
}

TEST(DepthCorrectionFit, RecoversScaleAndOffset) {
    const CameraModel ir = irCamera();
    const DepthCorrection truth = trueCorrection(ir, false);
    const auto poses = boardPoses(14, 7);
    const Views v = makeViews(ir, poses, truth, 0.001, 1);
    auto fit = fitDepthCorrection(ir, boardPoints(), v.views);
    ASSERT_TRUE(fit) << fit.status().toString();
    EXPECT_NEAR(fit->correction.scale, 1.02, 5e-4);
    EXPECT_NEAR(fit->correction.offset_m, -0.008, 5e-4);
    EXPECT_TRUE(fit->correction.distortion.empty());
    EXPECT_GT(fit->samples, 100000);
    EXPECT_GT(fit->rms_before_m, 0.01);
    // 1 mm noise and 1 mm quantisation, scaled by 1.02 (1.06 mm), are all that is left.
    EXPECT_LT(fit->rms_after_m, 0.0012);
}

TEST(DepthCorrectionFit, RecoversHerreraPerPixelTerm) {
    const CameraModel ir = irCamera();
    const DepthCorrection truth = trueCorrection(ir, true);
    const auto poses = boardPoses(28, 11);
    const Views v = makeViews(ir, poses, truth, 0.001, 2);

    DepthCorrectionOptions options;
    options.per_pixel = true;
    auto fit = fitDepthCorrection(ir, boardPoints(), v.views, options);
    ASSERT_TRUE(fit) << fit.status().toString();
    auto plain = fitDepthCorrection(ir, boardPoints(), v.views);
    ASSERT_TRUE(plain);
    const DepthCorrection& c = fit->correction;
    std::printf("fit: scale %.5f offset %.2f mm alpha0 %.3f alpha1 %.3f rms %.3f -> %.3f mm\n",
                c.scale, c.offset_m * 1e3, c.alpha0, c.alpha1, fit->rms_before_m * 1e3,
                fit->rms_after_m * 1e3);
    ASSERT_EQ(c.distortion.size(), static_cast<size_t>(ir.width) * ir.height);
    EXPECT_NEAR(c.scale, 1.02, 0.002);
    EXPECT_NEAR(c.offset_m, -0.008, 0.001);
    EXPECT_NEAR(c.alpha1, 0.6, 0.15);
    // The correction as a whole, where boards were seen, at 0.8–2.5 m.
    const auto covered = coveredPixels(ir, poses);
    const auto [rms, worst] = difference(c, truth, ir, covered);
    const auto [plain_rms, plain_worst] = difference(plain->correction, truth, ir, covered);
    std::printf("vs truth at 0.8-2.5 m: rms %.3f mm, max %.3f mm (scale/offset only: %.3f, %.3f)\n",
                rms * 1e3, worst * 1e3, plain_rms * 1e3, plain_worst * 1e3);
    EXPECT_LT(rms, 0.0005);
    EXPECT_LT(worst, 0.002);
    EXPECT_GT(plain_rms, 2 * rms);
    EXPECT_LT(fit->rms_after_m, plain->rms_after_m);
    EXPECT_LT(fit->rms_after_m, 0.0012);

    // Held-out boards, corrected with the fit, lie on their planes.
    const auto test_poses = boardPoses(5, 99);
    const Views held_out = makeViews(ir, test_poses, truth, 0, 3);
    DepthCorrectionOptions none;
    none.max_residual_m = 1;
    DepthCorrectionFit check;
    double sum = 0;
    int n = 0;
    for (const auto& view : held_out.views) {
        const Eigen::Vector3d normal = view.T_ir_board.linear().col(2);
        for (int y = 0; y < ir.height; y += 3)
            for (int x = 0; x < ir.width; x += 3) {
                const uint16_t raw = view.depth_mm.row<uint16_t>(y)[x];
                if (!raw || !covered[static_cast<size_t>(y) * ir.width + x])
                    continue;
                const auto dir = *ir.unproject({double(x), double(y)});
                const double z_true =
                    normal.dot(view.T_ir_board.translation()) / normal.dot(dir / dir.z());
                const double e = correctedDepth(c, raw * 1e-3, x, y, ir.width) - z_true;
                sum += e * e;
                ++n;
            }
    }
    ASSERT_GT(n, 1000);
    EXPECT_LT(std::sqrt(sum / n), 0.001);
}

TEST(DepthCorrectionFit, ClearErrors) {
    const CameraModel ir = irCamera();
    EXPECT_EQ(fitDepthCorrection(ir, boardPoints(), {}).status().code(),
              ErrorCode::kInvalidArgument);
    Image wrong(ImageDesc::packed(PixelFormat::kDepth16, 320, 240));
    auto r = fitDepthCorrection(ir, boardPoints(), {{Eigen::Isometry3d::Identity(), wrong.view()}});
    ASSERT_FALSE(r);
    EXPECT_NE(r.status().message().find("640x480"), std::string::npos) << r.status().message();
    // Boards all at one distance, facing the camera: the scale cannot be told from an offset.
    std::vector<Eigen::Isometry3d> flat;
    for (int i = 0; i < 3; ++i) {
        Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
        T.translation() = Eigen::Vector3d(-0.24 + 0.1 * i, -0.15, 1.2);
        flat.push_back(T);
    }
    const Views v = makeViews(ir, flat, DepthCorrection{}, 0, 1);
    r = fitDepthCorrection(ir, boardPoints(), v.views);
    ASSERT_FALSE(r);
    EXPECT_EQ(r.status().code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(r.status().message().find("not observable"), std::string::npos)
        << r.status().message();
}

}  // namespace
}  // namespace mixray::calibration
