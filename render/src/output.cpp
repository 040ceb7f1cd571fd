// PNG (OpenCV), EXR (OpenEXR) and video (FFmpeg) outputs; third-party exceptions and error codes
// become Status here.
#include "mixray/render/output.h"

#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfOutputFile.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "optics.h"

extern "C" {
#include <libavcodec/avcodec.h>
#include <libavformat/avformat.h>
#include <libavutil/imgutils.h>
#include <libavutil/opt.h>
#include <libswscale/swscale.h>
}

namespace mixray::render {
namespace {

std::string avError(int code) {
    char text[AV_ERROR_MAX_STRING_SIZE] = {};
    av_strerror(code, text, sizeof(text));
    return text;
}

// Writes `bytes` to `path` in one go; kIoError naming the file.
Status writeFile(const std::filesystem::path& path, const std::vector<uchar>& bytes) {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    if (!out)
        return Status(ErrorCode::kIoError, path.string() + ": cannot open for writing");
    out.write(reinterpret_cast<const char*>(bytes.data()),
              static_cast<std::streamsize>(bytes.size()));
    out.close();
    if (!out)
        return Status(ErrorCode::kIoError, path.string() + ": write failed");
    return Status::ok();
}

bool viewFits(const ImageView& image, int bytes_per_pixel) {
    const ImageDesc& d = image.desc;
    if (d.width <= 0 || d.height <= 0 || !image.data || d.stride_bytes < d.width * bytes_per_pixel)
        return false;
    const size_t needed = static_cast<size_t>(d.stride_bytes) * (d.height - 1) +
                          static_cast<size_t>(d.width) * bytes_per_pixel;
    return image.size_bytes >= needed;
}

}  // namespace

double ImageDifference::farOffPercent() const {
    return pixels > 0 ? 100.0 * static_cast<double>(pixels_far_off) / static_cast<double>(pixels)
                      : 0.0;
}

Result<ImageDifference> compareImages(const ImageView& a, const ImageView& b, int far_codes) {
    if (a.desc.format != PixelFormat::kRGB8 || b.desc.format != PixelFormat::kRGB8 ||
        a.desc.width != b.desc.width || a.desc.height != b.desc.height || a.desc.width < 1 ||
        a.desc.height < 1)
        return Status(ErrorCode::kInvalidArgument,
                      "compareImages: two rgb8 images of one size are needed");
    const int w = a.desc.width, h = a.desc.height;
    ImageDifference out;
    out.worst_x8 = Image(ImageDesc::packed(PixelFormat::kMono8, w, h));
    out.pixels = static_cast<uint64_t>(w) * static_cast<uint64_t>(h);
    double sum = 0;
    for (int y = 0; y < h; ++y) {
        const uint8_t* ra = a.row<uint8_t>(y);
        const uint8_t* rb = b.row<uint8_t>(y);
        uint8_t* worst_row = out.worst_x8.bytes().data() + static_cast<size_t>(y) * w;
        for (int x = 0; x < w; ++x) {
            int worst = 0;
            for (int c = 3 * x; c < 3 * x + 3; ++c) {
                const int d = static_cast<int>(ra[c]) - static_cast<int>(rb[c]);
                sum += d * d;
                worst = std::max(worst, std::abs(d));
            }
            out.pixels_far_off += worst > far_codes ? 1 : 0;
            worst_row[x] = static_cast<uint8_t>(std::min(255, 8 * worst));
        }
    }
    out.rmse = std::sqrt(sum / (3.0 * static_cast<double>(out.pixels)));
    return out;
}

Status writePng(const ImageView& image, const std::filesystem::path& path) {
    const std::string name = path.string();
    int type = 0;
    int bytes_per_pixel = 0;
    switch (image.desc.format) {
        case PixelFormat::kRGB8:
        case PixelFormat::kBGR8:
            type = CV_8UC3;
            bytes_per_pixel = 3;
            break;
        case PixelFormat::kMono8:
            type = CV_8UC1;
            bytes_per_pixel = 1;
            break;
        case PixelFormat::kMono16:
        case PixelFormat::kDepth16:
        case PixelFormat::kIR16:
            type = CV_16UC1;
            bytes_per_pixel = 2;
            break;
        default:
            return Status(ErrorCode::kInvalidArgument,
                          name + ": cannot write " + std::string(toString(image.desc.format)) +
                              " as PNG (rgb8, bgr8, mono8 or 16-bit grey)");
    }
    if (!viewFits(image, bytes_per_pixel)) {
        return Status(ErrorCode::kInvalidArgument,
                      name + ": empty image or a view smaller than its size and stride");
    }
    try {
        const cv::Mat view(image.desc.height, image.desc.width, type,
                           const_cast<uint8_t*>(image.data),
                           static_cast<size_t>(image.desc.stride_bytes));
        // A fresh Mat for the swap: the caller's pixels are read-only.
        cv::Mat bgr;
        if (image.desc.format == PixelFormat::kRGB8)
            cv::cvtColor(view, bgr, cv::COLOR_RGB2BGR);
        else
            bgr = view;
        std::vector<uchar> bytes;
        if (!cv::imencode(".png", bgr, bytes))
            return Status(ErrorCode::kInternal, name + ": PNG encoding failed");
        return writeFile(path, bytes);
    } catch (const cv::Exception& e) {
        return Status(ErrorCode::kInternal, name + ": PNG encoding failed: " + e.what());
    }
}

Result<Image> toSrgb8(const FloatImage& linear) {
    if (linear.channels != 3 || linear.width <= 0 || linear.height <= 0 ||
        linear.pixels.size() != static_cast<size_t>(linear.width) * linear.height * 3)
        return Status(ErrorCode::kInvalidArgument,
                      "toSrgb8: a 3-channel image of width x height x 3 pixels is needed");
    Image out(ImageDesc::packed(PixelFormat::kRGB8, linear.width, linear.height));
    const MutableImageView view = out.mutableView();
    for (int y = 0; y < linear.height; ++y) {
        uint8_t* row = view.row<uint8_t>(y);
        for (int x = 0; x < 3 * linear.width; ++x)
            row[x] =
                optics::encodeSrgb8(linear.pixels[static_cast<size_t>(y) * linear.width * 3 + x]);
    }
    return out;
}

Status writeExr(const FloatImage& image, const std::filesystem::path& path) {
    const std::string name = path.string();
    static const char* const kNames[4][4] = {{"Y"}, {}, {"R", "G", "B"}, {"R", "G", "B", "A"}};
    if (image.channels != 1 && image.channels != 3 && image.channels != 4) {
        return Status(
            ErrorCode::kInvalidArgument,
            name + ": EXR output takes 1, 3 or 4 channels, not " + std::to_string(image.channels));
    }
    if (image.width <= 0 || image.height <= 0 ||
        image.pixels.size() != static_cast<size_t>(image.width) * image.height * image.channels) {
        return Status(ErrorCode::kInvalidArgument,
                      name + ": empty image or pixels not width x height x channels");
    }
    try {
        Imf::Header header(image.width, image.height);
        header.compression() = Imf::ZIP_COMPRESSION;
        Imf::FrameBuffer frame;
        const size_t x_stride = sizeof(float) * image.channels;
        const size_t y_stride = x_stride * image.width;
        auto* base = reinterpret_cast<char*>(const_cast<float*>(image.pixels.data()));
        for (int c = 0; c < image.channels; ++c) {
            const char* channel = kNames[image.channels - 1][c];
            header.channels().insert(channel, Imf::Channel(Imf::FLOAT));
            frame.insert(channel,
                         Imf::Slice(Imf::FLOAT, base + c * sizeof(float), x_stride, y_stride));
        }
        Imf::OutputFile file(name.c_str(), header);
        file.setFrameBuffer(frame);
        file.writePixels(image.height);
    } catch (const std::exception& e) {
        return Status(ErrorCode::kIoError, name + ": cannot write EXR: " + e.what());
    }
    return Status::ok();
}

std::string_view toString(VideoCodec codec) {
    switch (codec) {
        case VideoCodec::kAuto:
            return "auto";
        case VideoCodec::kH264:
            return "h264";
        case VideoCodec::kMpeg4:
            return "mpeg4";
        case VideoCodec::kFfv1:
            return "ffv1";
    }
    return "auto";
}

Status VideoWriterOptions::validate() const {
    if (h264_crf < 0 || h264_crf > 51)
        return Status(ErrorCode::kInvalidArgument, "h264_crf: must be 0 to 51");
    static constexpr std::string_view kPresets[] = {"ultrafast", "superfast", "veryfast", "faster",
                                                    "fast",      "medium",    "slow",     "slower",
                                                    "veryslow",  "placebo"};
    if (std::find(std::begin(kPresets), std::end(kPresets), h264_preset) == std::end(kPresets)) {
        return Status(ErrorCode::kInvalidArgument,
                      "h264_preset: unknown libx264 preset \"" + h264_preset + "\"");
    }
    if (mpeg4_qscale < 1 || mpeg4_qscale > 31)
        return Status(ErrorCode::kInvalidArgument, "mpeg4_qscale: must be 1 to 31");
    if (keyframe_interval < 0 || keyframe_interval > 100000)
        return Status(ErrorCode::kInvalidArgument, "keyframe_interval: must be 0 to 100000");
    if (threads < 0 || threads > 256)
        return Status(ErrorCode::kInvalidArgument, "threads: must be 0 to 256");
    return Status::ok();
}

namespace {

// Time base of the encoders: 60 kHz divides the frame periods of 24, 25, 30, 50, 60 and
// 30000/1001 fps exactly and stays under MPEG-4 part 2's 16-bit limit.
constexpr AVRational kTimeBase{1, 60000};

class FfmpegVideoWriter final : public VideoWriter {
public:
    FfmpegVideoWriter(std::filesystem::path path, int width, int height, double fps)
        : path_(std::move(path)),
          name_(path_.string()),
          width_(width),
          height_(height),
          fps_(fps) {}
    ~FfmpegVideoWriter() override { (void)close(); }

    Status open(VideoCodec codec, const VideoWriterOptions& options, const char* muxer);
    Status write(const ImageView& image, int64_t stamp_ns) override;
    Status close() override;
    VideoCodec codec() const override { return codec_; }
    int64_t framesWritten() const override { return frames_; }
    const std::filesystem::path& path() const override { return path_; }
    bool fileCreated() const { return file_created_; }

private:
    Status error(ErrorCode code, const std::string& what) const {
        return Status(code, name_ + ": " + what);
    }
    // Sends `frame` (nullptr: flush) and writes every packet the encoder returns.
    Status encode(const AVFrame* frame);
    void release();

    std::filesystem::path path_;
    std::string name_;
    int width_;
    int height_;
    double fps_;
    VideoCodec codec_ = VideoCodec::kAuto;
    AVFormatContext* format_ = nullptr;
    AVCodecContext* encoder_ = nullptr;
    AVStream* stream_ = nullptr;
    AVFrame* frame_ = nullptr;
    AVPacket* packet_ = nullptr;
    SwsContext* sws_ = nullptr;
    AVPixelFormat sws_source_ = AV_PIX_FMT_NONE;
    bool file_created_ = false;
    bool header_written_ = false;
    bool closed_ = false;
    Status close_status_;
    int64_t frames_ = 0;
    int64_t first_stamp_ns_ = 0;
    int64_t last_pts_ = -1;
    int64_t frame_duration_ = 0;  // in kTimeBase units
    std::vector<uint8_t> staging_;
};

Status FfmpegVideoWriter::open(VideoCodec codec, const VideoWriterOptions& options,
                               const char* muxer) {
    codec_ = codec;
    const char* encoder_name = codec == VideoCodec::kH264    ? "libx264"
                               : codec == VideoCodec::kMpeg4 ? "mpeg4"
                                                             : "ffv1";
    const AVCodec* encoder = avcodec_find_encoder_by_name(encoder_name);
    if (!encoder) {
        return error(ErrorCode::kUnsupported,
                     std::string("this FFmpeg has no ") + encoder_name + " encoder");
    }
    const AVPixelFormat pixel_format =
        codec == VideoCodec::kFfv1 ? AV_PIX_FMT_BGR0 : AV_PIX_FMT_YUV420P;
    if (pixel_format == AV_PIX_FMT_YUV420P && (width_ % 2 != 0 || height_ % 2 != 0)) {
        return error(ErrorCode::kInvalidArgument,
                     std::string(toString(codec)) + " needs an even width and height, got " +
                         std::to_string(width_) + "x" + std::to_string(height_));
    }
    int rc = avformat_alloc_output_context2(&format_, nullptr, muxer, name_.c_str());
    if (rc < 0 || !format_)
        return error(ErrorCode::kInternal,
                     "cannot set up the " + std::string(muxer) + " muxer: " + avError(rc));
    encoder_ = avcodec_alloc_context3(encoder);
    frame_ = av_frame_alloc();
    packet_ = av_packet_alloc();
    if (!encoder_ || !frame_ || !packet_)
        return error(ErrorCode::kInternal, "out of memory");

    encoder_->width = width_;
    encoder_->height = height_;
    encoder_->pix_fmt = pixel_format;
    encoder_->time_base = kTimeBase;
    encoder_->framerate = av_d2q(fps_, 1000000);
    encoder_->sample_aspect_ratio = {1, 1};
    encoder_->gop_size = options.keyframe_interval > 0
                             ? options.keyframe_interval
                             : std::max(1, static_cast<int>(std::lround(fps_)));
    encoder_->thread_count = options.threads;
    if (pixel_format == AV_PIX_FMT_YUV420P) {
        // What swscale's default conversion produces, said in the stream so that players do
        // not guess BT.709 for HD sizes.
        encoder_->colorspace = AVCOL_SPC_SMPTE170M;
        encoder_->color_range = AVCOL_RANGE_MPEG;
        encoder_->color_primaries = AVCOL_PRI_BT709;
        encoder_->color_trc = AVCOL_TRC_IEC61966_2_1;
    }
    frame_duration_ = std::max<int64_t>(1, std::llround(kTimeBase.den / fps_));
    AVDictionary* settings = nullptr;
    if (codec == VideoCodec::kH264) {
        av_dict_set(&settings, "preset", options.h264_preset.c_str(), 0);
        av_dict_set_int(&settings, "crf", options.h264_crf, 0);
    } else if (codec == VideoCodec::kMpeg4) {
        encoder_->flags |= AV_CODEC_FLAG_QSCALE;
        encoder_->global_quality = FF_QP2LAMBDA * options.mpeg4_qscale;
        encoder_->max_b_frames = 0;
    } else {
        av_dict_set(&settings, "level", "3", 0);
        av_dict_set(&settings, "slicecrc", "1", 0);
        encoder_->gop_size = 1;  // FFV1 frames are all key frames; keeps any cut playable
    }
    if (format_->oformat->flags & AVFMT_GLOBALHEADER)
        encoder_->flags |= AV_CODEC_FLAG_GLOBAL_HEADER;
    rc = avcodec_open2(encoder_, encoder, &settings);
    av_dict_free(&settings);
    if (rc < 0)
        return error(ErrorCode::kInternal,
                     "cannot open the " + std::string(encoder_name) + " encoder: " + avError(rc));

    stream_ = avformat_new_stream(format_, nullptr);
    if (!stream_)
        return error(ErrorCode::kInternal, "cannot add a video stream");
    stream_->time_base = kTimeBase;
    stream_->avg_frame_rate = encoder_->framerate;
    rc = avcodec_parameters_from_context(stream_->codecpar, encoder_);
    if (rc < 0)
        return error(ErrorCode::kInternal, "cannot set stream parameters: " + avError(rc));

    frame_->format = pixel_format;
    frame_->width = width_;
    frame_->height = height_;
    rc = av_frame_get_buffer(frame_, 0);
    if (rc < 0)
        return error(ErrorCode::kInternal, "cannot allocate a frame: " + avError(rc));

    if (!(format_->oformat->flags & AVFMT_NOFILE)) {
        rc = avio_open(&format_->pb, name_.c_str(), AVIO_FLAG_WRITE);
        if (rc < 0)
            return error(ErrorCode::kIoError, "cannot open for writing: " + avError(rc));
        file_created_ = true;
    }
    rc = avformat_write_header(format_, nullptr);
    if (rc < 0)
        return error(ErrorCode::kIoError, "cannot write the file header: " + avError(rc));
    header_written_ = true;
    return Status::ok();
}

Status FfmpegVideoWriter::encode(const AVFrame* frame) {
    int rc = avcodec_send_frame(encoder_, frame);
    if (rc < 0)
        return error(ErrorCode::kInternal, "encoding failed: " + avError(rc));
    for (;;) {
        rc = avcodec_receive_packet(encoder_, packet_);
        if (rc == AVERROR(EAGAIN) || rc == AVERROR_EOF)
            return Status::ok();
        if (rc < 0)
            return error(ErrorCode::kInternal, "encoding failed: " + avError(rc));
        if (packet_->duration <= 0)
            packet_->duration = frame_duration_;
        av_packet_rescale_ts(packet_, encoder_->time_base, stream_->time_base);
        packet_->stream_index = stream_->index;
        rc = av_interleaved_write_frame(format_, packet_);
        av_packet_unref(packet_);
        if (rc < 0)
            return error(ErrorCode::kIoError, "write failed: " + avError(rc));
    }
}

Status FfmpegVideoWriter::write(const ImageView& image, int64_t stamp_ns) {
    if (closed_)
        return error(ErrorCode::kUnavailable, "the video writer is closed");
    const ImageDesc& d = image.desc;
    if (d.format != PixelFormat::kRGB8 && d.format != PixelFormat::kBGR8) {
        return error(ErrorCode::kInvalidArgument,
                     "video frames are rgb8 or bgr8, got " + std::string(toString(d.format)));
    }
    if (d.width != width_ || d.height != height_) {
        return error(ErrorCode::kInvalidArgument,
                     "frame is " + std::to_string(d.width) + "x" + std::to_string(d.height) +
                         ", the video " + std::to_string(width_) + "x" + std::to_string(height_));
    }
    if (!viewFits(image, 3))
        return error(ErrorCode::kInvalidArgument, "the view is smaller than its size and stride");
    if (frames_ == 0)
        first_stamp_ns_ = stamp_ns;
    // pts = (stamp - first) in kTimeBase units, rounded to nearest.
    const long double seconds = static_cast<long double>(stamp_ns - first_stamp_ns_) * 1e-9L;
    const int64_t pts = std::llround(seconds * kTimeBase.den / kTimeBase.num);
    if (pts <= last_pts_) {
        return error(ErrorCode::kInvalidArgument, "frame stamp " + std::to_string(stamp_ns) +
                                                      " ns is not later than the previous frame's");
    }

    const AVPixelFormat source =
        d.format == PixelFormat::kRGB8 ? AV_PIX_FMT_RGB24 : AV_PIX_FMT_BGR24;
    if (!sws_ || sws_source_ != source) {
        sws_freeContext(sws_);
        // Exact for packed RGB -> bgr0; BT.601 limited range for yuv420p.
        sws_ = sws_getContext(width_, height_, source, width_, height_, encoder_->pix_fmt,
                              SWS_BICUBIC | SWS_ACCURATE_RND | SWS_FULL_CHR_H_INP, nullptr, nullptr,
                              nullptr);
        sws_source_ = source;
        if (!sws_)
            return error(ErrorCode::kInternal, "cannot set up the pixel format conversion");
    }
    int rc = av_frame_make_writable(frame_);
    if (rc < 0)
        return error(ErrorCode::kInternal, "cannot reuse the frame: " + avError(rc));
    // swscale's SIMD reads up to 16 bytes past a row's end; the caller's buffer may end right
    // there, so convert from a padded copy.
    const int staging_stride = (width_ * 3 + 63) / 64 * 64;
    staging_.resize(static_cast<size_t>(staging_stride) * height_ + 64);
    for (int y = 0; y < height_; ++y) {
        std::memcpy(staging_.data() + static_cast<size_t>(y) * staging_stride,
                    image.row<uint8_t>(y), static_cast<size_t>(width_) * 3);
    }
    const uint8_t* source_planes[1] = {staging_.data()};
    const int source_strides[1] = {staging_stride};
    sws_scale(sws_, source_planes, source_strides, 0, height_, frame_->data, frame_->linesize);
    frame_->pts = pts;
    MIXRAY_RETURN_IF_ERROR(encode(frame_));
    last_pts_ = pts;
    ++frames_;
    return Status::ok();
}

Status FfmpegVideoWriter::close() {
    if (closed_)
        return close_status_;
    closed_ = true;
    if (header_written_) {
        close_status_ = encode(nullptr);
        const int rc = av_write_trailer(format_);
        if (rc < 0 && close_status_.isOk())
            close_status_ = error(ErrorCode::kIoError, "cannot write the trailer: " + avError(rc));
    }
    if (format_ && format_->pb && !(format_->oformat->flags & AVFMT_NOFILE)) {
        const int rc = avio_closep(&format_->pb);
        if (rc < 0 && close_status_.isOk())
            close_status_ = error(ErrorCode::kIoError, "close failed: " + avError(rc));
    }
    release();
    return close_status_;
}

void FfmpegVideoWriter::release() {
    sws_freeContext(sws_);
    sws_ = nullptr;
    av_packet_free(&packet_);
    av_frame_free(&frame_);
    avcodec_free_context(&encoder_);
    if (format_) {
        if (format_->pb && !(format_->oformat->flags & AVFMT_NOFILE))
            avio_closep(&format_->pb);
        avformat_free_context(format_);
        format_ = nullptr;
    }
}

std::string lowerExtension(const std::filesystem::path& path) {
    std::string ext = path.extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    return ext;
}

}  // namespace

Result<std::unique_ptr<VideoWriter>> VideoWriter::create(const std::filesystem::path& path,
                                                         int width, int height, double fps,
                                                         const VideoWriterOptions& options) {
    const std::string name = path.string();
    if (Status s = options.validate(); !s)
        return Status(ErrorCode::kInvalidArgument, name + ": " + s.message());
    if (width <= 0 || height <= 0 || width > 16384 || height > 16384) {
        return Status(ErrorCode::kInvalidArgument,
                      name + ": video size must be 1 to 16384 pixels a side, got " +
                          std::to_string(width) + "x" + std::to_string(height));
    }
    if (!(std::isfinite(fps) && fps >= 0.1 && fps <= 1000)) {
        return Status(ErrorCode::kInvalidArgument,
                      name + ": fps must be 0.1 to 1000, got " + std::to_string(fps));
    }
    const std::string ext = lowerExtension(path);
    const bool mp4 = ext == ".mp4" || ext == ".m4v" || ext == ".mov";
    const bool mkv = ext == ".mkv";
    if (!mp4 && !mkv) {
        return Status(ErrorCode::kInvalidArgument,
                      name + ": unknown video extension \"" + ext + "\" (.mp4, .m4v, .mov, .mkv)");
    }
    VideoCodec codec = options.codec;
    if (codec == VideoCodec::kAuto) {
        if (mkv)
            codec = VideoCodec::kFfv1;
        else
            codec =
                avcodec_find_encoder_by_name("libx264") ? VideoCodec::kH264 : VideoCodec::kMpeg4;
    }
    if (codec == VideoCodec::kFfv1 && !mkv) {
        return Status(ErrorCode::kInvalidArgument, name + ": FFV1 goes in .mkv files, not " + ext);
    }
    const char* muxer = mkv ? "matroska" : (ext == ".mov" ? "mov" : "mp4");
    auto writer = std::make_unique<FfmpegVideoWriter>(path, width, height, fps);
    if (Status s = writer->open(codec, options, muxer); !s) {
        (void)writer->close();
        if (writer->fileCreated()) {
            std::error_code ec;
            std::filesystem::remove(path, ec);  // no half-made file left behind
        }
        return s;
    }
    return std::unique_ptr<VideoWriter>(std::move(writer));
}

}  // namespace mixray::render
