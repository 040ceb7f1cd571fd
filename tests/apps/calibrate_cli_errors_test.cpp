// mixray calibrate on real photos (OpenCV's left*.jpg chessboard set) and on bad input: every
// failure names its cause, never a crash, and nothing but the corners is written when no camera
// could be calibrated.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <opencv2/core/persistence.hpp>
#include <string>

#include "cli_runner.h"
#include "mixray/calibration/calibration_file.h"
#include "test_data.h"

namespace mixray {
namespace {

namespace fs = std::filesystem;

using test::CliRun;
using test::mixray;
using test::q;

const fs::path kLeft = test::sharedDataDir() / "03_calib_chessboard_stereo_opencv";
const std::string kChessboard = " --target chessboard:9x6:0.025";

bool contains(const std::string& text, const std::string& part) {
    return text.find(part) != std::string::npos;
}

TEST(CalibrateCli, RefusesBadCommandLinesNamingTheCause) {
    const fs::path dir = test::tempDir();
    CliRun help = mixray("calibrate --help");
    EXPECT_EQ(help.exit_code, 0);
    EXPECT_TRUE(contains(help.output, "--target")) << help.output;

    CliRun no_target = mixray("calibrate " + q(dir));
    EXPECT_EQ(no_target.exit_code, 2) << no_target.output;

    CliRun bad_target =
        mixray("calibrate " + q(dir) + " --target chessboard:9x6 -o " + q(dir / "out"));
    EXPECT_EQ(bad_target.exit_code, 2) << bad_target.output;
    EXPECT_TRUE(contains(bad_target.output, "--target")) << bad_target.output;

    CliRun missing =
        mixray("calibrate " + q(dir / "nowhere") + kChessboard + " -o " + q(dir / "out"));
    EXPECT_EQ(missing.exit_code, 3) << missing.output;
    EXPECT_TRUE(contains(missing.output, "nowhere")) << missing.output;

    std::ofstream(dir / "notes.txt") << "not an image";
    CliRun text =
        mixray("calibrate " + q(dir / "notes.txt") + kChessboard + " -o " + q(dir / "out"));
    EXPECT_EQ(text.exit_code, 2) << text.output;
    EXPECT_TRUE(contains(text.output, "expected an image folder")) << text.output;

    CliRun marker = mixray("calibrate " + q(dir) + kChessboard + " --marker DICT_6X6_250:x:0.1");
    EXPECT_EQ(marker.exit_code, 2) << marker.output;
    EXPECT_TRUE(contains(marker.output, "DICTIONARY:ID:SIZE_M")) << marker.output;

    CliRun format = mixray("calibrate " + q(dir) + kChessboard + " --export matlab");
    EXPECT_EQ(format.exit_code, 2) << format.output;
    EXPECT_TRUE(contains(format.output, "matlab")) << format.output;

    CliRun solver = mixray("calibrate " + q(dir) + kChessboard + " --solver magic");
    EXPECT_EQ(solver.exit_code, 2) << solver.output;
}

TEST(CalibrateCli, AFolderWithoutImagesOrWithUnreadableOnesIsNamed) {
    const fs::path dir = test::tempDir();
    fs::create_directories(dir / "empty");
    CliRun empty = mixray("calibrate " + q(dir / "empty") + kChessboard + " -o " + q(dir / "out"));
    EXPECT_EQ(empty.exit_code, 3) << empty.output;
    EXPECT_TRUE(contains(empty.output, "empty")) << empty.output;

    // Files that are no images: views rejected as unreadable, too few to calibrate.
    fs::create_directories(dir / "broken");
    for (const char* name : {"a.jpg", "b.jpg", "c.jpg", "d.jpg", "e.jpg"})
        std::ofstream(dir / "broken" / name) << "JFIF? no";
    CliRun broken =
        mixray("calibrate " + q(dir / "broken") + kChessboard + " -o " + q(dir / "out"));
    EXPECT_EQ(broken.exit_code, 3) << broken.output;
    EXPECT_TRUE(contains(broken.output, "no camera calibrated")) << broken.output;
    EXPECT_TRUE(contains(broken.output, "unreadable")) << broken.output;
    EXPECT_TRUE(fs::exists(dir / "out" / "corners.vnl"));
    EXPECT_FALSE(fs::exists(dir / "out" / "calibration.yaml"));
}

TEST(CalibrateCli, TooFewViewsIsACameraNotCalibratedWithTheReason) {
    MIXRAY_REQUIRE_SHARED_DATA(kLeft / "left01.jpg");
    const fs::path dir = test::tempDir();
    fs::create_directories(dir / "cam");
    for (const char* name : {"left01.jpg", "left02.jpg"})
        fs::copy_file(kLeft / name, dir / "cam" / name);
    CliRun run = mixray("calibrate " + q(dir / "cam") + kChessboard + " -o " + q(dir / "out"));
    EXPECT_EQ(run.exit_code, 3) << run.output;
    EXPECT_TRUE(contains(run.output, "too few usable views")) << run.output;
    EXPECT_FALSE(fs::exists(dir / "out" / "calibration.yaml"));

    CliRun camera = mixray("calibrate " + q(dir / "cam") + kChessboard +
                           " --model nosuch=fisheye -o " + q(dir / "out"));
    EXPECT_EQ(camera.exit_code, 2) << camera.output;
    EXPECT_TRUE(contains(camera.output, "no camera nosuch")) << camera.output;
}

// The OpenCV sample's chessboard photos: OpenCV's own calibration of them is published
// (left_intrinsics.yml: fx = fy = 535.9157, cx 342.2832, cy 235.5708, 5 coefficients, fixed
// aspect ratio, RMS 0.3926 px). Solving OpenCV's own corners reproduces it exactly
// (CeresRealData in calibration_test). mixray's corners are better (RMS 0.16 px here; OpenCV's
// 11x11 cornerSubPix window drifts onto neighbouring corners on some views, tests/calibration/
// detect_test.cpp), which moves the lens by up to 0.8 % (cy): within 1 % of OpenCV's.
TEST(CalibrateCli, OpenCvSamplePhotosAgreeWithOpenCvsPublishedCalibration) {
    MIXRAY_REQUIRE_SHARED_DATA(kLeft / "left_intrinsics.yml");
    const fs::path dir = test::tempDir();
    CliRun run = mixray("calibrate " + q(kLeft) + " --pattern 'left*.jpg'" + kChessboard +
                        " --fix-aspect-ratio --export opencv --export ros -o " + q(dir));
    ASSERT_EQ(run.exit_code, 0) << run.output;
    EXPECT_TRUE(contains(run.output, "target in 13 of 13 views")) << run.output;
    auto file = calibration::readCalibrationFile(dir / "calibration.yaml");
    ASSERT_TRUE(file) << file.status().toString();
    ASSERT_EQ(file->cameras.size(), 1u);
    const calibration::CalibratedCamera& c = file->cameras.front();
    EXPECT_EQ(c.name, "03_calib_chessboard_stereo_opencv");
    EXPECT_EQ(c.views, 13);
    EXPECT_NEAR(c.model.fx, 535.9157, 0.01 * 535.9157);
    EXPECT_NEAR(c.model.fy, 535.9157, 0.01 * 535.9157);
    EXPECT_NEAR(c.model.cx, 342.2832, 0.01 * 342.2832);
    EXPECT_NEAR(c.model.cy, 235.5708, 0.01 * 235.5708);
    EXPECT_GT(c.rms_px, 0.05);
    EXPECT_LT(c.rms_px, 0.3926) << "mixray's corners fit better than OpenCV's";
    ASSERT_EQ(c.intrinsics_stddev.size(), 9u);
    EXPECT_LT(c.intrinsics_stddev[0], 2.0) << "fx known to a few pixels";
    for (const char* name :
         {"report.md", "corners.vnl", "03_calib_chessboard_stereo_opencv_residuals.png",
          "03_calib_chessboard_stereo_opencv_coverage.png",
          "03_calib_chessboard_stereo_opencv_uncertainty.png",
          "03_calib_chessboard_stereo_opencv.opencv.yml",
          "03_calib_chessboard_stereo_opencv.camera_info.yaml"})
        EXPECT_TRUE(fs::exists(dir / name)) << name;

    // OpenCV reads the export as it reads its own calibrations.
    cv::FileStorage storage((dir / "03_calib_chessboard_stereo_opencv.opencv.yml").string(),
                            cv::FileStorage::READ);
    ASSERT_TRUE(storage.isOpened());
    cv::Mat K;
    storage["camera_matrix"] >> K;
    ASSERT_EQ(K.rows, 3);
    EXPECT_NEAR(K.at<double>(0, 0), c.model.fx, 1e-9);

    // The corners cache alone gives the same lens.
    CliRun again = mixray("calibrate " + q(dir / "corners.vnl") + kChessboard +
                          " --fix-aspect-ratio --no-report -o " + q(dir / "again"));
    ASSERT_EQ(again.exit_code, 0) << again.output;
    auto second = calibration::readCalibrationFile(dir / "again" / "calibration.yaml");
    ASSERT_TRUE(second) << second.status().toString();
    ASSERT_EQ(second->cameras.size(), 1u);
    EXPECT_NEAR(second->cameras.front().model.fx, c.model.fx, 1e-6);
    EXPECT_NEAR(second->cameras.front().model.cx, c.model.cx, 1e-6);
    EXPECT_FALSE(fs::exists(dir / "again" / "report.md"));

    // mrcal's own form of that cache (no "##" rows, file names without folders) has no image
    // size: without the images or --image-size the error says how to give it; with either the
    // lens is the same.
    const fs::path plain = dir / "mrcal";
    fs::create_directories(plain);
    {
        std::ifstream in(dir / "corners.vnl");
        std::ofstream out(plain / "corners.vnl");
        for (std::string line; std::getline(in, line);) {
            if (line.rfind("##", 0) == 0)
                continue;
            if (line[0] != '#')
                line = line.substr(line.rfind('/', line.find(' ')) + 1);
            out << line << "\n";
        }
    }
    const std::string cache = "calibrate " + q(plain / "corners.vnl") + kChessboard +
                              " --fix-aspect-ratio --no-report -o " + q(plain / "out");
    CliRun no_size = mixray(cache);
    EXPECT_EQ(no_size.exit_code, 2) << no_size.output;
    EXPECT_TRUE(contains(no_size.output, "--image-size")) << no_size.output;
    EXPECT_TRUE(contains(no_size.output, (plain / "left01.jpg").string())) << no_size.output;
    CliRun bad_size = mixray(cache + " --image-size 640");
    EXPECT_EQ(bad_size.exit_code, 2) << bad_size.output;
    EXPECT_TRUE(contains(bad_size.output, "WIDTHxHEIGHT")) << bad_size.output;
    for (const std::string& size_from : {std::string("--image-size"), std::string("images")}) {
        SCOPED_TRACE(size_from);
        if (size_from == "images")
            fs::copy_file(kLeft / "left01.jpg", plain / "left01.jpg");
        CliRun run_plain = mixray(cache + (size_from == "images" ? "" : " --image-size 640x480"));
        ASSERT_EQ(run_plain.exit_code, 0) << run_plain.output;
        auto solved = calibration::readCalibrationFile(plain / "out" / "calibration.yaml");
        ASSERT_TRUE(solved) << solved.status().toString();
        ASSERT_EQ(solved->cameras.size(), 1u);
        EXPECT_EQ(solved->cameras.front().model.width, 640);
        EXPECT_NEAR(solved->cameras.front().model.fx, c.model.fx, 1e-6);
        EXPECT_NEAR(solved->cameras.front().model.cy, c.model.cy, 1e-6);
    }
}

}  // namespace
}  // namespace mixray
