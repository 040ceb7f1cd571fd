// mixray simulate, and mixray info / render on the committed simulated sessions (the render
// camera following the recording's ground-truth pose stream).
#include <gtest/gtest.h>
#include <signal.h>

#include <Eigen/Geometry>
#include <array>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <regex>
#include <sstream>
#include <string>
#include <thread>

#include "cli_runner.h"
#include "test_data.h"

namespace mixray {
namespace {

namespace fs = std::filesystem;

using test::CliRun;
using test::mixray;
using test::q;

const fs::path kSessions = test::fixturesDir() / "sessions";

TEST(SimulateCli, HelpAndBadOptions) {
    CliRun help = mixray("simulate --help");
    EXPECT_EQ(help.exit_code, 0);
    EXPECT_NE(help.output.find("--scenario"), std::string::npos) << help.output;
    EXPECT_EQ(mixray("simulate --scenario kitchen").exit_code, 2);
    const fs::path dir = test::tempDir();
    CliRun size = mixray("simulate --size 320 -o " + q(dir / "a.mkv"));
    EXPECT_EQ(size.exit_code, 2) << size.output;
    EXPECT_NE(size.output.find("WIDTHxHEIGHT"), std::string::npos) << size.output;
    CliRun samples = mixray("simulate --samples 3 -o " + q(dir / "a.mkv"));
    EXPECT_EQ(samples.exit_code, 2) << samples.output;
    CliRun extension = mixray("simulate -o " + q(dir / "a.avi"));
    EXPECT_EQ(extension.exit_code, 2) << extension.output;
    EXPECT_FALSE(fs::exists(dir / "a.mkv"));
}

TEST(SimulateCli, WritesARecordingThatInfoDescribes) {
    const fs::path dir = test::tempDir();
    CliRun run = mixray("simulate --scenario calibration --frames 2 --size 160x120 -o " +
                        q(dir / "cal.mkv"));
    ASSERT_EQ(run.exit_code, 0) << run.output;
    EXPECT_NE(run.output.find("2 frames (2 environment frames)"), std::string::npos) << run.output;
    EXPECT_NE(run.output.find("ms per frame"), std::string::npos) << run.output;
    for (const char* name : {"cal.truth.yaml", "cal.tum", "cal.scene.yaml", "cal.board.png"})
        EXPECT_TRUE(fs::exists(dir / name)) << name;
    CliRun info = mixray("info --json " + q(dir / "cal.mkv"));
    ASSERT_EQ(info.exit_code, 0) << info.output;
    auto json = nlohmann::json::parse(info.output);
    ASSERT_EQ(json["streams"].size(), 5u);
    EXPECT_EQ(json["streams"][4]["name"], "kinect/ir");
    EXPECT_EQ(json["streams"][4]["format"], "ir16");
    EXPECT_EQ(json["streams"][4]["frames"], 2);
}

// SIGTERM while it renders: the recording is closed with the frames done (info reads it to its
// end), the command says how many, and exits 143.
TEST(SimulateCli, SigtermKeepsAClosedRecordingOfTheFramesDone) {
    const fs::path dir = test::tempDir();
    const test::CliProcess process =
        test::startMixray({"simulate", "--frames", "40", "--size", "320x240", "--threads", "2",
                           "-o", (dir / "s.mkv").string()},
                          dir / "log.txt");
    ASSERT_GT(process.pid, 0);
    // The first frame's progress line (printed at once when stderr is a file).
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(120);
    while (test::readText(dir / "log.txt").find("frame 1/40") == std::string::npos &&
           std::chrono::steady_clock::now() < deadline)
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
    kill(process.pid, SIGTERM);
    const CliRun run = test::waitMixray(process);
    EXPECT_EQ(run.exit_code, 143) << run.output;
    std::smatch m;
    ASSERT_TRUE(std::regex_search(
        run.output, m,
        std::regex("stopped by SIGTERM after ([0-9]+) of 40 frames; .*s\\.mkv holds ([0-9]+) "
                   "frames? \\(the truth files describe all 40\\)")))
        << run.output;
    const int done = std::stoi(m[1]);
    EXPECT_EQ(std::stoi(m[2]), done);
    EXPECT_GE(done, 1);
    EXPECT_LT(done, 40);
    CliRun info = mixray("info --json " + q(dir / "s.mkv"));
    ASSERT_EQ(info.exit_code, 0) << info.output;
    auto json = nlohmann::json::parse(info.output);
    EXPECT_EQ(json["streams"][0]["name"], "kinect/color");
    EXPECT_EQ(json["streams"][0]["frames"], done);
}

TEST(SimulateCli, InfoDescribesTheCommittedSessions) {
    for (const auto& [name, frames, streams] :
         {std::tuple{"sim_tabletop.mkv", 36, 4}, std::tuple{"sim_calibration.mkv", 20, 5}}) {
        const fs::path path = kSessions / name;
        ASSERT_TRUE(fs::exists(path)) << path;
        EXPECT_LE(fs::file_size(path), 4u * 1000 * 1000) << name << " stays small";
        CliRun run = mixray("info --json " + q(path));
        ASSERT_EQ(run.exit_code, 0) << run.output;
        auto info = nlohmann::json::parse(run.output);
        EXPECT_TRUE(info["complete"]) << name;
        ASSERT_EQ(info["streams"].size(), static_cast<size_t>(streams)) << name;
        EXPECT_EQ(info["streams"][0]["name"], "kinect/color");
        EXPECT_EQ(info["streams"][0]["frames"], frames) << name;
        EXPECT_EQ(info["streams"][0]["width"], 640);
        EXPECT_EQ(info["streams"][1]["format"], "depth16");
        EXPECT_EQ(info["streams"][3]["name"], "truth/pose");
        EXPECT_EQ(info["streams"][3]["frames"], frames) << name;
        ASSERT_FALSE(info["attachments"].empty());
        EXPECT_EQ(info["attachments"][0]["name"], "truth.yaml");
    }
}

// The first pose of the committed tabletop session's TUM trajectory.
Eigen::Isometry3d firstTumPose(const fs::path& path) {
    std::ifstream in(path);
    std::string line;
    while (std::getline(in, line) && (line.empty() || line[0] == '#')) {
    }
    std::istringstream s(line);
    double stamp, x, y, z, qx, qy, qz, qw;
    s >> stamp >> x >> y >> z >> qx >> qy >> qz >> qw;
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = Eigen::Quaterniond(qw, qx, qy, qz).normalized().toRotationMatrix();
    T.translation() = Eigen::Vector3d(x, y, z);
    return T;
}

TEST(SimulateCli, RenderFollowsTheRecordingsPoseStream) {
    const fs::path dir = test::tempDir();
    const fs::path session = kSessions / "sim_tabletop.mkv";
    CliRun run = mixray("render " + q(session) + " --scene " +
                        q(test::fixturesDir() / "scenes" / "sim_tabletop.yaml") + " -o " +
                        q(dir / "out.mkv") + " --max-frames 1 --shadows hard");
    ASSERT_EQ(run.exit_code, 0) << run.output;
    EXPECT_NE(run.output.find("1 frames composited"), std::string::npos) << run.output;

    // A pure red virtual sphere over the real diffuse probe: it lands on the probe only if
    // the camera is where the pose stream says.
    const fs::path scene = dir / "overlay.yaml";
    std::ofstream(scene)
        << "materials:\n  red: { type: diffuse, albedo: [0.9, 0.0, 0.0] }\n"
           "objects:\n  - { name: cover, shape: { sphere: { radius: 0.041 } }, material: red,\n"
           "      pose: { translation: [0.15, -0.08, 0.0395] } }\n"
           "lights:\n  - { type: directional, direction: [0, 0, -1], irradiance: 3 }\n"
           "camera:\n  model: { width: 640, height: 480, fx: 524.8, fy: 525.4, cx: 318.6,\n"
           "           cy: 241.9, distortion: [0.045, -0.11, 0.0006, -0.0004, 0.04] }\n";
    CliRun overlay =
        mixray("render " + q(session) + " --scene " + q(scene) + " -o " + q(dir / "overlay.mkv") +
               " --max-frames 1 --png-dir " + q(dir / "png") + " --pose-stream truth/pose");
    ASSERT_EQ(overlay.exit_code, 0) << overlay.output;
    const cv::Mat image = cv::imread((dir / "png" / "frame_000000.png").string());
    ASSERT_FALSE(image.empty());
    const Eigen::Isometry3d T_world_cam = firstTumPose(kSessions / "sim_tabletop.tum");
    const Eigen::Vector3d p = T_world_cam.inverse() * Eigen::Vector3d(0.15, -0.08, 0.0395);
    // Distortion is mild at the probe; a pinhole projection is within a pixel or two.
    const int x = static_cast<int>(std::lround(524.8 * p.x() / p.z() + 318.6));
    const int y = static_cast<int>(std::lround(525.4 * p.y() / p.z() + 241.9));
    ASSERT_TRUE(x > 0 && x < 640 && y > 0 && y < 480);
    const cv::Vec3b bgr = image.at<cv::Vec3b>(y, x);
    EXPECT_GT(bgr[2], 150) << "red where the probe is";
    EXPECT_LT(bgr[1], 40);
    EXPECT_LT(bgr[0], 40);

    CliRun missing = mixray("render " + q(session) + " --scene " + q(scene) + " -o " +
                            q(dir / "x.mkv") + " --pose-stream nope/pose");
    EXPECT_EQ(missing.exit_code, 3) << missing.output;
    EXPECT_NE(missing.output.find("truth/pose"), std::string::npos) << missing.output;
    // A recording without a pose stream, and a scene camera without a pose: said plainly.
    CliRun none = mixray("render " + q(kSessions / "pattern_rgbd.mkv") + " --scene " + q(scene) +
                         " -o " + q(dir / "y.mkv"));
    EXPECT_NE(none.exit_code, 0) << none.output;
    EXPECT_NE(none.output.find("no pose stream"), std::string::npos) << none.output;
}

}  // namespace
}  // namespace mixray
