// mixray render --calibration: the calibrated colour camera, and raw Kinect depth (aligned with
// the IR camera) registered into it before it occludes virtual objects.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <string>

#include "cli_runner.h"
#include "mixray/calibration/calibration_file.h"
#include "mixray/calibration/camera_model_yaml.h"
#include "mixray/render/simulator.h"
#include "test_data.h"

namespace mixray {
namespace {

namespace fs = std::filesystem;

using test::CliRun;
using test::mixray;
using test::q;

const fs::path kSessions = test::fixturesDir() / "sessions";

// A red sphere hidden behind the board of the first board view: only the board's depth, which
// the session records raw (aligned with the IR camera), can hide it.
TEST(RenderCalibrationCli, RawDepthOccludesOnlyWhenTheCalibrationRegistersIt) {
    const fs::path dir = test::tempDir();
    auto options = render::readSimulationOptions(
        test::readText(kSessions / "sim_calibration.truth.yaml"), "sim_calibration.truth.yaml");
    ASSERT_TRUE(options) << options.status().toString();
    options->asset_dir = dir / "assets";
    auto sim = render::Simulator::create(*options);
    ASSERT_TRUE(sim) << sim.status().toString();
    const render::SimTruth& t = (*sim)->truth();
    ASSERT_FALSE(t.depth_registered) << "the session's depth is raw";
    ASSERT_TRUE(t.board);

    // The first view where the colour camera sees the whole board.
    size_t view = 0;
    while (view < t.frames.size() && t.frames[view].board_in_color < 1)
        ++view;
    ASSERT_LT(view, t.frames.size());
    const render::SimFrameTruth& f = t.frames[view];
    const Eigen::Vector3d centre_board(t.board->squares_x * t.board->square_m / 2,
                                       t.board->squares_y * t.board->square_m / 2, 0);
    const Eigen::Vector3d board_world = *f.T_world_board * centre_board;
    const Eigen::Vector3d eye = f.T_world_color.translation();
    const Eigen::Vector3d behind = board_world + 0.08 * (board_world - eye).normalized();
    const auto pixel = t.color.project(f.T_world_color.inverse() * behind);
    ASSERT_TRUE(pixel);

    std::ofstream(dir / "scene.yaml")
        << "version: 1\n"
           "materials:\n  red: {type: diffuse, albedo: [0.9, 0.05, 0.05]}\n"
           "objects:\n  - {name: ball, shape: {sphere: {radius: 0.03}}, material: red,\n"
           "     pose: {translation: ["
        << behind.x() << ", " << behind.y() << ", " << behind.z()
        << "]}}\n"
           "lights:\n  - {name: sun, type: directional, direction: [0, 0, -1], irradiance: [3, 3, "
           "3]}\n"
           "camera:\n  model: "
        << calibration::cameraModelYaml(t.color) << "\n";

    calibration::CalibrationFile file;
    calibration::CalibratedCamera color;
    color.name = "kinect/color";
    color.model = t.color;
    calibration::CalibratedCamera ir;
    ir.name = "kinect/ir";
    ir.model = t.ir;
    ir.parent = "kinect/color";
    ir.T_parent_camera = t.T_color_ir;
    file.cameras = {color, ir};
    file.depth.push_back({"kinect/depth", "kinect/ir", "kinect/color", {}});
    ASSERT_TRUE(calibration::writeCalibrationFile(dir / "calibration.yaml", file));

    const auto render = [&](const std::string& name, const std::string& extra) {
        const std::string command = "render " + q(kSessions / "sim_calibration.mkv") + " --scene " +
                                    q(dir / "scene.yaml") + " -o " + q(dir / (name + ".mkv")) +
                                    " --png-dir " + q(dir / name) + " --png-every 1 --max-frames " +
                                    std::to_string(view + 1) + " --shadows hard" + extra;
        CliRun run = mixray(command);
        EXPECT_EQ(run.exit_code, 0) << run.output;
        char png[32];
        std::snprintf(png, sizeof png, "frame_%06zu.png", view);
        return std::pair{cv::imread((dir / name / png).string(), cv::IMREAD_COLOR), run.output};
    };
    const auto [plain, plain_log] = render("plain", "");
    const auto [registered, registered_log] =
        render("registered", " --calibration " + q(dir / "calibration.yaml"));
    ASSERT_FALSE(plain.empty()) << plain_log;
    ASSERT_FALSE(registered.empty()) << registered_log;
    EXPECT_NE(registered_log.find("kinect/depth registered into kinect/color"), std::string::npos)
        << registered_log;

    const int x = static_cast<int>(std::lround(pixel->x()));
    const int y = static_cast<int>(std::lround(pixel->y()));
    const cv::Vec3b a = plain.at<cv::Vec3b>(y, x), b = registered.at<cv::Vec3b>(y, x);
    // BGR: without registration the raw depth is not used and the sphere shows; registered, the
    // board in front hides it.
    EXPECT_GT(a[2], a[1] + 60) << "plain " << a;
    EXPECT_LT(std::abs(b[2] - b[1]), 40) << "registered " << b;
}

}  // namespace
}  // namespace mixray
