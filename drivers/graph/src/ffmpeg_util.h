// Internal FFmpeg helpers for the Matroska reader and writer: RAII owners, error text, CRC.
#pragma once

extern "C" {
#include <libavcodec/avcodec.h>
#include <libavformat/avformat.h>
#include <libavutil/dict.h>
#include <libavutil/frame.h>
}

#include <cstddef>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <vector>

#include "mixray/graph/record_codec.h"
#include "mixray/graph/result.h"

namespace mixray::ffmpeg {

// FFmpeg's text for an AVERROR code: "Invalid data found when processing input".
std::string errorString(int av_error);

// kIoError for operating-system failures (disk full, permissions), kCorruptData for bad input,
// kInternal otherwise; the message is "<context>: <FFmpeg's text>".
Status toStatus(int av_error, std::string_view context);

// CRC-32 (IEEE, as in zlib and Matroska's CRC-32 element) of `size` bytes.
uint32_t crc32(const uint8_t* data, size_t size);
uint32_t crc32(std::string_view text);

struct PacketDeleter {
    void operator()(AVPacket* packet) const { av_packet_free(&packet); }
};
struct FrameDeleter {
    void operator()(AVFrame* frame) const { av_frame_free(&frame); }
};
struct CodecContextDeleter {
    void operator()(AVCodecContext* context) const { avcodec_free_context(&context); }
};
using PacketPtr = std::unique_ptr<AVPacket, PacketDeleter>;
using FramePtr = std::unique_ptr<AVFrame, FrameDeleter>;
using CodecContextPtr = std::unique_ptr<AVCodecContext, CodecContextDeleter>;

// The errors FFmpeg logs about one demuxer context, collected while this object lives: the
// Matroska demuxer reports damage it skips (and resynchronises after) only in its log. The
// first instance installs a process-wide log callback that keeps the errors of registered
// contexts and passes everything else to FFmpeg's default callback (which applies
// av_log_set_level). Does not take ownership of `context`; destroy this before the context.
// take() is thread-bound to the thread that uses the context.
class DemuxerErrors {
public:
    struct Entry {
        int64_t byte_offset = -1;  // the demuxer's read position when it logged, -1 unknown
        std::string message;
    };
    explicit DemuxerErrors(AVFormatContext* context);
    ~DemuxerErrors();
    DemuxerErrors(const DemuxerErrors&) = delete;
    DemuxerErrors& operator=(const DemuxerErrors&) = delete;

    // The errors logged since the last call, oldest first.
    std::vector<Entry> take();
    // Called by the log callback (any thread that logs about the context).
    void add(Entry entry);

private:
    AVFormatContext* context_;
    std::mutex mutex_;
    std::vector<Entry> entries_;
};

// The value of `key` in `dict`, or nullptr.
const char* dictValue(const AVDictionary* dict, const char* key);

// Little-endian field access for the on-disk records.
using record::getLe;
using record::putLe;

}  // namespace mixray::ffmpeg
