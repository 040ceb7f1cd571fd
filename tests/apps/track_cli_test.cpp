// mixray track, demo and bench track on the committed simulated session: what they write, how
// close it is to the truth, and what they do when the marker or the light is lost.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "cli_runner.h"
#include "mixray/graph/frame.h"
#include "mixray/graph/mkv.h"
#include "mixray/graph/pose.h"
#include "mixray/graph/rig.h"
#include "mixray/tracking/light_record.h"
#include "mixray/tracking/sun.h"
#include "test_data.h"

namespace mixray {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using test::CliRun;
using test::mixray;
using test::q;

const fs::path kSession = test::fixturesDir() / "sessions" / "sim_tabletop.mkv";
// The key light of sim_tabletop.truth.yaml (to_light_world).
const Eigen::Vector3d kKeyToLight(0.45058614322726115, -0.35045588917675863, 0.8210680832141203);

std::vector<std::string> lines(const fs::path& path) {
    std::ifstream in(path);
    std::vector<std::string> out;
    for (std::string line; std::getline(in, line);)
        out.push_back(line);
    return out;
}

std::vector<std::string> fields(const std::string& line) {
    std::vector<std::string> out;
    std::stringstream s(line);
    for (std::string field; std::getline(s, field, ',');)
        out.push_back(field);
    return out;
}

// The true camera positions of the session, by frame (its TUM trajectory).
std::vector<Eigen::Vector3d> truePositions() {
    std::vector<Eigen::Vector3d> out;
    for (const std::string& line : lines(test::fixturesDir() / "sessions" / "sim_tabletop.tum")) {
        if (line.empty() || line[0] == '#')
            continue;
        std::stringstream s(line);
        double t, x, y, z;
        s >> t >> x >> y >> z;
        out.emplace_back(x, y, z);
    }
    return out;
}

TEST(TrackCli, TracksTheSimulatedSessionAndWritesEverything) {
    const fs::path dir = test::tempDir();
    CliRun run = mixray("track " + q(kSession) + " --max-frames 12 -o " + q(dir));
    ASSERT_EQ(run.exit_code, 0) << run.output;
    EXPECT_NE(run.output.find("12 colour frames, 12 tracked"), std::string::npos) << run.output;
    for (const char* name : {"poses.csv", "lights.csv", "track.json", "overlay.mp4", "tracked.mkv"})
        EXPECT_GT(fs::file_size(dir / name), 100u) << name;

    const std::vector<Eigen::Vector3d> truth = truePositions();
    const auto poses = lines(dir / "poses.csv");
    ASSERT_EQ(poses.size(), 13u);
    EXPECT_EQ(poses[0].substr(0, 24), "frame,stamp_ns,state,sta");
    for (size_t i = 1; i < poses.size(); ++i) {
        const auto f = fields(poses[i]);
        ASSERT_EQ(f.size(), 15u) << poses[i];
        EXPECT_EQ(f[2], "tracking");
        const Eigen::Vector3d p(std::stod(f[8]), std::stod(f[9]), std::stod(f[10]));
        // Smoothed poses on an orbiting camera: within a centimetre of the truth.
        EXPECT_LT((p - truth[i - 1]).norm(), 0.01) << "frame " << i - 1;
    }

    // The fish-eye finds the key light (to within a degree); the probes find it too.
    bool environment_key = false, probe_key = false;
    for (const std::string& line : lines(dir / "lights.csv")) {
        const auto f = fields(line);
        if (f.size() < 9 || f[0] == "frame")
            continue;
        const Eigen::Vector3d l(std::stod(f[6]), std::stod(f[7]), std::stod(f[8]));
        const double deg = std::acos(std::min(1.0, l.normalized().dot(kKeyToLight))) * 180 / M_PI;
        if (f[2] == "environment" && deg < 1)
            environment_key = true;
        if (f[2].rfind("probe", 0) == 0 && deg < 5)
            probe_key = true;
    }
    EXPECT_TRUE(environment_key);
    EXPECT_TRUE(probe_key);

    std::ifstream json_file(dir / "track.json");
    const json doc = json::parse(json_file);
    ASSERT_EQ(doc["frames"].size(), 12u);
    EXPECT_EQ(doc["frames"][5]["state"], "tracking");
    EXPECT_EQ(doc["frames"][5]["markers"][0]["id"], 23);
    EXPECT_EQ(doc["frames"][5]["probes"].size(), 2u);
    EXPECT_FALSE(doc["frames"][5]["environment"]["stale"].get<bool>());

    // The pose is a stream of the recording written beside, like any other.
    CliRun info = mixray("info --json " + q(dir / "tracked.mkv"));
    ASSERT_EQ(info.exit_code, 0) << info.output;
    const json streams = json::parse(info.output)["streams"];
    bool pose_stream = false;
    for (const json& s : streams)
        if (s["name"] == "tracking/pose") {
            pose_stream = true;
            EXPECT_EQ(s["frames"], 12);
        }
    EXPECT_TRUE(pose_stream) << info.output;
}

// The session with the camera covered for frames 6 to 9: the pose goes stale (the last good
// one, with the reason) and comes back when the marker does — never a crash.
TEST(TrackCli, LostMarkerKeepsTheLastPoseStaleAndReacquires) {
    const fs::path dir = test::tempDir();
    {
        auto reader = openMkv(kSession);
        ASSERT_TRUE(reader) << reader.status().toString();
        RecordingHeader header;
        header.streams = (*reader)->streams();
        header.attachments = (*reader)->attachments();
        auto writer = createMkvWriter(dir / "covered.mkv", header);
        ASSERT_TRUE(writer) << writer.status().toString();
        BufferPoolOptions po;
        po.desc = header.streams[0].format;
        po.buffer_count = 2;
        po.name = "covered";
        auto pool = BufferPool::create(po);
        int colour = 0;
        while (true) {
            auto frame = (*reader)->next();
            if (!frame)
                break;
            const bool is_colour = header.streams[frame->meta().stream].name == "kinect/color";
            if (is_colour && colour >= 6 && colour <= 9) {
                Image black(frame->image().desc);
                FrameRef dark = copyIntoPool(*pool, black.view(), frame->meta());
                ASSERT_TRUE(dark);
                ASSERT_TRUE((*writer)->write(dark));
            } else {
                ASSERT_TRUE((*writer)->write(*frame));
            }
            if (is_colour && ++colour == 14)
                break;
        }
        ASSERT_TRUE((*writer)->close());
    }
    CliRun run = mixray("track " + q(dir / "covered.mkv") + " --no-video -o " + q(dir / "out"));
    ASSERT_EQ(run.exit_code, 0) << run.output;
    std::ifstream json_file(dir / "out" / "track.json");
    const json frames = json::parse(json_file)["frames"];
    ASSERT_EQ(frames.size(), 14u);
    EXPECT_EQ(frames[5]["state"], "tracking");
    const json last_good = frames[5]["pose"]["T_world_camera"];
    for (int i = 6; i <= 9; ++i) {
        EXPECT_EQ(frames[i]["state"], "lost") << i;
        EXPECT_TRUE(frames[i]["pose"]["stale"].get<bool>()) << i;
        EXPECT_EQ(frames[i]["pose"]["T_world_camera"], last_good) << i;
        EXPECT_NE(frames[i]["pose"]["reason"].get<std::string>().find("23"), std::string::npos)
            << frames[i]["pose"];
        // The probes wait for a fresh pose and say why.
        EXPECT_TRUE(frames[i]["probes"][0]["stale"].get<bool>());
    }
    EXPECT_EQ(frames[10]["state"], "tracking");
    EXPECT_TRUE(frames[10]["reacquired"].get<bool>());
    EXPECT_FALSE(frames[10]["pose"]["stale"].get<bool>());

    // The pose stream of the recording keeps the stale status and the reason.
    auto tracked = openMkv(dir / "out" / "tracked.mkv");
    ASSERT_TRUE(tracked) << tracked.status().toString();
    std::vector<PoseRecord> poses;
    while (true) {
        auto frame = (*tracked)->next();
        if (!frame)
            break;
        if ((*tracked)->streams()[frame->meta().stream].name != "tracking/pose")
            continue;
        auto record = decodePoseRecord(frame->image());
        ASSERT_TRUE(record) << record.status().toString();
        poses.push_back(*record);
    }
    ASSERT_EQ(poses.size(), 14u);
    EXPECT_EQ(poses[5].status, PoseStatus::kValid);
    EXPECT_TRUE(poses[5].reason.empty());
    for (int i = 6; i <= 9; ++i) {
        EXPECT_EQ(poses[i].status, PoseStatus::kStale) << i;
        EXPECT_EQ(poses[i].reason, frames[i]["pose"]["reason"].get<std::string>()) << i;
    }
}

// mixray info decodes pose, light and environment-map streams: stale and lost records are
// counted with the first reason, a damaged record is named with its place and makes info fail.
TEST(InfoCli, SummarisesRecordStreamsAndNamesDamagedRecords) {
    const fs::path dir = test::tempDir();
    RecordingHeader header;
    header.streams.push_back(makePoseStreamInfo("tracking/pose", "kinect/color", 30, false));
    header.streams.push_back(tracking::makeLightStreamInfo("lights/estimate", "kinect/color", 30));
    header.streams.push_back(
        tracking::makeEnvironmentMapStreamInfo("lights/map", "env/fisheye", 8, 4));
    const auto write = [&](const fs::path& path, bool damage) {
        auto writer = createMkvWriter(path, header, {});
        ASSERT_TRUE(writer) << writer.status().toString();
        auto pool = BufferPool::create(
            {ImageDesc::packed(PixelFormat::kBinary, 1 << 20, 1), 0, 4, "records"});
        ASSERT_TRUE(pool);
        const auto put = [&](StreamId stream, uint64_t i, const std::vector<uint8_t>& bytes) {
            FrameMetadata meta;
            meta.stream = stream;
            meta.sequence = i;
            meta.host_stamp_ns = meta.device_stamp_ns = 100000000 * static_cast<int64_t>(i + 1);
            // One record per frame, its own size (the stream's width is the largest).
            const ImageDesc desc =
                ImageDesc::packed(PixelFormat::kBinary, static_cast<int>(bytes.size()), 1);
            FrameRef frame = copyIntoPool(*pool, ImageView{desc, bytes.data(), bytes.size()}, meta);
            ASSERT_TRUE(frame);
            ASSERT_TRUE((*writer)->write(frame));
        };
        for (uint64_t i = 0; i < 4; ++i) {
            PoseRecord pose;
            pose.frame_sequence = i;
            if (i >= 2) {
                pose.status = i == 2 ? PoseStatus::kStale : PoseStatus::kLost;
                pose.reason = "marker 23 not seen";
            }
            auto pose_bytes = encodePoseRecord(pose);
            ASSERT_TRUE(pose_bytes);
            put(0, i, {pose_bytes->begin(), pose_bytes->end()});

            tracking::LightRecord lights;
            lights.frame_sequence = i;
            tracking::LightGroup group;
            group.name = "environment";
            group.stale = i == 1;
            group.reason = i == 1 ? "environment image over-exposed" : "";
            lights.groups.push_back(group);
            auto light_bytes = tracking::encodeLightRecord(lights);
            ASSERT_TRUE(light_bytes);
            if (damage && i == 3)
                (*light_bytes)[40] ^= 0x10;
            put(1, i, *light_bytes);

            FloatImage map;
            map.width = 8;
            map.height = 4;
            map.pixels.assign(8 * 4 * 3, 0.5f);
            tracking::EnvironmentMapHeader h;
            h.stale = false;
            std::vector<uint8_t> map_bytes(tracking::environmentMapRecordBytes(8, 4));
            ASSERT_TRUE(
                tracking::encodeEnvironmentMapRecord(map, h, map_bytes.data(), map_bytes.size()));
            put(2, i, map_bytes);
        }
        ASSERT_TRUE((*writer)->close());
    };
    write(dir / "good.mkv", false);
    write(dir / "damaged.mkv", true);

    CliRun good = mixray("info " + q(dir / "good.mkv"));
    ASSERT_EQ(good.exit_code, 0) << good.output;
    EXPECT_NE(good.output.find("records: 4 decoded, 1 stale, 1 lost, 0 damaged (first reason: "
                               "marker 23 not seen)"),
              std::string::npos)
        << good.output;
    EXPECT_NE(good.output.find("records: 4 decoded, 1 stale, 0 lost, 0 damaged (first reason: "
                               "environment: environment image over-exposed)"),
              std::string::npos)
        << good.output;
    EXPECT_NE(good.output.find("records: 4 decoded, 0 stale, 0 lost, 0 damaged\n"),
              std::string::npos)
        << good.output;

    CliRun damaged = mixray("info " + q(dir / "damaged.mkv"));
    EXPECT_EQ(damaged.exit_code, 3) << damaged.output;
    EXPECT_NE(damaged.output.find("damaged record 3 (300.0 ms after start): light record: CRC "
                                  "mismatch"),
              std::string::npos)
        << damaged.output;
    EXPECT_NE(damaged.output.find("stream 'lights/estimate' holds 1 damaged record(s)"),
              std::string::npos)
        << damaged.output;

    CliRun as_json = mixray("info --json " + q(dir / "damaged.mkv"));
    EXPECT_EQ(as_json.exit_code, 3) << as_json.output;
    const json doc = json::parse(as_json.output.substr(
        as_json.output.find('{'), as_json.output.rfind('}') - as_json.output.find('{') + 1));
    const json& lights = doc["streams"][1]["records"];
    EXPECT_EQ(lights["decoded"], 3);
    EXPECT_EQ(lights["stale"], 1);
    ASSERT_EQ(lights["damaged"].size(), 1u);
    EXPECT_EQ(lights["damaged"][0]["record"], 3);
    EXPECT_EQ(doc["streams"][0]["records"]["lost"], 1);
}

// The big-endian 32-bit number at `offset` of a file: a PNG's width and height sit at 16 and 20.
uint32_t beU32At(const fs::path& path, std::streamoff offset) {
    std::ifstream in(path, std::ios::binary);
    in.seekg(offset);
    unsigned char b[4] = {};
    in.read(reinterpret_cast<char*>(b), 4);
    return (uint32_t{b[0]} << 24) | (uint32_t{b[1]} << 16) | (uint32_t{b[2]} << 8) | b[3];
}

TEST(TrackCli, BuildsAnEnvironmentFromTheCamerasOwnFrames) {
    const fs::path dir = test::tempDir();
    CliRun run =
        mixray("track " + q(kSession) +
               " --max-frames 6 --no-video --no-record --camera-environment 64 -o " + q(dir));
    ASSERT_EQ(run.exit_code, 0) << run.output;
    EXPECT_NE(run.output.find("camera environment: 6 frames"), std::string::npos) << run.output;
    EXPECT_NE(run.output.find("% of the sphere seen"), std::string::npos) << run.output;
    EXPECT_GT(fs::file_size(dir / "camera_environment.exr"), 0u);
    EXPECT_EQ(beU32At(dir / "camera_environment.png", 16), 64u);
    EXPECT_EQ(beU32At(dir / "camera_environment.png", 20), 32u);
    CliRun odd =
        mixray("track " + q(kSession) +
               " --max-frames 1 --no-video --no-record --camera-environment 17 -o " + q(dir));
    EXPECT_NE(odd.exit_code, 0);
    EXPECT_NE(odd.output.find("width must be even"), std::string::npos) << odd.output;
}

TEST(TrackCli, BadInputIsAnErrorNotACrash) {
    const fs::path dir = test::tempDir();
    CliRun missing = mixray("track " + q(dir / "none.mkv") + " -o " + q(dir));
    EXPECT_EQ(missing.exit_code, 3) << missing.output;
    {
        std::ofstream setup(dir / "bad.yaml");
        setup << "version: 1\ncamera: {stream: kinect/color}\ntargets: []\n";
    }
    CliRun bad =
        mixray("track " + q(kSession) + " --setup " + q(dir / "bad.yaml") + " -o " + q(dir));
    EXPECT_EQ(bad.exit_code, 3) << bad.output;
    EXPECT_NE(bad.output.find("bad.yaml:2"), std::string::npos) << bad.output;
    // A recording without the tracked stream names the streams it has.
    CliRun pattern = mixray(
        "track " + q(test::fixturesDir() / "sessions" / "pattern_rgbd.mkv") + " --setup " +
        q(test::fixturesDir() / "sessions" / "sim_tabletop.tracking.yaml") + " -o " + q(dir));
    EXPECT_NE(pattern.exit_code, 0);
    EXPECT_NE(pattern.output.find("rgbd/color"), std::string::npos) << pattern.output;
}

TEST(DemoCli, CompositesAndMeasuresAgainstTheGroundTruth) {
    const fs::path dir = test::tempDir();
    CliRun run = mixray("demo --max-frames 3 --samples 1 --png-every 2 -o " + q(dir));
    ASSERT_EQ(run.exit_code, 0) << run.output;
    EXPECT_NE(run.output.find("composite vs ground truth: PSNR"), std::string::npos) << run.output;
    for (const char* name : {"composite.mp4", "summary.json", "frames/frame_0000.png",
                             "frames/frame_0000_truth.png", "frames/frame_0002_diff4x.png"})
        EXPECT_TRUE(fs::exists(dir / name)) << name;
    std::ifstream summary_file(dir / "summary.json");
    const json summary = json::parse(summary_file);
    EXPECT_EQ(summary["frames"], 3);
    const json& accuracy = summary["accuracy"];
    EXPECT_LT(accuracy["camera_position_error_mm"]["median"].get<double>(), 10);
    EXPECT_LT(
        accuracy["light_direction"]["environment"]["key_light_error_deg"]["median"].get<double>(),
        1);
    // One sample per pixel against the simulator's four: still well above 30 dB.
    EXPECT_GT(accuracy["psnr_db"]["mean"].get<double>(), 30);
}

TEST(BenchCli, TrackPrintsTrackingAgainstOpenCvAndLightTimes) {
    CliRun run = mixray("bench track --size 320x240 --frames 2 --repeats 1 --json");
    ASSERT_EQ(run.exit_code, 0) << run.output;
    const json out = json::parse(run.output.substr(run.output.find('[')));
    ASSERT_EQ(out.size(), 1u);
    EXPECT_EQ(out[0]["width"], 320);
    EXPECT_EQ(out[0]["tracked"], 2);
    for (const char* key :
         {"opencv_detect_markers_ms", "mixray_track_ms", "probe_lights_ms", "environment_ms"})
        EXPECT_GT(out[0][key].get<double>(), 0) << key;
}

}  // namespace
}  // namespace mixray

namespace mixray {
namespace {

// An outdoor rig: the rig file's site and the first frame's UTC give the sun's direction in
// the marker frame on every frame, as tracking::sunDirectionWorld computes it for that instant.
TEST(TrackCli, SunDirectionFromTheRigsSiteAndTheFramesTime) {
    const fs::path dir = test::tempDir();
    {
        std::ofstream rig(dir / "outdoor.yaml");
        rig << "version: 1\nrig: outdoor\ndevices:\n  - name: kinect\n    driver: pattern\n"
               "site: {latitude_deg: 48.8584, longitude_deg: 2.2945, heading_deg: 135, "
               "altitude_m: 35}\n";
    }
    CliRun run = mixray("track " + q(kSession) + " --max-frames 5 --no-video --no-record --rig " +
                        q(dir / "outdoor.yaml") + " --utc 2026-06-21T12:00:00.5Z -o " + q(dir));
    ASSERT_EQ(run.exit_code, 0) << run.output;
    auto rig = loadRig(dir / "outdoor.yaml");
    ASSERT_TRUE(rig && rig->site) << rig.status().toString();
    const int64_t utc0 = 1'782'043'200'500'000'000;  // 2026-06-21T12:00:00.5Z
    int64_t first_stamp = -1;
    int rows = 0;
    for (const std::string& line : lines(dir / "lights.csv")) {
        const auto f = fields(line);
        if (f.size() < 9 || f[2] != "sun")
            continue;
        const int64_t stamp = std::stoll(f[1]);
        if (first_stamp < 0)
            first_stamp = stamp;
        auto expected = tracking::sunDirectionWorld(*rig->site, utc0 + (stamp - first_stamp));
        ASSERT_TRUE(expected);
        const Eigen::Vector3d got(std::stod(f[6]), std::stod(f[7]), std::stod(f[8]));
        EXPECT_LT((got - *expected).norm(), 1e-5) << line;
        EXPECT_GT(got.z(), 0.5);  // midsummer noon in Paris: high in the sky
        ++rows;
    }
    EXPECT_EQ(rows, 5);

    // Without a time of day the sun is not guessed: stale, and the reason says what to give.
    CliRun untimed = mixray("track " + q(kSession) + " --max-frames 2 --no-video --no-record " +
                            "--rig " + q(dir / "outdoor.yaml") + " -o " + q(dir / "untimed"));
    ASSERT_EQ(untimed.exit_code, 0) << untimed.output;
    std::ifstream json_file(dir / "untimed" / "track.json");
    const json frames = json::parse(json_file)["frames"];
    EXPECT_TRUE(frames[0]["sun"]["stale"].get<bool>());
    EXPECT_NE(frames[0]["sun"]["reason"].get<std::string>().find("--utc"), std::string::npos);
    CliRun bad = mixray("track " + q(kSession) + " --rig " + q(dir / "outdoor.yaml") +
                        " --utc 2026-06-21 -o " + q(dir / "bad"));
    EXPECT_NE(bad.exit_code, 0);
    EXPECT_NE(bad.output.find("2026-06-21T12:00:00Z"), std::string::npos) << bad.output;
}

}  // namespace
}  // namespace mixray
