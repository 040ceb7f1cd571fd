// Environment-camera alignment: generated views with exact and noisy corners (seeding and the
// joint solve), and the simulated calibration session against its truth T_marker_env.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <numbers>
#include <random>

#include "environment_alignment_internal.h"
#include "mixray/calibration/environment_alignment.h"

namespace mixray::calibration {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

double angleDeg(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
    return Eigen::AngleAxisd(a.linear().transpose() * b.linear()).angle() / kDeg;
}

// A camera at `eye` looking at `at`, its +y as close to −up as possible.
Eigen::Isometry3d lookAt(const Eigen::Vector3d& eye, const Eigen::Vector3d& at,
                         const Eigen::Vector3d& up) {
    const Eigen::Vector3d z = (at - eye).normalized();
    const Eigen::Vector3d x = z.cross(-up).normalized();
    const Eigen::Vector3d y = z.cross(x);
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear().col(0) = x;
    T.linear().col(1) = y;
    T.linear().col(2) = z;
    T.translation() = eye;
    return T;
}

// The simulator's colour camera and fish-eye environment camera (sim_calibration.truth.yaml).
CameraModel mainCamera() {
    CameraModel m = CameraModel::pinhole(640, 480, 524.8, 525.4, 318.6, 241.9);
    m.distortion = {0.045, -0.11, 6e-4, -4e-4, 0.04};
    return m;
}

CameraModel envCamera() {
    CameraModel m = CameraModel::pinhole(480, 480, 140, 140, 239.2, 240.3);
    m.lens = LensModel::kFisheye;
    m.distortion = {0.02, -0.005, 0.001, -2e-4};
    return m;
}

// ChArUco 7x5, 50 mm: its 6x4 inner corners, OpenCV's ids (row-major) and positions.
std::vector<Eigen::Vector3d> charucoPoints() {
    std::vector<Eigen::Vector3d> points;
    for (int r = 0; r < 4; ++r)
        for (int c = 0; c < 6; ++c)
            points.emplace_back((c + 1) * 0.05, (r + 1) * 0.05, 0);
    return points;
}

struct Generated {
    Eigen::Isometry3d T_world_env;
    CameraViews main_board, env_board;
    std::vector<MarkerView> marker;
};

// The marker at the world origin on the table (z up); the environment camera beside it,
// looking up and forward; the main camera above and behind; a board held up between them,
// its front to both, in `keys` poses; corners with Gaussian noise of `noise_px`.
Generated generate(int keys, double noise_px, uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(-1, 1);
    std::normal_distribution<double> noise(0, noise_px);
    const CameraModel main = mainCamera(), env = envCamera();
    const auto points = charucoPoints();
    Generated g;
    g.T_world_env = lookAt({0.3, 0.05, 0.12}, {0.25, 0.6, 0.6}, {0, 0, 1});
    g.T_world_env.linear() =
        g.T_world_env.linear() * Eigen::AngleAxisd(20 * kDeg, Eigen::Vector3d::UnitZ());
    for (CameraViews* v : {&g.main_board, &g.env_board}) {
        v->target.kind = TargetKind::kCharuco;
        v->target.cols = 7;
        v->target.rows = 5;
        v->target.square_m = 0.05;
        v->target.marker_m = 0.037;
        v->target.dictionary = "DICT_6X6_250";
    }
    g.main_board.camera = "kinect/color";
    g.main_board.width = main.width;
    g.main_board.height = main.height;
    g.env_board.camera = "env/color";
    g.env_board.width = env.width;
    g.env_board.height = env.height;
    const double h = 0.05;
    const Eigen::Vector3d marker_world[4] = {{-h, h, 0}, {h, h, 0}, {h, -h, 0}, {-h, -h, 0}};

    int made = 0;
    for (int attempt = 0; made < keys && attempt < 1000; ++attempt) {
        const Eigen::Isometry3d T_world_main =
            lookAt({0.1 * u(rng), -0.55 + 0.05 * u(rng), 0.6 + 0.05 * u(rng)}, {0.15, 0.2, 0.15},
                   {0, 0, 1});
        // The board's front (−z of its frame) towards −y and down, tilted up to 20°.
        const Eigen::Vector3d centre(0.1 + 0.15 * u(rng), 0.45 + 0.05 * u(rng),
                                     0.35 + 0.08 * u(rng));
        Eigen::Isometry3d T_world_board =
            lookAt(centre, centre + Eigen::Vector3d(0, 1, 0.5), {0, 0, 1});
        T_world_board.linear() = T_world_board.linear() *
                                 (Eigen::AngleAxisd(20 * kDeg * u(rng), Eigen::Vector3d::UnitX()) *
                                  Eigen::AngleAxisd(20 * kDeg * u(rng), Eigen::Vector3d::UnitY()))
                                     .toRotationMatrix();
        T_world_board.translation() =
            centre - T_world_board.linear() * Eigen::Vector3d(0.175, 0.125, 0);

        TargetView mv, ev;
        mv.key = ev.key = 100 + made;
        const auto observe = [&](const CameraModel& cam, const Eigen::Isometry3d& T_world_cam,
                                 TargetView& view) {
            const Eigen::Isometry3d T_cam_board = T_world_cam.inverse() * T_world_board;
            for (size_t i = 0; i < points.size(); ++i) {
                const Eigen::Vector3d p = T_cam_board * points[i];
                const auto px = cam.project(p);
                if (!px || px->x() < 2 || px->y() < 2 || px->x() > cam.width - 3 ||
                    px->y() > cam.height - 3)
                    continue;
                view.corners.push_back(
                    {static_cast<int>(i), *px + Eigen::Vector2d(noise(rng), noise(rng)), 1.0});
            }
        };
        observe(main, T_world_main, mv);
        observe(env, g.T_world_env, ev);
        MarkerView m;
        m.key = mv.key;
        bool marker_seen = true;
        for (int j = 0; j < 4; ++j) {
            const auto px = main.project(T_world_main.inverse() * marker_world[j]);
            marker_seen = marker_seen && px && px->x() > 0 && px->y() > 0 &&
                          px->x() < main.width - 1 && px->y() < main.height - 1;
            if (px)
                m.corners[j] = *px + Eigen::Vector2d(noise(rng), noise(rng));
        }
        if (mv.corners.size() < 20 || ev.corners.size() < 20 || !marker_seen)
            continue;
        g.main_board.views.push_back(mv);
        g.env_board.views.push_back(ev);
        g.marker.push_back(m);
        ++made;
    }
    return g;
}

TEST(EnvironmentAlignment, SeedsAreExactForExactCorners) {
    const Generated g = generate(5, 0, 1);
    ASSERT_EQ(g.marker.size(), 5u);
    auto seed = detail::seedEnvironmentAlignment(mainCamera(), envCamera(), charucoPoints(),
                                                 g.main_board, g.env_board, g.marker, {});
    ASSERT_TRUE(seed) << seed.status().toString();
    EXPECT_EQ(seed->keys.size(), 5u);
    const Eigen::Isometry3d T_world_env = seed->T_env_world.inverse();
    EXPECT_LT(angleDeg(T_world_env, g.T_world_env), 1e-4);
    EXPECT_LT((T_world_env.translation() - g.T_world_env.translation()).norm(), 1e-5);
    EXPECT_LT(seed->spread_deg, 1e-4);
}

TEST(EnvironmentAlignment, ExactCornersRecoverThePose) {
    const Generated g = generate(6, 0, 2);
    auto a = detail::alignEnvironmentCamera(mainCamera(), envCamera(), charucoPoints(),
                                            g.main_board, g.env_board, g.marker, {});
    ASSERT_TRUE(a) << a.status().toString();
    EXPECT_LT(angleDeg(a->T_world_env, g.T_world_env), 1e-6);
    EXPECT_LT((a->T_world_env.translation() - g.T_world_env.translation()).norm(), 1e-8);
    EXPECT_LT(a->rms_px, 1e-6);
    EXPECT_EQ(a->keys.size(), 6u);
}

// 0.1 px of corner noise over 12 keys: the fish-eye sees the board small (fx 140 px), so its
// corners set the precision (a Monte-Carlo run of 30 seeds at 0.3 px and 8 keys gave 0.40°
// RMS error against a mean predicted σ of 0.46°: the covariance is honest).
TEST(EnvironmentAlignment, NoisyCornersWithinTheirCovariance) {
    const Generated g = generate(12, 0.1, 3);
    auto a = detail::alignEnvironmentCamera(mainCamera(), envCamera(), charucoPoints(),
                                            g.main_board, g.env_board, g.marker, {});
    ASSERT_TRUE(a) << a.status().toString();
    const double rot_err = angleDeg(a->T_world_env, g.T_world_env);
    const double t_err = (a->T_world_env.translation() - g.T_world_env.translation()).norm();
    const double rot_sigma = std::sqrt(a->covariance.topLeftCorner<3, 3>().trace()) / kDeg;
    const double t_sigma = std::sqrt(a->covariance.bottomRightCorner<3, 3>().trace());
    std::printf(
        "noisy: %.4f deg (σ %.4f), %.2f mm (σ %.2f), rms %.3f px (env %.3f, main %.3f, "
        "marker %.3f), seed spread %.3f deg\n",
        rot_err, rot_sigma, t_err * 1e3, t_sigma * 1e3, a->rms_px, a->env_rms_px, a->main_rms_px,
        a->marker_rms_px, a->seed_spread_deg);
    EXPECT_LT(rot_err, 0.2);
    // Per corner the residual's length: √2 · 0.1 px less the fitted share.
    EXPECT_NEAR(a->rms_px, 0.14, 0.03);
    // The error is of the size the covariance says (within 4σ), and σ is not absurdly large.
    EXPECT_LT(rot_err, 4 * rot_sigma);
    EXPECT_LT(t_err, 4 * t_sigma);
    EXPECT_LT(rot_sigma, 0.2);
    EXPECT_TRUE(a->covariance.allFinite());
    EXPECT_GT(a->covariance.diagonal().minCoeff(), 0);
}

// Keys without a marker view, the main camera's poses given instead (as a tracker would).
TEST(EnvironmentAlignment, KnownMainPosesStandInForTheMarker) {
    Generated g = generate(5, 0, 5);
    EnvironmentAlignmentOptions options;
    for (size_t i = 0; i < g.marker.size(); ++i) {
        // The main camera's pose from the exact marker corners.
        const std::vector<Eigen::Vector3d> marker_points = {
            {-0.05, 0.05, 0}, {0.05, 0.05, 0}, {0.05, -0.05, 0}, {-0.05, -0.05, 0}};
        const auto T_main_world = detail::poseFromCorners(
            mainCamera(), marker_points,
            std::vector<Eigen::Vector2d>(g.marker[i].corners.begin(), g.marker[i].corners.end()),
            true);
        ASSERT_TRUE(T_main_world);
        options.main_poses.push_back({g.marker[i].key, T_main_world->inverse()});
    }
    g.marker.erase(g.marker.begin() + 2, g.marker.end());  // keys 102.. keep no marker view
    auto a = detail::alignEnvironmentCamera(mainCamera(), envCamera(), charucoPoints(),
                                            g.main_board, g.env_board, g.marker, options);
    ASSERT_TRUE(a) << a.status().toString();
    EXPECT_EQ(a->keys.size(), 5u);
    EXPECT_EQ(a->keys_with_known_pose, 3);
    EXPECT_LT(angleDeg(a->T_world_env, g.T_world_env), 1e-5);
}

// A few mislabelled corners are dropped, not averaged in.
TEST(EnvironmentAlignment, DropsOutlyingCorners) {
    Generated g = generate(8, 0.1, 6);
    g.env_board.views[1].corners[3].pixel += Eigen::Vector2d(6, -4);
    g.main_board.views[4].corners[0].pixel += Eigen::Vector2d(-5, 5);
    auto a = detail::alignEnvironmentCamera(mainCamera(), envCamera(), charucoPoints(),
                                            g.main_board, g.env_board, g.marker, {});
    ASSERT_TRUE(a) << a.status().toString();
    EXPECT_GE(a->outliers, 2);
    EXPECT_LT(a->rms_px, 0.2);
    EXPECT_LT(angleDeg(a->T_world_env, g.T_world_env), 0.2);
}

TEST(EnvironmentAlignment, ClearErrors) {
    const Generated g = generate(3, 0, 4);
    EnvironmentAlignmentOptions options;
    options.min_views = 4;
    auto a = detail::alignEnvironmentCamera(mainCamera(), envCamera(), charucoPoints(),
                                            g.main_board, g.env_board, g.marker, options);
    ASSERT_FALSE(a);
    EXPECT_EQ(a.status().code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(a.status().message().find("at least 4"), std::string::npos) << a.status().message();
    // No marker view at the board's keys.
    std::vector<MarkerView> elsewhere = g.marker;
    for (auto& m : elsewhere)
        m.key += 1000;
    EXPECT_FALSE(detail::alignEnvironmentCamera(mainCamera(), envCamera(), charucoPoints(),
                                                g.main_board, g.env_board, elsewhere, {}));
    CameraViews wrong_size = g.env_board;
    wrong_size.width = 640;
    a = detail::alignEnvironmentCamera(mainCamera(), envCamera(), charucoPoints(), g.main_board,
                                       wrong_size, g.marker, {});
    ASSERT_FALSE(a);
    EXPECT_NE(a.status().message().find("640x480"), std::string::npos) << a.status().message();
}

}  // namespace
}  // namespace mixray::calibration
