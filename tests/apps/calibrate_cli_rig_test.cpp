// mixray calibrate --rig on rendered stereo image folders. A chessboard with even corner counts
// looks the same turned by 180°, and OpenCV's detector numbers some views of it from the other
// end in one camera only: the rig still comes out within a millimetre and a tenth of a degree,
// and the command names the views it renumbered. Folders whose images do not pair one instant
// are refused with the cause and a non-zero exit, never written as a rig.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

#include "../calibration/target_render.h"
#include "cli_runner.h"
#include "mixray/calibration/calibration_file.h"
#include "mixray/calibration/target.h"
#include "test_data.h"

namespace mixray {
namespace {

namespace fs = std::filesystem;
using calibration::CalibrationTarget;
using Eigen::Isometry3d;
using Eigen::Vector3d;
using test::CliRun;
using test::mixray;
using test::q;

// 8 × 6 inner corners: 9 × 7 squares, the same print turned by 180°.
const char* const kTarget = "chessboard:8x6:0.03";
constexpr int kPairs = 12;

bool contains(const std::string& text, const std::string& part) {
    return text.find(part) != std::string::npos;
}

// The right camera 80 mm to the right of the left one, turned 4° towards it and rolled 15°.
Isometry3d T_left_right() {
    Isometry3d T = Isometry3d::Identity();
    T.linear() = (Eigen::AngleAxisd(-4 * M_PI / 180, Vector3d::UnitY()) *
                  Eigen::AngleAxisd(15 * M_PI / 180, Vector3d::UnitZ()))
                     .toRotationMatrix();
    T.translation() = Vector3d(0.08, 0.002, 0.003);
    return T;
}

// Board poses in the left camera: tilted and yawed both ways, turned in their plane by up to
// ±75° (where OpenCV's detector changes its mind about which corner comes first).
std::vector<Isometry3d> boardPoses(const CalibrationTarget& target) {
    const Vector3d centre((target.cols - 1) * target.square_m / 2,
                          (target.rows - 1) * target.square_m / 2, 0);
    std::vector<Isometry3d> poses;
    for (int i = 0; i < kPairs; ++i) {
        const double tilt = (i % 2 ? 1 : -1) * (12 + 3 * (i % 5));
        const double yaw = (i % 3 - 1) * (10 + 2 * i);
        Isometry3d T = calibration::synth::boardPose(target, 0.5 + 0.01 * (i % 4), tilt, yaw);
        const double turn = -75 + 150.0 * i / (kPairs - 1);
        Isometry3d spin = Isometry3d::Identity();
        spin.linear() = Eigen::AngleAxisd(turn * M_PI / 180, Vector3d::UnitZ()).toRotationMatrix();
        spin.translation() = centre - spin.linear() * centre;
        poses.push_back(T * spin);
    }
    return poses;
}

void writeImage(const fs::path& path, const Image& image) {
    const ImageView v = image.view();
    const cv::Mat mat(v.desc.height, v.desc.width, CV_8UC1, const_cast<uint8_t*>(v.data),
                      static_cast<size_t>(v.desc.stride_bytes));
    ASSERT_TRUE(cv::imwrite(path.string(), mat)) << path;
}

// left/NN.png and right/NN.png; the right camera's images `lag` instants late.
void renderPairs(const fs::path& dir, int lag) {
    const CalibrationTarget target = calibration::parseTarget(kTarget).value();
    const calibration::CameraModel camera = calibration::synth::testCamera();
    const std::vector<Isometry3d> poses = boardPoses(target);
    fs::create_directories(dir / "left");
    fs::create_directories(dir / "right");
    for (int i = 0; i < kPairs; ++i) {
        char name[16];
        std::snprintf(name, sizeof name, "%02d.png", i);
        writeImage(dir / "left" / name,
                   calibration::synth::renderTarget(camera, target, poses[i], 2));
        writeImage(dir / "right" / name,
                   calibration::synth::renderTarget(
                       camera, target, T_left_right().inverse() * poses[(i + lag) % kPairs], 2));
    }
}

TEST(CalibrateCliRig, ViewsNumberedFromTheOtherEndAreRenumberedAndTheRigIsRight) {
    const fs::path dir = test::tempDir();
    renderPairs(dir, 0);
    CliRun run = mixray("calibrate " + q(dir / "left") + " " + q(dir / "right") + " --target " +
                        kTarget + " --rig left,right --no-report -o " + q(dir / "out"));
    std::printf("%s", run.output.c_str());
    ASSERT_EQ(run.exit_code, 0) << run.output;
    EXPECT_TRUE(contains(run.output, "target in 12 of 12 views")) << run.output;
    // The test is only worth its name when the detector did number some pair differently.
    EXPECT_TRUE(contains(run.output, "corners renumbered as the board turned by 180°"))
        << run.output;
    auto file = calibration::readCalibrationFile(dir / "out" / "calibration.yaml");
    ASSERT_TRUE(file) << file.status().toString();
    auto T = file->pose("left", "right");
    ASSERT_TRUE(T) << T.status().toString();
    const Isometry3d truth = T_left_right();
    const double mm = (T->translation() - truth.translation()).norm() * 1000;
    const double deg =
        Eigen::AngleAxisd(T->linear().transpose() * truth.linear()).angle() * 180 / M_PI;
    std::printf("baseline %.2f mm (truth %.2f mm): %.3f mm, %.4f° off\n",
                T->translation().norm() * 1000, truth.translation().norm() * 1000, mm, deg);
    EXPECT_LT(mm, 1.0);
    EXPECT_LT(deg, 0.1);
}

TEST(CalibrateCliRig, ImagesThatDoNotPairOneInstantAreRefusedNotWrittenAsARig) {
    const fs::path dir = test::tempDir();
    renderPairs(dir, 1);
    CliRun run = mixray("calibrate " + q(dir / "left") + " " + q(dir / "right") + " --target " +
                        kTarget + " --rig left,right --no-report -o " + q(dir / "out"));
    std::printf("%s", run.output.c_str());
    EXPECT_EQ(run.exit_code, 3) << run.output;
    EXPECT_TRUE(contains(run.output, "--rig left,right: rig: camera")) << run.output;
    EXPECT_TRUE(contains(run.output, "disagree")) << run.output;
    // The cameras' own calibrations are still written, without a pose between them.
    auto file = calibration::readCalibrationFile(dir / "out" / "calibration.yaml");
    ASSERT_TRUE(file) << file.status().toString();
    const calibration::CalibratedCamera* right = file->find("right");
    ASSERT_NE(right, nullptr);
    EXPECT_TRUE(right->parent.empty()) << "a pose for right was written: " << right->parent;
}

}  // namespace
}  // namespace mixray
