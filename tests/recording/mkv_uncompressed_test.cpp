// Matroska recordings with MkvCompression::kNone: every uncompressed format bit-exact, frames
// stored as they are, files cut anywhere keep their complete frames, and other tools read them.
#include <gtest/gtest.h>
#include <sys/resource.h>

#include <algorithm>
#include <array>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <set>

#include "mixray/graph/mkv.h"
#include "recording_test_util.h"
#include "test_data.h"

namespace mixray {
namespace {

using test::ExpectedFrame;

MkvWriterOptions uncompressed() {
    MkvWriterOptions options;
    options.compression = MkvCompression::kNone;
    return options;
}

std::vector<uint8_t> readBytes(const std::filesystem::path& path) {
    std::ifstream in(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void writeBytes(const std::filesystem::path& path, const std::vector<uint8_t>& bytes, size_t size) {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(size));
}

// The rows of an uncompressed image without padding: what a raw block must hold.
std::vector<uint8_t> packedRows(const ImageView& image) {
    const ImageDesc& d = image.desc;
    const bool nv12 = d.format == PixelFormat::kNV12;
    const size_t row =
        nv12 ? static_cast<size_t>(d.width)
             : static_cast<size_t>(d.width) * pixelFormatInfo(d.format).bits_per_pixel / 8;
    const int rows = nv12 ? d.height * 3 / 2 : d.height;
    std::vector<uint8_t> out;
    for (int y = 0; y < rows; ++y)
        out.insert(out.end(), image.row<uint8_t>(y), image.row<uint8_t>(y) + row);
    return out;
}

bool isImage(PixelFormat format) {
    return format != PixelFormat::kMJPEG && format != PixelFormat::kBinary;
}

// Like test::writeRecording, with writer options: `frames_per_stream` frames per stream in
// host-stamp order; `offsets` receives the file size after each frame.
std::vector<ExpectedFrame> writeWith(const std::filesystem::path& path,
                                     const RecordingHeader& header, int frames_per_stream,
                                     const MkvWriterOptions& options,
                                     std::vector<uint64_t>* offsets = nullptr,
                                     uint64_t* header_bytes = nullptr) {
    std::vector<ExpectedFrame> written;
    auto writer = createMkvWriter(path, header, options);
    EXPECT_TRUE(writer) << writer.status().toString();
    if (!writer)
        return written;
    if (header_bytes)
        *header_bytes = (*writer)->bytesWritten();
    const int64_t t0 = 1'700'000'000'987'654'321;
    for (int i = 0; i < frames_per_stream; ++i) {
        for (size_t s = 0; s < header.streams.size(); ++s) {
            FrameMetadata meta;
            meta.stream = static_cast<StreamId>(s);
            meta.sequence = 500 + static_cast<uint64_t>(i) * 7 + s;
            meta.host_stamp_ns = t0 + i * 33'333'333LL + static_cast<int64_t>(s) * 1'000'003;
            meta.device_stamp_ns = -77 + i * 16'000'001LL - static_cast<int64_t>(s);
            meta.clock_domain = header.streams[s].clock_domain;
            meta.exposure_us = (i + static_cast<int>(s)) % 3 == 0 ? -1 : 1000 + i;
            meta.status = static_cast<FrameStatus>((i + s) % 3);
            FrameRef frame =
                test::makeFrame(header.streams[s], meta, static_cast<uint32_t>(i * 53 + s));
            Status status = (*writer)->write(frame);
            EXPECT_TRUE(status) << status.toString();
            if (offsets)
                offsets->push_back((*writer)->bytesWritten());
            written.push_back({frame, meta});
        }
    }
    Status closed = (*writer)->close();
    EXPECT_TRUE(closed) << closed.toString();
    return written;
}

// How reading a whole file went.
struct ReadOutcome {
    bool opened = false;
    size_t frames = 0;
    Status status;  // the open error, or how reading ended
};

// Reads `path` to its end, expecting exactly the written frames in order.
ReadOutcome readInOrder(const std::filesystem::path& path, const std::vector<ExpectedFrame>& want) {
    ReadOutcome outcome;
    auto reader = openMkv(path);
    if (!reader) {
        outcome.status = reader.status();
        return outcome;
    }
    outcome.opened = true;
    while (true) {
        auto frame = (*reader)->next();
        if (!frame) {
            outcome.status = frame.status();
            return outcome;
        }
        if (outcome.frames >= want.size()) {
            ADD_FAILURE() << "more frames than written";
            return outcome;
        }
        EXPECT_TRUE(test::sameFrame(*frame, want[outcome.frames])) << "frame " << outcome.frames;
        ++outcome.frames;
    }
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

// Every stream format, and images of one or two pixels a side.
std::vector<StreamInfo> everyFormatAndTinySizes() {
    std::vector<StreamInfo> streams = test::everyFormatStreams();
    streams.push_back(test::makeStream("tiny/mono16", PixelFormat::kMono16, 1, 1));
    streams.push_back(test::makeStream("tiny/rgb", PixelFormat::kRGB8, 3, 2));
    streams.push_back(test::makeStream("tiny/bgr", PixelFormat::kBGR8, 1, 5));
    streams.push_back(test::makeStream("tiny/nv12", PixelFormat::kNV12, 2, 2));
    streams.push_back(test::makeStream("tiny/yuyv", PixelFormat::kYUYV, 2, 1));
    streams.push_back(test::makeStream("tiny/bayer", PixelFormat::kBayerBGGR8, 1, 1));
    return streams;
}

class MkvUncompressed : public ::testing::Test {
protected:
    static void SetUpTestSuite() { setFfmpegLogging(false); }
};

TEST_F(MkvUncompressed, EveryPixelFormatComesBackBitExactAndIsStoredAsIs) {
    const auto path = test::tempDir() / "raw_every_format.mkv";
    // Sizes FFV1 needs special care for are plain rows here; they must be just as exact.
    const RecordingHeader header = test::makeHeader(everyFormatAndTinySizes());
    const std::vector<ExpectedFrame> written = writeWith(path, header, 5, uncompressed());
    ASSERT_EQ(written.size(), header.streams.size() * 5);
    // The writer let go of every frame it was handed (raw packets borrow them).
    for (const ExpectedFrame& w : written)
        EXPECT_EQ(w.frame.useCount(), 1u);

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

    // Each image is in the file byte for byte, as its packed rows: stored, not encoded.
    const std::vector<uint8_t> file = readBytes(path);
    for (const ExpectedFrame& w : written) {
        const ImageView image = w.frame.image();
        if (!isImage(image.desc.format) || image.desc.width * image.desc.height < 16)
            continue;
        const std::vector<uint8_t> rows = packedRows(image);
        EXPECT_NE(std::search(file.begin(), file.end(), rows.begin(), rows.end()), file.end())
            << header.streams[w.meta.stream].name << " frame " << w.meta.sequence;
    }
}

TEST_F(MkvUncompressed, HuffyuvGivesBackEveryPixelFormatBitExactAndFfmpegNamesItsCodec) {
    const auto path = test::tempDir() / "ffvhuff_every_format.mkv";
    const RecordingHeader header = test::makeHeader(everyFormatAndTinySizes());
    MkvWriterOptions options;
    options.compression = MkvCompression::kHuffyuv;
    const std::vector<ExpectedFrame> written = writeWith(path, header, 5, options);
    ASSERT_EQ(written.size(), header.streams.size() * 5);
    const ReadOutcome outcome = readInOrder(path, written);
    EXPECT_EQ(outcome.frames, written.size());
    EXPECT_EQ(outcome.status.code(), ErrorCode::kEndOfStream) << outcome.status.toString();
    if (std::system("command -v ffprobe >/dev/null 2>&1") == 0) {
        const std::string codecs = runCommand(
            "ffprobe -v error -show_entries stream=codec_name "
            "-of csv=p=0 '" +
            path.string() + "'");
        EXPECT_NE(codecs.find("ffvhuff"), std::string::npos) << codecs;
        EXPECT_EQ(codecs.find("ffv1"), std::string::npos) << codecs;
    }
}

TEST_F(MkvUncompressed, BothModesReadBackTheSameFrames) {
    const auto dir = test::tempDir();
    RecordingHeader header;
    header.streams = {test::makeStream("k/depth", PixelFormat::kDepth16, 32, 24),
                      test::makeStream("k/color", PixelFormat::kBGR8, 32, 24),
                      test::makeStream("k/jpeg", PixelFormat::kMJPEG, 16, 8),
                      test::makeStream("k/imu", PixelFormat::kBinary, 0, 1)};
    const auto ffv1 = writeWith(dir / "ffv1.mkv", header, 4, MkvWriterOptions{});
    const auto raw = writeWith(dir / "raw.mkv", header, 4, uncompressed());
    ASSERT_EQ(ffv1.size(), raw.size());
    for (const auto& [file, written] : {std::pair{"ffv1.mkv", &ffv1}, std::pair{"raw.mkv", &raw}}) {
        SCOPED_TRACE(file);
        const ReadOutcome outcome = readInOrder(dir / file, *written);
        EXPECT_EQ(outcome.frames, written->size());
        EXPECT_EQ(outcome.status.code(), ErrorCode::kEndOfStream) << outcome.status.toString();
    }
    // The same frames (same seeds) either way, and nothing is compressed in the raw file.
    for (size_t i = 0; i < raw.size(); ++i)
        EXPECT_TRUE(test::sameFrame(raw[i].frame, ffv1[i]));
    size_t image_bytes = 0;
    for (const ExpectedFrame& w : raw) {
        if (isImage(w.frame.image().desc.format))
            image_bytes += w.frame.image().desc.bufferBytes();
    }
    EXPECT_GE(std::filesystem::file_size(dir / "raw.mkv"), image_bytes);
}

TEST_F(MkvUncompressed, PaddedFramesAndUnflushedClustersRoundTrip) {
    const auto path = test::tempDir() / "padded.mkv";
    RecordingHeader header;
    // The stream is packed; its frames arrive with padded rows (as drivers deliver them), and
    // the reverse for the second stream.
    header.streams = {test::makeStream("p/nv12", PixelFormat::kNV12, 10, 6),
                      test::makeStream("p/ir", PixelFormat::kIR16, 7, 5)};
    header.streams[1].format.stride_bytes = 32;
    MkvWriterOptions options = uncompressed();
    options.flush_every_frame = false;
    auto writer = createMkvWriter(path, header, options);
    ASSERT_TRUE(writer) << writer.status().toString();
    std::vector<ExpectedFrame> written;
    for (int i = 0; i < 6; ++i) {
        for (StreamId s = 0; s < 2; ++s) {
            FrameMetadata meta;
            meta.stream = s;
            meta.sequence = static_cast<uint64_t>(i);
            meta.host_stamp_ns = 3'000'000'000LL + i * 40'000'000LL + s;
            StreamInfo delivered = header.streams[s];
            delivered.format.stride_bytes = s == 0 ? 16 : 14;  // 14: packed 7-pixel ir16 rows
            FrameRef frame = test::makeFrame(delivered, meta, static_cast<uint32_t>(i * 3 + s));
            ASSERT_EQ(frame.image().desc.stride_bytes, delivered.format.stride_bytes);
            ASSERT_TRUE((*writer)->write(frame));
            written.push_back({frame, meta});
        }
    }
    ASSERT_TRUE((*writer)->close());
    for (const ExpectedFrame& w : written)
        EXPECT_EQ(w.frame.useCount(), 1u);  // borrowed or copied, every frame was let go
    auto reader = openMkv(path);
    ASSERT_TRUE(reader) << reader.status().toString();
    test::expectSameStreams((*reader)->streams(), header.streams);
    for (size_t i = 0; i < written.size(); ++i) {
        auto frame = (*reader)->next();
        ASSERT_TRUE(frame) << frame.status().toString();
        // Frames come back in the stream's layout, with the same pixels.
        EXPECT_EQ(frame->image().desc, header.streams[written[i].meta.stream].format);
        EXPECT_TRUE(test::sameFrame(*frame, written[i])) << "frame " << i;
    }
    EXPECT_EQ((*reader)->next().status().code(), ErrorCode::kEndOfStream);
}

TEST_F(MkvUncompressed, TruncatedFilesKeepEveryCompleteFrame) {
    const auto dir = test::tempDir();
    const auto path = dir / "raw_cut_source.mkv";
    RecordingHeader header =
        test::makeHeader({test::makeStream("k/depth", PixelFormat::kDepth16, 40, 30),
                          test::makeStream("k/color", PixelFormat::kMJPEG, 16, 8),
                          test::makeStream("k/yuyv", PixelFormat::kYUYV, 20, 10),
                          test::makeStream("k/imu", PixelFormat::kBinary, 0, 1)});
    std::vector<uint64_t> offsets;
    uint64_t header_bytes = 0;
    const auto written = writeWith(path, header, 6, uncompressed(), &offsets, &header_bytes);
    const std::vector<uint8_t> bytes = readBytes(path);
    ASSERT_EQ(offsets.size(), written.size());

    std::set<size_t> cuts = {static_cast<size_t>(header_bytes), bytes.size() - 1};
    for (size_t i = 0; i < offsets.size(); ++i) {
        cuts.insert(offsets[i] - 1);
        cuts.insert(offsets[i]);
        cuts.insert(offsets[i] + 1);
        const uint64_t start = i == 0 ? header_bytes : offsets[i - 1];
        cuts.insert((start + offsets[i]) / 2);  // inside a frame's payload
    }
    const auto cut_path = dir / "raw_cut.mkv";
    for (size_t cut : cuts) {
        if (cut >= bytes.size())
            continue;
        SCOPED_TRACE("cut at byte " + std::to_string(cut) + " of " + std::to_string(bytes.size()));
        writeBytes(cut_path, bytes, cut);
        const ReadOutcome outcome = readInOrder(cut_path, written);
        const std::string status = outcome.status.toString();
        if (!outcome.opened) {
            // Only a cut inside the header (or right at its end: FFmpeg's demuxer wants the
            // start of a cluster) may keep the file from opening.
            EXPECT_LE(cut, header_bytes) << status;
            continue;
        }
        size_t complete = 0;
        while (complete < offsets.size() && offsets[complete] <= cut)
            ++complete;
        EXPECT_GE(outcome.frames, complete) << status;
        EXPECT_TRUE(outcome.status.code() == ErrorCode::kCorruptData ||
                    outcome.status.code() == ErrorCode::kEndOfStream)
            << status;
        if (outcome.frames < written.size()) {
            EXPECT_EQ(outcome.status.code(), ErrorCode::kCorruptData) << status;
        }
    }
}

TEST_F(MkvUncompressed, RecordingCutOffByACrashReadsToItsLastFrame) {
    const auto dir = test::tempDir();
    RecordingHeader header;
    header.streams = {test::makeStream("c/rgb", PixelFormat::kRGB8, 24, 16),
                      test::makeStream("c/imu", PixelFormat::kBinary, 0, 1)};
    auto writer = createMkvWriter(dir / "live.mkv", header, uncompressed());
    ASSERT_TRUE(writer);
    std::vector<ExpectedFrame> written;
    for (int i = 0; i < 10; ++i) {
        for (StreamId s = 0; s < 2; ++s) {
            FrameMetadata meta;
            meta.stream = s;
            meta.sequence = static_cast<uint64_t>(i);
            meta.host_stamp_ns = 5'000'000'000 + i * 10'000'000 + s;
            FrameRef frame = test::makeFrame(header.streams[s], meta, static_cast<uint32_t>(i + s));
            ASSERT_TRUE((*writer)->write(frame));
            written.push_back({frame, meta});
        }
    }
    // What is on disk while the writer is still open is what a crash would leave.
    std::filesystem::copy_file(dir / "live.mkv", dir / "crashed.mkv");
    ASSERT_TRUE((*writer)->close());

    const ReadOutcome crashed = readInOrder(dir / "crashed.mkv", written);
    ASSERT_TRUE(crashed.opened) << crashed.status.toString();
    EXPECT_EQ(crashed.frames, written.size());
    EXPECT_EQ(crashed.status.code(), ErrorCode::kCorruptData) << crashed.status.toString();
    EXPECT_NE(crashed.status.message().find("never finished"), std::string::npos)
        << crashed.status.toString();
    const ReadOutcome finished = readInOrder(dir / "live.mkv", written);
    EXPECT_EQ(finished.frames, written.size());
    EXPECT_EQ(finished.status.code(), ErrorCode::kEndOfStream) << finished.status.toString();
}

// Lowers this process's file size limit (and ignores SIGXFSZ, so writes fail with EFBIG as on
// a full disk) for its lifetime.
class FileSizeLimit {
public:
    explicit FileSizeLimit(rlim_t bytes) {
        getrlimit(RLIMIT_FSIZE, &saved_);
        old_handler_ = std::signal(SIGXFSZ, SIG_IGN);
        rlimit limit = saved_;
        limit.rlim_cur = bytes;
        ok_ = setrlimit(RLIMIT_FSIZE, &limit) == 0;
    }
    ~FileSizeLimit() {
        setrlimit(RLIMIT_FSIZE, &saved_);
        std::signal(SIGXFSZ, old_handler_);
    }
    FileSizeLimit(const FileSizeLimit&) = delete;
    FileSizeLimit& operator=(const FileSizeLimit&) = delete;
    bool ok() const { return ok_; }

private:
    rlimit saved_{};
    void (*old_handler_)(int) = SIG_DFL;
    bool ok_ = false;
};

TEST_F(MkvUncompressed, FullDiskKeepsEveryFrameWrittenBeforeIt) {
    const auto path = test::tempDir() / "full.mkv";
    RecordingHeader header;
    header.streams = {test::makeStream("f/depth", PixelFormat::kDepth16, 64, 48)};
    std::vector<ExpectedFrame> written;
    Status failure;
    {
        FileSizeLimit limit(48 * 1024);  // the header and a few 6 KiB frames
        ASSERT_TRUE(limit.ok());
        auto writer = createMkvWriter(path, header, uncompressed());
        ASSERT_TRUE(writer) << writer.status().toString();
        for (int i = 0; i < 40 && failure.isOk(); ++i) {
            FrameMetadata meta;
            meta.stream = 0;
            meta.sequence = static_cast<uint64_t>(i);
            meta.host_stamp_ns = 1'000'000'000LL + i * 1'000'000LL;
            FrameRef frame = test::makeFrame(header.streams[0], meta, static_cast<uint32_t>(i));
            failure = (*writer)->write(frame);
            if (failure.isOk())
                written.push_back({frame, meta});
        }
        // After the error the writer refuses more and leaves the file as the last flush made it.
        EXPECT_FALSE((*writer)->close());
    }
    ASSERT_FALSE(failure.isOk()) << "the file size limit was never hit";
    EXPECT_EQ(failure.code(), ErrorCode::kIoError) << failure.toString();
    ASSERT_GT(written.size(), 0u);
    const ReadOutcome outcome = readInOrder(path, written);
    EXPECT_EQ(outcome.frames, written.size()) << outcome.status.toString();
    EXPECT_EQ(outcome.status.code(), ErrorCode::kCorruptData) << outcome.status.toString();
}

TEST_F(MkvUncompressed, OptionsRefuseAnUnknownCompression) {
    MkvWriterOptions options;
    std::string why;
    EXPECT_TRUE(options.validate(&why)) << why;
    options.compression = MkvCompression::kNone;
    EXPECT_TRUE(options.validate(&why)) << why;
    options.compression = MkvCompression::kHuffyuv;
    EXPECT_TRUE(options.validate(&why)) << why;
    options.compression = static_cast<MkvCompression>(7);
    EXPECT_FALSE(options.validate(&why));
    EXPECT_NE(why.find("compression"), std::string::npos) << why;
    RecordingHeader header;
    header.streams = {test::makeStream("o/depth", PixelFormat::kDepth16, 4, 4)};
    EXPECT_EQ(createMkvWriter(test::tempDir() / "o.mkv", header, options).status().code(),
              ErrorCode::kInvalidArgument);
}

TEST_F(MkvUncompressed, FfprobeListsTheStreamsAndFfmpegReadsThePixelsExactly) {
    if (std::system("command -v ffprobe >/dev/null 2>&1 && command -v ffmpeg >/dev/null 2>&1") !=
        0) {
        GTEST_SKIP() << "ffprobe/ffmpeg not on PATH (Debian package ffmpeg)";
    }
    const auto dir = test::tempDir();
    const auto path = dir / "raw_probe.mkv";
    struct Expected {
        PixelFormat format;
        const char* pix_fmt;  // FFmpeg's name of the layout
    };
    const std::vector<Expected> formats = {
        {PixelFormat::kMono8, "gray"},
        {PixelFormat::kMono16, "gray16le"},
        {PixelFormat::kRGB8, "rgb24"},
        {PixelFormat::kBGR8, "bgr24"},
        {PixelFormat::kBayerRGGB8, "bayer_rggb8"},
        {PixelFormat::kBayerGRBG8, "bayer_grbg8"},
        {PixelFormat::kBayerGBRG8, "bayer_gbrg8"},
        {PixelFormat::kBayerBGGR8, "bayer_bggr8"},
        {PixelFormat::kYUYV, "yuyv422"},
        {PixelFormat::kNV12, "nv12"},
        {PixelFormat::kDepth16, "gray16le"},
        {PixelFormat::kIR16, "gray16le"},
    };
    RecordingHeader header;
    for (const Expected& e : formats) {
        header.streams.push_back(
            test::makeStream("cam/" + std::string(toString(e.format)), e.format, 16, 8));
    }
    header.streams.push_back(test::makeStream("cam/mjpeg", PixelFormat::kMJPEG, 16, 8));
    header.streams.push_back(test::makeStream("imu/samples", PixelFormat::kBinary, 0, 1));
    const auto written = writeWith(path, header, 3, uncompressed());

    const std::string probe = runCommand(
        "ffprobe -v error -show_entries "
        "stream=index,codec_type,codec_name,pix_fmt,width,height:stream_tags=title "
        "-of compact '" +
        path.string() + "'");
    SCOPED_TRACE(probe);
    for (size_t i = 0; i < formats.size(); ++i) {
        const std::string line = "stream|index=" + std::to_string(i) +
                                 "|codec_name=rawvideo|codec_type=video|width=16|height=8|"
                                 "pix_fmt=" +
                                 formats[i].pix_fmt + "|tag:title=" + header.streams[i].name;
        EXPECT_NE(probe.find(line), std::string::npos) << line;
    }
    EXPECT_NE(probe.find("codec_name=mjpeg"), std::string::npos);
    EXPECT_NE(probe.find("codec_type=subtitle"), std::string::npos);
    EXPECT_NE(probe.find("tag:title=imu/samples"), std::string::npos);

    // Another tool reads every raw stream's pixels as exactly the bytes written.
    for (size_t i = 0; i < formats.size(); ++i) {
        SCOPED_TRACE(header.streams[i].name);
        const auto out = dir / ("stream" + std::to_string(i) + ".raw");
        ASSERT_EQ(std::system(("ffmpeg -v error -y -i '" + path.string() +
                               "' -map 0:" + std::to_string(i) +
                               " -fps_mode passthrough -c:v rawvideo -f " + "rawvideo -pix_fmt " +
                               formats[i].pix_fmt + " '" + out.string() + "'")
                                  .c_str()),
                  0);
        std::vector<uint8_t> expected;
        for (const ExpectedFrame& w : written) {
            if (w.meta.stream != i)
                continue;
            const std::vector<uint8_t> rows = packedRows(w.frame.image());
            expected.insert(expected.end(), rows.begin(), rows.end());
        }
        EXPECT_EQ(readBytes(out), expected);
    }
}

}  // namespace
}  // namespace mixray
