// The real Azure Kinect recording (pyk4a's test asset) through openMkv: streams, published
// timings, calibration attachment, and a lossless copy into a mixray recording.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>

#include "mixray/graph/mkv.h"
#include "recording_test_util.h"
#include "test_data.h"

namespace mixray {
namespace {

std::filesystem::path recordingPath() {
    return test::sharedDataDir() / "07_azure_kinect_mkv" / "pyk4a_recording.mkv";
}

std::vector<uint8_t> readBytes(const std::filesystem::path& path) {
    std::ifstream in(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// JSON text without insignificant whitespace or NUL padding.
std::string compactJson(const std::vector<uint8_t>& bytes) {
    std::string out;
    bool in_string = false;
    bool escaped = false;
    for (uint8_t b : bytes) {
        const char c = static_cast<char>(b);
        if (in_string) {
            out.push_back(c);
            if (escaped) {
                escaped = false;
            } else if (c == '\\') {
                escaped = true;
            } else if (c == '"') {
                in_string = false;
            }
            continue;
        }
        if (c == ' ' || c == '\n' || c == '\r' || c == '\t' || c == '\0')
            continue;
        if (c == '"')
            in_string = true;
        out.push_back(c);
    }
    return out;
}

class AzureKinect : public ::testing::Test {
protected:
    static void SetUpTestSuite() { setFfmpegLogging(false); }
};

const StreamInfo* findStream(const RecordingReader& reader, const std::string& name) {
    for (const auto& s : reader.streams()) {
        if (s.name == name)
            return &s;
    }
    return nullptr;
}

TEST_F(AzureKinect, StreamsTagsAndCalibration) {
    MIXRAY_REQUIRE_SHARED_DATA(recordingPath());
    auto reader = openMkv(recordingPath());
    ASSERT_TRUE(reader) << reader.status().toString();
    EXPECT_EQ((*reader)->format(), "azure-kinect-mkv");

    const StreamInfo* color = findStream(**reader, "azure_kinect/color");
    const StreamInfo* depth = findStream(**reader, "azure_kinect/depth");
    const StreamInfo* ir = findStream(**reader, "azure_kinect/ir");
    const StreamInfo* imu = findStream(**reader, "azure_kinect/imu");
    ASSERT_TRUE(color && depth && ir && imu);
    EXPECT_EQ(color->format, ImageDesc::packed(PixelFormat::kMJPEG, 1280, 720));
    EXPECT_EQ(color->kind, StreamKind::kColor);
    EXPECT_EQ(depth->format, ImageDesc::packed(PixelFormat::kDepth16, 640, 576));
    EXPECT_EQ(depth->kind, StreamKind::kDepth);
    EXPECT_EQ(ir->format, ImageDesc::packed(PixelFormat::kIR16, 640, 576));
    EXPECT_EQ(ir->kind, StreamKind::kInfrared);
    EXPECT_EQ(imu->format.format, PixelFormat::kBinary);
    EXPECT_EQ(imu->kind, StreamKind::kImu);
    EXPECT_DOUBLE_EQ(depth->nominal_fps, 5.0);
    EXPECT_EQ(color->tags.at("K4A_COLOR_MODE"), "MJPG_720P");
    EXPECT_EQ(depth->tags.at("K4A_DEPTH_MODE"), "NFOV_UNBINNED");
    for (const auto& s : (*reader)->streams())
        EXPECT_EQ(s.clock_domain, kAzureKinectClockDomain);

    const auto& tags = (*reader)->tags();
    EXPECT_EQ(tags.at("K4A_DEVICE_SERIAL_NUMBER"), "001514394512");
    EXPECT_EQ(tags.at("K4A_START_OFFSET_NS"), "336277000");
    EXPECT_EQ(tags.at("K4A_COLOR_FIRMWARE_VERSION"), "1.6.110");

    // The attached factory calibration is the JSON pyk4a publishes beside the recording.
    const auto json_path = test::sharedDataDir() / "07_azure_kinect_mkv" / "pyk4a_calibration.json";
    MIXRAY_REQUIRE_SHARED_DATA(json_path);
    const auto& attachments = (*reader)->attachments();
    auto calibration =
        std::find_if(attachments.begin(), attachments.end(),
                     [](const Attachment& a) { return a.name == "calibration.json"; });
    ASSERT_NE(calibration, attachments.end());
    // The published file is the same JSON pretty-printed: equal once whitespace outside
    // strings (and the recorder's trailing NUL) is removed.
    EXPECT_EQ(compactJson(calibration->data), compactJson(readBytes(json_path)));
    EXPECT_GT(calibration->data.size(), 1000u);
}

TEST_F(AzureKinect, ReplaysWithPublishedTimings) {
    MIXRAY_REQUIRE_SHARED_DATA(recordingPath());
    auto reader = openMkv(recordingPath());
    ASSERT_TRUE(reader) << reader.status().toString();
    const auto& streams = (*reader)->streams();
    Status end;
    const std::vector<FrameRef> frames = test::readAll(**reader, &end);
    EXPECT_EQ(end.code(), ErrorCode::kEndOfStream) << end.toString();
    ASSERT_FALSE(frames.empty());

    int64_t previous = INT64_MIN;
    int64_t last_ns = INT64_MIN;
    std::map<std::string, int64_t> first_ns;
    for (const FrameRef& f : frames) {
        EXPECT_GE(f.meta().host_stamp_ns, previous) << "frames out of host-stamp order";
        previous = f.meta().host_stamp_ns;
        EXPECT_EQ(f.meta().device_stamp_ns, f.meta().host_stamp_ns);
        last_ns = std::max(last_ns, f.meta().device_stamp_ns);
        first_ns.emplace(streams[f.meta().stream].name, f.meta().device_stamp_ns);
    }
    // pyk4a tests/functional/test_playback.py: first capture 800222 us, first IMU sample
    // 336277 us, recording length 463945 us (the last timestamp after the start offset).
    EXPECT_EQ(first_ns.at("azure_kinect/color"), 800'222'000);
    EXPECT_EQ(first_ns.at("azure_kinect/depth"), 800'222'000);
    EXPECT_EQ(first_ns.at("azure_kinect/ir"), 800'222'000);
    EXPECT_EQ(first_ns.at("azure_kinect/imu"), 336'277'000);
    EXPECT_EQ(last_ns - 336'277'000, 463'945'000);
    EXPECT_EQ(streams[frames.front().meta().stream].name, "azure_kinect/imu");
}

TEST_F(AzureKinect, PayloadsAreUsable) {
    MIXRAY_REQUIRE_SHARED_DATA(recordingPath());
    auto reader = openMkv(recordingPath());
    ASSERT_TRUE(reader);
    const auto& streams = (*reader)->streams();
    auto frames = test::readAll(**reader, nullptr);
    bool saw_depth = false;
    bool saw_color = false;
    bool saw_imu = false;
    for (const FrameRef& f : frames) {
        const std::string& name = streams[f.meta().stream].name;
        const ImageView view = f.image();
        if (name == "azure_kinect/depth") {
            saw_depth = true;
            // Millimetres in native order: a room at 0.5-6 m, not byte-swapped nonsense.
            std::vector<uint16_t> valid;
            for (int y = 0; y < view.desc.height; ++y) {
                for (int x = 0; x < view.desc.width; ++x) {
                    if (const uint16_t d = view.row<uint16_t>(y)[x])
                        valid.push_back(d);
                }
            }
            ASSERT_GT(valid.size(), 640u * 576u / 4);
            std::nth_element(valid.begin(), valid.begin() + valid.size() / 2, valid.end());
            const uint16_t median = valid[valid.size() / 2];
            EXPECT_GT(median, 300);
            EXPECT_LT(median, 6000);
        } else if (name == "azure_kinect/color") {
            saw_color = true;
            ASSERT_GT(view.size_bytes, 1000u);
            EXPECT_EQ(view.data[0], 0xFF);  // JPEG start-of-image
            EXPECT_EQ(view.data[1], 0xD8);
        } else if (name == "azure_kinect/imu") {
            auto sample = parseAzureKinectImuSample(view);
            ASSERT_TRUE(sample);
            if (!saw_imu) {
                EXPECT_EQ(sample->acc_stamp_ns, 336'277'000);
            }
            saw_imu = true;
            EXPECT_EQ(sample->acc_stamp_ns, f.meta().device_stamp_ns);
            const double g = std::sqrt(sample->acc_m_s2[0] * sample->acc_m_s2[0] +
                                       sample->acc_m_s2[1] * sample->acc_m_s2[1] +
                                       sample->acc_m_s2[2] * sample->acc_m_s2[2]);
            EXPECT_NEAR(g, 9.81, 1.0) << "accelerometer at rest should read gravity";
        }
    }
    EXPECT_TRUE(saw_depth && saw_color && saw_imu);
}

TEST_F(AzureKinect, SeekToFirstCaptureSkipsEarlierImu) {
    MIXRAY_REQUIRE_SHARED_DATA(recordingPath());
    auto reader = openMkv(recordingPath());
    ASSERT_TRUE(reader);
    ASSERT_TRUE((*reader)->seek(800'222'000));
    auto frames = test::readAll(**reader, nullptr);
    ASSERT_FALSE(frames.empty());
    for (const auto& f : frames)
        EXPECT_GE(f.meta().host_stamp_ns, 800'222'000);
}

TEST_F(AzureKinect, CopiesLosslesslyIntoAMixrayRecording) {
    MIXRAY_REQUIRE_SHARED_DATA(recordingPath());
    auto source = openMkv(recordingPath());
    ASSERT_TRUE(source);
    RecordingHeader header;
    header.streams = (*source)->streams();
    header.attachments = (*source)->attachments();
    header.tags = (*source)->tags();
    const auto path = test::tempDir() / "from_azure.mkv";
    std::vector<test::ExpectedFrame> written;
    {
        auto writer = createMkvWriter(path, header);
        ASSERT_TRUE(writer) << writer.status().toString();
        while (true) {
            auto frame = (*source)->next();
            if (!frame)
                break;
            ASSERT_TRUE((*writer)->write(*frame));
            written.push_back({test::copyFrame(*frame), frame->meta()});
        }
        ASSERT_TRUE((*writer)->close());
    }
    auto copy = openMkv(path);
    ASSERT_TRUE(copy) << copy.status().toString();
    EXPECT_EQ((*copy)->format(), "mixray-mkv");
    test::expectSameStreams((*copy)->streams(), header.streams);
    EXPECT_EQ((*copy)->attachments(), header.attachments);
    EXPECT_EQ((*copy)->tags(), header.tags);
    Status end;
    auto frames = test::readAll(**copy, &end);
    EXPECT_EQ(end.code(), ErrorCode::kEndOfStream) << end.toString();
    ASSERT_EQ(frames.size(), written.size());
    for (size_t i = 0; i < frames.size(); ++i) {
        test::expectSameFrame(frames[i], written[i], "frame " + std::to_string(i));
    }
}

}  // namespace
}  // namespace mixray
