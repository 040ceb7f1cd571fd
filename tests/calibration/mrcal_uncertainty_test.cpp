// projectionUncertainty(): closed forms for both gradient paths (mrcal's analytic one and the
// numeric one of lenses mrcal lacks), its scaling, where it is small, and its input checks. The
// agreement with mrcal's Python implementation is in mrcal_cli_test.cpp.
#include <gtest/gtest.h>

#include <cmath>

#include "mrcal_test_support.h"

namespace mixray::calibration {
namespace {

CameraCalibration withOnlyFocalLengthVariance(CameraModel model, double sigma_fx, int views) {
    CameraCalibration c;
    c.model = std::move(model);
    const Eigen::Index n = 4 + static_cast<Eigen::Index>(c.model.distortion.size()) + 6 * views;
    c.covariance = Eigen::MatrixXd::Zero(n, n);
    c.covariance(0, 0) = sigma_fx * sigma_fx;
    for (int v = 0; v < views; ++v) {
        ViewFit fit;
        fit.view = static_cast<size_t>(v);
        fit.T_camera_target.translation() = Eigen::Vector3d(0.1 * v, 0, 1);
        c.views.push_back(fit);
    }
    return c;
}

TEST(ProjectionUncertaintyTest, FocalLengthAloneMovesPixelsInProportionToTheirOffset) {
    // With only fx uncertain, q_x = fx·x_d + cx moves by σ·x_d = σ·(q_x − cx)/fx for every lens
    // that distorts before the focal length: the OpenCV lens (mrcal's gradients) and the
    // Kannala–Brandt one (numeric gradients).
    CameraModel opencv = CameraModel::pinhole(640, 480, 500, 505, 319.5, 239.5);
    opencv.distortion = {-0.2, 0.05, 0.001, -0.001, 0.01};
    CameraModel fisheye = CameraModel::pinhole(640, 480, 300, 300, 319.5, 239.5);
    fisheye.lens = LensModel::kFisheye;
    fisheye.distortion = {0.01, -0.002, 0.0005, -0.0001};
    for (const CameraModel& model : {opencv, fisheye}) {
        SCOPED_TRACE(model.lensName());
        const double sigma = 0.5;
        for (double distance : {0.0, 2.0}) {
            auto map =
                projectionUncertainty(withOnlyFocalLengthVariance(model, sigma, 3), 40, distance);
            ASSERT_TRUE(map.isOk()) << map.status().toString();
            EXPECT_EQ(map->cols, 16);  // 0, 40, ..., 600
            EXPECT_EQ(map->rows, 12);  // 0, 40, ..., 440
            for (int row = 0; row < map->rows; ++row) {
                for (int col = 0; col < map->cols; ++col) {
                    const double expected = sigma * std::abs(col * 40 - model.cx) / model.fx;
                    EXPECT_NEAR(map->at(col, row), expected, 1e-5 + 1e-5 * expected)
                        << col << "," << row;
                }
            }
        }
    }
}

TEST(ProjectionUncertaintyTest, ScalesWithTheNoiseAndIsSmallestWhereTheBoardsWere) {
    const CameraModel truth = [] {
        CameraModel m = CameraModel::pinhole(1280, 704, 563.578, 563.600, 628.876, 347.846);
        m.distortion = {-0.0127, 0.0359, -0.00025, 0.00053, 0.0197};
        return m;
    }();
    const CalibrationTarget board = test::mrcalChessboard();
    const test::SyntheticViews data = test::syntheticViews(truth, board, 15, 0.3, 8);
    CalibrationOptions options;
    options.model = "opencv5";
    auto solved = detail::solveWithMrcal(test::seededInput(data.views, truth), options);
    ASSERT_TRUE(solved.isOk()) << solved.status().toString();
    auto map = projectionUncertainty(*solved, 64, 0);
    ASSERT_TRUE(map.isOk()) << map.status().toString();
    CameraCalibration noisier = *solved;
    noisier.covariance *= 4;
    auto doubled = projectionUncertainty(noisier, 64, 0);
    ASSERT_TRUE(doubled.isOk());
    float smallest = INFINITY, largest = 0;
    for (size_t k = 0; k < map->stddev_px.size(); ++k) {
        ASSERT_TRUE(std::isfinite(map->stddev_px[k]));
        EXPECT_NEAR(doubled->stddev_px[k], 2 * map->stddev_px[k], 1e-5 * map->stddev_px[k]);
        smallest = std::min(smallest, map->stddev_px[k]);
        largest = std::max(largest, map->stddev_px[k]);
    }
    // The boards cover the middle of the image: there a calibration from 1000 corners at
    // 0.3 px pins projection (at infinity, beyond the boards' ~1 m) under the noise; the image
    // corners are extrapolated.
    const float centre = map->at(map->cols / 2, map->rows / 2);
    EXPECT_LT(centre, 0.2f);
    EXPECT_LT(smallest, 0.2f);
    EXPECT_GT(largest, 3 * centre);
    EXPECT_GT(map->at(0, 0), centre);
}

TEST(ProjectionUncertaintyTest, RefusesAMismatchedCovariance) {
    CameraCalibration c =
        withOnlyFocalLengthVariance(CameraModel::pinhole(640, 480, 500, 500, 319.5, 239.5), 1.0, 2);
    c.covariance = Eigen::MatrixXd::Identity(10, 10);
    auto map = projectionUncertainty(c, 20, 0);
    ASSERT_FALSE(map.isOk());
    EXPECT_EQ(map.status().code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(map.status().message().find("expected 16"), std::string::npos)
        << map.status().message();
    c = withOnlyFocalLengthVariance(CameraModel::pinhole(640, 480, 500, 500, 319.5, 239.5), 1, 2);
    EXPECT_FALSE(projectionUncertainty(c, 0, 0).isOk());
    EXPECT_FALSE(projectionUncertainty(c, 20, -1).isOk());
}

}  // namespace
}  // namespace mixray::calibration
