// Writing rendered results: PNG stills, EXR float layers, and video files (FFmpeg).
#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>

#include "mixray/graph/image.h"
#include "mixray/graph/result.h"
#include "mixray/render/renderer.h"

namespace mixray::render {

// Writes an 8-bit image as PNG (whatever the file's extension), losslessly: kRGB8, kBGR8 and
// kMono8, and kMono16/kDepth16/kIR16 as 16-bit grey. Any stride. kInvalidArgument for other
// formats or an empty image; kIoError naming the file when it cannot be written. Reentrant.
Status writePng(const ImageView& image, const std::filesystem::path& path);

// Writes a float image as OpenEXR with 32-bit float channels (exact round trip), ZIP
// compressed: 1 channel as Y, 3 as R G B, 4 as R G B A. kInvalidArgument for other channel
// counts or a pixel vector of the wrong size; kIoError naming the file. Reentrant.
Status writeExr(const FloatImage& image, const std::filesystem::path& path);

// A linear 3-channel float image as an 8-bit sRGB picture (kRGB8), clipped to [0, 1] as a
// camera clips: a look at an environment map or a layer. kInvalidArgument for other channel
// counts or a pixel vector of the wrong size. Reentrant.
Result<Image> toSrgb8(const FloatImage& linear);

// How two rgb8 images of one frame differ, over every pixel and channel, in 8-bit codes.
struct ImageDifference {
    double rmse = 0;
    uint64_t pixels_far_off = 0;  // pixels with a channel more than `far_codes` apart
    double farOffPercent() const;
    Image worst_x8;  // mono8: each pixel's largest channel difference times 8, clipped
    uint64_t pixels = 0;
};

// kInvalidArgument when the two are not rgb8 images of one size. Reentrant.
Result<ImageDifference> compareImages(const ImageView& a, const ImageView& b, int far_codes);

enum class VideoCodec : uint8_t {
    kAuto,   // .mp4/.m4v/.mov: H.264 when the build has libx264, else MPEG-4 part 2; .mkv: FFV1
    kH264,   // libx264, yuv420p (widely playable); .mp4 or .mkv
    kMpeg4,  // MPEG-4 part 2 (FFmpeg's own encoder), yuv420p; .mp4 or .mkv
    kFfv1,   // FFV1 lossless, bgr0: decodes to the exact input pixels; .mkv only
};

std::string_view toString(VideoCodec codec);

// How a VideoWriter encodes. Every field has a working default.
struct VideoWriterOptions {
    VideoCodec codec = VideoCodec::kAuto;
    int h264_crf = 18;                     // H.264 constant rate factor, 0 (lossless) to 51
    std::string h264_preset = "veryfast";  // libx264 preset: ultrafast ... veryslow
    int mpeg4_qscale = 3;                  // MPEG-4 part 2 fixed quantiser, 1 (best) to 31
    int keyframe_interval = 0;             // frames between key frames; 0: one per second
    int threads = 0;                       // encoder threads; 0: FFmpeg decides

    // kInvalidArgument naming the field.
    Status validate() const;
};

// Encodes a sequence of RGB frames into a video file. Frame times come from the stamps: the
// first frame is at t = 0, each later one at (stamp_ns - first stamp_ns); the nominal fps
// sets the time base granularity hint, the key-frame interval and the last frame's duration.
// A writer destroyed without close() closes itself (flushing the encoder and writing the
// container's index), so the file plays; errors at that point are lost — call close() to see
// them. Thread-bound: one thread uses a writer at a time.
class VideoWriter {
public:
    // Opens `path` for writing (replacing it). kInvalidArgument for sizes, fps or options that
    // cannot work (H.264 and MPEG-4 need even sizes), an unknown extension or a codec the
    // container cannot hold; kUnsupported when the codec is missing from this FFmpeg;
    // kIoError when the file cannot be created. Messages name the file.
    static Result<std::unique_ptr<VideoWriter>> create(const std::filesystem::path& path, int width,
                                                       int height, double fps,
                                                       const VideoWriterOptions& options = {});
    virtual ~VideoWriter() = default;

    // Encodes one frame: kRGB8 or kBGR8 of the writer's size, any stride. kInvalidArgument for
    // another format or size, or a stamp not later than the previous frame's (at the time
    // base's resolution); kIoError when writing fails; kUnavailable after close().
    virtual Status write(const ImageView& image, int64_t stamp_ns) = 0;

    // Flushes the encoder, writes the trailer and closes the file. Idempotent: a second call
    // returns the first call's outcome.
    virtual Status close() = 0;

    virtual VideoCodec codec() const = 0;  // the codec chosen (never kAuto)
    virtual int64_t framesWritten() const = 0;
    virtual const std::filesystem::path& path() const = 0;
};

}  // namespace mixray::render
