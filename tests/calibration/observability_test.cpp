// calibrateCamera() judging its own result on rendered views (target_render.h): four ChArUco
// views tilted alike are weakly determined (refused naming the weak parameters, kept with
// accept_weak with their 1σ), well spread views are not; a chessboard declared one row and
// column smaller than printed is found as a sub-board, rejected and refused naming the size
// printed; an RMS far above a corner detector's accuracy is an error.
#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/core.hpp>
#include <random>
#include <string>
#include <vector>

#include "ceres_synthetic.h"
#include "detect_internal.h"
#include "mixray/calibration/calibrate.h"
#include "mixray/calibration/detect.h"
#include "target_render.h"

namespace mixray::calibration {
namespace {

using Eigen::Isometry3d;
using Eigen::Vector3d;

bool contains(const std::string& text, const std::string& part) {
    return text.find(part) != std::string::npos;
}

// The board `distance_m` ahead, tilted and turned (synth::boardPose), then moved by `shift_m`
// in the camera frame: the same orientation seen in another part of the image.
Isometry3d pose(const CalibrationTarget& target, double distance_m, double tilt_deg, double yaw_deg,
                const Vector3d& shift_m = Vector3d::Zero()) {
    Isometry3d T = synth::boardPose(target, distance_m, tilt_deg, yaw_deg);
    T.translation() += shift_m;
    return T;
}

// Renders of `printed` from `poses` through synth::testCamera(), searched for `declared`.
CameraViews renderedViews(const CalibrationTarget& printed, const CalibrationTarget& declared,
                          const std::vector<Isometry3d>& poses,
                          const DetectionOptions& detection = {}) {
    const CameraModel camera = synth::testCamera();
    CameraViews views;
    views.camera = "cam";
    views.width = camera.width;
    views.height = camera.height;
    views.target = declared;
    for (size_t i = 0; i < poses.size(); ++i) {
        const Image image = synth::renderTarget(camera, printed, poses[i]);
        Result<TargetView> view = detectTarget(image.view(), declared, detection);
        EXPECT_TRUE(view) << view.status().toString();
        if (!view)
            continue;
        view->source = "view" + std::to_string(i);
        view->key = static_cast<int64_t>(i);
        views.views.push_back(std::move(view).value());
    }
    return views;
}

CalibrationTarget charuco() {
    return *parseTarget("charuco:7x5:0.05:0.037:DICT_6X6_250");
}

// The case: four views, each tilted 21–25° to the optical axis, their boards within a
// few degrees of parallel, in different parts of the image.
std::vector<Isometry3d> nearlyParallelTilted(const CalibrationTarget& target) {
    return {pose(target, 0.6, 21, 1, Vector3d(-0.07, -0.05, 0)),
            pose(target, 0.6, 23, -1, Vector3d(0.07, -0.04, 0.05)),
            pose(target, 0.6, 25, 2, Vector3d(-0.06, 0.05, 0.1)),
            pose(target, 0.6, 22, 0, Vector3d(0.06, 0.05, -0.03))};
}

std::vector<Isometry3d> spreadTilted(const CalibrationTarget& target) {
    return {pose(target, 0.6, 25, 0, Vector3d(-0.05, -0.04, 0)),
            pose(target, 0.6, -25, 0, Vector3d(0.05, 0.04, 0)),
            pose(target, 0.6, 0, 25, Vector3d(0.05, -0.04, 0)),
            pose(target, 0.6, 0, -25, Vector3d(-0.05, 0.04, 0)),
            pose(target, 0.65, 20, 20, Vector3d(0, 0, 0)),
            pose(target, 0.65, -20, -20, Vector3d(0, 0, 0))};
}

TEST(Observability, FourViewsTiltedAlikeAreWeakRefusedWithoutAcceptWeakKeptWithIt) {
    const CalibrationTarget board = charuco();
    const CameraViews views = renderedViews(board, board, nearlyParallelTilted(board));
    ASSERT_EQ(views.usable().size(), 4u);

    CalibrationOptions options;
    const Result<CameraCalibration> refused = calibrateCamera(views, options);
    ASSERT_FALSE(refused);
    EXPECT_EQ(refused.status().code(), ErrorCode::kInvalidArgument);
    const std::string message = refused.status().message();
    EXPECT_TRUE(contains(message, "weakly determined intrinsics")) << message;
    EXPECT_TRUE(contains(message, "fx")) << message;
    EXPECT_TRUE(contains(message, "of the focal length")) << message;
    EXPECT_TRUE(contains(message, "accept-weak")) << message;
    // The cause, from the poses: the boards are nearly parallel.
    EXPECT_TRUE(contains(message, "lie within")) << message;

    options.accept_weak = true;
    const Result<CameraCalibration> kept = calibrateCamera(views, options);
    ASSERT_TRUE(kept) << kept.status().toString();
    const Observability& seen = kept->observability;
    ASSERT_FALSE(seen.weak.empty());
    EXPECT_EQ(seen.weak.front(), "fx");
    EXPECT_GT(seen.relative_stddev[0], options.max_relative_stddev);
    EXPECT_LT(seen.normal_spread_deg, 10.0);
    EXPECT_GT(seen.condition, 1.0);
    EXPECT_FALSE(seen.summary.empty());
    // The uncertainty reported is the covariance's (at the judged noise, at least as large).
    const Eigen::VectorXd stddev = kept->intrinsicsStddev();
    ASSERT_GE(stddev.size(), 4);
    EXPECT_GT(stddev[0], 0);
    EXPECT_LE(stddev[0] / kept->model.fx, seen.relative_stddev[0] * (1 + 1e-9));
    // Weak, but still the camera: the corners fit.
    EXPECT_LT(kept->rms_px, 0.3);
}

TEST(Observability, WellSpreadViewsAreNotWeak) {
    const CalibrationTarget board = charuco();
    const CameraViews views = renderedViews(board, board, spreadTilted(board));
    ASSERT_EQ(views.usable().size(), 6u);
    const Result<CameraCalibration> result = calibrateCamera(views, {});
    ASSERT_TRUE(result) << result.status().toString();
    const Observability& seen = result->observability;
    EXPECT_TRUE(seen.weak.empty()) << seen.summary;
    EXPECT_TRUE(seen.summary.empty());
    EXPECT_GT(seen.normal_spread_deg, 30.0);
    for (int k = 0; k < 4; ++k) {
        EXPECT_GT(seen.relative_stddev[k], 0);
        EXPECT_LT(seen.relative_stddev[k], 0.01) << k;
    }
    // Renders' corners are cleaner than a real detector's: judged at the floor.
    EXPECT_DOUBLE_EQ(seen.noise_px, CalibrationOptions{}.min_judged_noise_px);
    const CameraModel truth = synth::testCamera();
    EXPECT_NEAR(result->model.fx, truth.fx, 0.01 * truth.fx);
}

TEST(Observability, AChessboardDeclaredSmallerThanPrintedIsRefusedNamingItsSize) {
    const CalibrationTarget printed = test::chessboard(10, 7, 0.03);
    const CalibrationTarget declared = test::chessboard(9, 6, 0.03);
    const std::vector<Isometry3d> poses = {
        pose(printed, 0.6, 20, 0),    pose(printed, 0.6, -20, 10),  pose(printed, 0.65, 0, 25),
        pose(printed, 0.65, 10, -25), pose(printed, 0.7, -15, -15), pose(printed, 0.6, 25, 15)};

    // As printed: the margin beyond the outer corners is no X-junction.
    const CameraViews right = renderedViews(printed, printed, poses);
    for (const TargetView& view : right.views) {
        EXPECT_EQ(view.rejection, ViewRejection::kNone) << view.source << ": " << view.why;
        EXPECT_EQ(view.seen_cols, 0);
    }

    const CameraViews views = renderedViews(printed, declared, poses);
    int larger = 0;
    for (const TargetView& view : views.views) {
        if (view.rejection != ViewRejection::kLargerBoard)
            continue;
        ++larger;
        EXPECT_EQ(view.seen_cols, 10) << view.source << ": " << view.why;
        EXPECT_EQ(view.seen_rows, 7) << view.source << ": " << view.why;
        EXPECT_TRUE(contains(view.why, "looks 10x7")) << view.why;
    }
    EXPECT_GE(larger, 4) << "of " << views.views.size() << " views";
    const Result<CameraCalibration> result = calibrateCamera(views, {});
    ASSERT_FALSE(result);
    EXPECT_EQ(result.status().code(), ErrorCode::kInvalidArgument);
    EXPECT_TRUE(contains(result.status().message(), "looks like 10x7 inner corners, not 9x6"))
        << result.status().message();
    EXPECT_TRUE(contains(result.status().message(), "--target chessboard:10x7:0.03"))
        << result.status().message();
}

// The look beyond a grid found at the declared size, which catches a sub-board the classic
// detector or a partly hidden board gives: the 9x6 corners at either end of a found 10x7 grid.
TEST(Observability, TheGridIsFollowedBeyondASubBoardToTheBoardsSize) {
    const CalibrationTarget printed = test::chessboard(10, 7, 0.03);
    const CameraModel camera = synth::testCamera();
    for (const Isometry3d& T : {pose(printed, 0.6, 20, 0), pose(printed, 0.65, 10, -25)}) {
        const Image image = synth::renderTarget(camera, printed, T);
        const ImageView v = image.view();
        const cv::Mat grey(v.desc.height, v.desc.width, CV_8UC1, const_cast<uint8_t*>(v.data),
                           static_cast<size_t>(v.desc.stride_bytes));
        const Result<TargetView> whole = detectTarget(v, printed);
        ASSERT_TRUE(whole);
        ASSERT_EQ(whole->corners.size(), 70u) << whole->why;
        EXPECT_EQ(detail::chessboardBeyond(grey, whole->corners, 10, 7),
                  (std::array<int, 4>{0, 0, 0, 0}));
        // The sub-grids at the first and at the last corner, renumbered as a 9x6 board.
        for (const int offset : {0, 1}) {
            std::vector<Corner> sub;
            for (int r = 0; r < 6; ++r)
                for (int c = 0; c < 9; ++c) {
                    Corner corner =
                        whole->corners[static_cast<size_t>((r + offset) * 10 + c + offset)];
                    corner.id = r * 9 + c;
                    sub.push_back(corner);
                }
            const std::array<int, 4> beyond = detail::chessboardBeyond(grey, sub, 9, 6);
            const std::array<int, 4> expected =
                offset == 0 ? std::array<int, 4>{0, 1, 0, 1} : std::array<int, 4>{1, 0, 1, 0};
            EXPECT_EQ(beyond, expected) << "offset " << offset;
        }
    }
}

TEST(Observability, AnRmsFarAboveADetectorsAccuracyIsAnError) {
    CameraModel truth = CameraModel::pinhole(640, 480, 536.2, 538.9, 338.1, 237.4);
    truth.distortion = {-0.266, -0.039, 0.0018, -0.0003, 0.238};
    std::mt19937 rng(11);
    // Corners 3 px off at random: an RMS of about 4 px, twenty times a detector's.
    const CameraViews views =
        test::generateViews("cam", truth, test::chessboard(9, 6, 0.025), 20, 3.0, rng);
    CalibrationOptions options;
    options.outlier_sigma = 0;
    const Result<CameraCalibration> result = calibrateCamera(views, options);
    ASSERT_FALSE(result);
    EXPECT_EQ(result.status().code(), ErrorCode::kInvalidArgument);
    EXPECT_TRUE(contains(result.status().message(), "RMS reprojection error"))
        << result.status().message();
    EXPECT_TRUE(contains(result.status().message(), "limit 2.00 px")) << result.status().message();
    // The same corners are kept when the limit is lifted: only the RMS stopped them.
    options.max_rms_px = 0;
    options.accept_weak = true;
    const Result<CameraCalibration> lifted = calibrateCamera(views, options);
    ASSERT_TRUE(lifted) << lifted.status().toString();
    EXPECT_GT(lifted->rms_px, 2.0);
}

TEST(Observability, OptionsAreValidated) {
    const CalibrationTarget board = charuco();
    CameraViews views;
    views.camera = "cam";
    views.width = 640;
    views.height = 480;
    views.target = board;
    CalibrationOptions options;
    options.max_relative_stddev = 0;
    EXPECT_TRUE(
        contains(calibrateCamera(views, options).status().message(), "max_relative_stddev"));
    options = {};
    options.min_judged_noise_px = -1;
    EXPECT_TRUE(
        contains(calibrateCamera(views, options).status().message(), "min_judged_noise_px"));
    options = {};
    options.max_rms_px = NAN;
    EXPECT_TRUE(contains(calibrateCamera(views, options).status().message(), "max_rms_px"));
}

}  // namespace
}  // namespace mixray::calibration
