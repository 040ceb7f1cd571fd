// calibrateRig() on generated corners with ground truth: three cameras (pinhole OpenCV 5,
// pinhole OpenCV 4, Kannala–Brandt fish-eye), the third linked to the reference only through
// the second; extrinsics within 1 mm and 0.1° with the intrinsics fixed and refined, pose
// covariances against the errors, a non-first reference, and the refusals. Chessboard views whose
// corners a detector numbered from another corner (turned 180°, or 90° on square boards) in one
// camera only are renumbered and the rig comes out as without them; views no corner order
// explains are dropped, or the solve refused, never a wrong rig.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <numbers>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "ceres_synthetic.h"
#include "mixray/calibration/calibrate.h"

namespace mixray::calibration {
namespace {

constexpr double kNoisePx = 0.2;
constexpr double kDeg = std::numbers::pi / 180;

struct Camera {
    std::string name;
    CameraModel model;
    Eigen::Isometry3d T_ref_camera;
};

Eigen::Isometry3d pose(double yaw_deg, double pitch_deg, const Eigen::Vector3d& t) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = (Eigen::AngleAxisd(yaw_deg * kDeg, Eigen::Vector3d::UnitY()) *
                  Eigen::AngleAxisd(pitch_deg * kDeg, Eigen::Vector3d::UnitX()))
                     .toRotationMatrix();
    T.translation() = t;
    return T;
}

std::vector<Camera> rigTruth() {
    CameraModel left = CameraModel::pinhole(640, 480, 536.2, 538.9, 338.1, 237.4);
    left.distortion = {-0.266, -0.039, 0.0018, -0.0003, 0.238};
    CameraModel right = CameraModel::pinhole(1280, 720, 910.4, 909.1, 648.2, 355.9);
    right.distortion = {0.0995, -0.206, 0.0075, 0.0034};
    CameraModel env = CameraModel::pinhole(1032, 778, 281.3, 282.0, 517.6, 386.2);
    env.lens = LensModel::kFisheye;
    env.distortion = {0.031, -0.012, 0.0021, -0.0004};
    return {
        {"left", left, Eigen::Isometry3d::Identity()},
        {"right", right, pose(-10, 2, Eigen::Vector3d(0.12, 0.005, 0.01))},
        {"env", env, pose(-25, -5, Eigen::Vector3d(0.25, -0.02, 0.04))},
    };
}

// Keys [0, per_pair) are seen by cameras 0 and 1, keys [per_pair, 2·per_pair) by cameras 1
// and 2: camera 2 shares no key with camera 0. Each camera also sees `solo` views alone, at
// keys of its own, as a user takes for intrinsics: a board that fits a narrow camera's view is
// small in the fish-eye's.
std::vector<CameraViews> rigViews(const std::vector<Camera>& cameras, int per_pair,
                                  std::mt19937& rng, int solo = 10,
                                  const CalibrationTarget& board = test::chessboard(12, 9, 0.03)) {
    std::vector<CameraViews> views(cameras.size());
    for (size_t i = 0; i < cameras.size(); ++i) {
        views[i].camera = cameras[i].name;
        views[i].width = cameras[i].model.width;
        views[i].height = cameras[i].model.height;
        views[i].target = board;
    }
    for (int key = 0; key < 2 * per_pair; ++key) {
        const size_t a = key < per_pair ? 0 : 1;
        const size_t b = a + 1;
        for (;;) {
            const Eigen::Isometry3d T_a_target =
                test::randomBoardPose(cameras[a].model, board, rng);
            const Eigen::Isometry3d T_ref_target = cameras[a].T_ref_camera * T_a_target;
            const Eigen::Isometry3d T_b_target = cameras[b].T_ref_camera.inverse() * T_ref_target;
            if (test::visibleFraction(cameras[b].model, board, T_b_target) < 0.8)
                continue;
            for (size_t c : {a, b}) {
                const Eigen::Isometry3d T = cameras[c].T_ref_camera.inverse() * T_ref_target;
                views[c].views.push_back(
                    test::observe(cameras[c].model, board, T, kNoisePx, rng, key,
                                  cameras[c].name + "/" + std::to_string(key)));
            }
            break;
        }
    }
    for (size_t c = 0; c < cameras.size(); ++c) {
        for (int i = 0; i < solo; ++i) {
            const int64_t key = 1000 * static_cast<int64_t>(c + 1) + i;
            views[c].views.push_back(test::observe(
                cameras[c].model, board, test::randomBoardPose(cameras[c].model, board, rng),
                kNoisePx, rng, key, cameras[c].name + "/solo" + std::to_string(i)));
        }
    }
    return views;
}

RigOptions rigOptions(bool refine_intrinsics) {
    RigOptions options;
    options.camera.solver = Solver::kCeres;
    options.camera.model = "opencv5";
    options.models = {{"right", "opencv4"}, {"env", "fisheye"}};
    options.refine_intrinsics = refine_intrinsics;
    return options;
}

class CeresRig : public ::testing::TestWithParam<bool> {};

TEST_P(CeresRig, RecoversExtrinsicsThroughAChainWithin1MmAnd0_1Deg) {
    const std::vector<Camera> truth = rigTruth();
    std::mt19937 rng(99);
    const std::vector<CameraViews> views = rigViews(truth, 18, rng);
    std::vector<std::pair<double, std::string>> progress;
    RigOptions options = rigOptions(GetParam());
    options.camera.progress = [&](double fraction, std::string_view stage) {
        progress.emplace_back(fraction, stage);
    };
    const Result<RigCalibration> rig = calibrateRig(views, options);
    ASSERT_TRUE(rig) << rig.status().toString();

    EXPECT_EQ(rig->reference, "left");
    ASSERT_EQ(rig->cameras.size(), 3u);
    ASSERT_EQ(rig->T_ref_camera.size(), 3u);
    ASSERT_EQ(rig->pose_covariance.size(), 3u);
    EXPECT_TRUE(rig->T_ref_camera[0].isApprox(Eigen::Isometry3d::Identity()));
    EXPECT_EQ(rig->pose_covariance[0].norm(), 0.0);
    for (size_t i = 1; i < 3; ++i) {
        SCOPED_TRACE(truth[i].name);
        EXPECT_EQ(rig->cameras[i].camera, truth[i].name);
        const Eigen::Vector3d error =
            rig->T_ref_camera[i].translation() - truth[i].T_ref_camera.translation();
        const double angle = test::rotationErrorDeg(rig->T_ref_camera[i], truth[i].T_ref_camera);
        std::cout << truth[i].name << (GetParam() ? " (intrinsics refined)" : "")
                  << ": position error " << error.norm() * 1e3 << " mm, rotation error " << angle
                  << " deg; 1-sigma " << std::sqrt(rig->pose_covariance[i](3, 3)) * 1e3 << " "
                  << std::sqrt(rig->pose_covariance[i](4, 4)) * 1e3 << " "
                  << std::sqrt(rig->pose_covariance[i](5, 5)) * 1e3 << " mm\n";
        EXPECT_LT(error.norm(), 1e-3);
        EXPECT_LT(angle, 0.1);
        const Eigen::Matrix<double, 6, 6>& cov = rig->pose_covariance[i];
        EXPECT_TRUE(cov.isApprox(cov.transpose()));
        EXPECT_GT(cov.diagonal().minCoeff(), 0.0);
        for (int k = 0; k < 3; ++k) {
            EXPECT_LT(std::sqrt(cov(3 + k, 3 + k)), 1e-3);
            // With the intrinsics in the solve the covariance covers the error (each position
            // axis within 4σ); with them fixed it is conditional on them and leaves their own
            // error out.
            if (GetParam()) {
                EXPECT_LT(std::abs(error[k]), 4 * std::sqrt(cov(3 + k, 3 + k)));
            }
        }
    }
    EXPECT_EQ(rig->cameras[2].model.lens, LensModel::kFisheye);
    EXPECT_EQ(rig->cameras[1].model.distortion.size(), 4u);
    for (size_t i = 0; i < 3; ++i) {
        EXPECT_NEAR(rig->cameras[i].model.fx, truth[i].model.fx, 0.002 * truth[i].model.fx);
        EXPECT_NEAR(rig->cameras[i].model.cy, truth[i].model.cy, 0.002 * truth[i].model.cy);
    }
    EXPECT_NEAR(rig->rms_px, kNoisePx * std::sqrt(2.0), 0.03);
    ASSERT_FALSE(progress.empty());
    EXPECT_EQ(progress.back().first, 1.0);
    for (size_t p = 1; p < progress.size(); ++p)
        EXPECT_GE(progress[p].first, progress[p - 1].first) << progress[p].second;
}

TEST(CeresRigReference, ANamedReferenceIsTheIdentityAndTheOthersFollow) {
    const std::vector<Camera> truth = rigTruth();
    std::mt19937 rng(7);
    const std::vector<CameraViews> views = rigViews(truth, 18, rng);
    RigOptions options = rigOptions(false);
    options.reference = "right";
    const Result<RigCalibration> rig = calibrateRig(views, options);
    ASSERT_TRUE(rig) << rig.status().toString();
    EXPECT_EQ(rig->reference, "right");
    EXPECT_TRUE(rig->T_ref_camera[1].isApprox(Eigen::Isometry3d::Identity()));
    EXPECT_EQ(rig->pose_covariance[1].norm(), 0.0);
    for (size_t i : {size_t{0}, size_t{2}}) {
        const Eigen::Isometry3d expected = truth[1].T_ref_camera.inverse() * truth[i].T_ref_camera;
        EXPECT_LT((rig->T_ref_camera[i].translation() - expected.translation()).norm(), 1e-3);
        EXPECT_LT(test::rotationErrorDeg(rig->T_ref_camera[i], expected), 0.1);
    }
}

void expectInvalid(const Status& status, const std::string& cause) {
    EXPECT_EQ(status.code(), ErrorCode::kInvalidArgument) << status.toString();
    EXPECT_NE(status.message().find(cause), std::string::npos)
        << "'" << status.message() << "' does not name '" << cause << "'";
}

// Cameras already calibrated on the same views are taken as they are: the same rig comes out.
TEST(CeresRigReference, CamerasAlreadySolvedAreNotSolvedAgain) {
    const std::vector<Camera> truth = rigTruth();
    std::mt19937 rng(7);
    const std::vector<CameraViews> views = rigViews(truth, 18, rng);
    RigOptions options = rigOptions(false);
    const Result<RigCalibration> first = calibrateRig(views, options);
    ASSERT_TRUE(first) << first.status().toString();
    for (const CameraCalibration& c : first->cameras)
        options.solved[c.camera] = c;
    int own_solves = 0;
    options.camera.progress = [&](double, std::string_view stage) {
        own_solves += stage.find("checking views") != std::string_view::npos;
    };
    const Result<RigCalibration> again = calibrateRig(views, options);
    ASSERT_TRUE(again) << again.status().toString();
    EXPECT_EQ(own_solves, 0);
    for (size_t i = 0; i < views.size(); ++i) {
        EXPECT_EQ(again->cameras[i].model.fx, first->cameras[i].model.fx);
        EXPECT_LT(
            (again->T_ref_camera[i].translation() - first->T_ref_camera[i].translation()).norm(),
            1e-9);
    }
}

TEST(CeresRigRefuses, ACameraLinkedToNoOtherNamingIt) {
    const std::vector<Camera> truth = rigTruth();
    std::mt19937 rng(11);
    std::vector<CameraViews> views = rigViews(truth, 10, rng);
    // A fourth camera whose views all come at keys no other camera has.
    CameraViews lone =
        test::generateViews("lone", truth[0].model, views[0].target, 8, kNoisePx, rng);
    for (TargetView& view : lone.views)
        view.key += 9000;
    views.push_back(lone);
    RigOptions options = rigOptions(false);
    expectInvalid(calibrateRig(views, options).status(), "'lone' never linked to the reference");
}

TEST(CeresRigRefuses, BadNamesAndKeys) {
    const std::vector<Camera> truth = rigTruth();
    std::mt19937 rng(13);
    const std::vector<CameraViews> views = rigViews(truth, 8, rng);
    RigOptions options = rigOptions(false);
    options.reference = "top";
    expectInvalid(calibrateRig(views, options).status(),
                  "reference camera 'top' is not one of the rig's cameras (left, right, env)");
    options = rigOptions(false);
    options.models["rear"] = "fisheye";
    expectInvalid(calibrateRig(views, options).status(), "camera 'rear'");
    expectInvalid(calibrateRig({views[0], views[0]}, rigOptions(false)).status(),
                  "camera 'left' appears twice");
    expectInvalid(calibrateRig({}, rigOptions(false)).status(), "no cameras");
    std::vector<CameraViews> repeated = views;
    repeated[1].views[3].key = repeated[1].views[2].key;
    expectInvalid(calibrateRig(repeated, rigOptions(false)).status(), "have the same key");
    // A camera's own calibration failing names the camera.
    std::vector<CameraViews> few = views;
    few[2].views.resize(2);
    expectInvalid(calibrateRig(few, rigOptions(false)).status(), "camera 'env': too few");
}

// What a chessboard detector gives when it numbers the corners from another corner: the corner
// at (col, row) labelled as the one the board turned by `deg` about its centre puts there.
void turnCorners(TargetView& view, const CalibrationTarget& board, int deg) {
    for (Corner& corner : view.corners) {
        const int col = corner.id % board.cols, row = corner.id / board.cols;
        int c = col, r = row;
        if (deg == 180) {
            c = board.cols - 1 - col;
            r = board.rows - 1 - row;
        } else if (deg == 90) {
            c = board.rows - 1 - row;
            r = col;
        }
        corner.id = r * board.cols + c;
    }
}

// The stereo pair left (reference) and right of rigTruth(): keys 0–17 seen by both.
std::vector<Camera> stereoTruth() {
    std::vector<Camera> truth = rigTruth();
    truth.resize(2);
    return truth;
}

std::vector<CameraViews> stereoViews(std::mt19937& rng,
                                     const CalibrationTarget& board = test::chessboard(12, 9,
                                                                                       0.03)) {
    std::vector<CameraViews> views = rigViews(rigTruth(), 18, rng, 10, board);
    views.resize(2);
    return views;
}

RigOptions stereoOptions() {
    RigOptions options;
    options.camera.solver = Solver::kCeres;
    options.models = {{"right", "opencv4"}};
    return options;
}

// Index of the view with `key` in `camera`.
size_t viewAt(const CameraViews& camera, int64_t key) {
    for (size_t i = 0; i < camera.views.size(); ++i)
        if (camera.views[i].key == key)
            return i;
    ADD_FAILURE() << camera.camera << " has no view at key " << key;
    return 0;
}

void expectRightRig(const RigCalibration& rig) {
    const Eigen::Isometry3d truth = stereoTruth()[1].T_ref_camera;
    const double mm = (rig.T_ref_camera[1].translation() - truth.translation()).norm() * 1e3;
    const double deg = test::rotationErrorDeg(rig.T_ref_camera[1], truth);
    std::cout << "baseline " << rig.T_ref_camera[1].translation().norm() * 1e3 << " mm (truth "
              << truth.translation().norm() * 1e3 << "): " << mm << " mm, " << deg
              << " deg off; joint RMS " << rig.rms_px << " px\n";
    EXPECT_LT(mm, 1.0);
    EXPECT_LT(deg, 0.1);
    EXPECT_NEAR(rig.rms_px, kNoisePx * std::sqrt(2.0), 0.03);
}

struct Turned {
    size_t camera;
    int64_t key;
};

TEST(CeresRigCornerOrder, ViewsNumberedFromTheOppositeCornerInOneCameraAreRenumbered) {
    const CalibrationTarget board = test::chessboard(12, 9, 0.03);
    // One pair; four pairs, some turned in the left camera; every view of an upside-down right
    // camera whose detector numbers from the image's top left.
    std::vector<std::vector<Turned>> cases = {{{1, 5}}, {{1, 2}, {0, 7}, {1, 11}, {0, 16}}, {}};
    for (int64_t key = 0; key < 18; ++key)
        cases.back().push_back({1, key});
    for (const std::vector<Turned>& turned : cases) {
        SCOPED_TRACE(std::to_string(turned.size()) + " views turned");
        std::mt19937 rng(21);
        std::vector<CameraViews> views = stereoViews(rng, board);
        for (const Turned& t : turned)
            turnCorners(views[t.camera].views[viewAt(views[t.camera], t.key)], board, 180);
        const Result<RigCalibration> rig = calibrateRig(views, stereoOptions());
        ASSERT_TRUE(rig) << rig.status().toString();
        expectRightRig(*rig);
        // Each turned pair renumbered once: in the camera it was turned in, or (where all of one
        // camera's views are turned) the other, the key's first camera keeping its order.
        size_t reordered = 0;
        for (const RigViewChange& change : rig->changes) {
            EXPECT_EQ(change.kind, RigViewChange::Kind::kReordered) << change.message;
            EXPECT_EQ(change.rotation_deg, 180);
            EXPECT_NE(change.message.find("turned by 180°"), std::string::npos) << change.message;
            const bool expected = std::any_of(turned.begin(), turned.end(),
                                              [&](const Turned& t) { return t.key == change.key; });
            EXPECT_TRUE(expected) << change.message;
            ++reordered;
        }
        EXPECT_EQ(reordered, turned.size());
    }
}

TEST(CeresRigCornerOrder, ASquareBoardTurnedByAQuarterIsRenumbered) {
    const CalibrationTarget board = test::chessboard(8, 8, 0.04);
    std::mt19937 rng(23);
    std::vector<CameraViews> views = stereoViews(rng, board);
    turnCorners(views[1].views[viewAt(views[1], 4)], board, 90);
    turnCorners(views[1].views[viewAt(views[1], 9)], board, 180);
    const Result<RigCalibration> rig = calibrateRig(views, stereoOptions());
    ASSERT_TRUE(rig) << rig.status().toString();
    expectRightRig(*rig);
    ASSERT_EQ(rig->changes.size(), 2u);
    EXPECT_EQ(rig->changes[0].key, 4);
    EXPECT_TRUE(rig->changes[0].rotation_deg == 90 || rig->changes[0].rotation_deg == 270);
    EXPECT_EQ(rig->changes[1].key, 9);
    EXPECT_EQ(rig->changes[1].rotation_deg, 180);
}

// Views of keys 0–17 seen by both cameras, with the board's poses in the reference frame.
std::vector<CameraViews> stereoViewsWithTruth(std::mt19937& rng,
                                              std::vector<Eigen::Isometry3d>& T_ref_board) {
    const std::vector<Camera> truth = stereoTruth();
    const CalibrationTarget board = test::chessboard(12, 9, 0.03);
    std::vector<CameraViews> views(2);
    for (size_t c = 0; c < 2; ++c) {
        views[c].camera = truth[c].name;
        views[c].width = truth[c].model.width;
        views[c].height = truth[c].model.height;
        views[c].target = board;
    }
    for (int key = 0; key < 18;) {
        const Eigen::Isometry3d T = test::randomBoardPose(truth[0].model, board, rng);
        if (test::visibleFraction(truth[1].model, board, truth[1].T_ref_camera.inverse() * T) < 0.8)
            continue;
        T_ref_board.push_back(T);
        for (size_t c = 0; c < 2; ++c)
            views[c].views.push_back(
                test::observe(truth[c].model, board, truth[c].T_ref_camera.inverse() * T, kNoisePx,
                              rng, key, truth[c].name + "/" + std::to_string(key)));
        ++key;
    }
    for (size_t c = 0; c < 2; ++c)
        for (int i = 0; i < 10; ++i)
            views[c].views.push_back(test::observe(
                truth[c].model, board, test::randomBoardPose(truth[c].model, board, rng), kNoisePx,
                rng, 1000 * static_cast<int64_t>(c + 1) + i, truth[c].name + "/solo"));
    return views;
}

// The right camera's view at `key` replaced by one of the board moved by `turn_deg` about its
// own x axis and `shift_m` along it, as a frame paired with the wrong instant shows.
void mispair(std::vector<CameraViews>& views, const std::vector<Eigen::Isometry3d>& T_ref_board,
             int64_t key, double turn_deg, double shift_m, std::mt19937& rng) {
    const Camera right = stereoTruth()[1];
    Eigen::Isometry3d moved = T_ref_board[static_cast<size_t>(key)];
    moved.translate(Eigen::Vector3d(shift_m, 0, 0));
    moved.rotate(Eigen::AngleAxisd(turn_deg * kDeg, Eigen::Vector3d::UnitX()));
    views[1].views[viewAt(views[1], key)] =
        test::observe(right.model, views[1].target, right.T_ref_camera.inverse() * moved, kNoisePx,
                      rng, key, "right/" + std::to_string(key) + "-mispaired");
}

size_t countChanges(const RigCalibration& rig, RigViewChange::Kind kind) {
    return static_cast<size_t>(
        std::count_if(rig.changes.begin(), rig.changes.end(),
                      [&](const RigViewChange& c) { return c.kind == kind; }));
}

TEST(CeresRigMismatch, AFewMispairedViewsAreDroppedNamingThem) {
    std::mt19937 rng(31);
    std::vector<Eigen::Isometry3d> T_ref_board;
    std::vector<CameraViews> views = stereoViewsWithTruth(rng, T_ref_board);
    // Far off (no board symmetry explains it: dropped before the solve), and slightly off (it
    // passes as the same instant, its residuals give it away).
    mispair(views, T_ref_board, 3, 25, 0.05, rng);
    mispair(views, T_ref_board, 12, 2, 0.01, rng);
    const Result<RigCalibration> rig = calibrateRig(views, stereoOptions());
    ASSERT_TRUE(rig) << rig.status().toString();
    expectRightRig(*rig);
    EXPECT_EQ(countChanges(*rig, RigViewChange::Kind::kReordered), 0u);
    std::set<int64_t> dropped_keys;
    for (const RigViewChange& change : rig->changes) {
        std::cout << change.message << "\n";
        EXPECT_EQ(change.kind, RigViewChange::Kind::kDropped);
        dropped_keys.insert(change.key);
    }
    EXPECT_EQ(dropped_keys, (std::set<int64_t>{3, 12}));
    const auto named = [&](const std::string& part) {
        return std::any_of(rig->changes.begin(), rig->changes.end(), [&](const RigViewChange& c) {
            return c.message.find(part) != std::string::npos;
        });
    };
    EXPECT_TRUE(named("right/3-mispaired")) << "the dropped view is named";
    EXPECT_TRUE(named("in every corner order")) << "key 3: no order explains it";
    EXPECT_TRUE(named("px RMS in the joint solve")) << "key 12: its residuals give it away";
}

TEST(CeresRigMismatch, MostViewsMispairedIsRefusedNotARig) {
    std::mt19937 rng(37);
    std::vector<Eigen::Isometry3d> T_ref_board;
    std::vector<CameraViews> views = stereoViewsWithTruth(rng, T_ref_board);
    // The right camera's frames one instant late: every shared key pairs different poses.
    std::vector<TargetView> late = views[1].views;
    for (int64_t key = 0; key < 18; ++key) {
        TargetView& view = views[1].views[viewAt(views[1], key)];
        view.corners = late[viewAt(views[1], (key + 1) % 18)].corners;
    }
    const Result<RigCalibration> rig = calibrateRig(views, stereoOptions());
    ASSERT_FALSE(rig) << "baseline " << rig->T_ref_camera[1].translation().norm() * 1e3 << " mm at "
                      << rig->rms_px << " px passed as a rig";
    expectInvalid(rig.status(), "disagree");
    std::cout << rig.status().message() << "\n";
}

TEST(CeresRigMismatch, AJointSolveFarWorseThanTheCamerasOwnIsRefused) {
    std::mt19937 rng(41);
    std::vector<Eigen::Isometry3d> T_ref_board;
    std::vector<CameraViews> views = stereoViewsWithTruth(rng, T_ref_board);
    mispair(views, T_ref_board, 6, 2, 0.01, rng);
    mispair(views, T_ref_board, 9, 2, -0.01, rng);
    RigOptions options = stereoOptions();
    options.view_outlier_ratio = 0;  // keep every view: the RMS check is the last guard
    const Result<RigCalibration> rig = calibrateRig(views, options);
    ASSERT_FALSE(rig) << "joint RMS " << rig->rms_px << " px passed as a rig";
    expectInvalid(rig.status(), "fits the joint solve at");
    std::cout << rig.status().message() << "\n";
}

TEST(CeresRigRefuses, BadCheckOptionsNamingTheField) {
    std::mt19937 rng(43);
    const std::vector<CameraViews> views = stereoViews(rng);
    RigOptions options = stereoOptions();
    options.max_rms_ratio = 0.5;
    expectInvalid(calibrateRig(views, options).status(), "max_rms_ratio");
    options = stereoOptions();
    options.view_outlier_ratio = 0.5;
    expectInvalid(calibrateRig(views, options).status(), "view_outlier_ratio");
    options = stereoOptions();
    options.rms_floor_px = 0;
    expectInvalid(calibrateRig(views, options).status(), "rms_floor_px");
    options = stereoOptions();
    options.max_dropped_fraction = 2;
    expectInvalid(calibrateRig(views, options).status(), "max_dropped_fraction");
}

INSTANTIATE_TEST_SUITE_P(RefineIntrinsics, CeresRig, ::testing::Bool());

}  // namespace
}  // namespace mixray::calibration
