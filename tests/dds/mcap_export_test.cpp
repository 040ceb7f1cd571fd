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
    const std::string rig = "rig: my-studio\ndevices:\n  - name: kinect\n    driver: pattern\n";
    header.attachments = {{"rig.yaml", "application/x-yaml", {rig.begin(), rig.end()}},
                          {"calibration.yaml", "application/x-yaml", {1, 2, 3, 4, 5}}};
    constexpr int64_t kUtcMinusHost = 1'795'000'000'000'000'000;
    header.tags = {{std::string(kUtcMinusHostTag), std::to_string(kUtcMinusHost)},
                   {"title", "a test session"}};

    const auto unwritable = mcapUnwritableStreams(header);
    ASSERT_EQ(unwritable.size(), 1u);
    EXPECT_EQ(unwritable[0].first, 2u);
    EXPECT_NE(unwritable[0].second.find("env/color"), std::string::npos) << unwritable[0].second;
    EXPECT_EQ(mcapChangedData(header).size(), 1u) << "stamps are on UTC: the tag is there";

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
    ASSERT_EQ(got["schemas"].size(), 1u);
    EXPECT_EQ(got["schemas"][0]["name"], "sensor_msgs/msg/Image");
    EXPECT_EQ(got["schemas"][0]["encoding"], "ros2msg");
    ASSERT_EQ(got["channels"].size(), 2u);
    for (const auto& channel : got["channels"]) {
        EXPECT_EQ(channel["messageEncoding"], "cdr");
        EXPECT_TRUE(channel["offeredQos"].is_string()) << "rosbag2 needs offered_qos_profiles";
    }
    EXPECT_EQ(got["statistics"]["messageCount"], 12);
    EXPECT_GT(got["statistics"]["chunkCount"].get<int>(), 1);
    EXPECT_EQ(got["chunkIndexes"], got["statistics"]["chunkCount"]);
    EXPECT_EQ(got["streamedMessages"], 12);
    EXPECT_TRUE(got["streamDone"].get<bool>());
    EXPECT_TRUE(got["dataSectionCrcMatches"].get<bool>());

    const auto& messages = got["messages"];
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

    ASSERT_EQ(got["attachments"].size(), 2u);
    EXPECT_EQ(got["attachments"][0]["name"], "rig.yaml");
    EXPECT_EQ(got["attachments"][0]["sha256"],
              sha256(reinterpret_cast<const uint8_t*>(rig.data()), rig.size()));
    EXPECT_EQ(got["attachments"][1]["name"], "calibration.yaml");
    EXPECT_EQ(got["attachments"][1]["size"], 5);
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
