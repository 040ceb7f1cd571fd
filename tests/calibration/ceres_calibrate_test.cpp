// calibrateCamera() through the Ceres back end on generated corners with ground truth: the
// intrinsics recovered within 0.2 % for every lens model, fx = fy kept, outliers dropped, the
// covariance against the spread of repeated solves, progress reports, the solver names, and
// every bad input refused naming its cause.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "ceres_synthetic.h"
#include "mixray/calibration/calibrate.h"

namespace mixray::calibration {
namespace {

constexpr double kNoisePx = 0.2;

CameraModel opencv5Truth() {
    CameraModel model = CameraModel::pinhole(640, 480, 536.2, 538.9, 338.1, 237.4);
    model.distortion = {-0.266, -0.039, 0.0018, -0.0003, 0.238};
    return model;
}

CameraModel opencv4Truth() {
    CameraModel model = CameraModel::pinhole(1280, 720, 910.4, 909.1, 648.2, 355.9);
    model.distortion = {0.0995, -0.206, 0.0075, 0.0034};
    return model;
}

CameraModel opencv8Truth() {
    // mrcal's test/data/cam0.opencv8 lens, at a quarter of its 4000x2200 resolution.
    CameraModel model = CameraModel::pinhole(1000, 550, 440.295, 440.313, 491.302, 271.755);
    model.distortion = {-0.01266, 0.03591, -0.000255, 0.000528,
                        0.01969,  0.01483, -0.05622,  0.05002};
    return model;
}

CameraModel fisheyeTruth() {
    CameraModel model = CameraModel::pinhole(1032, 778, 281.3, 282.0, 517.6, 386.2);
    model.lens = LensModel::kFisheye;
    model.distortion = {0.031, -0.012, 0.0021, -0.0004};
    return model;
}

CalibrationOptions options(const std::string& model, Solver solver = Solver::kCeres) {
    CalibrationOptions o;
    o.model = model;
    o.solver = solver;
    return o;
}

void expectIntrinsicsWithin(const CameraModel& solved, const CameraModel& truth, double relative) {
    EXPECT_NEAR(solved.fx, truth.fx, relative * truth.fx);
    EXPECT_NEAR(solved.fy, truth.fy, relative * truth.fy);
    EXPECT_NEAR(solved.cx, truth.cx, relative * truth.cx);
    EXPECT_NEAR(solved.cy, truth.cy, relative * truth.cy);
}

// The largest distance between the solved and true projections of directions inside the
// image (less a `margin` fraction at each border, where no board reached), pixels: what the
// distortion coefficients are for, whatever their correlations.
double worstProjectionError(const CameraModel& solved, const CameraModel& truth,
                            double margin = 0.1) {
    double worst = 0;
    for (int y = 0; y <= 10; ++y) {
        for (int x = 0; x <= 10; ++x) {
            const Eigen::Vector2d pixel(
                (margin + (1 - 2 * margin) * x / 10.0) * (truth.width - 1),
                (margin + (1 - 2 * margin) * y / 10.0) * (truth.height - 1));
            const auto ray = truth.unproject(pixel);
            if (!ray)
                continue;
            const auto projected = solved.project(*ray);
            worst = projected ? std::max(worst, (*projected - pixel).norm()) : 1e9;
        }
    }
    return worst;
}

struct Case {
    std::string model;
    CameraModel truth;
    int views;
};

TEST(CeresCalibrate, RecoversIntrinsicsOfEveryModelWithin0_2Percent) {
    const std::vector<Case> cases = {
        {"opencv4", opencv4Truth(), 25},
        {"opencv5", opencv5Truth(), 25},
        {"opencv8", opencv8Truth(), 25},
        {"fisheye", fisheyeTruth(), 20},
    };
    const CalibrationTarget board = test::chessboard(12, 9, 0.03);
    std::mt19937 rng(2024);
    for (const Case& c : cases) {
        SCOPED_TRACE(c.model);
        std::vector<Eigen::Isometry3d> poses;
        const CameraViews views =
            test::generateViews(c.model, c.truth, board, c.views, kNoisePx, rng, &poses);
        const Result<CameraCalibration> result = calibrateCamera(views, options(c.model));
        ASSERT_TRUE(result) << result.status().toString();
        EXPECT_EQ(result->solver, Solver::kCeres);
        EXPECT_EQ(result->camera, c.model);
        EXPECT_EQ(result->model.lens, c.truth.lens);
        ASSERT_EQ(result->model.distortion.size(), c.truth.distortion.size());
        expectIntrinsicsWithin(result->model, c.truth, 0.002);
        // The distortion as a whole: the projections agree over the image (mind that a
        // principal-point error within its σ of ~0.3 px shows here in full).
        EXPECT_LT(worstProjectionError(result->model, c.truth, 0.05), 1.0);
        // Noise of 0.2 px per coordinate: the residual vector's RMS length is 0.2·√2.
        EXPECT_NEAR(result->rms_px, kNoisePx * std::sqrt(2.0), 0.03);
        ASSERT_EQ(result->views.size(), views.views.size());
        size_t corners = 0;
        for (size_t v = 0; v < views.views.size(); ++v) {
            const ViewFit& fit = result->views[v];
            EXPECT_EQ(fit.view, v);
            EXPECT_EQ(fit.corners, static_cast<int>(views.views[v].corners.size()));
            EXPECT_LT((fit.T_camera_target.translation() - poses[v].translation()).norm(), 3e-3);
            EXPECT_LT(test::rotationErrorDeg(fit.T_camera_target, poses[v]), 0.3);
            corners += views.views[v].corners.size();
        }
        EXPECT_EQ(result->residuals.size(), corners);
        const Eigen::Index state =
            static_cast<Eigen::Index>(4 + c.truth.distortion.size() + 6 * views.views.size());
        EXPECT_EQ(result->covariance.rows(), state);
        EXPECT_EQ(result->covariance.cols(), state);
        // The truth lies within 4σ of the solution.
        const Eigen::VectorXd stddev = result->intrinsicsStddev();
        ASSERT_EQ(stddev.size(), static_cast<Eigen::Index>(4 + c.truth.distortion.size()));
        EXPECT_LT(std::abs(result->model.fx - c.truth.fx), 4 * stddev[0]);
        EXPECT_LT(std::abs(result->model.cy - c.truth.cy), 4 * stddev[3]);
    }
}

TEST(CeresCalibrate, AutoSolvesTheFisheyeWithCeres) {
    std::mt19937 rng(5);
    const CameraViews views = test::generateViews("env", fisheyeTruth(),
                                                  test::chessboard(10, 7, 0.03), 18, kNoisePx, rng);
    const Result<CameraCalibration> result =
        calibrateCamera(views, options("fisheye", Solver::kAuto));
    ASSERT_TRUE(result) << result.status().toString();
    EXPECT_EQ(result->solver, Solver::kCeres);
    expectIntrinsicsWithin(result->model, fisheyeTruth(), 0.002);
}

TEST(CeresCalibrate, AutoSolvesWhatMrcalHasWithMrcal) {
    std::mt19937 rng(6);
    const CameraViews pinhole = test::generateViews(
        "cam", opencv5Truth(), test::chessboard(12, 9, 0.03), 20, kNoisePx, rng);
    const Result<CameraCalibration> opencv =
        calibrateCamera(pinhole, options("opencv5", Solver::kAuto));
    ASSERT_TRUE(opencv) << opencv.status().toString();
    EXPECT_EQ(opencv->solver, Solver::kMrcal);
    expectIntrinsicsWithin(opencv->model, opencv5Truth(), 0.002);
    // fx = fy is Ceres' alone: kAuto takes Ceres for it.
    CalibrationOptions aspect = options("opencv5", Solver::kAuto);
    aspect.fix_aspect_ratio = true;
    const Result<CameraCalibration> tied = calibrateCamera(pinhole, aspect);
    ASSERT_TRUE(tied) << tied.status().toString();
    EXPECT_EQ(tied->solver, Solver::kCeres);

    // A splined model of a wide lens, seeded through the stereographic lens.
    const CameraViews wide = test::generateViews("env", fisheyeTruth(),
                                                 test::chessboard(12, 9, 0.03), 20, kNoisePx, rng);
    const Result<CameraCalibration> splined = calibrateCamera(
        wide,
        options("LENSMODEL_SPLINED_STEREOGRAPHIC_order=3_Nx=12_Ny=9_fov_x_deg=200", Solver::kAuto));
    ASSERT_TRUE(splined) << splined.status().toString();
    EXPECT_EQ(splined->solver, Solver::kMrcal);
    EXPECT_EQ(splined->model.lens, LensModel::kSplinedStereographic);
    EXPECT_LT(splined->rms_px, 0.35);
}

TEST(CeresCalibrate, FixAspectRatioKeepsFxEqualToFy) {
    CameraModel truth = opencv5Truth();
    truth.fy = truth.fx;
    std::mt19937 rng(9);
    const CameraViews views =
        test::generateViews("cam", truth, test::chessboard(9, 6, 0.025), 15, kNoisePx, rng);
    CalibrationOptions o = options("opencv5");
    o.fix_aspect_ratio = true;
    const Result<CameraCalibration> result = calibrateCamera(views, o);
    ASSERT_TRUE(result) << result.status().toString();
    EXPECT_EQ(result->model.fx, result->model.fy);
    expectIntrinsicsWithin(result->model, truth, 0.002);
    // fx and fy move as one: their covariance is one number.
    const Eigen::MatrixXd& cov = result->covariance;
    EXPECT_NEAR(cov(0, 1), cov(0, 0), 1e-9 * cov(0, 0));
    EXPECT_NEAR(cov(1, 1), cov(0, 0), 1e-9 * cov(0, 0));
}

TEST(CeresCalibrate, DropsOutliersAndStillRecoversTheIntrinsics) {
    const CameraModel truth = opencv5Truth();
    std::mt19937 rng(13);
    CameraViews views =
        test::generateViews("cam", truth, test::chessboard(12, 9, 0.03), 22, kNoisePx, rng);
    // Gross errors: misdetected corners 8 px off.
    std::vector<std::pair<size_t, int>> planted;
    for (size_t v = 0; v < views.views.size(); v += 3) {
        Corner& corner = views.views[v].corners[5];
        corner.pixel += Eigen::Vector2d(8, -6);
        planted.emplace_back(v, corner.id);
    }
    const Result<CameraCalibration> result = calibrateCamera(views, options("opencv5"));
    ASSERT_TRUE(result) << result.status().toString();
    for (const auto& [view, id] : planted) {
        const auto found =
            std::find_if(result->residuals.begin(), result->residuals.end(),
                         [&](const PointResidual& r) { return r.view == view && r.id == id; });
        ASSERT_NE(found, result->residuals.end());
        EXPECT_TRUE(found->outlier) << "view " << view << " corner " << id;
        EXPECT_GT(found->residual.norm(), 5.0);
    }
    // 3σ trimming also takes the far tail of the Gaussian noise, but little of it.
    EXPECT_GE(result->outliers, static_cast<int>(planted.size()));
    EXPECT_LT(result->outliers, static_cast<int>(planted.size()) + 20);
    expectIntrinsicsWithin(result->model, truth, 0.002);
    EXPECT_LT(result->rms_px, 0.3);

    // Without rejection the planted errors pull the fit.
    CalibrationOptions keep = options("opencv5");
    keep.outlier_sigma = 0;
    const Result<CameraCalibration> kept = calibrateCamera(views, keep);
    ASSERT_TRUE(kept) << kept.status().toString();
    EXPECT_EQ(kept->outliers, 0);
    EXPECT_GT(kept->rms_px, 0.5);
}

TEST(CeresCalibrate, CovarianceMatchesTheSpreadOfRepeatedSolves) {
    const CameraModel truth = opencv5Truth();
    const CalibrationTarget board = test::chessboard(10, 7, 0.03);
    std::mt19937 rng(17);
    std::vector<Eigen::Isometry3d> poses;
    for (int i = 0; i < 15; ++i)
        poses.push_back(test::randomBoardPose(truth, board, rng));
    CalibrationOptions o = options("opencv5");
    o.outlier_sigma = 0;
    constexpr int kRuns = 16;
    std::vector<Eigen::Vector4d> solved;
    Eigen::Vector4d predicted = Eigen::Vector4d::Zero();
    for (int run = 0; run < kRuns; ++run) {
        CameraViews views;
        views.camera = "cam";
        views.width = truth.width;
        views.height = truth.height;
        views.target = board;
        for (size_t i = 0; i < poses.size(); ++i)
            views.views.push_back(
                test::observe(truth, board, poses[i], kNoisePx, rng, static_cast<int64_t>(i), "v"));
        const Result<CameraCalibration> result = calibrateCamera(views, o);
        ASSERT_TRUE(result) << result.status().toString();
        solved.emplace_back(result->model.fx, result->model.fy, result->model.cx, result->model.cy);
        predicted += result->intrinsicsStddev().head<4>() / kRuns;
    }
    Eigen::Vector4d mean = Eigen::Vector4d::Zero();
    for (const Eigen::Vector4d& s : solved)
        mean += s / kRuns;
    Eigen::Vector4d spread = Eigen::Vector4d::Zero();
    for (const Eigen::Vector4d& s : solved)
        spread += (s - mean).cwiseAbs2() / (kRuns - 1);
    spread = spread.cwiseSqrt();
    // 16 samples estimate a standard deviation to about ±18 % (1σ); allow a factor 1.7.
    for (int i = 0; i < 4; ++i) {
        EXPECT_GT(spread[i], predicted[i] / 1.7) << "parameter " << i;
        EXPECT_LT(spread[i], predicted[i] * 1.7) << "parameter " << i;
    }
}

TEST(CeresCalibrate, ReportsProgressFromStartToEnd) {
    std::mt19937 rng(21);
    const CameraViews views = test::generateViews("cam", opencv5Truth(),
                                                  test::chessboard(9, 6, 0.025), 10, kNoisePx, rng);
    // Both back ends: the mrcal one reports stages of its own within the front end's.
    for (Solver solver : {Solver::kCeres, Solver::kMrcal}) {
        SCOPED_TRACE(std::string(toString(solver)));
        std::vector<double> fractions;
        std::vector<std::string> stages;
        CalibrationOptions o = options("opencv5", solver);
        o.progress = [&](double fraction, std::string_view stage) {
            fractions.push_back(fraction);
            stages.emplace_back(stage);
        };
        ASSERT_TRUE(calibrateCamera(views, o));
        ASSERT_GE(fractions.size(), 3u);
        EXPECT_EQ(fractions.front(), 0.0);
        EXPECT_EQ(fractions.back(), 1.0);
        EXPECT_TRUE(std::is_sorted(fractions.begin(), fractions.end()));
        EXPECT_NE(std::find(stages.begin(), stages.end(), "solving"), stages.end());
        for (const std::string& stage : stages)
            EXPECT_FALSE(stage.empty());
    }
}

TEST(CeresCalibrate, SolverNamesRoundTrip) {
    for (Solver solver : {Solver::kAuto, Solver::kCeres, Solver::kMrcal})
        EXPECT_EQ(solverFromString(toString(solver)), solver);
    EXPECT_EQ(toString(Solver::kCeres), "ceres");
    EXPECT_EQ(toString(Solver::kMrcal), "mrcal");
    EXPECT_EQ(toString(Solver::kAuto), "auto");
    EXPECT_FALSE(solverFromString("Ceres"));
    EXPECT_FALSE(solverFromString(""));
}

TEST(CeresCalibrate, IntrinsicsStddevIsTheRootOfTheCovarianceDiagonal) {
    CameraCalibration calibration;
    calibration.model = CameraModel::pinhole(640, 480, 500, 500, 320, 240);
    calibration.model.distortion = {0, 0, 0, 0};
    calibration.covariance = Eigen::MatrixXd::Identity(14, 14);
    for (int i = 0; i < 14; ++i)
        calibration.covariance(i, i) = (i + 1) * (i + 1);
    const Eigen::VectorXd stddev = calibration.intrinsicsStddev();
    ASSERT_EQ(stddev.size(), 8);
    for (int i = 0; i < 8; ++i)
        EXPECT_DOUBLE_EQ(stddev[i], i + 1);
}

// ---- bad input ----

Status calibrateStatus(const CameraViews& views, const CalibrationOptions& o) {
    return calibrateCamera(views, o).status();
}

CameraViews goodViews(int count = 8) {
    std::mt19937 rng(31);
    return test::generateViews("left", opencv5Truth(), test::chessboard(9, 6, 0.025), count,
                               kNoisePx, rng);
}

void expectInvalid(const Status& status, const std::string& cause) {
    EXPECT_EQ(status.code(), ErrorCode::kInvalidArgument) << status.toString();
    EXPECT_NE(status.message().find(cause), std::string::npos)
        << "'" << status.message() << "' does not name '" << cause << "'";
    EXPECT_NE(status.message().find("left"), std::string::npos) << status.message();
}

TEST(CeresCalibrate, RefusesTooFewViewsSayingWhyTheOthersWereLeftOut) {
    CameraViews views = goodViews(6);
    views.views[0].rejection = ViewRejection::kNoTarget;
    views.views[1].rejection = ViewRejection::kNoTarget;
    views.views[2].corners.resize(5);
    const Status status = calibrateStatus(views, options("opencv5"));
    expectInvalid(status, "too few usable views: 3 of 6, need 4");
    EXPECT_NE(status.message().find("2 " + std::string(toString(ViewRejection::kNoTarget))),
              std::string::npos)
        << status.message();
    EXPECT_NE(status.message().find("too few corners"), std::string::npos) << status.message();
}

TEST(CeresCalibrate, RefusesCornersOutsideTheImageAsMismatchedSizes) {
    CameraViews views = goodViews();
    views.width = 320;  // the corners were found in 640x480 images
    views.height = 240;
    expectInvalid(calibrateStatus(views, options("opencv5")), "mismatched image sizes");
}

TEST(CeresCalibrate, RefusesFrontoParallelViews) {
    const CameraModel truth = opencv5Truth();
    const CalibrationTarget board = test::chessboard(9, 6, 0.025);
    CameraViews views;
    views.camera = "left";
    views.width = truth.width;
    views.height = truth.height;
    views.target = board;
    std::mt19937 rng(37);
    for (int i = 0; i < 8; ++i) {
        Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
        T.translation() = Eigen::Vector3d(-0.12 + 0.02 * i, -0.07 + 0.01 * (i % 3), 0.5 + 0.05 * i);
        views.views.push_back(test::observe(truth, board, T, kNoisePx, rng, i, "v"));
    }
    // Judged from the solve: exactly fronto-parallel views leave the focal length undetermined
    // (a singular covariance), and the poses say why.
    const Status status = calibrateStatus(views, options("opencv5"));
    expectInvalid(status, "covariance is singular");
    EXPECT_NE(status.message().find("the board normals of all 8 views lie within"),
              std::string::npos)
        << status.message();
    // No uncertainty to keep them with: accept_weak does not make them a result.
    CalibrationOptions o = options("opencv5");
    o.accept_weak = true;
    expectInvalid(calibrateStatus(views, o), "covariance is singular");
}

TEST(CeresCalibrate, RefusesUnknownModelsAndModelsTheSolverLacks) {
    const CameraViews views = goodViews();
    expectInvalid(calibrateStatus(views, options("opencv6")), "unknown lens model 'opencv6'");
    expectInvalid(calibrateStatus(views, options("fisheye", Solver::kMrcal)),
                  "mrcal solver does not have lens model 'fisheye'");
    expectInvalid(
        calibrateStatus(views, options("LENSMODEL_SPLINED_STEREOGRAPHIC_order=3_Nx=16_Ny=12_"
                                       "fov_x_deg=120")),
        "Ceres solver does not have lens model 'LENSMODEL_SPLINED");
    CalibrationOptions aspect = options("opencv5", Solver::kMrcal);
    aspect.fix_aspect_ratio = true;
    expectInvalid(calibrateStatus(views, aspect), "fix_aspect_ratio");
}

TEST(CeresCalibrate, RefusesCornersOffTheTarget) {
    CameraViews views = goodViews();
    views.views[3].corners[0].id = 999;
    expectInvalid(calibrateStatus(views, options("opencv5")), "corner id 999");
    views = goodViews();
    views.views[3].corners[1].id = views.views[3].corners[0].id;
    expectInvalid(calibrateStatus(views, options("opencv5")), "appears twice");
}

}  // namespace
}  // namespace mixray::calibration
