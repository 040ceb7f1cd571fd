// Rig files: the examples parse to the expected structs, every malformed input is a clear
// kCorruptData error naming file, line and field, and calibration paths follow the rig file.
#include "mixray/graph/rig.h"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <fstream>
#include <sstream>

#include "test_data.h"

namespace mixray {

// gtest prints locations in failures as text.
void PrintTo(const SourceLocation& where, std::ostream* os) {
    *os << where.toString();
}

namespace {

std::string readText(const std::filesystem::path& path) {
    std::ifstream in(path, std::ios::binary);
    std::stringstream buffer;
    buffer << in.rdbuf();
    return buffer.str();
}

void writeText(const std::filesystem::path& path, std::string_view text) {
    std::filesystem::create_directories(path.parent_path());
    std::ofstream(path, std::ios::binary) << text;
}

std::string option(const RigDevice& device, const std::string& key) {
    auto it = device.config.options.find(key);
    return it == device.config.options.end() ? "<unset>" : it->second;
}

TEST(Rig, KinectEnvFixture) {
    const auto path = test::fixturesDir() / "rigs" / "kinect_env.yaml";
    auto rig = loadRig(path);
    ASSERT_TRUE(rig.isOk()) << rig.status().toString();
    EXPECT_EQ(rig->version, 1);
    EXPECT_EQ(rig->name, "tabletop");
    EXPECT_EQ(rig->source_path, path.string());
    EXPECT_EQ(rig->source_text, readText(path));
    ASSERT_EQ(rig->devices.size(), 2u);

    const RigDevice& kinect = rig->devices[0];
    EXPECT_EQ(kinect.name(), "kinect");
    EXPECT_EQ(kinect.config.driver, "openni2");
    EXPECT_EQ(kinect.config.id, "1d27/0600@1/4");
    EXPECT_EQ(kinect.id_kind, DeviceIdKind::kId);
    EXPECT_EQ(kinect.config.streams, (std::vector<std::string>{"depth", "color"}));
    EXPECT_EQ(kinect.where.line, 7);
    ASSERT_EQ(kinect.streams.size(), 2u);
    const RigStream* depth = kinect.findStream("depth");
    ASSERT_NE(depth, nullptr);
    EXPECT_EQ(depth->width, 640);
    EXPECT_EQ(depth->height, 480);
    EXPECT_EQ(depth->fps, 30.0);
    EXPECT_FALSE(depth->format.has_value());
    EXPECT_TRUE(depth->enabled);
    EXPECT_EQ(depth->queue, QueuePolicy::kLossless);
    EXPECT_EQ(depth->capacity, 8u);
    EXPECT_EQ(option(kinect, "registration"), "true");
    EXPECT_EQ(option(kinect, "depth.width"), "640");
    EXPECT_EQ(option(kinect, "depth.height"), "480");
    EXPECT_EQ(option(kinect, "color.fps"), "30");
    EXPECT_EQ(option(kinect, "color.format"), "<unset>");

    const RigDevice& env = rig->devices[1];
    EXPECT_EQ(env.name(), "env");
    EXPECT_EQ(env.config.driver, "v4l2");
    EXPECT_EQ(env.config.id, "/dev/video2");
    EXPECT_EQ(env.id_kind, DeviceIdKind::kUri);
    EXPECT_EQ(env.config.streams, std::vector<std::string>{"color"});
    const RigStream* color = env.findStream("color");
    ASSERT_NE(color, nullptr);
    EXPECT_EQ(color->width, 1280);
    EXPECT_EQ(color->height, 720);
    EXPECT_EQ(color->fps, 30.0);
    EXPECT_EQ(color->format, PixelFormat::kMJPEG);
    EXPECT_EQ(color->queue, QueuePolicy::kLossless);
    EXPECT_EQ(color->capacity, 16u);
    EXPECT_EQ(option(env, "exposure_us"), "8000");
    EXPECT_EQ(option(env, "auto_white_balance"), "false");
    EXPECT_EQ(option(env, "color.format"), "mjpeg");

    ASSERT_EQ(rig->sync.streams.size(), 3u);
    EXPECT_EQ(rig->sync.streams[0].name(), "kinect/depth");
    EXPECT_EQ(rig->sync.streams[2].name(), "env/color");
    EXPECT_EQ(rig->sync.max_skew_ms, 20.0);

    const auto rigs_dir = std::filesystem::absolute(path).parent_path().lexically_normal();
    ASSERT_EQ(rig->calibration.size(), 3u);
    const RigCalibrationFile* kinect_calibration = rig->findCalibration("kinect", "depth");
    ASSERT_NE(kinect_calibration, nullptr);
    EXPECT_EQ(kinect_calibration->path, "calib/kinect.yaml");
    EXPECT_EQ(kinect_calibration->resolved, rigs_dir / "calib" / "kinect.yaml");
    EXPECT_EQ(rig->findCalibration("env")->resolved, rigs_dir / "calib/env_fisheye.cameramodel");
    EXPECT_EQ(rig->findCalibration("other")->resolved, rigs_dir / "calib/rig_extrinsics.yaml");

    ASSERT_TRUE(rig->site.has_value());
    EXPECT_DOUBLE_EQ(rig->site->latitude_deg, 48.8584);
    EXPECT_DOUBLE_EQ(rig->site->longitude_deg, 2.2945);
    EXPECT_DOUBLE_EQ(rig->site->heading_deg, 135);
    EXPECT_DOUBLE_EQ(rig->site->altitude_m, 35);

    auto configs = rig->deviceConfigs();
    ASSERT_EQ(configs.size(), 2u);
    EXPECT_EQ(configs[1].name, "env");
}

TEST(Rig, PatternFixture) {
    auto rig = loadRig(test::fixturesDir() / "rigs" / "pattern_rgbd.yaml");
    ASSERT_TRUE(rig.isOk()) << rig.status().toString();
    EXPECT_EQ(rig->name, "pattern-rgbd");
    ASSERT_EQ(rig->devices.size(), 2u);
    const RigDevice& rgbd = rig->devices[0];
    EXPECT_EQ(rgbd.name(), "rgbd");
    EXPECT_EQ(rgbd.config.driver, "pattern");
    EXPECT_EQ(rgbd.config.id, "rgbd");
    EXPECT_EQ(rgbd.id_kind, DeviceIdKind::kId);
    EXPECT_EQ(rgbd.config.streams, (std::vector<std::string>{"color", "depth"}));
    EXPECT_EQ(rgbd.config.options.at("color.width"), "320");
    EXPECT_EQ(rgbd.config.options.at("frames"), "60");
    EXPECT_EQ(rgbd.config.options.at("realtime"), "false");
    const RigDevice& mono = rig->devices[1];
    EXPECT_EQ(mono.config.id, "mono");
    EXPECT_TRUE(mono.config.streams.empty());
    EXPECT_EQ(mono.config.options.at("drift_ppm"), "100");
    ASSERT_EQ(rig->sync.streams.size(), 3u);
    EXPECT_EQ(rig->sync.streams[2].name(), "mono/mono");
    EXPECT_DOUBLE_EQ(rig->sync.max_skew_ms, 10.0);
    EXPECT_TRUE(rig->calibration.empty());
    EXPECT_FALSE(rig->site.has_value());
}

// The complete example in docs/rig-format.md must stay a valid rig.
TEST(Rig, DocumentedExampleParses) {
    const std::string doc = readText(test::sourceDir() / "docs" / "rig-format.md");
    const size_t begin = doc.find("```yaml\n");
    ASSERT_NE(begin, std::string::npos);
    const size_t end = doc.find("```", begin + 8);
    ASSERT_NE(end, std::string::npos);
    auto rig = parseRig(doc.substr(begin + 8, end - begin - 8), "docs/rig.yaml");
    ASSERT_TRUE(rig.isOk()) << rig.status().toString();
    EXPECT_EQ(rig->devices.size(), 2u);
    const RigDevice& env = rig->devices[1];
    ASSERT_NE(env.findStream("ir"), nullptr);
    EXPECT_FALSE(env.findStream("ir")->enabled);
    EXPECT_EQ(env.config.streams, std::vector<std::string>{"color"});
    EXPECT_EQ(rig->devices[0].findStream("color")->format, PixelFormat::kRGB8);
    EXPECT_EQ(rig->findCalibration("env", "color")->resolved,
              std::filesystem::path("docs/calib/env_fisheye.cameramodel"));
    EXPECT_EQ(rig->findCalibration("env", "ir")->resolved,
              std::filesystem::path("docs/calib/rig_extrinsics.yaml"));
}

TEST(Rig, StreamForms) {
    auto rig = parseRig(R"(rig: forms
devices:
  - name: cam
    driver: aravis
    serial: GV01
    streams:
      - mono
      - { name: left, width: 1024, height: 768, fps: 12.5, format: bayer_rggb8, queue: live }
      - name: right
        enabled: false
        capacity: 2
    mode: { left: , right: 1024x768 }
)",
                        "forms.yaml");
    // "left:" with no mode is a mode entry for a listed stream without a value.
    ASSERT_FALSE(rig.isOk());
    EXPECT_EQ(rig.status().message(),
              "forms.yaml:12:13: devices[0].mode.left: expected WIDTHxHEIGHT@FPS like "
              "640x480@30, got nothing");

    rig = parseRig(R"(rig: forms
devices:
  - name: cam
    driver: aravis
    serial: GV01
    streams:
      - mono
      - { name: left, width: 1024, height: 768, fps: 12.5, format: bayer_rggb8, queue: live }
      - name: right
        enabled: false
        capacity: 2
    mode: { right: 1024x768, trigger: software }
)",
                   "forms.yaml");
    ASSERT_TRUE(rig.isOk()) << rig.status().toString();
    const RigDevice& cam = rig->devices[0];
    EXPECT_EQ(cam.id_kind, DeviceIdKind::kSerial);
    EXPECT_EQ(cam.config.id, "GV01");
    EXPECT_EQ(cam.config.streams, (std::vector<std::string>{"mono", "left"}));
    const RigStream* left = cam.findStream("left");
    ASSERT_NE(left, nullptr);
    EXPECT_EQ(left->fps, 12.5);
    EXPECT_EQ(left->format, PixelFormat::kBayerRGGB8);
    EXPECT_EQ(left->queue, QueuePolicy::kLive);
    EXPECT_EQ(left->where, (SourceLocation{"forms.yaml", 8, 9}));
    const RigStream* right = cam.findStream("right");
    ASSERT_NE(right, nullptr);
    EXPECT_FALSE(right->enabled);
    EXPECT_EQ(right->capacity, 2u);
    EXPECT_EQ(right->width, 1024);
    EXPECT_FALSE(right->fps.has_value());
    EXPECT_EQ(option(cam, "trigger"), "software");
    EXPECT_EQ(option(cam, "left.fps"), "12.5");
    EXPECT_EQ(option(cam, "right.height"), "768");

    // Mapping form with the mode shorthand and a bare entry.
    rig = parseRig(
        "rig: m\ndevices:\n  - name: k\n    driver: openni2\n    streams:\n"
        "      depth:\n      color: 1280x1024@15 rgb8\n",
        "m.yaml");
    ASSERT_TRUE(rig.isOk()) << rig.status().toString();
    EXPECT_EQ(rig->devices[0].config.streams, (std::vector<std::string>{"depth", "color"}));
    EXPECT_EQ(rig->devices[0].findStream("color")->height, 1024);
    EXPECT_FALSE(rig->devices[0].findStream("depth")->width.has_value());
}

struct BadRig {
    const char* label;
    std::string text;
    std::string where;     // expected "rig.yaml:LINE" or "rig.yaml:LINE:COLUMN" prefix
    std::string contains;  // expected field path and/or what is wrong
};

// A valid two-device rig with `insert` added at the end of the first device.
std::string withDevice(const std::string& insert) {
    return "rig: r\n"                         // 1
           "devices:\n"                       // 2
           "  - name: kinect\n"               // 3
           "    driver: openni2\n"            // 4
           "    streams: [depth, color]\n" +  // 5
           insert +
           "  - name: env\n"
           "    driver: v4l2\n";
}

std::vector<BadRig> badRigs() {
    const std::string ok_devices = "devices:\n  - name: a\n    driver: pattern\n";
    return {
        {"yaml syntax", "rig: [a, b\ndevices: x\n", "rig.yaml:", "YAML syntax error"},
        {"undefined alias", "rig: *nope\n", "rig.yaml:1:", "YAML syntax error"},
        {"empty file", "", "rig.yaml:1:1", "the file is empty"},
        {"comment only", "# nothing here\n", "rig.yaml:1:1", "the file is empty"},
        {"root list", "- rig: a\n", "rig.yaml:1:1", "expected a mapping with rig: and devices:"},
        {"root scalar", "hello\n", "rig.yaml:1:1", "got \"hello\""},
        {"two documents", "rig: a\n" + ok_devices + "---\nrig: b\n", "rig.yaml:5:1",
         "a second YAML document"},
        // yaml-cpp 0.7's LoadAll loops forever on these (found by rig_parser_fuzz).
        {"stray comma", ",\n", "rig.yaml:1:1", "unexpected ','"},
        {"stray comma in second document", "rig: a\n" + ok_devices + "---\n, x\n", "rig.yaml:6:1",
         "unexpected ','"},
        {"unknown top key", "rig: a\n" + ok_devices + "snyc: {}\n", "rig.yaml:5:1",
         "snyc: unknown field (did you mean sync?)"},
        {"duplicate key", "rig: a\nrig: b\n" + ok_devices, "rig.yaml:2:1",
         "rig: duplicate key (first given at line 1)"},
        {"missing rig", ok_devices, "rig.yaml:1:1", "rig: missing required field"},
        {"missing devices", "rig: a\n", "rig.yaml:1:1", "devices: missing required field"},
        {"empty devices", "rig: a\ndevices: []\n", "rig.yaml:2:10",
         "devices: expected a list of at least one device, got an empty list"},
        {"devices not a list", "rig: a\ndevices: kinect\n", "rig.yaml:2:10",
         "devices: expected a list of at least one device, got \"kinect\""},
        {"empty rig name", "rig:\n" + ok_devices, "rig.yaml:1:1", "rig: expected a value"},
        {"version 2", "version: 2\nrig: a\n" + ok_devices, "rig.yaml:1:10",
         "version: unsupported rig format version 2"},
        {"device not a mapping", "rig: a\ndevices:\n  - kinect\n", "rig.yaml:3:5",
         "devices[0]: expected a device mapping"},
        {"missing driver", "rig: a\ndevices:\n  - name: k\n", "rig.yaml:3:5",
         "devices[0].driver: missing required field"},
        {"typo in device key", withDevice("    drvier: x\n"), "rig.yaml:6:5",
         "devices[0].drvier: unknown field (did you mean driver?)"},
        {"bad device name", "rig: a\ndevices:\n  - name: a/b\n    driver: x\n", "rig.yaml:3:11",
         "devices[0].name: expected a name"},
        {"duplicate device", withDevice("  - name: env\n    driver: x\n"), "rig.yaml:8:5",
         "devices[2].name: duplicate device name \"env\" (first at rig.yaml:6:5)"},
        {"id and serial", withDevice("    id: a\n    serial: b\n"), "rig.yaml:7:13",
         "devices[0].serial: give one of id, serial and uri"},
        {"bad resolution",
         "rig: r\ndevices:\n  - name: kinect\n    driver: openni2\n  - name: env\n"
         "    driver: v4l2\n    mode: { depth: 640x }\n",
         "rig.yaml:7:20", "devices[1].mode.depth: expected WIDTHxHEIGHT@FPS like 640x480@30"},
        {"bad resolution got", withDevice("    mode:\n      depth: 640x\n"), "rig.yaml:7:14",
         "got \"640x\""},
        {"zero width mode", withDevice("    mode: { color: 0x480@30 }\n"), "rig.yaml:6:20",
         "devices[0].mode.color: image size out of range"},
        {"zero fps mode", withDevice("    mode: { color: 640x480@0 }\n"), "rig.yaml:6:20",
         "frame rate out of range"},
        {"unknown format", withDevice("    mode: { color: 640x480@30 rgb9 }\n"), "rig.yaml:6:20",
         "unknown pixel format \"rgb9\" (known: mono8,"},
        {"mode of unlisted stream", withDevice("    mode: { ir: 640x480 }\n"), "rig.yaml:6:13",
         "devices[0].mode.ir: stream ir is not listed under streams"},
        {"mode value a list", withDevice("    mode: { registration: [1] }\n"), "rig.yaml:6:27",
         "devices[0].mode.registration: expected a single value, got a list"},
        {"fps fast",
         "rig: r\ndevices:\n  - name: k\n    driver: x\n    streams:\n      color: { fps: fast }\n",
         "rig.yaml:6:21",
         "devices[0].streams.color.fps: expected a number above 0 up to 10000, "
         "got \"fast\""},
        {"negative width",
         "rig: r\ndevices:\n  - name: k\n    driver: x\n    streams:\n"
         "      color: { width: -640, height: 480 }\n",
         "rig.yaml:6:23",
         "devices[0].streams.color.width: expected an integer from 1 to 65535, "
         "got \"-640\""},
        {"width without height",
         "rig: r\ndevices:\n  - name: k\n    driver: x\n    streams:\n      color: { width: 8 }\n",
         "rig.yaml:6:14", "devices[0].streams.color: give both width and height"},
        {"mode and width",
         "rig: r\ndevices:\n  - name: k\n    driver: x\n    streams:\n"
         "      - { name: c, mode: 8x8, width: 8 }\n",
         "rig.yaml:6:38", "devices[0].streams[0].width: give either mode or width"},
        {"mode in both places",
         "rig: r\ndevices:\n  - name: k\n    driver: x\n    streams: { depth: 8x8 }\n"
         "    mode: { depth: 8x8 }\n",
         "rig.yaml:6:13", "devices[0].mode.depth: the mode of stream depth is also given"},
        {"bad queue",
         "rig: r\ndevices:\n  - name: k\n    driver: x\n    streams: { c: { queue: fast } }\n",
         "rig.yaml:5:28", "devices[0].streams.c.queue: expected live or lossless"},
        {"zero capacity",
         "rig: r\ndevices:\n  - name: k\n    driver: x\n    streams: { c: { capacity: 0 } }\n",
         "rig.yaml:5:31", "devices[0].streams.c.capacity: expected an integer from 1 to 4096"},
        {"bad enabled",
         "rig: r\ndevices:\n  - name: k\n    driver: x\n    streams: { c: { enabled: 2 } }\n",
         "rig.yaml:5:30", "expected true or false, got \"2\""},
        {"all disabled",
         "rig: r\ndevices:\n  - name: k\n    driver: x\n    streams: { c: { enabled: false } }\n",
         "rig.yaml:5:14", "devices[0].streams: every listed stream is disabled"},
        {"stream twice",
         withDevice("").replace(withDevice("").find("[depth, color]"), 14, "[depth, depth]"),
         "rig.yaml:5:22", "devices[0].streams[1]: stream depth is listed twice"},
        {"empty stream list",
         withDevice("").replace(withDevice("").find("[depth, color]"), 14, "[]"), "rig.yaml:5:14",
         "devices[0].streams: expected at least one stream"},
        {"nested option", withDevice("    options: { gain: { a: 1 } }\n"), "rig.yaml:6:22",
         "devices[0].options.gain: expected a single value, got a mapping"},
        {"option collides with mode",
         withDevice("    options: { registration: 1 }\n    mode: { registration: true }\n"),
         "rig.yaml:7:13", "devices[0].mode.registration: also set under options (line 6)"},
        {"option collides with stream",
         withDevice("    options: { depth.width: 1 }\n    mode: { depth: 8x8 }\n"), "rig.yaml:6:16",
         "devices[0].options.depth.width: collides with the width of stream"},
        {"sync unknown device", withDevice("") + "sync: { streams: [kinect/depth, cam/color] }\n",
         "rig.yaml:8:33", "sync.streams[1]: no device named \"cam\" (devices: kinect, env)"},
        {"sync unknown stream", withDevice("") + "sync:\n  streams: [kinect/depth, kinect/ir]\n",
         "rig.yaml:9:27",
         "sync.streams[1]: device kinect has no stream \"ir\" (streams: depth, "
         "color)"},
        {"sync any stream of unlisted device",
         withDevice("") + "sync:\n  streams: [kinect/depth, env/color, env/colour]\n  "
                          "max_skew_ms: -1\n",
         "rig.yaml:10:16", "sync.max_skew_ms: expected a number above 0"},
        {"sync one stream", withDevice("") + "sync: { streams: [kinect/depth] }\n", "rig.yaml:8:18",
         "sync.streams: expected a list of at least two streams"},
        {"sync duplicate", withDevice("") + "sync: { streams: [env/a, env/a] }\n", "rig.yaml:8:26",
         "sync.streams[1]: stream env/a is listed twice"},
        {"sync bad reference", withDevice("") + "sync: { streams: [kinect, env/a] }\n",
         "rig.yaml:8:19", "sync.streams[0]: expected DEVICE/STREAM"},
        {"sync missing streams", withDevice("") + "sync: { max_skew_ms: 3 }\n", "rig.yaml:8:7",
         "sync.streams: missing required field"},
        {"calibration not a path", withDevice("    calibration: [a]\n"), "rig.yaml:6:18",
         "devices[0].calibration: expected a value, got a list"},
        {"site latitude",
         "rig: a\n" + ok_devices + "site: { latitude_deg: 100, longitude_deg: 0 }\n",
         "rig.yaml:5:23", "site.latitude_deg: expected a number from -90 to 90, got \"100\""},
        {"site missing longitude", "rig: a\n" + ok_devices + "site: { latitude_deg: 10 }\n",
         "rig.yaml:5:7", "site.longitude_deg: missing required field"},
        {"nan", "rig: a\n" + ok_devices + "site: { latitude_deg: .nan, longitude_deg: 0 }\n",
         "rig.yaml:5:23", "expected a finite number, got \".nan\""},
        {"site heading and orientation",
         "rig: a\n" + ok_devices +
             "site: { latitude_deg: 1, longitude_deg: 0, heading_deg: 5,\n"
             "        orientation: { quaternion: [1, 0, 0, 0] } }\n",
         "rig.yaml:5:57", "site.heading_deg: give either heading_deg or orientation, not both"},
        {"site orientation not unit",
         "rig: a\n" + ok_devices +
             "site: { latitude_deg: 1, longitude_deg: 0, orientation: { quaternion: [0.5, 0.5, 0, "
             "0] } }\n",
         "rig.yaml:5:71", "site.orientation.quaternion: expected a unit quaternion"},
        {"site orientation three numbers",
         "rig: a\n" + ok_devices +
             "site: { latitude_deg: 1, longitude_deg: 0, orientation: { quaternion: [1, 0, 0] } "
             "}\n",
         "rig.yaml:5:71", "site.orientation.quaternion: expected a list of 4 numbers"},
        {"site orientation nan",
         "rig: a\n" + ok_devices +
             "site: { latitude_deg: 1, longitude_deg: 0, orientation: { quaternion: [.nan, 0, 0, "
             "0] } }\n",
         "rig.yaml:5:72", "site.orientation.quaternion[0]: expected a finite number"},
        {"site orientation unknown key",
         "rig: a\n" + ok_devices +
             "site: { latitude_deg: 1, longitude_deg: 0, orientation: { quaternon: [1, 0, 0, 0] } "
             "}\n",
         "rig.yaml:5:", "quaternon"},
        {"tab indentation", "rig: a\ndevices:\n\t- name: a\n", "rig.yaml:3:1",
         "tab in indentation"},
        {"control character", std::string("rig: a\ndevices: \x01\n"), "rig.yaml:2:10",
         "control character \"\\x01\""},
        {"nul byte", std::string("rig: a\0\n", 8), "rig.yaml:1:7", "control character"},
        {"deep flow nesting", "rig: a\ndevices: " + std::string(100, '[') + "\n",
         "rig.yaml:2:", "nesting deeper than 32 levels"},
        {"deep block nesting",
         [] {
             std::string text = "rig: a\ndevices:\n";
             for (int i = 0; i < 40; ++i)
                 text += std::string(2 * i, ' ') + "- a:\n";
             return text;
         }(),
         "rig.yaml:", "nesting deeper than 32 levels"},
        {"dash run",
         "rig: a\ndevices:\n" +
             [] {
                 std::string dashes;
                 for (int i = 0; i < 50; ++i)
                     dashes += "- ";
                 return dashes + "x\n";
             }(),
         "rig.yaml:3:", "nesting deeper than 32 levels"},
        {"huge file", "rig: a\n# " + std::string(kMaxRigFileBytes, 'x') + "\n", "rig.yaml",
         "a rig file is at most 1048576"},
    };
}

TEST(Rig, MalformedFilesGiveClearErrors) {
    for (const BadRig& bad : badRigs()) {
        SCOPED_TRACE(bad.label);
        auto rig = parseRig(bad.text, "rig.yaml");
        ASSERT_FALSE(rig.isOk());
        EXPECT_EQ(rig.status().code(), ErrorCode::kCorruptData);
        const std::string message = rig.status().message();
        EXPECT_EQ(message.rfind(bad.where, 0), 0u) << message;
        EXPECT_NE(message.find(bad.contains), std::string::npos) << message;
    }
}

// The nesting guard counts depth, not collections: a long flow list of small devices is fine.
TEST(Rig, WideFlowListsAreNotDeep) {
    std::string text = "rig: wide\ndevices: [";
    for (int i = 0; i < 100; ++i) {
        text += "{name: d" + std::to_string(i) + ", driver: pattern, options: {frames: 1}}, ";
    }
    text += "]\n";
    auto rig = parseRig(text, "wide.yaml");
    ASSERT_TRUE(rig.isOk()) << rig.status().toString();
    EXPECT_EQ(rig->devices.size(), 100u);
    const int column = static_cast<int>(text.find("{name: d99") - text.find("devices")) + 1;
    EXPECT_EQ(rig->devices[99].where, (SourceLocation{"wide.yaml", 2, column}));
}

TEST(Rig, ErrorNamesFileLineColumnAndField) {
    const std::string text =
        "rig: tabletop\n"             // 1
        "devices:\n"                  // 2
        "  - name: kinect\n"          // 3
        "    driver: openni2\n"       // 4
        "  - name: env\n"             // 5
        "    driver: v4l2\n"          // 6
        "    mode: {depth: 640x}\n";  // 7: the value starts at column 19
    auto rig = parseRig(text, "rig.yaml");
    ASSERT_FALSE(rig.isOk());
    EXPECT_EQ(rig.status().message(),
              "rig.yaml:7:19: devices[1].mode.depth: expected WIDTHxHEIGHT@FPS like 640x480@30 "
              "(fps and a pixel format after a space are optional), got \"640x\"");
}

TEST(Rig, MissingFileIsNotFound) {
    const auto path = test::tempDir() / "absent.yaml";
    auto rig = loadRig(path);
    ASSERT_FALSE(rig.isOk());
    EXPECT_EQ(rig.status().code(), ErrorCode::kNotFound);
    EXPECT_NE(rig.status().message().find(path.string()), std::string::npos);

    auto dir = loadRig(test::tempDir());
    ASSERT_FALSE(dir.isOk());
    EXPECT_EQ(dir.status().code(), ErrorCode::kInvalidArgument);
}

TEST(Rig, LoadedErrorsNameThePath) {
    const auto path = test::tempDir() / "bad.yaml";
    writeText(path, "rig: a\ndevices: []\n");
    auto rig = loadRig(path);
    ASSERT_FALSE(rig.isOk());
    EXPECT_EQ(rig.status().code(), ErrorCode::kCorruptData);
    EXPECT_EQ(rig.status().message().rfind(path.string() + ":2:10: devices: ", 0), 0u)
        << rig.status().message();
}

TEST(Rig, CalibrationPathsResolveAgainstTheRigFile) {
    const auto dir = test::tempDir();
    const auto path = dir / "rigs" / "lab" / "rig.yaml";
    const std::string text =
        "rig: lab\n"
        "calibration: extrinsics.yaml\n"
        "devices:\n"
        "  - name: cam\n"
        "    driver: aravis\n"
        "    calibration: ../calib/cam.cameramodel\n"
        "    streams:\n"
        "      left: { calibration: /abs/left.yaml }\n"
        "      right: { calibration: ./sub/../right.yaml }\n"
        "      mono:\n";
    writeText(path, text);
    auto rig = loadRig(path);
    ASSERT_TRUE(rig.isOk()) << rig.status().toString();
    const auto base = std::filesystem::absolute(path).parent_path().lexically_normal();
    ASSERT_EQ(rig->calibration.size(), 4u);
    EXPECT_EQ(rig->findCalibration("cam", "left")->resolved,
              std::filesystem::path("/abs/left.yaml"));
    EXPECT_EQ(rig->findCalibration("cam", "right")->resolved, base / "right.yaml");
    EXPECT_EQ(rig->findCalibration("cam", "right")->path, "./sub/../right.yaml");
    EXPECT_EQ(rig->findCalibration("cam", "mono")->resolved,
              base.parent_path() / "calib" / "cam.cameramodel");
    EXPECT_EQ(rig->findCalibration("cam")->device, "cam");
    EXPECT_EQ(rig->findCalibration("cam")->where, (SourceLocation{path.string(), 6, 18}));
    EXPECT_EQ(rig->findCalibration("other")->resolved, base / "extrinsics.yaml");

    // parseRig resolves against the folder of the source name, left relative.
    auto parsed = parseRig(text, "rigs/lab/rig.yaml");
    ASSERT_TRUE(parsed.isOk()) << parsed.status().toString();
    EXPECT_EQ(parsed->findCalibration("cam", "mono")->resolved,
              std::filesystem::path("rigs/calib/cam.cameramodel"));
    auto bare = parseRig(text, "rig.yaml");
    ASSERT_TRUE(bare.isOk());
    EXPECT_EQ(bare->findCalibration("x")->resolved, std::filesystem::path("extrinsics.yaml"));
}

TEST(Rig, ValidateChecksRigsBuiltInCode) {
    RigDescription rig;
    rig.name = "code";
    EXPECT_EQ(rig.validate().code(), ErrorCode::kCorruptData);
    RigDevice a;
    a.config.name = "a";
    a.config.driver = "pattern";
    rig.devices.push_back(a);
    EXPECT_TRUE(rig.validate().isOk()) << rig.validate().toString();
    rig.devices.push_back(a);
    EXPECT_EQ(rig.validate().message(), "devices[1].name: duplicate device name \"a\"");
    rig.devices[1].config.name = "b";
    rig.sync.streams = {{"a", "color", {}}, {"c", "color", {}}};
    EXPECT_EQ(rig.validate().message(), "sync.streams[1]: no device named \"c\" (devices: a, b)");
    rig.sync.streams[1].device = "b";
    EXPECT_TRUE(rig.validate().isOk());
    rig.devices[0].streams.push_back({});
    EXPECT_NE(rig.validate().message().find("invalid stream name"), std::string::npos);
}

// The device orientation (R_enu_world as w, x, y, z) comes back as written, and validate()
// refuses one that is not a unit quaternion.
TEST(Rig, SiteOrientation) {
    const std::string text =
        "rig: a\n"
        "devices:\n"
        "  - { name: cam, driver: pattern }\n"
        "site:\n"
        "  latitude_deg: 39.742476\n"
        "  longitude_deg: -105.1786\n"
        "  orientation: { quaternion: [0.9238795, 0, 0, -0.3826834] }\n";
    auto rig = parseRig(text, "rig.yaml");
    ASSERT_TRUE(rig.isOk()) << rig.status().toString();
    ASSERT_TRUE(rig->site.has_value());
    ASSERT_TRUE(rig->site->orientation_wxyz.has_value());
    EXPECT_EQ(*rig->site->orientation_wxyz, (std::array<double, 4>{0.9238795, 0, 0, -0.3826834}));
    EXPECT_DOUBLE_EQ(rig->site->heading_deg, 0);
    EXPECT_TRUE(rig->validate().isOk());

    RigDescription bad = *rig;
    bad.site->orientation_wxyz = std::array<double, 4>{1, 1, 0, 0};
    Status status = bad.validate();
    EXPECT_EQ(status.code(), ErrorCode::kCorruptData);
    EXPECT_NE(status.message().find("site.orientation"), std::string::npos) << status.message();
    bad.site->orientation_wxyz = std::array<double, 4>{std::nan(""), 0, 0, 0};
    EXPECT_FALSE(bad.validate().isOk());
}

TEST(Rig, SourceLocationText) {
    EXPECT_EQ((SourceLocation{"rig.yaml", 7, 12}).toString(), "rig.yaml:7:12");
    EXPECT_EQ((SourceLocation{"rig.yaml", 7, 0}).toString(), "rig.yaml:7");
    EXPECT_EQ((SourceLocation{"rig.yaml", 0, 0}).toString(), "rig.yaml");
    EXPECT_EQ((SourceLocation{"", 3, 1}).toString(), "line 3:1");
}

}  // namespace
}  // namespace mixray
