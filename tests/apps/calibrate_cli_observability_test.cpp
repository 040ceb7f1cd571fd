// mixray calibrate judging what the views determine, on rendered image folders
// (tests/calibration/target_render.h): four ChArUco views tilted alike fail naming the weak
// parameters and are kept with --accept-weak, their weakness in calibration.yaml and the
// report; a chessboard declared one row and column smaller than printed fails naming the size
// printed.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <filesystem>
#include <fstream>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "cli_runner.h"
#include "mixray/calibration/calibration_file.h"
#include "target_render.h"

namespace mixray {
namespace {

namespace fs = std::filesystem;
using calibration::CalibrationTarget;
using Eigen::Isometry3d;
using Eigen::Vector3d;
using test::CliRun;
using test::mixray;
using test::q;

bool contains(const std::string& text, const std::string& part) {
    return text.find(part) != std::string::npos;
}

std::string readText(const fs::path& path) {
    std::ifstream in(path);
    std::stringstream text;
    text << in.rdbuf();
    return text.str();
}

Isometry3d pose(const CalibrationTarget& target, double distance_m, double tilt_deg, double yaw_deg,
                const Vector3d& shift_m = Vector3d::Zero()) {
    Isometry3d T = calibration::synth::boardPose(target, distance_m, tilt_deg, yaw_deg);
    T.translation() += shift_m;
    return T;
}

// view0.png, view1.png, … in `folder`: `target` rendered from `poses` (testCamera()).
void renderFolder(const fs::path& folder, const CalibrationTarget& target,
                  const std::vector<Isometry3d>& poses) {
    fs::create_directories(folder);
    const calibration::CameraModel camera = calibration::synth::testCamera();
    for (size_t i = 0; i < poses.size(); ++i) {
        const Image image = calibration::synth::renderTarget(camera, target, poses[i]);
        const ImageView v = image.view();
        const cv::Mat mat(v.desc.height, v.desc.width, CV_8UC1, const_cast<uint8_t*>(v.data),
                          static_cast<size_t>(v.desc.stride_bytes));
        ASSERT_TRUE(cv::imwrite((folder / ("view" + std::to_string(i) + ".png")).string(), mat));
    }
}

const std::string kCharuco = "charuco:7x5:0.05:0.037:DICT_6X6_250";

TEST(CalibrateCliObservability, HelpNamesTheOptions) {
    const CliRun help = mixray("calibrate --help");
    EXPECT_EQ(help.exit_code, 0);
    EXPECT_TRUE(contains(help.output, "--accept-weak")) << help.output;
    EXPECT_TRUE(contains(help.output, "--max-rms")) << help.output;
}

TEST(CalibrateCliObservability, ViewsTiltedAlikeFailNamingTheWeakParametersUnlessAccepted) {
    const fs::path dir = test::tempDir();
    const CalibrationTarget board = *calibration::parseTarget(kCharuco);
    renderFolder(dir / "cam", board,
                 {pose(board, 0.6, 21, 1, Vector3d(-0.07, -0.05, 0)),
                  pose(board, 0.6, 23, -1, Vector3d(0.07, -0.04, 0.05)),
                  pose(board, 0.6, 25, 2, Vector3d(-0.06, 0.05, 0.1)),
                  pose(board, 0.6, 22, 0, Vector3d(0.06, 0.05, -0.03))});

    const CliRun refused =
        mixray("calibrate " + q(dir / "cam") + " --target " + kCharuco + " -o " + q(dir / "a"));
    EXPECT_EQ(refused.exit_code, 3) << refused.output;
    EXPECT_TRUE(contains(refused.output, "target in 4 of 4 views")) << refused.output;
    EXPECT_TRUE(contains(refused.output, "weakly determined intrinsics: fx")) << refused.output;
    EXPECT_TRUE(contains(refused.output, "--accept-weak")) << refused.output;
    EXPECT_FALSE(fs::exists(dir / "a" / "calibration.yaml"));

    const CliRun kept = mixray("calibrate " + q(dir / "cam") + " --target " + kCharuco +
                               " --accept-weak -o " + q(dir / "b"));
    ASSERT_EQ(kept.exit_code, 0) << kept.output;
    EXPECT_TRUE(contains(kept.output, "cam: weakly determined, kept (--accept-weak): fx"))
        << kept.output;
    auto file = calibration::readCalibrationFile(dir / "b" / "calibration.yaml");
    ASSERT_TRUE(file) << file.status().toString();
    ASSERT_EQ(file->cameras.size(), 1u);
    const calibration::CalibratedCamera& c = file->cameras.front();
    EXPECT_TRUE(contains(c.weak, "fx")) << c.weak;
    EXPECT_TRUE(contains(c.weak, "of the focal length")) << c.weak;
    ASSERT_GE(c.intrinsics_stddev.size(), 4u);
    EXPECT_GT(c.intrinsics_stddev[0], 0);
    const std::string report = readText(dir / "b" / "report.md");
    EXPECT_TRUE(contains(report, "**Weakly determined, kept (--accept-weak):** fx")) << report;
    EXPECT_TRUE(contains(report, "Intrinsics' 1σ as a share of the focal length")) << report;
}

TEST(CalibrateCliObservability, AChessboardDeclaredSmallerThanPrintedFailsNamingItsSize) {
    const fs::path dir = test::tempDir();
    const CalibrationTarget printed = *calibration::parseTarget("chessboard:10x7:0.03");
    renderFolder(
        dir / "cam", printed,
        {pose(printed, 0.6, 20, 0), pose(printed, 0.6, -20, 10), pose(printed, 0.65, 0, 25),
         pose(printed, 0.65, 10, -25), pose(printed, 0.7, -15, -15), pose(printed, 0.6, 25, 15)});
    const CliRun run = mixray("calibrate " + q(dir / "cam") + " --target chessboard:9x6:0.03 -o " +
                              q(dir / "out"));
    EXPECT_EQ(run.exit_code, 3) << run.output;
    EXPECT_TRUE(contains(run.output, "looks like 10x7 inner corners, not 9x6")) << run.output;
    EXPECT_TRUE(contains(run.output, "--target chessboard:10x7:0.03")) << run.output;
    EXPECT_FALSE(fs::exists(dir / "out" / "calibration.yaml"));

    const CliRun right = mixray("calibrate " + q(dir / "cam") +
                                " --target chessboard:10x7:0.03 -o " + q(dir / "right"));
    EXPECT_EQ(right.exit_code, 0) << right.output;
    EXPECT_TRUE(contains(right.output, "target in 6 of 6 views")) << right.output;
}

}  // namespace
}  // namespace mixray
