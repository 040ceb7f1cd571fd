// MCAP export (mixray/dds/mcap_export.h) read back by Foxglove's own readers through Node.js
// (tests/mcap/read_mcap.mjs: @mcap/core's indexed and stream readers, the CDR decoded with the
// schema the file carries): every image arrives byte for byte with its stamp, size and encoding;
// the summary, indexes and CRCs hold; attachments and tags come along.
#include "mixray/dds/mcap_export.h"

#include <gtest/gtest.h>
#include <openssl/evp.h>

#include <array>
#include <map>
#include <string>
#include <vector>

#include "foxglove_mcap.h"
#include "mixray/graph/graph.h"
#include "test_data.h"

namespace mixray::dds {
namespace {

namespace fs = std::filesystem;

std::string sha256(const uint8_t* data, size_t size) {
    std::array<unsigned char, 32> digest{};
    unsigned int length = 0;
    EVP_Digest(data, size, digest.data(), &length, EVP_sha256(), nullptr);
    std::string hex;
    for (unsigned char byte : digest) {
        static constexpr char kHex[] = "0123456789abcdef";
        hex += kHex[byte >> 4];
        hex += kHex[byte & 15];
    }
    return hex;
}

StreamInfo stream(const std::string& name, StreamKind kind, PixelFormat format) {
    StreamInfo info;
    info.name = name;
    info.device = name.substr(0, name.find('/'));
    info.kind = kind;
    info.format = ImageDesc::packed(format, 64, 48);
    info.nominal_fps = 30;
    return info;
}

TEST(McapExport, FoxglovesReadersGetEveryImageByteForByteWithItsStamp) {
    Graph graph;
    RecordingHeader header;
    header.streams = {stream("kinect/color", StreamKind::kColor, PixelFormat::kRGB8),
                      stream("kinect/depth", StreamKind::kDepth, PixelFormat::kDepth16),
                      stream("env/color", StreamKind::kColor, PixelFormat::kMJPEG)};
    // The rig names the Kinect's calibration, which the recording carries: kinect/color's
    // camera is calibrated at the stream's size, kinect/depth's at another.
    const std::string rig =
        "rig: my-studio\ndevices:\n  - name: kinect\n    driver: pattern\n"
        "    calibration: calib/kinect.yaml\n";
    const std::string calibration =
        "version: 1\ncameras:\n"
        "  - name: kinect/color\n"
        "    model: {lens: pinhole, width: 64, height: 48, fx: 50, fy: 51, cx: 31.5, cy: 23.5,\n"
        "            distortion: [0.1, -0.2, 0.001, 0.002]}\n"
        "    parent: world\n"
        "    T_parent_camera: {translation: [0.1, 0.2, 0.3], quaternion: [1, 0, 0, 0]}\n"
        "  - name: kinect/depth\n"
        "    model: {lens: pinhole, width: 32, height: 24, fx: 25, fy: 25, cx: 15.5, cy: 11.5,\n"
        "            distortion: []}\n"
        "    parent: kinect/color\n"
        "    T_parent_camera: {translation: [-0.025, 0, 0], quaternion: [1, 0, 0, 0]}\n";
    header.attachments = {
        {"rig.yaml", "application/x-yaml", {rig.begin(), rig.end()}},
        {"kinect.yaml", "application/x-yaml", {calibration.begin(), calibration.end()}}};
    constexpr int64_t kUtcMinusHost = 1'795'000'000'000'000'000;
    header.tags = {{std::string(kUtcMinusHostTag), std::to_string(kUtcMinusHost)},
                   {"title", "a test session"}};

    const auto unwritable = mcapUnwritableStreams(header);
    ASSERT_EQ(unwritable.size(), 1u);
    EXPECT_EQ(unwritable[0].first, 2u);
    EXPECT_NE(unwritable[0].second.find("env/color"), std::string::npos) << unwritable[0].second;
    const std::vector<std::string> changed = mcapChangedData(header);
    ASSERT_EQ(changed.size(), 2u) << "stamps are on UTC: the tag is there";
    EXPECT_NE(changed[1].find("camera_info of kinect/depth: the calibration is for 32x24"),
              std::string::npos)
        << changed[1];

    const fs::path file = test::tempDir() / "session.mcap";
    // Small chunks: the file has several, each with its message indexes.
    auto writer = createMcapWriter(file, header, {.rig = "", .chunk_bytes = 20'000});
    ASSERT_TRUE(writer.isOk()) << writer.status().toString();

    std::vector<std::shared_ptr<BufferPool>> pools;
    for (const StreamInfo& info : header.streams) {
        auto added =
            addPooledStream(graph, info, 2, info.format.format == PixelFormat::kMJPEG ? 4096 : 0);
        ASSERT_TRUE(added.isOk());
        pools.push_back(added->pool);
    }
    struct Sent {
        std::string topic;
        int64_t stamp_ns;
        std::string sha256;
    };
    std::vector<Sent> sent;
    for (int i = 0; i < 12; ++i) {
        const StreamId id = static_cast<StreamId>(i % 2);
        WritableFrame frame = pools[id]->acquire();
        ASSERT_TRUE(frame);
        const size_t bytes = header.streams[id].format.bufferBytes();
        for (size_t k = 0; k < bytes; ++k)
            frame.image().data[k] = static_cast<uint8_t>(k * 7 + i * 13);
        frame.meta().stream = id;
        frame.meta().sequence = static_cast<uint64_t>(i / 2);
        frame.meta().host_stamp_ns = 5'000'000'000 + i * 33'333'333;
        const std::string topic =
            id == 0 ? "/my_studio/kinect/color/image_raw" : "/my_studio/kinect/depth/image_raw";
        sent.push_back(
            {topic, frame.meta().host_stamp_ns + kUtcMinusHost, sha256(frame.image().data, bytes)});
        ASSERT_TRUE((*writer)->write(std::move(frame).publish()).isOk());
    }
    // A stream with no ROS 2 image: its frames are left out, not an error.
    WritableFrame mjpeg = pools[2]->acquire();
    mjpeg.meta().stream = 2;
    mjpeg.meta().host_stamp_ns = 6'000'000'000;
    ASSERT_TRUE((*writer)->write(std::move(mjpeg).publish()).isOk());
    ASSERT_TRUE((*writer)->close().isOk());

    const nlohmann::json got = test::readMcapWithFoxglove(file);
    ASSERT_TRUE(got.is_object());
    EXPECT_EQ(got["profile"], "ros2");
    ASSERT_EQ(got["schemas"].size(), 3u);
    EXPECT_EQ(got["schemas"][0]["name"], "sensor_msgs/msg/Image");
    EXPECT_EQ(got["schemas"][1]["name"], "sensor_msgs/msg/CameraInfo");
    EXPECT_EQ(got["schemas"][2]["name"], "tf2_msgs/msg/TFMessage");
    EXPECT_EQ(got["schemas"][0]["encoding"], "ros2msg");
    std::vector<std::string> topics;
    for (const auto& channel : got["channels"])
        topics.push_back(channel["topic"]);
    EXPECT_EQ(topics, (std::vector<std::string>{
                          "/my_studio/kinect/color/image_raw", "/my_studio/kinect/depth/image_raw",
                          "/my_studio/kinect/color/camera_info", "/tf_static"}));
    for (const auto& channel : got["channels"]) {
        EXPECT_EQ(channel["messageEncoding"], "cdr");
        EXPECT_TRUE(channel["offeredQos"].is_string()) << "rosbag2 needs offered_qos_profiles";
    }
    // 12 images, a camera_info with each of the 6 colour images, tf_static once.
    EXPECT_EQ(got["statistics"]["messageCount"], 19);
    EXPECT_GT(got["statistics"]["chunkCount"].get<int>(), 1);
    EXPECT_EQ(got["chunkIndexes"], got["statistics"]["chunkCount"]);
    EXPECT_EQ(got["streamedMessages"], 19);
    EXPECT_TRUE(got["streamDone"].get<bool>());
    EXPECT_TRUE(got["dataSectionCrcMatches"].get<bool>());

    nlohmann::json messages = nlohmann::json::array();
    nlohmann::json infos = nlohmann::json::array();
    nlohmann::json tf_static = nlohmann::json::array();
    for (const auto& m : got["messages"]) {
        if (m["schema"] == "sensor_msgs/msg/Image")
            messages.push_back(m);
        else if (m["schema"] == "sensor_msgs/msg/CameraInfo")
            infos.push_back(m);
        else
            tf_static.push_back(m);
    }
    ASSERT_EQ(messages.size(), sent.size());
    std::map<std::string, uint32_t> next_sequence;
    for (size_t i = 0; i < sent.size(); ++i) {
        SCOPED_TRACE("message " + std::to_string(i));
        const auto& m = messages[i];
        const bool color = sent[i].topic.find("color") != std::string::npos;
        EXPECT_EQ(m["topic"], sent[i].topic);
        EXPECT_EQ(m["sequence"], next_sequence[sent[i].topic]++);
        EXPECT_EQ(m["logTime"], std::to_string(sent[i].stamp_ns));
        EXPECT_EQ(m["publishTime"], std::to_string(sent[i].stamp_ns));
        EXPECT_EQ(m["sec"], sent[i].stamp_ns / 1'000'000'000);
        EXPECT_EQ(m["nanosec"], sent[i].stamp_ns % 1'000'000'000);
        EXPECT_EQ(m["frameId"], color ? "kinect_color" : "kinect_depth");
        EXPECT_EQ(m["width"], 64);
        EXPECT_EQ(m["height"], 48);
        EXPECT_EQ(m["encoding"], color ? "rgb8" : "16UC1");
        EXPECT_EQ(m["step"], color ? 64 * 3 : 64 * 2);
        EXPECT_EQ(m["isBigendian"], 0);
        EXPECT_EQ(m["sha256"], sent[i].sha256) << "the pixels differ";
    }

    // Each colour image's camera_info: the calibration's K, D (plumb_bob), P, with its header.
    ASSERT_EQ(infos.size(), 6u);
    for (size_t i = 0; i < infos.size(); ++i) {
        const auto& info = infos[i];
        const auto& image = messages[2 * i];
        EXPECT_EQ(info["sec"], image["sec"]);
        EXPECT_EQ(info["nanosec"], image["nanosec"]);
        EXPECT_EQ(info["frameId"], "kinect_color");
        EXPECT_EQ(info["width"], 64);
        EXPECT_EQ(info["distortionModel"], "plumb_bob");
        EXPECT_EQ(info["d"], (std::vector<double>{0.1, -0.2, 0.001, 0.002, 0}));
        EXPECT_EQ(info["k"], (std::vector<double>{50, 0, 31.5, 0, 51, 23.5, 0, 0, 1}));
        EXPECT_EQ(info["p"], (std::vector<double>{50, 0, 31.5, 0, 0, 51, 23.5, 0, 0, 0, 1, 0}));
    }
    // The extrinsics once, with the first image's stamp.
    ASSERT_EQ(tf_static.size(), 1u);
    EXPECT_EQ(tf_static[0]["logTime"], messages[0]["logTime"]);
    const auto& transforms = tf_static[0]["transforms"];
    ASSERT_EQ(transforms.size(), 2u);
    EXPECT_EQ(transforms[0]["parent"], "world");
    EXPECT_EQ(transforms[0]["child"], "kinect_color");
    EXPECT_EQ(transforms[0]["translation"], (std::vector<double>{0.1, 0.2, 0.3}));
    EXPECT_EQ(transforms[1]["parent"], "kinect_color");
    EXPECT_EQ(transforms[1]["child"], "kinect_depth");
    EXPECT_EQ(transforms[1]["rotation"], (std::vector<double>{0, 0, 0, 1}));

    ASSERT_EQ(got["attachments"].size(), 2u);
    EXPECT_EQ(got["attachments"][0]["name"], "rig.yaml");
    EXPECT_EQ(got["attachments"][0]["sha256"],
              sha256(reinterpret_cast<const uint8_t*>(rig.data()), rig.size()));
    EXPECT_EQ(got["attachments"][1]["name"], "kinect.yaml");
    EXPECT_EQ(got["attachments"][1]["size"], calibration.size());
    ASSERT_EQ(got["metadata"].size(), 1u);
    EXPECT_EQ(got["metadata"][0]["name"], "mixray");
    EXPECT_EQ(got["metadata"][0]["entries"]["title"], "a test session");
}

TEST(McapExport, ABadRigNameOrAnUnwritablePathIsRefused) {
    RecordingHeader header;
    header.streams = {stream("cam/mono", StreamKind::kMono, PixelFormat::kMono8)};
    const fs::path dir = test::tempDir();
    EXPECT_EQ(createMcapWriter(dir / "x.mcap", header, {.rig = "my-rig", .chunk_bytes = 1 << 20})
                  .status()
                  .code(),
              ErrorCode::kInvalidArgument);
    EXPECT_EQ(createMcapWriter(dir / "no/such/dir/x.mcap", header).status().code(),
              ErrorCode::kIoError);
    EXPECT_EQ(mcapChangedData(header).size(), 2u) << "no UTC tag: stamps stay on the host clock";
}

}  // namespace
}  // namespace mixray::dds
