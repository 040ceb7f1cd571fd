// The mixray command line end to end: exit codes, messages, and the bundled session.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <string>

#include "cli_runner.h"
#include "test_data.h"

namespace mixray {
namespace {

namespace fs = std::filesystem;

using test::CliRun;
using test::mixray;
using test::q;

const fs::path kSession = test::fixturesDir() / "sessions" / "pattern_rgbd.mkv";

TEST(Cli, HelpAndUsageErrors) {
    EXPECT_EQ(mixray("--help").exit_code, 0);
    CliRun none = mixray("");
    EXPECT_EQ(none.exit_code, 2) << none.output;
    CliRun unknown = mixray("frobnicate");
    EXPECT_EQ(unknown.exit_code, 2) << unknown.output;
    for (const char* command : {"devices", "record", "info", "play", "convert", "bench graph",
                                "bench render", "bench drivers"}) {
        CliRun help = mixray(std::string(command) + " --help");
        EXPECT_EQ(help.exit_code, 0) << command;
        EXPECT_NE(help.output.find("Usage"), std::string::npos) << command;
    }
}

TEST(Cli, DevicesSaysPlainlyWhenThereIsNoHardware) {
    CliRun run = mixray("devices");
    EXPECT_EQ(run.exit_code, 0) << run.output;
    EXPECT_NE(run.output.find("No camera or sensor found"), std::string::npos) << run.output;
    CliRun virt = mixray("devices --virtual --json");
    ASSERT_EQ(virt.exit_code, 0) << virt.output;
    auto list = nlohmann::json::parse(virt.output);
    ASSERT_GE(list.size(), 2u);
    EXPECT_EQ(list[0]["backend"], "pattern");
}

TEST(Cli, InfoDescribesTheBundledSession) {
    CliRun run = mixray("info --json " + q(kSession));
    ASSERT_EQ(run.exit_code, 0) << run.output;
    auto info = nlohmann::json::parse(run.output);
    EXPECT_EQ(info["format"], "mixray-mkv");
    EXPECT_EQ(info["frames"], 150);
    EXPECT_TRUE(info["complete"]);
    ASSERT_EQ(info["streams"].size(), 3u);
    EXPECT_EQ(info["streams"][0]["name"], "rgbd/color");
    EXPECT_EQ(info["streams"][1]["format"], "depth16");
    EXPECT_EQ(info["streams"][2]["frames"], 30);
    EXPECT_EQ(info["streams"][0]["gaps"], 0);
    EXPECT_NEAR(info["streams"][0]["measured_fps"].get<double>(), 30.0, 0.1);
    ASSERT_EQ(info["attachments"].size(), 1u);
    EXPECT_EQ(info["attachments"][0]["name"], "rig.yaml");
    CliRun text = mixray("info " + q(kSession));
    EXPECT_EQ(text.exit_code, 0);
    EXPECT_NE(text.output.find("mono/mono"), std::string::npos) << text.output;
}

TEST(Cli, BadInputGivesExitCode3AndNamesTheFile) {
    const fs::path dir = test::tempDir();
    CliRun missing = mixray("info " + q(dir / "nope.mkv"));
    EXPECT_EQ(missing.exit_code, 3) << missing.output;
    EXPECT_NE(missing.output.find("nope.mkv"), std::string::npos) << missing.output;

    // A recording cut off mid-file: what was complete is described, the damage reported.
    const fs::path cut = dir / "cut.mkv";
    fs::copy_file(kSession, cut);
    fs::resize_file(cut, fs::file_size(cut) * 2 / 3);
    CliRun truncated = mixray("info " + q(cut));
    EXPECT_EQ(truncated.exit_code, 3) << truncated.output;
    EXPECT_NE(truncated.output.find("readable up to frame"), std::string::npos) << truncated.output;

    const fs::path rig = dir / "bad_rig.yaml";
    std::ofstream(rig) << "rig: x\ndevices:\n  - name: a\n    driver: pattern\n    fps: fast\n";
    CliRun bad_rig = mixray("record " + q(rig) + " -o " + q(dir / "x.mkv"));
    EXPECT_EQ(bad_rig.exit_code, 3) << bad_rig.output;
    EXPECT_NE(bad_rig.output.find("bad_rig.yaml:5"), std::string::npos) << bad_rig.output;
    EXPECT_FALSE(fs::exists(dir / "x.mkv"));
}

TEST(Cli, RecordThenPlayThenConvertRoundTrip) {
    const fs::path dir = test::tempDir();
    const fs::path out = dir / "session.mkv";
    CliRun record =
        mixray("record " + q(test::fixturesDir() / "rigs" / "pattern_rgbd.yaml") + " -o " + q(out));
    ASSERT_EQ(record.exit_code, 0) << record.output;
    EXPECT_NE(record.output.find("recorded 150 frames"), std::string::npos) << record.output;
    EXPECT_NE(record.output.find("sync"), std::string::npos) << record.output;

    // The recording says how its host stamps map to UTC (the sun needs the time of day): UTC
    // minus the monotonic clock, now.
    const auto recorded = nlohmann::json::parse(mixray("info --json " + q(out)).output);
    const int64_t utc_minus_host =
        std::stoll(recorded["tags"]["utc_minus_host_ns"].get<std::string>());
    const int64_t now_utc_minus_host = std::chrono::duration_cast<std::chrono::nanoseconds>(
                                           std::chrono::system_clock::now().time_since_epoch())
                                           .count() -
                                       std::chrono::duration_cast<std::chrono::nanoseconds>(
                                           std::chrono::steady_clock::now().time_since_epoch())
                                           .count();
    EXPECT_LT(std::llabs(utc_minus_host - now_utc_minus_host), 60'000'000'000LL);
    // And whether this host's clock was PTP-locked, as the summary said.
    ASSERT_TRUE(recorded["tags"].contains("host_ptp")) << recorded.dump();
    const std::string host_ptp = recorded["tags"]["host_ptp"].get<std::string>();
    EXPECT_TRUE(host_ptp.rfind("PTP-locked", 0) == 0 || host_ptp.rfind("not PTP-locked", 0) == 0)
        << host_ptp;
    EXPECT_NE(record.output.find("host clock: " + host_ptp), std::string::npos) << record.output;

    CliRun again =
        mixray("record " + q(test::fixturesDir() / "rigs" / "pattern_rgbd.yaml") + " -o " + q(out));
    EXPECT_EQ(again.exit_code, 2) << "refuses to overwrite without --force";

    CliRun play = mixray("play --fast " + q(out));
    ASSERT_EQ(play.exit_code, 0) << play.output;
    EXPECT_NE(play.output.find("replay/color"), std::string::npos) << play.output;
    EXPECT_NE(play.output.find("60 frames"), std::string::npos) << play.output;

    // mkv -> TUM folder -> mkv keeps colour and depth frames and their stamps (to the
    // microsecond TUM names keep); mkv -> PCL TIFF folder works too.
    // (The mono stream and the rig attachment do not fit those formats: left out on request.)
    CliRun to_tum = mixray("convert --drop-unsupported " + q(out) + " " + q(dir / "tum"));
    ASSERT_EQ(to_tum.exit_code, 0) << to_tum.output;
    EXPECT_TRUE(fs::exists(dir / "tum" / "rgb.txt"));
    CliRun to_pcl =
        mixray("convert --drop-unsupported --to pcl-tiff " + q(out) + " " + q(dir / "pcl"));
    ASSERT_EQ(to_pcl.exit_code, 0) << to_pcl.output;
    EXPECT_TRUE(fs::exists(dir / "pcl"));
    CliRun back = mixray("convert " + q(dir / "tum") + " " + q(dir / "back.mkv"));
    ASSERT_EQ(back.exit_code, 0) << back.output;
    auto a = nlohmann::json::parse(mixray("info --json " + q(out)).output);
    auto b = nlohmann::json::parse(mixray("info --json " + q(dir / "back.mkv")).output);
    ASSERT_EQ(b["streams"].size(), 2u);
    EXPECT_EQ(b["streams"][0]["frames"], a["streams"][0]["frames"]);
    EXPECT_EQ(b["streams"][1]["frames"], a["streams"][1]["frames"]);
    // The first colour stamp survives to the microsecond.
    EXPECT_EQ(b["streams"][0]["first_stamp_ns"].get<int64_t>() / 1000,
              a["streams"][0]["first_stamp_ns"].get<int64_t>() / 1000);
}

// A rig whose device is the Kinect v1 .oni recording, opened by the openni2 backend.
TEST(Cli, RecordsAKinectRecordingThroughTheOpenNI2Backend) {
    const fs::path oni = test::kinectV1Oni();
    const fs::path empty =
        test::sharedDataDir() / "01_oni" / "negative" / "bloyot_empty_image_only.oni";
    MIXRAY_REQUIRE_SHARED_DATA(oni);
    MIXRAY_REQUIRE_SHARED_DATA(empty);
    const fs::path dir = test::tempDir();
    const auto writeRig = [&](const fs::path& rig, const fs::path& id) {
        std::ofstream(rig) << "rig: oni\ndevices:\n  - name: kinect\n    driver: openni2\n"
                           << "    id: " << id.string() << "\n    options: { pace: fast }\n";
    };
    writeRig(dir / "rig.yaml", oni);
    CliRun record = mixray("record " + q(dir / "rig.yaml") + " -o " + q(dir / "kinect.mkv"));
    ASSERT_EQ(record.exit_code, 0) << record.output;
    EXPECT_NE(record.output.find("recorded 24 frames"), std::string::npos) << record.output;
    const auto info = nlohmann::json::parse(mixray("info --json " + q(dir / "kinect.mkv")).output);
    ASSERT_EQ(info["streams"].size(), 2u);
    EXPECT_EQ(info["streams"][0]["name"], "kinect/depth");
    EXPECT_EQ(info["streams"][0]["format"], "depth16");
    EXPECT_EQ(info["streams"][0]["frames"], 12);
    EXPECT_EQ(info["streams"][1]["name"], "kinect/color");
    EXPECT_EQ(info["streams"][1]["frames"], 12);

    writeRig(dir / "empty.yaml", empty);
    CliRun bad = mixray("record " + q(dir / "empty.yaml") + " -o " + q(dir / "empty.mkv"));
    EXPECT_EQ(bad.exit_code, 3) << bad.output;
    EXPECT_NE(bad.output.find("bloyot_empty_image_only.oni"), std::string::npos) << bad.output;
}

TEST(Cli, ConvertsTheRealTumPairToMkvAndBackByteForByte) {
    const fs::path src = test::sharedDataDir() / "02_rgbd_single_frames_open3d";
    MIXRAY_REQUIRE_SHARED_DATA(src / "TUM_depth.png");
    const fs::path dir = test::tempDir();
    const fs::path tum = dir / "tum";
    fs::create_directories(tum / "rgb");
    fs::create_directories(tum / "depth");
    fs::copy_file(src / "TUM_color.png", tum / "rgb" / "1305031102.175304.png");
    fs::copy_file(src / "TUM_depth.png", tum / "depth" / "1305031102.160407.png");
    std::ofstream(tum / "rgb.txt")
        << "# color images\n1305031102.175304 rgb/1305031102.175304.png\n";
    std::ofstream(tum / "depth.txt")
        << "# depth maps\n1305031102.160407 depth/1305031102.160407.png\n";

    CliRun to_mkv = mixray("convert " + q(tum) + " " + q(dir / "tum.mkv"));
    ASSERT_EQ(to_mkv.exit_code, 0) << to_mkv.output;
    CliRun to_tum = mixray("convert " + q(dir / "tum.mkv") + " " + q(dir / "back"));
    ASSERT_EQ(to_tum.exit_code, 0) << to_tum.output;
    auto slurp = [](const fs::path& p) {
        std::ifstream in(p, std::ios::binary);
        return std::string(std::istreambuf_iterator<char>(in), {});
    };
    EXPECT_EQ(slurp(dir / "back" / "rgb.txt"), slurp(tum / "rgb.txt"));
    EXPECT_EQ(slurp(dir / "back" / "depth.txt"), slurp(tum / "depth.txt"));
    auto a = nlohmann::json::parse(mixray("info --json " + q(tum)).output);
    auto b = nlohmann::json::parse(mixray("info --json " + q(dir / "back")).output);
    EXPECT_EQ(a["streams"], b["streams"]);
}

// A red wall 2.95 m in front of a camera at the origin, composited into a real Kinect frame:
// visible exactly where the recorded depth is missing or farther, the camera image elsewhere.
// Depth in TUM units (5000 per metre) and a depth map stored after its colour image (PCL TIFF)
// both reach the renderer. (--depth-rays none: with the light behind the camera, real surfaces
// would rightly shadow parts of the wall in the other modes.)
void expectHiddenWhereTheDepthIsNearer(const fs::path& dir, const fs::path& session,
                                       const fs::path& color_file, const fs::path& depth_file,
                                       double depth_units_per_m) {
    fs::create_directories(dir);
    std::ofstream(dir / "wall.yaml") << R"(materials:
  red: { type: diffuse, albedo: [0.8, 0, 0] }
objects:
  - name: wall
    shape: { box: { size: [10, 10, 0.1] } }
    material: red
    pose: { translation: [0, 0, 3.0] }
lights:
  - { name: sun, type: directional, direction: [0, 0, 1], irradiance: 3 }
camera:
  pose: { translation: [0, 0, 0] }
  model: { width: 640, height: 480, fx: 525, fy: 525, cx: 319.5, cy: 239.5 }
)";
    CliRun run = mixray("render " + q(session) + " --scene " + q(dir / "wall.yaml") + " -o " +
                        q(dir / "out.mkv") + " --png-dir " + q(dir / "png") +
                        " --max-frames 1 --depth-rays none");
    ASSERT_EQ(run.exit_code, 0) << run.output;
    const cv::Mat out = cv::imread((dir / "png" / "frame_000000.png").string());
    const cv::Mat camera = cv::imread(color_file.string());
    const cv::Mat depth = cv::imread(depth_file.string(), cv::IMREAD_ANYDEPTH);
    ASSERT_FALSE(out.empty() || camera.empty() || depth.empty());
    ASSERT_EQ(depth.type(), CV_16UC1);
    int hidden = 0, shown = 0;
    for (int y = 0; y < out.rows; ++y)
        for (int x = 0; x < out.cols; ++x) {
            const double z = depth.at<uint16_t>(y, x) / depth_units_per_m;
            const cv::Vec3b o = out.at<cv::Vec3b>(y, x);
            if (z > 0 && z < 2.94) {
                ++hidden;
                ASSERT_EQ(o, camera.at<cv::Vec3b>(y, x)) << x << "," << y;
            } else if (z == 0 || z > 2.96) {
                ++shown;
                ASSERT_TRUE(o[0] == 0 && o[1] == 0 && o[2] > 0) << x << "," << y;
            }
        }
    EXPECT_GT(hidden, 10000);
    EXPECT_GT(shown, 1000);
}

TEST(Cli, RenderHidesVirtualObjectsBehindRealKinectDepth) {
    const fs::path tum_src = test::sharedDataDir() / "02_rgbd_single_frames_open3d";
    const fs::path pcl = test::sharedDataDir() / "02_rgbd_pcl_openni_tiff";
    MIXRAY_REQUIRE_SHARED_DATA(tum_src / "TUM_depth.png");
    MIXRAY_REQUIRE_SHARED_DATA(pcl / "frame_20121214T142255.814212_depth.tiff");
    const fs::path dir = test::tempDir();
    const fs::path tum = dir / "tum";
    fs::create_directories(tum / "rgb");
    fs::create_directories(tum / "depth");
    fs::copy_file(tum_src / "TUM_color.png", tum / "rgb" / "1305031102.175304.png");
    fs::copy_file(tum_src / "TUM_depth.png", tum / "depth" / "1305031102.160407.png");
    std::ofstream(tum / "rgb.txt") << "1305031102.175304 rgb/1305031102.175304.png\n";
    std::ofstream(tum / "depth.txt") << "1305031102.160407 depth/1305031102.160407.png\n";
    {
        SCOPED_TRACE("TUM");
        expectHiddenWhereTheDepthIsNearer(dir / "tum_out", tum, tum_src / "TUM_color.png",
                                          tum_src / "TUM_depth.png", 5000);
    }
    {
        SCOPED_TRACE("PCL TIFF");
        expectHiddenWhereTheDepthIsNearer(dir / "pcl_out", pcl,
                                          pcl / "frame_20121214T142255.814212_rgb.tiff",
                                          pcl / "frame_20121214T142255.814212_depth.tiff", 1000);
    }
}

TEST(Cli, RenderCompositesTheSceneIntoEveryFrame) {
    const fs::path dir = test::tempDir();
    CliRun run = mixray("render " + q(kSession) + " --scene " +
                        q(test::fixturesDir() / "scenes" / "pattern_session.yaml") + " -o " +
                        q(dir / "out.mkv") + " --png-dir " + q(dir / "png") +
                        " --png-every 1 --max-frames 2 --shadows hard");
    ASSERT_EQ(run.exit_code, 0) << run.output;
    EXPECT_NE(run.output.find("2 frames composited (ffv1)"), std::string::npos) << run.output;
    EXPECT_TRUE(fs::exists(dir / "png" / "frame_000000.png"));
    EXPECT_TRUE(fs::exists(dir / "png" / "frame_000001.png"));

    for (const char* mode : {"mesh", "none"}) {
        CliRun depth = mixray("render " + q(kSession) + " --scene " +
                              q(test::fixturesDir() / "scenes" / "pattern_session.yaml") + " -o " +
                              q(dir / (std::string(mode) + ".mkv")) +
                              " --max-frames 1 --shadows hard --depth-rays " + mode);
        ASSERT_EQ(depth.exit_code, 0) << depth.output;
        EXPECT_NE(depth.output.find("1 frames composited"), std::string::npos) << depth.output;
    }
    CliRun bad_depth = mixray("render " + q(kSession) + " --scene " +
                              q(test::fixturesDir() / "scenes" / "pattern_session.yaml") + " -o " +
                              q(dir / "z.mkv") + " --depth-rays triangles");
    EXPECT_EQ(bad_depth.exit_code, 2) << bad_depth.output;

    CliRun wrong_size =
        mixray("render " + q(kSession) + " --scene " +
               q(test::fixturesDir() / "scenes" / "demo.yaml") + " -o " + q(dir / "x.mkv"));
    EXPECT_NE(wrong_size.exit_code, 0) << wrong_size.output;
    CliRun no_scene = mixray("render " + q(kSession) + " --scene " + q(dir / "none.yaml") + " -o " +
                             q(dir / "y.mkv"));
    EXPECT_EQ(no_scene.exit_code, 3) << no_scene.output;
}

TEST(Cli, BenchGraphPrintsItsFigures) {
    CliRun run = mixray("bench graph --frames 300 --record-frames 10 --disk-mb 16 --dir " +
                        q(test::tempDir()));
    ASSERT_EQ(run.exit_code, 0) << run.output;
    for (const char* line :
         {"synchronized sets/s", "heap allocations per set", "pixel copies per frame",
          "raw disk write, ", "recording uncompressed,", "recording FFV1,"}) {
        EXPECT_NE(run.output.find(line), std::string::npos) << line << "\n" << run.output;
    }
}

// Each backend against its peer's own API; the figures themselves are the benchmark's, only
// their presence is checked.
TEST(Cli, BenchDriversComparesEachBackendWithItsPeer) {
    CliRun run = mixray("bench drivers --frames 60 --duration 0.5");
    ASSERT_EQ(run.exit_code, 0) << run.output;
    for (const char* line : {"ratio = mixray / peer", "no peer: the backend is its own reference",
                             "pattern_rgbd.mkv, pace=fast loop", "Matroska reader next()",
                             "in-process fake camera Mono8 512x512 at 200 fps",
                             "ArvStream pop loop", "no V4L2 capture node here"}) {
        EXPECT_NE(run.output.find(line), std::string::npos) << line << "\n" << run.output;
    }
    if (std::filesystem::exists(test::kinectV1Oni())) {
        EXPECT_NE(run.output.find("VideoStream::readFrame"), std::string::npos) << run.output;
    }
    if (access("/usr/bin/arv-fake-gv-camera-0.8", X_OK) == 0) {
        EXPECT_NE(run.output.find("GigE Vision simulator on loopback"), std::string::npos)
            << run.output;
    }
}

TEST(Cli, BenchDriversSaysWhichPeerIsMissing) {
    CliRun run =
        mixray("bench drivers --frames 60 --backends openni2 --shared-data " + q(test::tempDir()));
    EXPECT_EQ(run.exit_code, 0) << run.output;
    EXPECT_NE(run.output.find("peer missing: "), std::string::npos) << run.output;
    EXPECT_NE(run.output.find("3dj_kinect1_test.oni"), std::string::npos) << run.output;
    CliRun bad = mixray("bench drivers --backends pattern,nope");
    EXPECT_NE(bad.exit_code, 0) << bad.output;
    EXPECT_NE(bad.output.find("unknown backend 'nope'"), std::string::npos) << bad.output;
}

TEST(Cli, BenchRenderRejectsBadArguments) {
    for (const char* args :
         {"--size 64by48", "--size 64x48,8x8", "--size ''", "--scenes nope", "--scenes teapot,",
          "--frames 0", "--threads -1", "--repeats 0", "--map-sizes 8", "--map-sizes 512,x"}) {
        CliRun run = mixray(std::string("bench render ") + args);
        EXPECT_EQ(run.exit_code, 2) << args << "\n" << run.output;
    }
    CliRun size = mixray("bench render --size 64by48");
    EXPECT_NE(size.output.find("'64by48' is not WIDTHxHEIGHT"), std::string::npos) << size.output;
    CliRun scene = mixray("bench render --scenes teapot,nope");
    EXPECT_NE(scene.output.find("unknown scene 'nope'"), std::string::npos) << scene.output;
}

TEST(Cli, BenchRenderSaysWhichDataIsMissing) {
    CliRun run = mixray("bench render --size 64x48 --frames 1 --scenes teapot --shared-data " +
                        q(test::tempDir()));
    EXPECT_EQ(run.exit_code, 0) << run.output;
    EXPECT_NE(run.output.find("teapot: skipped: "), std::string::npos) << run.output;
    EXPECT_NE(run.output.find("newell_teapot.obj not found"), std::string::npos) << run.output;
    CliRun json = mixray(
        "bench render --size 64x48 --frames 1 --scenes teapot --json "
        "--shared-data " +
        q(test::tempDir()));
    EXPECT_EQ(json.exit_code, 0) << json.output;
    const auto figures = nlohmann::json::parse(json.output, nullptr, false);
    ASSERT_TRUE(figures.is_array()) << json.output;
    ASSERT_EQ(figures.size(), 1u);
    EXPECT_EQ(figures[0]["scene"], "teapot");
    EXPECT_NE(figures[0]["skipped"].get<std::string>().find("newell_teapot.obj not found"),
              std::string::npos);
}

TEST(Cli, BenchRenderPrintsItsFigures) {
    MIXRAY_REQUIRE_SHARED_DATA(test::sharedDataDir() / "06_models" / "newell_teapot.obj");
    CliRun run = mixray("bench render --size 64x48 --frames 1 --repeats 1 --scenes teapot");
    ASSERT_EQ(run.exit_code, 0) << run.output;
    for (const char* line : {"teapot: primary only, 64x48", "teapot: + hard shadows, 64x48",
                             "teapot: + shadows + 3 bounces, 64x48",
                             "teapot: + shadows + 3 bounces + bloom and glare, 64x48",
                             "teapot: + shadows + 3 bounces + camera noise matched, 64x48", "fps ",
                             "pixels traced", "rays/frame  primary", "Mrays/s", "bare Embree",
                             "efficiency", "bare Embree, each way: primary rtcIntersect1 ",
                             ", rtcIntersect16 ", "; shadow rtcOccluded1 "}) {
        EXPECT_NE(run.output.find(line), std::string::npos) << line << "\n" << run.output;
    }
    EXPECT_EQ(run.output.find("does not match"), std::string::npos) << run.output;

    CliRun json = mixray("bench render --size 64x48 --frames 1 --repeats 1 --scenes teapot --json");
    ASSERT_EQ(json.exit_code, 0) << json.output;
    const auto figures = nlohmann::json::parse(json.output, nullptr, false);
    ASSERT_TRUE(figures.is_array()) << json.output;
    ASSERT_EQ(figures.size(), 5u);
    for (const auto& f : figures) {
        EXPECT_EQ(f["width"], 64);
        EXPECT_TRUE(f["log_matches_stats"].get<bool>());
        EXPECT_GT(f["fps"].get<double>(), 0);
        EXPECT_GT(f["rays_per_frame"]["primary"].get<double>(), 0);
        EXPECT_GT(f["bare_ms"]["total"].get<double>(), 0);
        EXPECT_GE(f["bare_tried"].size(), 2u);  // primaries as single rays and as packets
    }
    EXPECT_EQ(figures[0]["rays_per_frame"]["shadow"].get<double>(), 0);  // primary only
    EXPECT_GT(figures[2]["rays_per_frame"]["secondary"].get<double>(), 0);
    // The lens effects add no ray to the frame they follow.
    EXPECT_EQ(figures[3]["rays_per_frame"]["secondary"], figures[2]["rays_per_frame"]["secondary"]);
    // Nor does camera matching.
    EXPECT_EQ(figures[4]["rays_per_frame"]["secondary"], figures[2]["rays_per_frame"]["secondary"]);
}

// The soft scene measures the adaptive aim: each row against the uniform one, its speed-up and
// the RMSE of its composite; the hard-shadow row is the floor, the row without rays to the lights
// the ceiling.
TEST(Cli, BenchRenderSoftComparesEachRowWithTheUniformOne) {
    MIXRAY_REQUIRE_SHARED_DATA(test::sharedDataDir() / "06_models" / "newell_teapot.obj");
    CliRun run = mixray("bench render --size 64x48 --frames 1 --repeats 1 --scenes soft");
    ASSERT_EQ(run.exit_code, 0) << run.output;
    for (const char* line :
         {"soft shadows, 20 samples uniform, 3 bounces (reference), 64x48",
          "soft shadows, 20 samples adaptive, 3 bounces, 64x48",
          "hard shadows (one ray to the lamp's centre), 3 bounces, 64x48",
          "no shadow rays to the lights (every light unoccluded), 3 bounces, 64x48",
          "vs the reference: ", "x its fps; composite RMSE "}) {
        EXPECT_NE(run.output.find(line), std::string::npos) << line << "\n" << run.output;
    }
    CliRun json = mixray("bench render --size 64x48 --frames 1 --repeats 1 --scenes soft --json");
    ASSERT_EQ(json.exit_code, 0) << json.output;
    const auto rows = nlohmann::json::parse(json.output, nullptr, false);
    ASSERT_TRUE(rows.is_array() && rows.size() == 4u) << json.output;
    EXPECT_TRUE(rows[0]["rmse_vs_reference"].is_null());
    EXPECT_TRUE(rows[0]["speedup_vs_reference"].is_null());
    for (int i : {1, 2, 3}) {
        EXPECT_GE(rows[i]["rmse_vs_reference"].get<double>(), 0);
        EXPECT_GT(rows[i]["speedup_vs_reference"].get<double>(), 0);
    }
    // One ray per point traces fewer shadow rays than the adaptive test, which traces fewer
    // than 20 per point.
    EXPECT_LT(rows[2]["rays_per_frame"]["shadow"].get<double>(),
              rows[1]["rays_per_frame"]["shadow"].get<double>());
    EXPECT_LT(rows[1]["rays_per_frame"]["shadow"].get<double>(),
              rows[0]["rays_per_frame"]["shadow"].get<double>());
    // The ceiling traces no ray to the lamp: its only shadow rays are those that test whether
    // the camera saw a real point that a reflection shows.
    EXPECT_LT(rows[3]["rays_per_frame"]["shadow"].get<double>(),
              rows[2]["rays_per_frame"]["shadow"].get<double>());
}

// The same teapot frame in mixray and in POV-Ray: both timed (POV-Ray's median run), and the
// images alike.
// The compositor's quality ladder (render::qualityLadder), each rung a row against the first,
// full quality: its label numbered as the run's status line numbers it, its fps, its RMSE.
TEST(Cli, BenchRenderLadderComparesEveryRungWithFullQuality) {
    MIXRAY_REQUIRE_SHARED_DATA(test::sharedDataDir() / "06_models" / "newell_teapot.obj");
    CliRun run = mixray("bench render --size 64x48 --frames 1 --repeats 1 --scenes ladder");
    ASSERT_EQ(run.exit_code, 0) << run.output;
    for (const char* line :
         {"ladder: rung 1 of 5 (spp 4, shadows adaptive/20, depth 3) (reference), 64x48",
          "ladder: rung 2 of 5 (spp 1, shadows adaptive/20, depth 3), 64x48",
          "ladder: rung 5 of 5 (spp 1, shadows hard, depth 0), 64x48", "fps ",
          "vs the reference: ", "x its fps; composite RMSE "}) {
        EXPECT_NE(run.output.find(line), std::string::npos) << line << "\n" << run.output;
    }
    CliRun json = mixray("bench render --size 64x48 --frames 1 --repeats 1 --scenes ladder --json");
    ASSERT_EQ(json.exit_code, 0) << json.output;
    const auto rows = nlohmann::json::parse(json.output, nullptr, false);
    ASSERT_TRUE(rows.is_array() && rows.size() == 5u) << json.output;
    EXPECT_TRUE(rows[0]["rmse_vs_reference"].is_null());
    for (int i = 0; i < 5; ++i) {
        EXPECT_EQ(rows[i]["rung"], i + 1);
        EXPECT_GT(rows[i]["fps"].get<double>(), 0);
        if (i > 0) {
            EXPECT_GE(rows[i]["rmse_vs_reference"].get<double>(), 0);
            EXPECT_GT(rows[i]["speedup_vs_reference"].get<double>(), 0);
        }
    }
    // Rung 5 gives up the bounces: fewer secondary rays than rung 4's one bounce.
    EXPECT_LT(rows[4]["rays_per_frame"]["secondary"].get<double>(),
              rows[3]["rays_per_frame"]["secondary"].get<double>());
}

TEST(Cli, BenchRenderAgainstPovray) {
    MIXRAY_REQUIRE_SHARED_DATA(test::sharedDataDir() / "06_models" / "newell_teapot.obj");
    EXPECT_EQ(mixray("bench render --peer blender").exit_code, 2);
    CliRun json = mixray("bench render --peer povray --size 96x72 --frames 1 --threads 2 --json");
    ASSERT_EQ(json.exit_code, 0) << json.output;
    if (json.output.find("peer povray: skipped: cannot run povray") != std::string::npos)
        GTEST_SKIP() << json.output;
    const auto figures = nlohmann::json::parse(json.output, nullptr, false);
    ASSERT_TRUE(figures.is_array()) << json.output;
    ASSERT_EQ(figures.size(), 3u);  // primary only, + hard shadows, + 3 bounces
    for (const auto& f : figures) {
        EXPECT_EQ(f["peer"], "povray");
        EXPECT_GE(f["mixray_rays"].get<double>(), 96 * 72);  // every pixel
        EXPECT_GT(f["mixray_ms"].get<double>(), 0);
        EXPECT_GT(f["povray_trace_ms"].get<double>(), 0);
        // POV-Ray runs --repeats times (3 by default); the median run counts.
        std::vector<double> runs = f["povray_trace_runs_ms"].get<std::vector<double>>();
        ASSERT_EQ(runs.size(), 3u) << f.dump();
        std::sort(runs.begin(), runs.end());
        EXPECT_EQ(f["povray_trace_ms"].get<double>(), runs[1]) << f.dump();
        EXPECT_GT(f["ar_frame_ms"].get<double>(), 0);
        EXPECT_LT(f["ar_frame_rays"].get<double>(), f["mixray_rays"].get<double>());
        EXPECT_LT(f["rmse_codes"].get<double>(), 8.0) << f.dump();
        const std::filesystem::path images = f["images"].get<std::string>();
        for (const char* file : {"scene.pov", "scene.png", "mixray.png", "difference_x8.png"})
            EXPECT_TRUE(std::filesystem::exists(images / file)) << images / file;
    }
    EXPECT_GT(figures[2]["mixray_rays"].get<double>(), figures[1]["mixray_rays"].get<double>());
    // The bench leaves its files for a person to look at; the test does not.
    std::error_code ignored;
    std::filesystem::remove_all(
        std::filesystem::path(figures[0]["images"].get<std::string>()).parent_path(), ignored);
}

// Kán & Kaufmann's Table 1: each row's photon shooting and grid times where the photons are shot
// again, none where they are reused, and the row without caustics has none at all.
TEST(Cli, BenchRenderTimesTheCausticsPhases) {
    MIXRAY_REQUIRE_SHARED_DATA(test::sharedDataDir() / "06_models" / "photon_dragon_100k.obj");
    CliRun json =
        mixray("bench render --size 96x72 --frames 2 --repeats 1 --scenes caustics --json");
    ASSERT_EQ(json.exit_code, 0) << json.output;
    const auto figures = nlohmann::json::parse(json.output, nullptr, false);
    ASSERT_TRUE(figures.is_array()) << json.output;
    ASSERT_EQ(figures.size(), 8u);
    EXPECT_EQ(figures[0]["caustics"]["photons_stored"].get<double>(), 0);
    for (size_t i = 1; i < figures.size(); ++i) {
        const std::string config = figures[i]["config"].get<std::string>();
        SCOPED_TRACE(config);
        EXPECT_GT(figures[i]["caustics"]["photons_stored"].get<double>(), 100);
        if (config.find("shot every frame") != std::string::npos)
            EXPECT_GT(figures[i]["caustics"]["t_p_ms"].get<double>(), 0);
        else
            EXPECT_EQ(figures[i]["caustics"]["t_p_ms"].get<double>(), 0);
    }
}

// Castro et al.'s Tabela I: ray-traced soft shadows (the reference), hard shadows, then per map
// size the hard, PCF, packed-PCF, VSM and 8-bit VSM maps, each with its map time and its
// composite's difference from the reference.
TEST(Cli, BenchRenderComparesShadowMapsWithRayTracedShadows) {
    MIXRAY_REQUIRE_SHARED_DATA(test::sharedDataDir() / "06_models" / "newell_teapot.obj");
    CliRun json = mixray(
        "bench render --size 96x72 --frames 1 --repeats 1 --scenes shadow-maps --map-sizes "
        "64,128 --json");
    ASSERT_EQ(json.exit_code, 0) << json.output;
    const auto figures = nlohmann::json::parse(json.output, nullptr, false);
    ASSERT_TRUE(figures.is_array()) << json.output;
    ASSERT_EQ(figures.size(), 12u);
    EXPECT_EQ(figures[0]["rmse_vs_reference"], nullptr);
    EXPECT_EQ(figures[0]["shadow_map_ms"].get<double>(), 0);
    EXPECT_GT(figures[0]["rays_per_frame"]["shadow"].get<double>(), 0);
    for (size_t i = 2; i < figures.size(); ++i) {
        SCOPED_TRACE(figures[i]["config"].get<std::string>());
        EXPECT_NE(figures[i]["config"].get<std::string>().find("shadow map "), std::string::npos);
        EXPECT_GT(figures[i]["shadow_map_ms"].get<double>(), 0);
        // The map answers the shading points it covers: shadow rays are left only outside it
        // and towards the camera (real surfaces seen through glass).
        EXPECT_LT(figures[i]["rays_per_frame"]["shadow"].get<double>(),
                  figures[1]["rays_per_frame"]["shadow"].get<double>());
        const double rmse = figures[i]["rmse_vs_reference"].get<double>();
        EXPECT_GE(rmse, 0);
        EXPECT_LT(rmse, 40);
    }
}

}  // namespace
}  // namespace mixray
