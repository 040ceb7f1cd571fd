// solveWithMrcal: generated chessboard views through known lenses are solved back to them, every
// CameraCalibration field is filled, and bad input is refused with its cause.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <set>
#include <utility>

#include "mrcal_test_support.h"
#include "solve_internal.h"

namespace mixray::calibration {
namespace {

using detail::solveWithMrcal;

using test::opencv8Truth;

CameraModel pinholeSeed(const CameraModel& truth) {
    // What a front end's seed looks like: a focal length 10 % off, the principal point at the
    // image centre, no distortion.
    return CameraModel::pinhole(truth.width, truth.height, truth.fx * 1.1, truth.fx * 1.1,
                                (truth.width - 1) / 2.0, (truth.height - 1) / 2.0);
}

TEST(MrcalSolverTest, HasTheModelsMrcalHas) {
    EXPECT_TRUE(detail::mrcalHasModel("opencv4"));
    EXPECT_TRUE(detail::mrcalHasModel("opencv5"));
    EXPECT_TRUE(detail::mrcalHasModel("opencv8"));
    EXPECT_TRUE(detail::mrcalHasModel("LENSMODEL_OPENCV8"));
    EXPECT_TRUE(
        detail::mrcalHasModel("LENSMODEL_SPLINED_STEREOGRAPHIC_order=3_Nx=16_Ny=12_fov_x_deg=120"));
    EXPECT_FALSE(detail::mrcalHasModel("fisheye"));
    EXPECT_FALSE(detail::mrcalHasModel("LENSMODEL_SPLINED_STEREOGRAPHIC_order=3_Nx=16"));
    EXPECT_FALSE(
        detail::mrcalHasModel("LENSMODEL_SPLINED_STEREOGRAPHIC_order=7_Nx=16_Ny=12_fov_x_deg=120"));
}

// mrcal's own outlier rejection runs inside the back end: the corners moved far off are the
// ones left out, the rest stay, and a corner the front end left out stays out.
TEST(MrcalSolverTest, RejectsTheCornersMrcalRejects) {
    const CameraModel truth = opencv8Truth();
    test::SyntheticViews data = test::syntheticViews(truth, test::mrcalChessboard(), 20, 0.3, 5);
    std::set<std::pair<size_t, int>> moved;
    for (size_t v = 0; v < data.views.views.size(); v += 2) {
        Corner& corner = data.views.views[v].corners[v % 7];
        corner.pixel += Eigen::Vector2d(4.0, -3.0);  // 5 px: ~17σ of the 0.3 px noise
        moved.insert({v, corner.id});
    }
    detail::SolveInput input = test::seededInput(data.views, pinholeSeed(truth));
    input.inlier[1][3] = false;
    CalibrationOptions options;
    options.model = "opencv8";
    auto result = solveWithMrcal(input, options);
    ASSERT_TRUE(result.isOk()) << result.status().toString();
    EXPECT_EQ(result->outliers, static_cast<int>(moved.size()) + 1);
    for (const PointResidual& r : result->residuals) {
        const bool expected = moved.count({r.view, r.id}) > 0 ||
                              (r.view == 1 && r.id == input.views->views[1].corners[3].id);
        EXPECT_EQ(r.outlier, expected) << "view " << r.view << " corner " << r.id;
    }
    EXPECT_NEAR(result->rms_px, 0.3 * std::sqrt(2.0), 0.03) << "the moved corners are out";

    options.outlier_sigma = 0;  // no rejection: only the front end's own outlier
    auto kept = solveWithMrcal(input, options);
    ASSERT_TRUE(kept.isOk()) << kept.status().toString();
    EXPECT_EQ(kept->outliers, 1);
    EXPECT_GT(kept->rms_px, result->rms_px);
}

TEST(MrcalSolverTest, Opencv8RecoversTheLens) {
    const CameraModel truth = opencv8Truth();
    const test::SyntheticViews data =
        test::syntheticViews(truth, test::mrcalChessboard(), 20, 0.3, 11);
    const detail::SolveInput input = test::seededInput(data.views, pinholeSeed(truth));
    CalibrationOptions options;
    options.model = "opencv8";
    auto result = solveWithMrcal(input, options);
    ASSERT_TRUE(result.isOk()) << result.status().toString();
    const CameraCalibration& c = *result;
    EXPECT_EQ(c.solver, Solver::kMrcal);
    EXPECT_EQ(c.camera, "synthetic");
    ASSERT_EQ(c.model.distortion.size(), 8u);
    EXPECT_TRUE(c.model.validate().isOk());
    // 0.3 px noise on 1400 corners: the core to a few tenths of a pixel; the projections,
    // where the boards were seen, to a fraction of the noise.
    EXPECT_NEAR(c.model.fx, truth.fx, 0.002 * truth.fx);
    EXPECT_NEAR(c.model.fy, truth.fy, 0.002 * truth.fy);
    EXPECT_NEAR(c.model.cx, truth.cx, 1.0);
    EXPECT_NEAR(c.model.cy, truth.cy, 1.0);
    // RMS of 2-D residuals of σ = 0.3 px per axis: σ√2 less the fitted degrees of freedom.
    EXPECT_NEAR(c.rms_px, 0.3 * std::sqrt(2.0), 0.03);
    ASSERT_EQ(c.views.size(), 20u);
    ASSERT_EQ(c.residuals.size(), 20u * 70u);
    EXPECT_EQ(c.outliers, 0);
    double sum2 = 0;
    for (const PointResidual& r : c.residuals) {
        EXPECT_FALSE(r.outlier);
        sum2 += r.residual.squaredNorm();
    }
    EXPECT_NEAR(std::sqrt(sum2 / c.residuals.size()), c.rms_px, 1e-9);
    for (size_t v = 0; v < c.views.size(); ++v) {
        EXPECT_EQ(c.views[v].view, v);
        EXPECT_EQ(c.views[v].corners, 70);
        EXPECT_GT(c.views[v].rms_px, 0.2);
        EXPECT_LT(c.views[v].rms_px, 0.7);
        const Eigen::Isometry3d error =
            data.T_camera_target[v].inverse() * c.views[v].T_camera_target;
        EXPECT_LT(error.translation().norm(), 0.003) << "view " << v;
        EXPECT_LT(Eigen::AngleAxisd(error.rotation()).angle(), 0.003) << "view " << v;
    }
    // The covariance: intrinsics then 6 per view, symmetric positive definite, and its focal
    // length sigma is of the size the fit's scatter implies (0.3 px over ~1400 corners).
    ASSERT_EQ(c.covariance.rows(), 12 + 6 * 20);
    ASSERT_EQ(c.covariance.cols(), 12 + 6 * 20);
    EXPECT_LT((c.covariance - c.covariance.transpose()).norm(), 1e-9 * c.covariance.norm());
    EXPECT_EQ(Eigen::LLT<Eigen::MatrixXd>(c.covariance).info(), Eigen::Success);
    const double sigma_fx = std::sqrt(c.covariance(0, 0));
    EXPECT_GT(sigma_fx, 0.01);
    EXPECT_LT(sigma_fx, 2.0);
    EXPECT_GT(std::abs(c.model.fx - truth.fx), 0.0);
    EXPECT_LT(std::abs(c.model.fx - truth.fx), 5 * sigma_fx);
}

TEST(MrcalSolverTest, OutliersPassedInStayOut) {
    const CameraModel truth = opencv8Truth();
    test::SyntheticViews data = test::syntheticViews(truth, test::mrcalChessboard(), 15, 0.2, 5);
    // Ten corners moved 20 px and flagged: the solve must not see them.
    detail::SolveInput input = test::seededInput(data.views, pinholeSeed(truth));
    for (int k = 0; k < 10; ++k) {
        data.views.views[static_cast<size_t>(k)].corners[7].pixel += Eigen::Vector2d(20, -20);
        input.inlier[static_cast<size_t>(k)][7] = false;
    }
    CalibrationOptions options;
    options.model = "opencv5";
    auto result = solveWithMrcal(input, options);
    ASSERT_TRUE(result.isOk()) << result.status().toString();
    EXPECT_EQ(result->outliers, 10);
    EXPECT_LT(result->rms_px, 0.35);
    int flagged = 0;
    for (const PointResidual& r : result->residuals) {
        if (r.outlier) {
            ++flagged;
            EXPECT_GT(r.residual.norm(), 25);
        }
    }
    EXPECT_EQ(flagged, 10);
    EXPECT_EQ(result->views[0].outliers, 1);
}

TEST(MrcalSolverTest, SplinedFitsAWideLens) {
    // mrcal's own cam0 lens resampled to a splined model (04_mrcal/cam0.splined) is too big a
    // problem for a unit test; a coarser grid over a 1280x704 image is the same model.
    CameraModel truth = opencv8Truth();
    const test::SyntheticViews data =
        test::syntheticViews(truth, test::mrcalChessboard(), 20, 0.2, 3);
    const detail::SolveInput input = test::seededInput(data.views, pinholeSeed(truth));
    CalibrationOptions options;
    options.model = "LENSMODEL_SPLINED_STEREOGRAPHIC_order=3_Nx=10_Ny=7_fov_x_deg=120";
    auto result = solveWithMrcal(input, options);
    ASSERT_TRUE(result.isOk()) << result.status().toString();
    const CameraCalibration& c = *result;
    EXPECT_EQ(c.model.lens, LensModel::kSplinedStereographic);
    EXPECT_EQ(c.model.spline, (SplineConfig{3, 10, 7, 120}));
    ASSERT_EQ(c.model.distortion.size(), 2u * 10u * 7u);
    EXPECT_NEAR(c.rms_px, 0.2 * std::sqrt(2.0), 0.03);
    // The splined core is fixed after the stereographic pre-solve: no variance there.
    ASSERT_EQ(c.covariance.rows(), 4 + 140 + 6 * 20);
    EXPECT_EQ(c.covariance(0, 0), 0.0);
    EXPECT_GT(c.covariance(4 + 70, 4 + 70), 0.0);
    // Where the boards were seen the two lenses image the same bundle of rays, up to the
    // rotation a splined model can absorb: the angles between the rays through pixels around the
    // centre agree.
    const Eigen::Vector2d centre((truth.width - 1) / 2.0, (truth.height - 1) / 2.0);
    const std::vector<Eigen::Vector2d> offsets = {
        {0, 0}, {300, 0}, {0, 200}, {-300, -200}, {400, 250}};
    for (size_t i = 1; i < offsets.size(); ++i) {
        const auto a_truth = truth.unproject(centre + offsets[0]);
        const auto b_truth = truth.unproject(centre + offsets[i]);
        const auto a_fit = c.model.unproject(centre + offsets[0]);
        const auto b_fit = c.model.unproject(centre + offsets[i]);
        ASSERT_TRUE(a_truth && b_truth && a_fit && b_fit);
        const double angle_truth = std::acos(a_truth->dot(*b_truth));
        const double angle_fit = std::acos(a_fit->dot(*b_fit));
        // 0.5 px at ~560 px focal length.
        EXPECT_NEAR(angle_fit, angle_truth, 0.5 / truth.fx) << "offset " << offsets[i].transpose();
    }
}

TEST(MrcalSolverTest, ASolvedSplinedSeedStaysPut) {
    // Seeding with a solution of the same configuration starts at the optimum: the solve keeps
    // its core (no stereographic pre-solve moves it) and returns the same lens.
    const CameraModel truth = opencv8Truth();
    const test::SyntheticViews data =
        test::syntheticViews(truth, test::mrcalChessboard(), 12, 0.2, 9);
    CalibrationOptions options;
    options.model = "LENSMODEL_SPLINED_STEREOGRAPHIC_order=3_Nx=8_Ny=6_fov_x_deg=120";
    auto first = solveWithMrcal(test::seededInput(data.views, pinholeSeed(truth)), options);
    ASSERT_TRUE(first.isOk()) << first.status().toString();
    detail::SolveInput again = test::seededInput(data.views, first->model);
    for (size_t v = 0; v < again.T_camera_target.size(); ++v)
        again.T_camera_target[v] = first->views[v].T_camera_target;
    auto second = solveWithMrcal(again, options);
    ASSERT_TRUE(second.isOk()) << second.status().toString();
    EXPECT_EQ(second->model.fx, first->model.fx);
    EXPECT_EQ(second->model.cx, first->model.cx);
    EXPECT_LT(test::maxProjectionDifferencePx(first->model, second->model, 32), 1e-3);
    EXPECT_NEAR(second->rms_px, first->rms_px, 1e-6);
}

TEST(MrcalSolverTest, RefusesWhatMrcalCannotSolve) {
    const CameraModel truth = opencv8Truth();
    const test::SyntheticViews data =
        test::syntheticViews(truth, test::mrcalChessboard(), 5, 0.2, 1);
    const detail::SolveInput input = test::seededInput(data.views, pinholeSeed(truth));
    CalibrationOptions options;
    options.model = "fisheye";
    auto fisheye = solveWithMrcal(input, options);
    ASSERT_FALSE(fisheye.isOk());
    EXPECT_EQ(fisheye.status().code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(fisheye.status().message().find("fisheye"), std::string::npos);

    CameraViews aprilgrid = data.views;
    aprilgrid.target.kind = TargetKind::kAprilGrid;
    detail::SolveInput april_input = input;
    april_input.views = &aprilgrid;
    options.model = "opencv5";
    auto april = solveWithMrcal(april_input, options);
    ASSERT_FALSE(april.isOk());
    EXPECT_NE(april.status().message().find("AprilGrid"), std::string::npos);

    detail::SolveInput short_inliers = input;
    short_inliers.inlier[2].pop_back();
    auto mismatched = solveWithMrcal(short_inliers, options);
    ASSERT_FALSE(mismatched.isOk());
    EXPECT_NE(mismatched.status().message().find("inlier"), std::string::npos);
}

}  // namespace
}  // namespace mixray::calibration
