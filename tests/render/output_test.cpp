// Outputs: PNG and EXR round trips are exact; videos decode (libavformat) to the frames, size,
// duration and time stamps written, FFV1 to the exact pixels; bad input gives errors.
#include "mixray/render/output.h"

#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "test_data.h"

extern "C" {
#include <libavcodec/avcodec.h>
#include <libavformat/avformat.h>
#include <libavutil/log.h>
#include <libswscale/swscale.h>
}

namespace mixray::render {
namespace {

namespace fs = std::filesystem;

// An rgb8 test pattern that moves with `t`, with `pad` bytes of padding per row.
Image pattern(int width, int height, int t, int pad = 0) {
    Image image(ImageDesc{PixelFormat::kRGB8, width, height, width * 3 + pad});
    auto& bytes = image.bytes();
    std::fill(bytes.begin(), bytes.end(), 0xAB);  // padding that must not leak
    for (int y = 0; y < height; ++y) {
        uint8_t* row = bytes.data() + static_cast<size_t>(y) * (width * 3 + pad);
        for (int x = 0; x < width; ++x) {
            const bool square = ((x + 3 * t) / 8 + y / 8) % 2 == 0;
            row[3 * x + 0] = static_cast<uint8_t>(square ? 230 : (x * 7 + t * 11) & 0xff);
            row[3 * x + 1] = static_cast<uint8_t>((y * 5 + t * 3) & 0xff);
            row[3 * x + 2] = static_cast<uint8_t>(square ? 20 : (x + y + t) & 0xff);
        }
    }
    return image;
}

// FFmpeg's encoders log at info level; keep test output readable.
class QuietFfmpeg : public ::testing::Environment {
public:
    void SetUp() override { av_log_set_level(AV_LOG_ERROR); }
};
const auto* const kQuiet = ::testing::AddGlobalTestEnvironment(new QuietFfmpeg);

TEST(OutputTest, PngRoundTripIsExact) {
    const fs::path file = test::tempDir() / "frame.png";
    const Image image = pattern(37, 21, 5, /*pad=*/7);
    const Image original = pattern(37, 21, 5, /*pad=*/7);
    ASSERT_TRUE(writePng(image.view(), file).isOk());
    EXPECT_EQ(image.bytes(), original.bytes());  // the input is left alone
    const cv::Mat read = cv::imread(file.string(), cv::IMREAD_UNCHANGED);
    ASSERT_EQ(read.type(), CV_8UC3);
    ASSERT_EQ(read.cols, 37);
    ASSERT_EQ(read.rows, 21);
    for (int y = 0; y < 21; ++y) {
        const uint8_t* expected = image.view().row<uint8_t>(y);
        for (int x = 0; x < 37; ++x) {
            const cv::Vec3b bgr = read.at<cv::Vec3b>(y, x);
            ASSERT_EQ(bgr[2], expected[3 * x + 0]) << x << "," << y;
            ASSERT_EQ(bgr[1], expected[3 * x + 1]) << x << "," << y;
            ASSERT_EQ(bgr[0], expected[3 * x + 2]) << x << "," << y;
        }
    }
}

TEST(OutputTest, PngGreyAndDepth) {
    Image depth(ImageDesc::packed(PixelFormat::kDepth16, 9, 4));
    auto* values = reinterpret_cast<uint16_t*>(depth.bytes().data());
    for (int i = 0; i < 36; ++i)
        values[i] = static_cast<uint16_t>(i * 1800 + 1);
    const fs::path file = test::tempDir() / "depth.png";
    ASSERT_TRUE(writePng(depth.view(), file).isOk());
    const cv::Mat read = cv::imread(file.string(), cv::IMREAD_UNCHANGED);
    ASSERT_EQ(read.type(), CV_16UC1);
    for (int i = 0; i < 36; ++i)
        EXPECT_EQ(read.at<uint16_t>(i / 9, i % 9), values[i]);
}

TEST(OutputTest, PngErrors) {
    const Image image = pattern(8, 8, 0);
    const fs::path bad = test::tempDir() / "no_such_dir" / "x.png";
    const Status status = writePng(image.view(), bad);
    EXPECT_EQ(status.code(), ErrorCode::kIoError);
    EXPECT_NE(status.message().find(bad.string()), std::string::npos) << status.message();

    Image yuyv(ImageDesc::packed(PixelFormat::kYUYV, 8, 8));
    EXPECT_EQ(writePng(yuyv.view(), test::tempDir() / "y.png").code(), ErrorCode::kInvalidArgument);
    EXPECT_EQ(writePng(ImageView{}, test::tempDir() / "e.png").code(), ErrorCode::kInvalidArgument);
}

// Reads every channel of an EXR file as floats, in `names` order.
FloatImage readExr(const fs::path& file, const std::vector<const char*>& names) {
    Imf::InputFile in(file.string().c_str());
    const Imath::Box2i window = in.header().dataWindow();
    FloatImage image;
    image.width = window.max.x - window.min.x + 1;
    image.height = window.max.y - window.min.y + 1;
    image.channels = static_cast<int>(names.size());
    image.pixels.resize(static_cast<size_t>(image.width) * image.height * image.channels);
    Imf::FrameBuffer frame;
    const size_t xs = sizeof(float) * image.channels;
    for (size_t c = 0; c < names.size(); ++c) {
        EXPECT_EQ(in.header().channels().findChannel(names[c])->type, Imf::FLOAT);
        frame.insert(names[c],
                     Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(image.pixels.data() + c), xs,
                                xs * image.width));
    }
    in.setFrameBuffer(frame);
    in.readPixels(window.min.y, window.max.y);
    return image;
}

TEST(OutputTest, ExrRoundTripIsExact) {
    for (int channels : {1, 3, 4}) {
        FloatImage image;
        image.width = 13;
        image.height = 7;
        image.channels = channels;
        image.pixels.resize(13 * 7 * channels);
        const float specials[] = {
            0.0f,   -0.0f,    1.0f / 3.0f, 1e-30f,
            -7.25f, 65504.5f, 1e30f,       std::numeric_limits<float>::denorm_min(),
            0.1f};
        for (size_t i = 0; i < image.pixels.size(); ++i)
            image.pixels[i] = specials[i % 9] * (1.0f + static_cast<float>(i) * 1e-3f);
        const fs::path file = test::tempDir() / ("layer" + std::to_string(channels) + ".exr");
        ASSERT_TRUE(writeExr(image, file).isOk());
        const std::vector<const char*> names = channels == 1 ? std::vector<const char*>{"Y"}
                                               : channels == 3
                                                   ? std::vector<const char*>{"R", "G", "B"}
                                                   : std::vector<const char*>{"R", "G", "B", "A"};
        const FloatImage read = readExr(file, names);
        ASSERT_EQ(read.width, 13);
        ASSERT_EQ(read.height, 7);
        ASSERT_EQ(read.pixels.size(), image.pixels.size());
        EXPECT_EQ(std::memcmp(read.pixels.data(), image.pixels.data(),
                              image.pixels.size() * sizeof(float)),
                  0)
            << channels << " channels";
    }
}

TEST(OutputTest, ExrErrors) {
    FloatImage image;
    image.width = 2;
    image.height = 2;
    image.channels = 3;
    image.pixels.assign(12, 0.5f);
    const fs::path bad = test::tempDir() / "no_such_dir" / "x.exr";
    const Status status = writeExr(image, bad);
    EXPECT_EQ(status.code(), ErrorCode::kIoError);
    EXPECT_NE(status.message().find(bad.string()), std::string::npos) << status.message();
    image.channels = 2;
    EXPECT_EQ(writeExr(image, test::tempDir() / "c.exr").code(), ErrorCode::kInvalidArgument);
    image.channels = 3;
    image.pixels.resize(11);
    EXPECT_EQ(writeExr(image, test::tempDir() / "s.exr").code(), ErrorCode::kInvalidArgument);
}

// What a video file decodes to.
struct Decoded {
    AVCodecID codec = AV_CODEC_ID_NONE;
    int width = 0;
    int height = 0;
    double duration_s = 0;
    std::vector<double> times_s;    // presentation time of each frame
    std::vector<Image> frames_rgb;  // each frame converted to rgb8
};

Decoded decode(const fs::path& file) {
    Decoded out;
    AVFormatContext* format = nullptr;
    if (avformat_open_input(&format, file.string().c_str(), nullptr, nullptr) < 0) {
        ADD_FAILURE() << "cannot open " << file;
        return out;
    }
    EXPECT_GE(avformat_find_stream_info(format, nullptr), 0);
    const int index = av_find_best_stream(format, AVMEDIA_TYPE_VIDEO, -1, -1, nullptr, 0);
    EXPECT_GE(index, 0);
    AVStream* stream = format->streams[index];
    out.codec = stream->codecpar->codec_id;
    out.width = stream->codecpar->width;
    out.height = stream->codecpar->height;
    out.duration_s = static_cast<double>(format->duration) / AV_TIME_BASE;
    const AVCodec* codec = avcodec_find_decoder(stream->codecpar->codec_id);
    AVCodecContext* decoder = avcodec_alloc_context3(codec);
    avcodec_parameters_to_context(decoder, stream->codecpar);
    EXPECT_GE(avcodec_open2(decoder, codec, nullptr), 0);
    AVPacket* packet = av_packet_alloc();
    AVFrame* frame = av_frame_alloc();
    SwsContext* sws = nullptr;
    auto drain = [&] {
        while (avcodec_receive_frame(decoder, frame) >= 0) {
            out.times_s.push_back(static_cast<double>(frame->best_effort_timestamp) *
                                  av_q2d(stream->time_base));
            Image rgb(ImageDesc::packed(PixelFormat::kRGB8, frame->width, frame->height));
            sws = sws_getCachedContext(
                sws, frame->width, frame->height, static_cast<AVPixelFormat>(frame->format),
                frame->width, frame->height, AV_PIX_FMT_RGB24,
                SWS_BICUBIC | SWS_ACCURATE_RND | SWS_FULL_CHR_H_INT, nullptr, nullptr, nullptr);
            uint8_t* planes[1] = {rgb.bytes().data()};
            const int strides[1] = {rgb.desc().stride_bytes};
            sws_scale(sws, frame->data, frame->linesize, 0, frame->height, planes, strides);
            out.frames_rgb.push_back(std::move(rgb));
        }
    };
    while (av_read_frame(format, packet) >= 0) {
        if (packet->stream_index == index) {
            EXPECT_GE(avcodec_send_packet(decoder, packet), 0);
            drain();
        }
        av_packet_unref(packet);
    }
    avcodec_send_packet(decoder, nullptr);
    drain();
    sws_freeContext(sws);
    av_frame_free(&frame);
    av_packet_free(&packet);
    avcodec_free_context(&decoder);
    avformat_close_input(&format);
    return out;
}

constexpr int kWidth = 64;
constexpr int kHeight = 48;
constexpr int kFrames = 30;
constexpr double kFps = 30;
constexpr int64_t kFirstStamp = 5'000'000'000;  // the video starts at 0 whatever the stamps

// Frame i's slot: 0..14, then two dropped frames, then 17..31.
int slot(int i) {
    return i < 15 ? i : i + 2;
}
int64_t stampOf(int i) {
    return kFirstStamp + slot(i) * 1'000'000'000LL / 30;
}

// Writes kFrames moving-pattern frames with one gap; the writer is closed unless `abandon`.
void writeVideo(const fs::path& file, const VideoWriterOptions& options, bool abandon = false) {
    auto writer = VideoWriter::create(file, kWidth, kHeight, kFps, options);
    ASSERT_TRUE(writer.isOk()) << writer.status().toString();
    for (int i = 0; i < kFrames; ++i) {
        const Image frame = pattern(kWidth, kHeight, i, i % 3);  // strides vary too
        ASSERT_TRUE((*writer)->write(frame.view(), stampOf(i)).isOk());
    }
    EXPECT_EQ((*writer)->framesWritten(), kFrames);
    if (!abandon) {
        const Status closed = (*writer)->close();
        ASSERT_TRUE(closed.isOk()) << closed.toString();
        EXPECT_TRUE((*writer)->close().isOk());  // idempotent
    }
}

void expectTiming(const Decoded& video) {
    EXPECT_EQ(video.width, kWidth);
    EXPECT_EQ(video.height, kHeight);
    ASSERT_EQ(static_cast<int>(video.times_s.size()), kFrames);
    const double first = video.times_s.front();
    for (int i = 0; i < kFrames; ++i)
        EXPECT_NEAR(video.times_s[i] - first, slot(i) / kFps, 1.5e-3) << "frame " << i;
    // 32 frame slots of 1/30 s: the last frame lasts one nominal period.
    EXPECT_NEAR(video.duration_s, 32 / kFps, 1.0 / kFps + 1e-3);
}

// Mean absolute difference per channel between written and decoded frames.
double meanError(const Decoded& video) {
    double sum = 0;
    size_t n = 0;
    for (int i = 0; i < static_cast<int>(video.frames_rgb.size()); ++i) {
        const Image expected = pattern(kWidth, kHeight, i);
        for (size_t b = 0; b < expected.bytes().size(); ++b, ++n)
            sum += std::abs(int(expected.bytes()[b]) - int(video.frames_rgb[i].bytes()[b]));
    }
    return n ? sum / n : 1e9;
}

TEST(OutputTest, Ffv1IsLossless) {
    const fs::path file = test::tempDir() / "lossless.mkv";
    writeVideo(file, {});
    const Decoded video = decode(file);
    EXPECT_EQ(video.codec, AV_CODEC_ID_FFV1);
    expectTiming(video);
    ASSERT_EQ(static_cast<int>(video.frames_rgb.size()), kFrames);
    for (int i = 0; i < kFrames; ++i) {
        EXPECT_TRUE(sameImage(video.frames_rgb[i].view(), pattern(kWidth, kHeight, i).view()))
            << "frame " << i;
    }
}

TEST(OutputTest, Mp4Auto) {
    const fs::path file = test::tempDir() / "clip.mp4";
    writeVideo(file, {});
    const Decoded video = decode(file);
    const bool have_x264 = avcodec_find_encoder_by_name("libx264") != nullptr;
    EXPECT_EQ(video.codec, have_x264 ? AV_CODEC_ID_H264 : AV_CODEC_ID_MPEG4);
    expectTiming(video);
    EXPECT_LT(meanError(video), 12.0);
}

TEST(OutputTest, Mpeg4InMp4AndH264InMkv) {
    VideoWriterOptions options;
    options.codec = VideoCodec::kMpeg4;
    const fs::path mp4 = test::tempDir() / "part2.mp4";
    writeVideo(mp4, options);
    const Decoded part2 = decode(mp4);
    EXPECT_EQ(part2.codec, AV_CODEC_ID_MPEG4);
    expectTiming(part2);
    EXPECT_LT(meanError(part2), 12.0);

    if (!avcodec_find_encoder_by_name("libx264"))
        GTEST_SKIP() << "this FFmpeg has no libx264";
    options.codec = VideoCodec::kH264;
    const fs::path mkv = test::tempDir() / "h264.mkv";
    writeVideo(mkv, options);
    const Decoded h264 = decode(mkv);
    EXPECT_EQ(h264.codec, AV_CODEC_ID_H264);
    expectTiming(h264);
    EXPECT_LT(meanError(h264), 12.0);
}

TEST(OutputTest, WriterDestroyedWithoutCloseLeavesAPlayableFile) {
    for (const char* name : {"abandoned.mp4", "abandoned.mkv"}) {
        const fs::path file = test::tempDir() / name;
        writeVideo(file, {}, /*abandon=*/true);
        const Decoded video = decode(file);
        EXPECT_EQ(static_cast<int>(video.frames_rgb.size()), kFrames) << name;
    }
}

TEST(OutputTest, VideoErrors) {
    const fs::path dir = test::tempDir();
    auto expectCreate = [](const fs::path& file, int w, int h, double fps,
                           VideoWriterOptions options, ErrorCode code) {
        auto writer = VideoWriter::create(file, w, h, fps, options);
        ASSERT_FALSE(writer.isOk()) << file;
        EXPECT_EQ(writer.status().code(), code) << writer.status().toString();
        EXPECT_NE(writer.status().message().find(file.string()), std::string::npos)
            << writer.status().message();
    };
    expectCreate(dir / "no_such_dir" / "x.mkv", 64, 48, 30, {}, ErrorCode::kIoError);
    expectCreate(dir / "no_such_dir" / "x.mp4", 64, 48, 30, {}, ErrorCode::kIoError);
    EXPECT_FALSE(fs::exists(dir / "no_such_dir"));
    expectCreate(dir / "x.avi", 64, 48, 30, {}, ErrorCode::kInvalidArgument);
    expectCreate(dir / "x.mkv", 0, 48, 30, {}, ErrorCode::kInvalidArgument);
    expectCreate(dir / "x.mkv", 64, 48, std::nan(""), {}, ErrorCode::kInvalidArgument);
    expectCreate(dir / "x.mp4", 63, 48, 30, {}, ErrorCode::kInvalidArgument);
    VideoWriterOptions ffv1;
    ffv1.codec = VideoCodec::kFfv1;
    expectCreate(dir / "x.mp4", 64, 48, 30, ffv1, ErrorCode::kInvalidArgument);
    VideoWriterOptions bad;
    bad.h264_crf = 60;
    expectCreate(dir / "x.mp4", 64, 48, 30, bad, ErrorCode::kInvalidArgument);
    EXPECT_FALSE(fs::exists(dir / "x.mp4"));
    // A refused create leaves an existing file alone.
    std::ofstream(dir / "keep.mp4") << "precious";
    expectCreate(dir / "keep.mp4", 63, 48, 30, {}, ErrorCode::kInvalidArgument);
    EXPECT_EQ(fs::file_size(dir / "keep.mp4"), 8u);

    // Odd sizes are fine losslessly.
    auto writer = VideoWriter::create(dir / "odd.mkv", 33, 17, 30);
    ASSERT_TRUE(writer.isOk()) << writer.status().toString();
    EXPECT_EQ((*writer)->codec(), VideoCodec::kFfv1);
    EXPECT_EQ((*writer)->write(pattern(32, 17, 0).view(), 0).code(), ErrorCode::kInvalidArgument);
    Image grey(ImageDesc::packed(PixelFormat::kMono8, 33, 17));
    EXPECT_EQ((*writer)->write(grey.view(), 0).code(), ErrorCode::kInvalidArgument);
    ASSERT_TRUE((*writer)->write(pattern(33, 17, 0).view(), 1000).isOk());
    const Status same = (*writer)->write(pattern(33, 17, 1).view(), 1000);
    EXPECT_EQ(same.code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(same.message().find("odd.mkv"), std::string::npos) << same.message();
    ASSERT_TRUE((*writer)->write(pattern(33, 17, 1).view(), 40'000'000).isOk());
    ASSERT_TRUE((*writer)->close().isOk());
    EXPECT_EQ((*writer)->write(pattern(33, 17, 2).view(), 80'000'000).code(),
              ErrorCode::kUnavailable);
    const Decoded odd = decode(dir / "odd.mkv");
    EXPECT_EQ(odd.frames_rgb.size(), 2u);
    EXPECT_EQ(odd.width, 33);
}

}  // namespace
}  // namespace mixray::render
