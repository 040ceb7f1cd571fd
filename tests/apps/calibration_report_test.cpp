// The calibration report's pictures and tables (apps/src/calibration_report.cpp), from
// calibrations filled by hand: arrows where residuals are, outliers marked, legends drawn,
// coverage cells, labelled uncertainty contours at the right radius, frusta where cameras are.
#include "calibration_report.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>

#include "test_data.h"

namespace mixray::cli {
namespace {

namespace fs = std::filesystem;
using calibration::CameraCalibration;
using calibration::PointResidual;

cv::Vec3b viridis(double fraction) {
    cv::Mat ramp(1, 1, CV_8U, cv::Scalar(std::lround(std::clamp(fraction, 0.0, 1.0) * 255)));
    cv::Mat out;
    cv::applyColorMap(ramp, out, cv::COLORMAP_VIRIDIS);
    return out.at<cv::Vec3b>(0, 0);
}

bool near(const cv::Vec3b& a, const cv::Vec3b& b, int tolerance = 2) {
    for (int i = 0; i < 3; ++i) {
        if (std::abs(a[i] - b[i]) > tolerance)
            return false;
    }
    return true;
}

bool isWhite(const cv::Vec3b& c) {
    return c == cv::Vec3b(255, 255, 255);
}

CameraCalibration camera() {
    CameraCalibration c;
    c.camera = "kinect/color";
    c.model = calibration::CameraModel::pinhole(640, 480, 500, 500, 319.5, 239.5);
    c.rms_px = 0.1;
    return c;
}

PointResidual residual(size_t view, double u, double v, double du, double dv, bool outlier) {
    PointResidual r;
    r.view = view;
    r.observed = {u, v};
    r.residual = {du, dv};
    r.outlier = outlier;
    return r;
}

TEST(CalibrationReport, ResidualArrowsWhereResidualsAre) {
    const fs::path dir = test::tempDir();
    CameraCalibration c = camera();
    c.residuals = {residual(0, 100, 100, 1.5, 0, false), residual(0, 300, 300, 0, -0.5, false),
                   residual(1, 500, 400, 3, 3, true)};
    c.outliers = 1;
    const fs::path png = dir / "residuals.png";
    ASSERT_TRUE(writeResidualPlot(png, c, 20).isOk());
    const cv::Mat m = cv::imread(png.string());
    ASSERT_FALSE(m.empty());
    const ImagePlotLayout layout = imagePlotLayout(640, 480);
    EXPECT_EQ(layout.scale, 1.0);
    EXPECT_EQ(m.cols, 640);
    EXPECT_EQ(m.rows, 480 + layout.legend_px);
    // The 1.5 px residual at (100, 100), 20 times: an arrow along the row to x = 130, in the
    // colour of the longest inlier (the top of the bar, 0.85 up the palette).
    for (int x = 102; x <= 126; ++x)
        EXPECT_TRUE(near(m.at<cv::Vec3b>(100, x), viridis(0.85), 40))
            << x << " " << m.at<cv::Vec3b>(100, x);
    EXPECT_TRUE(isWhite(m.at<cv::Vec3b>(100, 140)));
    EXPECT_TRUE(isWhite(m.at<cv::Vec3b>(110, 115)));  // nothing off the arrow
    // The 0.5 px one points up from (300, 300) to y = 290, in the colour of a third of the bar.
    EXPECT_FALSE(isWhite(m.at<cv::Vec3b>(295, 300)));
    EXPECT_TRUE(near(m.at<cv::Vec3b>(295, 300), viridis(0.85 / 3), 40))
        << m.at<cv::Vec3b>(295, 300);
    EXPECT_TRUE(isWhite(m.at<cv::Vec3b>(305, 300)));
    // The outlier: red, with a cross at the observed point.
    int red = 0;
    for (int y = 394; y <= 406; ++y) {
        for (int x = 494; x <= 506; ++x) {
            const cv::Vec3b p = m.at<cv::Vec3b>(y, x);
            red += p[2] > 200 && p[1] < 60 && p[0] < 60;
        }
    }
    EXPECT_GT(red, 15);
    // The legend's colour bar runs from the palette's bottom to its top.
    const int bar_y = 480 + 8 + 7;
    EXPECT_TRUE(near(m.at<cv::Vec3b>(bar_y, 11), viridis(0.0), 6)) << m.at<cv::Vec3b>(bar_y, 11);
    EXPECT_TRUE(near(m.at<cv::Vec3b>(bar_y, 409), viridis(0.85), 6)) << m.at<cv::Vec3b>(bar_y, 409);
    // Its caption and labels: ink below the bar.
    int ink = 0;
    for (int y = bar_y + 10; y < m.rows; ++y) {
        for (int x = 0; x < 400; ++x)
            ink += m.at<cv::Vec3b>(y, x)[0] < 128;
    }
    EXPECT_GT(ink, 200);
}

TEST(CalibrationReport, ResidualPlotErrors) {
    const fs::path dir = test::tempDir();
    CameraCalibration c = camera();
    EXPECT_EQ(writeResidualPlot(dir / "r.png", c).code(), ErrorCode::kInvalidArgument);
    c.residuals = {residual(0, 100, 100, 1, 0, false)};
    const Status s = writeResidualPlot(dir / "no/such/dir/r.png", c);
    EXPECT_EQ(s.code(), ErrorCode::kIoError);
    EXPECT_NE(s.message().find("no/such/dir/r.png"), std::string::npos);
    // The automatic arrow scale: 5 % of 640 px for the 1 px residual, rounded down to 20.
    ASSERT_TRUE(writeResidualPlot(dir / "auto.png", c).isOk());
    const cv::Mat m = cv::imread((dir / "auto.png").string());
    EXPECT_FALSE(isWhite(m.at<cv::Vec3b>(100, 115)));
    EXPECT_TRUE(isWhite(m.at<cv::Vec3b>(100, 130)));
}

TEST(CalibrationReport, CoverageCountsCornersPerCell) {
    const fs::path dir = test::tempDir();
    CameraCalibration c = camera();
    // Corners in the left half only, three in cell (0, 0) and one in cell (2, 1).
    for (double u : {5.0, 15.0, 25.0})
        c.residuals.push_back(residual(0, u, 5, 0.1, 0, false));
    c.residuals.push_back(residual(1, 95, 45, 0.1, 0, true));
    const fs::path png = dir / "coverage.png";
    ASSERT_TRUE(writeCoverageMap(png, c, 40).isOk());
    const cv::Mat m = cv::imread(png.string());
    ASSERT_FALSE(m.empty());
    EXPECT_TRUE(near(m.at<cv::Vec3b>(30, 30), viridis(1.0)));       // 3 of 3
    EXPECT_TRUE(near(m.at<cv::Vec3b>(70, 110), viridis(1.0 / 3)));  // 1 of 3
    EXPECT_EQ(m.at<cv::Vec3b>(300, 500), cv::Vec3b(0, 0, 0));       // none
    EXPECT_EQ(m.at<cv::Vec3b>(70, 30), cv::Vec3b(0, 0, 0));
    EXPECT_TRUE(isWhite(m.at<cv::Vec3b>(5, 15)));  // the corner itself, a white dot
    EXPECT_EQ(writeCoverageMap(png, c, 0).code(), ErrorCode::kInvalidArgument);
}

TEST(CalibrationReport, UncertaintyLevels) {
    EXPECT_EQ(uncertaintyLevels(0.1, 3.65), (std::vector<double>{0.2, 0.5, 1, 2}));
    EXPECT_EQ(uncertaintyLevels(0.1, 3.65, 2), (std::vector<double>{1, 2}));
    EXPECT_EQ(uncertaintyLevels(0.03, 0.3), (std::vector<double>{0.05, 0.1, 0.2}));
    EXPECT_TRUE(uncertaintyLevels(1, 1).empty());
}

TEST(CalibrationReport, UncertaintyContoursAtTheirLevels) {
    const fs::path dir = test::tempDir();
    calibration::UncertaintyMap map;
    map.cols = 33;
    map.rows = 25;
    map.step_px = 20;
    // 0.1 px at the centre, growing with the square of the distance: the level-L contour is a
    // circle of radius 300 · sqrt((L − 0.1) / 2).
    for (int r = 0; r < map.rows; ++r) {
        for (int col = 0; col < map.cols; ++col) {
            const double d = std::hypot(col * 20 - 319.5, r * 20 - 239.5);
            map.stddev_px.push_back(static_cast<float>(0.1 + 2 * (d / 300) * (d / 300)));
        }
    }
    const fs::path png = dir / "uncertainty.png";
    ASSERT_TRUE(writeUncertaintyMap(png, map, 640, 480).isOk());
    const cv::Mat m = cv::imread(png.string());
    ASSERT_FALSE(m.empty());
    // Levels 0.2, 0.5, 1 and 2; the colour scale runs to 2.
    EXPECT_TRUE(near(m.at<cv::Vec3b>(240, 320), viridis(0.1 / 2), 3)) << m.at<cv::Vec3b>(240, 320);
    for (double level : {0.5, 1.0}) {
        SCOPED_TRACE(level);
        const double radius = 300 * std::sqrt((level - 0.1) / 2);
        // Below the centre (labels sit elsewhere on the contour): a white contour pixel within
        // 2 px of the radius, and none well inside it.
        bool found = false;
        for (int dy = -2; dy <= 2; ++dy) {
            const int y = static_cast<int>(std::lround(239.5 + radius)) + dy;
            found |= isWhite(m.at<cv::Vec3b>(y, 320));
        }
        EXPECT_TRUE(found);
        EXPECT_FALSE(isWhite(m.at<cv::Vec3b>(static_cast<int>(239.5 + radius - 8), 320)));
    }
    // Labels: dark text on white halos somewhere on the picture beside the contours.
    int dark = 0;
    for (int y = 0; y < 480; ++y) {
        for (int x = 0; x < 640; ++x) {
            const cv::Vec3b p = m.at<cv::Vec3b>(y, x);
            dark += p[0] < 60 && p[1] < 60 && p[2] < 60;
        }
    }
    EXPECT_GT(dark, 40);
    // The legend bar.
    EXPECT_TRUE(near(m.at<cv::Vec3b>(480 + 15, 409), viridis(1.0), 6));

    calibration::UncertaintyMap broken = map;
    broken.stddev_px.pop_back();
    EXPECT_EQ(writeUncertaintyMap(png, broken, 640, 480).code(), ErrorCode::kInvalidArgument);
    EXPECT_EQ(writeUncertaintyMap(dir / "no/dir/u.png", map, 640, 480).code(), ErrorCode::kIoError);
}

TEST(CalibrationReport, RigDiagramDrawsEachCameraWhereItIs) {
    const fs::path dir = test::tempDir();
    calibration::RigCalibration rig;
    rig.reference = "kinect/color";
    rig.cameras = {camera(), camera()};
    rig.cameras[1].camera = "env/color";
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    rig.T_ref_camera.push_back(T);
    // 0.3 m to the right, 0.1 m down, turned 90° to look along the reference's +x.
    T.translation() = Eigen::Vector3d(0.3, 0.1, 0);
    T.linear() = Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitY()).toRotationMatrix();
    rig.T_ref_camera.push_back(T);
    rig.pose_covariance.resize(2, Eigen::Matrix<double, 6, 6>::Zero());
    const fs::path png = dir / "rig.png";
    ASSERT_TRUE(writeRigDiagram(png, rig).isOk());
    const cv::Mat m = cv::imread(png.string());
    ASSERT_FALSE(m.empty());
    const RigDiagramLayout l = rigDiagramLayout(rig);
    EXPECT_EQ(m.cols, l.width);
    EXPECT_EQ(m.rows, l.height);
    auto pixel = [&](const Eigen::Vector2d& p) {
        return m.at<cv::Vec3b>(static_cast<int>(std::lround(p.y())),
                               static_cast<int>(std::lround(p.x())));
    };
    auto dark = [](const cv::Vec3b& c) { return c[0] < 100 && c[1] < 100 && c[2] < 100; };
    auto blue = [](const cv::Vec3b& c) { return c[0] > 150 && c[1] < 110 && c[2] < 110; };
    auto red = [](const cv::Vec3b& c) { return c[2] > 150 && c[1] < 110 && c[0] < 110; };
    const double d = l.frustum_depth_m;
    for (size_t i = 0; i < 2; ++i) {
        SCOPED_TRACE(i);
        const Eigen::Isometry3d& Ti = rig.T_ref_camera[i];
        // The centre dot in both views.
        EXPECT_TRUE(dark(pixel(l.top(Ti.translation()))));
        EXPECT_TRUE(dark(pixel(l.side(Ti.translation()))));
        // The optical axis (z, blue) and x (red) part-way along, in the top view.
        EXPECT_TRUE(blue(pixel(l.top(Ti * Eigen::Vector3d(0, 0, 0.3 * d)))))
            << pixel(l.top(Ti * Eigen::Vector3d(0, 0, 0.3 * d)));
        EXPECT_TRUE(red(pixel(l.top(Ti * Eigen::Vector3d(0.3 * d, 0, 0)))));
        // The frustum's far edge midpoint (image centre ray at the frustum depth) is inked.
        const Eigen::Vector2d edge = l.top(Ti * Eigen::Vector3d(0, 0, d));
        bool inked = false;
        for (int dy = -2; dy <= 2; ++dy) {
            for (int dx = -2; dx <= 2; ++dx)
                inked |= dark(pixel(edge + Eigen::Vector2d(dx, dy)));
        }
        EXPECT_TRUE(inked);
    }
    // In the top view the second camera is 0.3 m to the right of the first; in the side view
    // 0.1 m below it.
    EXPECT_NEAR(l.top(rig.T_ref_camera[1].translation()).x() - l.top(Eigen::Vector3d::Zero()).x(),
                0.3 * l.px_per_m, 1e-9);
    EXPECT_NEAR(l.side(rig.T_ref_camera[1].translation()).y() - l.side(Eigen::Vector3d::Zero()).y(),
                0.1 * l.px_per_m, 1e-9);
    EXPECT_GT(l.side(Eigen::Vector3d::Zero()).x(), l.side_left);

    calibration::RigCalibration empty;
    EXPECT_EQ(writeRigDiagram(png, empty).code(), ErrorCode::kInvalidArgument);
}

TEST(CalibrationReport, PerViewTable) {
    const fs::path dir = test::tempDir();
    CameraCalibration c = camera();
    c.rms_px = 0.41;
    c.outliers = 1;
    calibration::CameraViews views;
    views.camera = c.camera;
    for (int i = 0; i < 4; ++i) {
        calibration::TargetView v;
        v.source = "img" + std::to_string(i) + ".png";
        v.key = i;
        views.views.push_back(v);
    }
    views.views[3].rejection = calibration::ViewRejection::kBlurred;
    views.views[3].why = "sharpness 3.1 < 8";
    for (size_t i = 0; i < 3; ++i) {
        calibration::ViewFit f;
        f.view = i;
        f.corners = 40;
        f.outliers = i == 2 ? 1 : 0;
        f.rms_px = i == 2 ? 1.0 : 0.2 + 0.05 * i;
        c.views.push_back(f);
    }
    const std::string table = viewTable(c, &views);
    EXPECT_NE(table.find("RMS 0.410 px over 3 views, 1 outliers."), std::string::npos) << table;
    EXPECT_NE(table.find("| 0 | img0.png | 0 | 40 | 0 | 0.200 |  |"), std::string::npos) << table;
    EXPECT_NE(table.find("| 2 | img2.png | 2 | 40 | 1 | 1.000 | RMS over twice the median |"),
              std::string::npos)
        << table;
    EXPECT_NE(table.find("| 3 | img3.png | 3 | blurred: sharpness 3.1 < 8 |"), std::string::npos)
        << table;
    const fs::path md = dir / "views.md";
    ASSERT_TRUE(writeViewTable(md, c, &views).isOk());
    std::ifstream in(md);
    std::stringstream text;
    text << in.rdbuf();
    EXPECT_EQ(text.str(), table);
    EXPECT_EQ(writeViewTable(dir / "no/dir/views.md", c).code(), ErrorCode::kIoError);
    // Without the views, no sources.
    EXPECT_NE(viewTable(c).find("| 1 |  |  | 40 | 0 | 0.250 |  |"), std::string::npos);
    EXPECT_EQ(reportFileStem("kinect/color"), "kinect_color");
}

}  // namespace
}  // namespace mixray::cli
