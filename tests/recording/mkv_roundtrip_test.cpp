// Matroska round trips: every pixel format, exact stamps and metadata, attachments, tags, order,
// seeking, and what ffprobe makes of the file.
#include <gtest/gtest.h>

#include <array>
#include <cstdio>
#include <cstdlib>
#include <fstream>

#include "mixray/graph/mkv.h"
#include "recording_test_util.h"
#include "test_data.h"

namespace mixray {
namespace {

using test::ExpectedFrame;

class MkvRoundTrip : public ::testing::Test {
protected:
    static void SetUpTestSuite() { setFfmpegLogging(false); }
};

TEST_F(MkvRoundTrip, EveryPixelFormatComesBackBitExact) {
    const auto path = test::tempDir() / "every_format.mkv";
    const RecordingHeader header = test::makeHeader(test::everyFormatStreams());
    const std::vector<ExpectedFrame> written = test::writeRecording(path, header, 6);
    ASSERT_EQ(written.size(), header.streams.size() * 6);

    auto reader = openMkv(path);
    ASSERT_TRUE(reader) << reader.status().toString();
    EXPECT_EQ((*reader)->format(), "mixray-mkv");
    test::expectSameStreams((*reader)->streams(), header.streams);
    EXPECT_EQ((*reader)->attachments(), header.attachments);
    EXPECT_EQ((*reader)->tags(), header.tags);

    Status end;
    const std::vector<FrameRef> frames = test::readAll(**reader, &end);
    EXPECT_EQ(end.code(), ErrorCode::kEndOfStream) << end.toString();
    ASSERT_EQ(frames.size(), written.size());
    for (size_t i = 0; i < frames.size(); ++i) {
        test::expectSameFrame(
            frames[i], written[i],
            "frame " + std::to_string(i) + " of " + header.streams[written[i].meta.stream].name);
    }
}

TEST_F(MkvRoundTrip, ExtremeStampsAndMetadataAreExact) {
    const auto path = test::tempDir() / "stamps.mkv";
    RecordingHeader header;
    header.streams = {test::makeStream("kinect/depth", PixelFormat::kDepth16, 8, 6),
                      test::makeStream("imu/samples", PixelFormat::kBinary, 0, 1)};
    auto writer = createMkvWriter(path, header);
    ASSERT_TRUE(writer) << writer.status().toString();
    const std::array<int64_t, 6> host = {-9'000'000'000'000'000'001, -1, 0, 1, 999'999,
                                         9'000'000'000'000'000'007};
    std::vector<ExpectedFrame> written;
    for (size_t i = 0; i < host.size(); ++i) {
        for (StreamId s = 0; s < 2; ++s) {
            FrameMetadata meta;
            meta.stream = s;
            meta.sequence = UINT64_MAX - i;
            meta.host_stamp_ns = host[i];
            meta.device_stamp_ns = INT64_MIN + static_cast<int64_t>(i * 7 + s);
            meta.clock_domain = UINT32_MAX - s;
            meta.exposure_us = i % 2 ? INT64_MAX : -1;
            meta.status = static_cast<FrameStatus>(i % 3);
            FrameRef frame = test::makeFrame(header.streams[s], meta, static_cast<uint32_t>(i + 1));
            ASSERT_TRUE((*writer)->write(frame));
            written.push_back({frame, meta});
        }
    }
    ASSERT_TRUE((*writer)->close());
    auto reader = openMkv(path);
    ASSERT_TRUE(reader) << reader.status().toString();
    Status end;
    auto frames = test::readAll(**reader, &end);
    EXPECT_EQ(end.code(), ErrorCode::kEndOfStream) << end.toString();
    ASSERT_EQ(frames.size(), written.size());
    for (size_t i = 0; i < frames.size(); ++i) {
        test::expectSameFrame(frames[i], written[i], "frame " + std::to_string(i));
    }
}

TEST_F(MkvRoundTrip, FramesComeBackInHostStampOrderAcrossStreams) {
    const auto path = test::tempDir() / "order.mkv";
    RecordingHeader header;
    header.streams = {test::makeStream("a/depth", PixelFormat::kDepth16, 4, 4),
                      test::makeStream("b/ir", PixelFormat::kIR16, 4, 4)};
    auto writer = createMkvWriter(path, header);
    ASSERT_TRUE(writer);
    // Stream a's frames at 0, 10, 20 ms are written before b's at 5, 15, 25 ms: within each
    // stream in order, across streams not.
    std::vector<ExpectedFrame> written;
    for (StreamId s = 0; s < 2; ++s) {
        for (int i = 0; i < 3; ++i) {
            FrameMetadata meta;
            meta.stream = s;
            meta.sequence = static_cast<uint64_t>(i);
            meta.host_stamp_ns = 1'000'000'000 + (i * 10 + static_cast<int>(s) * 5) * 1'000'000;
            FrameRef frame = test::makeFrame(header.streams[s], meta, static_cast<uint32_t>(i));
            ASSERT_TRUE((*writer)->write(frame));
            written.push_back({frame, meta});
        }
    }
    ASSERT_TRUE((*writer)->close());
    auto reader = openMkv(path);
    ASSERT_TRUE(reader);
    auto frames = test::readAll(**reader, nullptr);
    ASSERT_EQ(frames.size(), 6u);
    const std::array<size_t, 6> expected_order = {0, 3, 1, 4, 2, 5};
    for (size_t i = 0; i < frames.size(); ++i) {
        test::expectSameFrame(frames[i], written[expected_order[i]],
                              "position " + std::to_string(i));
    }
}

TEST_F(MkvRoundTrip, TinyImagesAndUnflushedWriterRoundTrip) {
    const auto path = test::tempDir() / "tiny.mkv";
    RecordingHeader header;
    header.streams = {test::makeStream("t/mono16", PixelFormat::kMono16, 1, 1),
                      test::makeStream("t/rgb", PixelFormat::kRGB8, 3, 2),
                      test::makeStream("t/bgr", PixelFormat::kBGR8, 1, 5),
                      test::makeStream("t/nv12", PixelFormat::kNV12, 2, 2),
                      test::makeStream("t/yuyv", PixelFormat::kYUYV, 2, 1),
                      test::makeStream("t/bayer", PixelFormat::kBayerGBRG8, 1, 1)};
    MkvWriterOptions options;
    options.flush_every_frame = false;
    options.ffv1_slices = 16;
    options.threads = 1;
    auto writer = createMkvWriter(path, header, options);
    ASSERT_TRUE(writer) << writer.status().toString();
    std::vector<ExpectedFrame> written;
    for (int i = 0; i < 4; ++i) {
        for (StreamId s = 0; s < header.streams.size(); ++s) {
            FrameMetadata meta;
            meta.stream = s;
            meta.sequence = static_cast<uint64_t>(i);
            meta.host_stamp_ns = 77 + i * 1'000'000'000LL;
            FrameRef frame =
                test::makeFrame(header.streams[s], meta, static_cast<uint32_t>(i * 9 + s));
            ASSERT_TRUE((*writer)->write(frame));
            written.push_back({frame, meta});
        }
    }
    ASSERT_TRUE((*writer)->close());
    EXPECT_EQ((*writer)->bytesWritten(), std::filesystem::file_size(path));
    MkvReaderOptions read_options;
    read_options.decoder_threads = 1;
    auto reader = openMkv(path, read_options);
    ASSERT_TRUE(reader) << reader.status().toString();
    Status end;
    auto frames = test::readAll(**reader, &end);
    EXPECT_EQ(end.code(), ErrorCode::kEndOfStream) << end.toString();
    ASSERT_EQ(frames.size(), written.size());
    for (size_t i = 0; i < frames.size(); ++i) {
        test::expectSameFrame(frames[i], written[i], "frame " + std::to_string(i));
    }
}

TEST_F(MkvRoundTrip, HeldBuffersGiveUnavailableUntilReleased) {
    const auto path = test::tempDir() / "held.mkv";
    RecordingHeader header;
    header.streams = {test::makeStream("c/depth", PixelFormat::kDepth16, 8, 8)};
    const auto written = test::writeRecording(path, header, 5);
    MkvReaderOptions options;
    options.buffers_per_stream = 2;
    auto reader = openMkv(path, options);
    ASSERT_TRUE(reader);
    auto first = (*reader)->next();
    auto second = (*reader)->next();
    ASSERT_TRUE(first && second);
    auto third = (*reader)->next();
    ASSERT_FALSE(third);
    EXPECT_EQ(third.status().code(), ErrorCode::kUnavailable) << third.status().toString();
    first->reset();
    third = (*reader)->next();
    ASSERT_TRUE(third) << third.status().toString();
    test::expectSameFrame(*third, written[2], "third frame after release");
}

TEST_F(MkvRoundTrip, SeekGivesFirstFrameAtOrAfterStampOfEveryStream) {
    const auto path = test::tempDir() / "seek.mkv";
    RecordingHeader header;
    header.streams = {test::makeStream("s/depth", PixelFormat::kDepth16, 8, 8),
                      test::makeStream("s/imu", PixelFormat::kBinary, 0, 1)};
    // 3 s of 30 fps: far enough for a real (index) seek, not only a rewind.
    const auto written = test::writeRecording(path, header, 90);
    auto reader = openMkv(path);
    ASSERT_TRUE(reader);
    for (size_t target_index : {size_t{120}, size_t{7}, size_t{0}, size_t{179}}) {
        const int64_t target = written[target_index].meta.host_stamp_ns;
        ASSERT_TRUE((*reader)->seek(target));
        auto frames = test::readAll(**reader, nullptr);
        // Frames are written in host order, so what follows is exactly the tail.
        ASSERT_EQ(frames.size(), written.size() - target_index) << "seek to " << target_index;
        for (size_t i = 0; i < frames.size(); ++i) {
            ASSERT_TRUE(test::sameFrame(frames[i], written[target_index + i]))
                << "seek to " << target_index << ", frame " << i;
        }
    }
    // Past the end: nothing, cleanly.
    ASSERT_TRUE((*reader)->seek(written.back().meta.host_stamp_ns + 1));
    auto none = (*reader)->next();
    ASSERT_FALSE(none);
    EXPECT_EQ(none.status().code(), ErrorCode::kEndOfStream) << none.status().toString();
}

TEST_F(MkvRoundTrip, WriterRefusesBadInputAndStaysUsable) {
    const auto dir = test::tempDir();
    RecordingHeader header;
    header.streams = {test::makeStream("w/depth", PixelFormat::kDepth16, 4, 4)};

    RecordingHeader odd = header;
    odd.streams.push_back(test::makeStream("w/nv12", PixelFormat::kNV12, 3, 3));
    auto bad = createMkvWriter(dir / "odd.mkv", odd);
    ASSERT_FALSE(bad);
    EXPECT_EQ(bad.status().code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(bad.status().message().find("w/nv12"), std::string::npos) << bad.status().message();

    RecordingHeader empty_attachment = header;
    empty_attachment.attachments.push_back({"empty.txt", "text/plain", {}});
    EXPECT_EQ(createMkvWriter(dir / "a.mkv", empty_attachment).status().code(),
              ErrorCode::kInvalidArgument);
    EXPECT_EQ(createMkvWriter(dir / "none.mkv", RecordingHeader{}).status().code(),
              ErrorCode::kInvalidArgument);
    EXPECT_EQ(createMkvWriter(dir, header).status().code(), ErrorCode::kInvalidArgument);
    auto no_dir = createMkvWriter(dir / "missing" / "x.mkv", header);
    ASSERT_FALSE(no_dir);
    EXPECT_NE(no_dir.status().message().find("missing"), std::string::npos);
    MkvWriterOptions bad_options;
    bad_options.ffv1_slices = 0;
    EXPECT_EQ(createMkvWriter(dir / "b.mkv", header, bad_options).status().code(),
              ErrorCode::kInvalidArgument);

    auto writer = createMkvWriter(dir / "ok.mkv", header);
    ASSERT_TRUE(writer);
    FrameMetadata meta;
    meta.host_stamp_ns = 100;
    const StreamInfo wrong = test::makeStream("w/rgb", PixelFormat::kRGB8, 4, 4);
    EXPECT_EQ((*writer)->write(test::makeFrame(wrong, meta, 1)).code(),
              ErrorCode::kInvalidArgument);
    meta.stream = 3;
    EXPECT_EQ((*writer)->write(test::makeFrame(header.streams[0], meta, 1)).code(),
              ErrorCode::kInvalidArgument);
    meta.stream = 0;
    FrameRef good = test::makeFrame(header.streams[0], meta, 2);
    ASSERT_TRUE((*writer)->write(good));
    meta.host_stamp_ns = 99;  // back in time
    EXPECT_EQ((*writer)->write(test::makeFrame(header.streams[0], meta, 3)).code(),
              ErrorCode::kInvalidArgument);
    ASSERT_TRUE((*writer)->close());
    EXPECT_FALSE((*writer)->write(good));

    auto reader = openMkv(dir / "ok.mkv");
    ASSERT_TRUE(reader);
    auto frames = test::readAll(**reader, nullptr);
    ASSERT_EQ(frames.size(), 1u);
    test::expectSameFrame(frames[0], {good, good.meta()}, "the one good frame");
}

// Runs `command` and returns its standard output.
std::string runCommand(const std::string& command) {
    std::string output;
    FILE* pipe = popen(command.c_str(), "r");
    if (!pipe)
        return output;
    std::array<char, 4096> buffer{};
    size_t n = 0;
    while ((n = fread(buffer.data(), 1, buffer.size(), pipe)) > 0)
        output.append(buffer.data(), n);
    pclose(pipe);
    return output;
}

TEST_F(MkvRoundTrip, FfprobeListsTheStreamsAndFfmpegDecodesDepthExactly) {
    if (std::system("command -v ffprobe >/dev/null 2>&1 && command -v ffmpeg >/dev/null 2>&1") !=
        0) {
        GTEST_SKIP() << "ffprobe/ffmpeg not on PATH (Debian package ffmpeg)";
    }
    const auto dir = test::tempDir();
    const auto path = dir / "probe.mkv";
    RecordingHeader header;
    header.streams = {test::makeStream("kinect/depth", PixelFormat::kDepth16, 16, 8),
                      test::makeStream("kinect/color", PixelFormat::kMJPEG, 16, 8),
                      test::makeStream("kinect/rgb", PixelFormat::kRGB8, 16, 8),
                      test::makeStream("imu/samples", PixelFormat::kBinary, 0, 1)};
    header.attachments = {{"rig.yaml", "application/x-yaml", {'a', ':', ' ', '1', '\n'}}};
    const auto written = test::writeRecording(path, header, 3);

    const std::string probe = runCommand(
        "ffprobe -v error -show_entries stream=index,codec_type,codec_name:stream_tags=title,"
        "filename,MIXRAY_PIXEL_FORMAT -of compact '" +
        path.string() + "'");
    SCOPED_TRACE(probe);
    EXPECT_NE(probe.find("codec_name=ffv1|codec_type=video|tag:title=kinect/depth"),
              std::string::npos);
    EXPECT_NE(probe.find("codec_name=mjpeg"), std::string::npos);
    EXPECT_NE(probe.find("tag:title=kinect/rgb"), std::string::npos);
    EXPECT_NE(probe.find("codec_type=subtitle"), std::string::npos);
    EXPECT_NE(probe.find("tag:title=imu/samples"), std::string::npos);
    EXPECT_NE(probe.find("tag:filename=rig.yaml"), std::string::npos);
    EXPECT_NE(probe.find("tag:MIXRAY_PIXEL_FORMAT=depth16"), std::string::npos);

    // Another tool decodes the 16-bit depth to exactly the values written.
    const auto raw = dir / "depth.raw";
    ASSERT_EQ(std::system(("ffmpeg -v error -y -i '" + path.string() +
                           "' -map 0:0 -fps_mode passthrough -f rawvideo -pix_fmt gray16le '" +
                           raw.string() + "'")
                              .c_str()),
              0);
    std::ifstream in(raw, std::ios::binary);
    std::vector<uint8_t> bytes((std::istreambuf_iterator<char>(in)),
                               std::istreambuf_iterator<char>());
    std::vector<uint8_t> expected;
    for (const auto& w : written) {
        if (w.meta.stream != 0)
            continue;
        const ImageView view = w.frame.image();
        expected.insert(expected.end(), view.data, view.data + view.desc.bufferBytes());
    }
    EXPECT_EQ(bytes, expected);
}

}  // namespace
}  // namespace mixray
