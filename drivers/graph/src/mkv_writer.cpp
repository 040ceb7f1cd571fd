// Lossless Matroska recordings through libavformat: FFV1 or raw images, copied MJPEG and binary
// blocks, exact per-frame metadata as BlockAdditional, one flushed cluster per frame.
#include <algorithm>
#include <cstring>
#include <limits>
#include <memory>
#include <utility>
#include <vector>

#include "ffmpeg_util.h"
#include "mixray/graph/mkv.h"
#include "mkv_format.h"

extern "C" {
#include <libavutil/opt.h>
}

namespace mixray {
namespace {

using ffmpeg::CodecContextPtr;
using ffmpeg::FramePtr;
using ffmpeg::PacketPtr;

constexpr uint64_t kNsPerMs = 1000000;

// Frees the FrameRef whose bytes a raw packet borrowed (av_buffer_create's free callback).
void releaseFrame(void* opaque, uint8_t* /*data*/) {
    delete static_cast<FrameRef*>(opaque);
}

// createMkvWriter's writer: one libavformat muxer, one FFV1 or ffvhuff encoder per image stream
// stored coded. Thread-bound, like every RecordingWriter.
class MkvWriter final : public RecordingWriter {
public:
    MkvWriter(std::filesystem::path path, const MkvWriterOptions& options)
        : path_(std::move(path)), options_(options), packet_(av_packet_alloc()) {}
    ~MkvWriter() override { (void)close(); }
    MkvWriter(const MkvWriter&) = delete;
    MkvWriter& operator=(const MkvWriter&) = delete;

    Status open(const RecordingHeader& header);
    Status write(const FrameRef& frame) override {
        return frame ? writeAs(frame.meta().stream, frame)
                     : Status(ErrorCode::kInvalidArgument, "write: empty frame");
    }
    Status writeAs(StreamId stream, const FrameRef& frame) override;
    Status close() override;
    uint64_t bytesWritten() const override {
        return fmt_ && fmt_->pb ? static_cast<uint64_t>(fmt_->pb->bytes_written) : bytes_;
    }

private:
    struct Track {
        StreamInfo info;
        mkv::Storage storage;
        AVStream* stream = nullptr;
        CodecContextPtr encoder;
        FramePtr frame;
        int64_t last_host_ns = std::numeric_limits<int64_t>::min();
    };

    Status addTrack(const StreamInfo& info);
    Status addAttachment(const Attachment& attachment);
    Status encode(Track& track, const FrameRef& frame);
    Status wrapRaw(const FrameRef& frame, AVPacket* packet);
    Status checkFrame(const Track& track, const ImageView& image) const;
    std::string context() const { return "writing " + path_.string(); }
    // Remembers the first failure: after it the file is left as it is and every call reports it.
    Status fail(Status status) {
        if (error_.isOk())
            error_ = status;
        return status;
    }
    Status checkIo() {
        if (fmt_->pb && fmt_->pb->error < 0)
            return fail(ffmpeg::toStatus(fmt_->pb->error, context()));
        return Status::ok();
    }

    std::filesystem::path path_;
    MkvWriterOptions options_;
    AVFormatContext* fmt_ = nullptr;
    std::vector<Track> tracks_;
    PacketPtr packet_;
    bool have_base_ = false;
    int64_t base_ns_ = 0;  // host stamp of the first frame: pts 0
    Status error_;
    bool closed_ = false;
    Status close_status_;
    uint64_t bytes_ = 0;
};

Status MkvWriter::open(const RecordingHeader& header) {
    if (header.streams.empty()) {
        return {ErrorCode::kInvalidArgument, context() + ": a recording needs at least one stream"};
    }
    for (size_t i = 0; i < header.streams.size(); ++i) {
        MIXRAY_RETURN_IF_ERROR(mkv::validateStreamInfo(header.streams[i]).withContext(context()));
        for (size_t j = 0; j < i; ++j) {
            if (header.streams[j].name == header.streams[i].name) {
                return {ErrorCode::kInvalidArgument,
                        context() + ": stream '" + header.streams[i].name + "' listed twice"};
            }
        }
    }
    for (const auto& [key, value] : header.tags) {
        if (key.empty() || key.find('\0') != std::string::npos ||
            value.find('\0') != std::string::npos) {
            return {ErrorCode::kInvalidArgument,
                    context() + ": recording tags need non-empty keys and no NUL bytes"};
        }
    }
    std::error_code ec;
    if (std::filesystem::is_directory(path_, ec)) {
        return {ErrorCode::kInvalidArgument, context() + ": is a directory"};
    }

    int err = avformat_alloc_output_context2(&fmt_, nullptr, "matroska", nullptr);
    if (err < 0 || !fmt_)
        return ffmpeg::toStatus(err, context() + ": no Matroska muxer");
    for (const StreamInfo& info : header.streams)
        MIXRAY_RETURN_IF_ERROR(addTrack(info));
    const bool raw = std::any_of(tracks_.begin(), tracks_.end(),
                                 [](const Track& track) { return track.storage.raw(); });
    if (raw) {
        // FFmpeg 5.1's muxer checks codec tags against the AVI (RIFF) list, which lacks
        // FFmpeg's own raw-video FourCCs for 16-bit grey, RGB24, BGR24 and Bayer; Matroska
        // refuses raw video without a FourCC. "Unofficial" lets the tags through and changes
        // nothing else (an FFV1 file comes out byte-identical with it).
        fmt_->strict_std_compliance = FF_COMPLIANCE_UNOFFICIAL;
    }
    for (const Attachment& attachment : header.attachments) {
        MIXRAY_RETURN_IF_ERROR(addAttachment(attachment));
    }
    for (const auto& [key, value] : mkv::globalTags(header)) {
        av_dict_set(&fmt_->metadata, key.c_str(), value.c_str(), 0);
    }

    // "file:" keeps a colon in the path from being read as a protocol name.
    const std::string url = "file:" + path_.string();
    err = avio_open(&fmt_->pb, url.c_str(), AVIO_FLAG_WRITE);
    if (err < 0)
        return ffmpeg::toStatus(err, "cannot create " + path_.string());

    AVDictionary* muxer_options = nullptr;
    if (!options_.flush_every_frame) {
        // Bounds what a crash can lose when clusters are not closed after every frame.
        av_dict_set(&muxer_options, "cluster_time_limit", "1000", 0);
    }
    if (raw) {
        // Matroska's optional CRC-32 element over each cluster would be a second pass over
        // every raw frame, costing about as much CPU as writing it, and guards nothing more:
        // every block's frame record holds the CRC of its payload, the header tags and
        // attachments have theirs, and FFmpeg's demuxer skips CRC-32 elements.
        av_dict_set(&muxer_options, "write_crc32", "0", 0);
    }
    err = avformat_write_header(fmt_, &muxer_options);
    av_dict_free(&muxer_options);
    if (err < 0)
        return fail(ffmpeg::toStatus(err, context() + ": header"));
    // The header (streams, attachments, tags) is on disk before the first frame, so a
    // recording cut off at any later point still opens.
    avio_flush(fmt_->pb);
    MIXRAY_RETURN_IF_ERROR(checkIo());
    return Status::ok();
}

Status MkvWriter::addTrack(const StreamInfo& info) {
    const mkv::Storage storage = *mkv::storageFor(info.format.format, options_.compression);
    Track track;
    track.info = info;
    track.storage = storage;
    track.stream = avformat_new_stream(fmt_, nullptr);
    if (!track.stream)
        return {ErrorCode::kInternal, context() + ": cannot add a stream"};
    AVStream* st = track.stream;
    st->time_base = AVRational{1, 1000};
    const std::string what = context() + ": stream '" + info.name + "'";

    if (storage.encoded()) {
        const AVCodec* codec = avcodec_find_encoder(storage.codec);
        const bool ffv1 = storage.codec == AV_CODEC_ID_FFV1;
        if (!codec)
            return {ErrorCode::kUnsupported, what + ": FFmpeg lacks the " +
                                                 avcodec_get_name(storage.codec) + " encoder"};
        // FFmpeg 5.1's FFV1 version 3 silently decodes to zeros when a slice is 1 pixel wide
        // or high (found by brute force over all sizes up to 48x48); version 1 has no slices
        // and no such case. Slices of at least 2x2 were verified exact for every size and
        // format used here. Version 3 also refuses some slice counts on small images.
        const int w = info.format.width;
        const int h = info.format.height;
        const int wanted = options_.ffv1_slices;
        std::vector<std::pair<int, int>> tries;  // (level, slices)
        if (ffv1 && w / wanted >= 2 && h / wanted >= 2)
            tries.emplace_back(3, wanted);
        if (ffv1 && w >= 2 && h >= 2)
            tries.emplace_back(3, 1);
        tries.emplace_back(1, 1);  // ffvhuff: neither levels nor slices
        int err = 0;
        for (const auto& [level, slices] : tries) {
            track.encoder.reset(avcodec_alloc_context3(codec));
            AVCodecContext* c = track.encoder.get();
            c->width = w;
            c->height = h;
            c->pix_fmt = storage.pixel;
            c->time_base = AVRational{1, 1000};
            c->gop_size = 1;  // every frame a keyframe: seekable, and damage stays in one frame
            c->level = level;
            c->slices = slices;
            c->thread_count = slices > 1 ? options_.threads : 1;
            c->thread_type = FF_THREAD_SLICE;
            if (fmt_->oformat->flags & AVFMT_GLOBALHEADER)
                c->flags |= AV_CODEC_FLAG_GLOBAL_HEADER;
            if (ffv1) {
                if (level >= 3)
                    av_opt_set_int(c->priv_data, "slicecrc", 1, 0);
                av_opt_set_int(c->priv_data, "coder", 1, 0);  // range coder: smaller than Golomb
            } else {
                // Each frame its own Huffman tables: keyframes only, and smaller files.
                av_opt_set_int(c->priv_data, "context", 1, 0);
            }
            err = avcodec_open2(c, codec, nullptr);
            if (err >= 0)
                break;
        }
        if (err < 0)
            return ffmpeg::toStatus(err,
                                    what + ": " + avcodec_get_name(storage.codec) + " encoder");
        err = avcodec_parameters_from_context(st->codecpar, track.encoder.get());
        if (err < 0)
            return ffmpeg::toStatus(err, what);
        track.frame.reset(av_frame_alloc());
        track.frame->format = storage.pixel;
        track.frame->width = info.format.width;
        track.frame->height = info.format.height;
        err = av_frame_get_buffer(track.frame.get(), 0);
        if (err < 0)
            return ffmpeg::toStatus(err, what);
    } else {
        st->codecpar->codec_type = storage.media;
        st->codecpar->codec_id = storage.codec;
        if (storage.media == AVMEDIA_TYPE_VIDEO) {
            st->codecpar->width = info.format.width;
            st->codecpar->height = info.format.height;
        }
        if (storage.raw()) {
            // The muxer writes the tag as the track's ColourSpace: the layout other tools read.
            st->codecpar->format = storage.pixel;
            st->codecpar->codec_tag = storage.codec_tag;
        }
    }
    av_dict_set(&st->metadata, "title", info.name.c_str(), 0);
    for (const auto& [key, value] : mkv::streamTags(info)) {
        av_dict_set(&st->metadata, key.c_str(), value.c_str(), 0);
    }
    tracks_.push_back(std::move(track));
    return Status::ok();
}

Status MkvWriter::addAttachment(const Attachment& attachment) {
    const std::string what = context() + ": attachment '" + attachment.name + "'";
    if (attachment.name.empty() ||
        attachment.name.find_first_of(std::string("/\\\0", 3)) != std::string::npos) {
        return {ErrorCode::kInvalidArgument, what + ": needs a plain file name"};
    }
    if (attachment.data.empty()) {
        // FFmpeg's demuxer drops empty attachments: refusing here keeps round trips exact.
        return {ErrorCode::kInvalidArgument, what + ": Matroska cannot hold an empty attachment"};
    }
    if (attachment.data.size() > static_cast<size_t>(INT32_MAX - AV_INPUT_BUFFER_PADDING_SIZE)) {
        return {ErrorCode::kInvalidArgument, what + ": larger than 2 GiB"};
    }
    AVStream* st = avformat_new_stream(fmt_, nullptr);
    if (!st)
        return {ErrorCode::kInternal, what + ": cannot add"};
    st->codecpar->codec_type = AVMEDIA_TYPE_ATTACHMENT;
    st->codecpar->extradata =
        static_cast<uint8_t*>(av_mallocz(attachment.data.size() + AV_INPUT_BUFFER_PADDING_SIZE));
    if (!st->codecpar->extradata)
        return {ErrorCode::kUnavailable, what + ": out of memory"};
    std::memcpy(st->codecpar->extradata, attachment.data.data(), attachment.data.size());
    st->codecpar->extradata_size = static_cast<int>(attachment.data.size());
    av_dict_set(&st->metadata, "filename", attachment.name.c_str(), 0);
    const std::string mime =
        attachment.mime_type.empty() ? "application/octet-stream" : attachment.mime_type;
    av_dict_set(&st->metadata, "mimetype", mime.c_str(), 0);
    return Status::ok();
}

Status MkvWriter::checkFrame(const Track& track, const ImageView& image) const {
    const ImageDesc& want = track.info.format;
    const ImageDesc& got = image.desc;
    const std::string what = context() + ": frame of '" + track.info.name + "'";
    if (got.format != want.format) {
        return {ErrorCode::kInvalidArgument, what + " is " + std::string(toString(got.format)) +
                                                 ", the stream is " +
                                                 std::string(toString(want.format))};
    }
    if (want.format == PixelFormat::kBinary || want.format == PixelFormat::kMJPEG) {
        if (!image.data && image.size_bytes > 0) {
            return {ErrorCode::kInvalidArgument, what + " has no payload"};
        }
        return Status::ok();
    }
    if (got.width != want.width || got.height != want.height) {
        return {ErrorCode::kInvalidArgument, what + " is " + std::to_string(got.width) + "x" +
                                                 std::to_string(got.height) + ", the stream " +
                                                 std::to_string(want.width) + "x" +
                                                 std::to_string(want.height)};
    }
    const ImageDesc packed = ImageDesc::packed(got.format, got.width, got.height);
    if (got.stride_bytes < packed.stride_bytes || image.size_bytes < got.bufferBytes() ||
        !image.data) {
        return {ErrorCode::kInvalidArgument, what + ": payload smaller than its layout"};
    }
    return Status::ok();
}

Status MkvWriter::wrapRaw(const FrameRef& frame, AVPacket* pkt) {
    const ImageView image = frame.image();
    const size_t bytes = mkv::packedBytes(image.desc);
    const ImageDesc packed =
        ImageDesc::packed(image.desc.format, image.desc.width, image.desc.height);
    if (image.desc.stride_bytes == packed.stride_bytes) {
        // The frame's own bytes, no copy: the packet holds a reference to the frame, dropped
        // when libavformat has written them. Published frames are immutable and the buffer is
        // marked read-only, so the const_cast lets nothing write to it.
        auto owner = std::make_unique<FrameRef>(frame);
        pkt->buf = av_buffer_create(const_cast<uint8_t*>(image.data), bytes, releaseFrame,
                                    owner.get(), AV_BUFFER_FLAG_READONLY);
        if (!pkt->buf)
            return {ErrorCode::kUnavailable, context() + ": out of memory"};
        owner.release();
        pkt->data = pkt->buf->data;
        pkt->size = static_cast<int>(bytes);
        return Status::ok();
    }
    // Padded rows: the file holds packed rows, so that other tools read the layout its tag
    // names. One copy of the rows, no per-pixel work.
    const int err = av_new_packet(pkt, static_cast<int>(bytes));
    if (err < 0)
        return ffmpeg::toStatus(err, context());
    mkv::packRows(image, pkt->data);
    return Status::ok();
}

Status MkvWriter::encode(Track& track, const FrameRef& frame) {
    const ImageView image = frame.image();
    AVPacket* pkt = packet_.get();
    if (track.storage.raw())
        return wrapRaw(frame, pkt);
    if (!track.storage.encoded()) {
        const int err = av_new_packet(pkt, static_cast<int>(image.size_bytes));
        if (err < 0)
            return ffmpeg::toStatus(err, context());
        if (image.size_bytes > 0)
            std::memcpy(pkt->data, image.data, image.size_bytes);
        return Status::ok();
    }
    AVFrame* f = track.frame.get();
    int err = av_frame_make_writable(f);
    if (err < 0)
        return ffmpeg::toStatus(err, context());
    mkv::packImage(image, f);
    f->pts = 0;
    err = avcodec_send_frame(track.encoder.get(), f);
    if (err >= 0)
        err = avcodec_receive_packet(track.encoder.get(), pkt);
    if (err < 0)
        return ffmpeg::toStatus(
            err, context() + ": " + avcodec_get_name(track.storage.codec) + " encoder");
    return Status::ok();
}

Status MkvWriter::writeAs(StreamId stream, const FrameRef& frame) {
    if (closed_)
        return {ErrorCode::kInvalidArgument, context() + ": writer already closed"};
    if (!error_.isOk())
        return error_;
    if (!frame)
        return {ErrorCode::kInvalidArgument, context() + ": empty frame"};
    if (stream >= tracks_.size()) {
        return {ErrorCode::kInvalidArgument,
                context() + ": no stream " + std::to_string(stream) + " in this recording"};
    }
    Track& track = tracks_[stream];
    const FrameMetadata& meta = frame.meta();
    MIXRAY_RETURN_IF_ERROR(checkFrame(track, frame.image()));
    if (meta.host_stamp_ns < track.last_host_ns) {
        return {ErrorCode::kInvalidArgument,
                context() + ": frames of '" + track.info.name + "' must come in host-stamp order"};
    }
    if (frame.image().size_bytes > static_cast<size_t>(INT32_MAX / 2)) {
        return {ErrorCode::kInvalidArgument, context() + ": frame larger than 1 GiB"};
    }

    av_packet_unref(packet_.get());
    MIXRAY_RETURN_IF_ERROR(encode(track, frame));
    AVPacket* pkt = packet_.get();

    if (!have_base_) {
        have_base_ = true;
        base_ns_ = meta.host_stamp_ns;
    }
    // Players pace by pts: host time in ms since the first frame. Frames stamped before it
    // (another stream's first frame came later) are clamped to 0; the exact stamps are in
    // the frame record.
    int64_t pts_ms = 0;
    if (meta.host_stamp_ns > base_ns_) {
        // Unsigned: the difference of two int64 stamps may exceed INT64_MAX.
        const uint64_t delta =
            static_cast<uint64_t>(meta.host_stamp_ns) - static_cast<uint64_t>(base_ns_);
        pts_ms = static_cast<int64_t>(delta / kNsPerMs);
    }
    pkt->pts = pkt->dts = av_rescale_q(pts_ms, AVRational{1, 1000}, track.stream->time_base);
    // 1 ms: a finished file with frames then always has a non-zero duration, which the
    // reader uses to tell a finished file from one cut off at a cluster boundary.
    pkt->duration = av_rescale_q(1, AVRational{1, 1000}, track.stream->time_base);
    pkt->stream_index = track.stream->index;
    pkt->flags |= AV_PKT_FLAG_KEY;

    mkv::FrameRecord record;
    record.meta = meta;
    record.meta.stream = stream;
    record.payload_crc = ffmpeg::crc32(pkt->data, static_cast<size_t>(pkt->size));
    const std::vector<uint8_t> side = mkv::encodeFrameRecord(record);
    uint8_t* side_data =
        av_packet_new_side_data(pkt, AV_PKT_DATA_MATROSKA_BLOCKADDITIONAL, side.size());
    if (!side_data) {
        av_packet_unref(pkt);  // a raw packet holds its frame: let it go now
        return {ErrorCode::kUnavailable, context() + ": out of memory"};
    }
    std::memcpy(side_data, side.data(), side.size());

    int err = av_write_frame(fmt_, pkt);
    av_packet_unref(pkt);
    if (err < 0)
        return fail(ffmpeg::toStatus(err, context()));
    track.last_host_ns = meta.host_stamp_ns;
    if (options_.flush_every_frame) {
        // Closing the cluster and handing it to the OS now means a crash loses at most the
        // frame being written.
        err = av_write_frame(fmt_, nullptr);
        if (err < 0)
            return fail(ffmpeg::toStatus(err, context()));
        avio_flush(fmt_->pb);
    }
    return checkIo();
}

Status MkvWriter::close() {
    if (closed_)
        return close_status_;
    closed_ = true;
    if (!fmt_)
        return close_status_;
    Status status;
    const bool header_written = fmt_->pb != nullptr && error_.isOk();
    if (header_written) {
        // Only a healthy file gets its index: after a write error (disk full) the trailer
        // would land behind a cut cluster, so the file is left as the last flush made it.
        const int err = av_write_trailer(fmt_);
        if (err < 0)
            status = ffmpeg::toStatus(err, context() + ": finishing");
        if (status.isOk() && fmt_->pb->error < 0) {
            status = ffmpeg::toStatus(fmt_->pb->error, context() + ": finishing");
        }
    }
    if (fmt_->pb) {
        avio_flush(fmt_->pb);
        // The trailer rewrote parts of the header in place: the file's size, not the bytes
        // handed to the OS, is what was written.
        const int64_t size = avio_size(fmt_->pb);
        bytes_ = static_cast<uint64_t>(size >= 0 ? size : fmt_->pb->bytes_written);
        const int err = avio_closep(&fmt_->pb);
        if (err < 0 && status.isOk())
            status = ffmpeg::toStatus(err, context() + ": closing");
    }
    tracks_.clear();
    avformat_free_context(fmt_);
    fmt_ = nullptr;
    close_status_ = error_.isOk() ? status : error_;
    return close_status_;
}

}  // namespace

const char* toString(MkvCompression compression) {
    switch (compression) {
        case MkvCompression::kFfv1:
            return "ffv1";
        case MkvCompression::kNone:
            return "none";
        case MkvCompression::kHuffyuv:
            return "ffvhuff";
    }
    return "unknown";
}

bool MkvWriterOptions::validate(std::string* why) const {
    if (ffv1_slices < 1 || ffv1_slices > 1024) {
        if (why)
            *why = "ffv1_slices must be between 1 and 1024";
        return false;
    }
    if (threads < 0) {
        if (why)
            *why = "threads must not be negative";
        return false;
    }
    if (compression != MkvCompression::kFfv1 && compression != MkvCompression::kNone &&
        compression != MkvCompression::kHuffyuv) {
        if (why)
            *why = "compression must be kFfv1, kNone or kHuffyuv";
        return false;
    }
    return true;
}

Result<std::unique_ptr<RecordingWriter>> createMkvWriter(const std::filesystem::path& path,
                                                         const RecordingHeader& header,
                                                         const MkvWriterOptions& options) {
    std::string why;
    if (!options.validate(&why)) {
        return {ErrorCode::kInvalidArgument, "writing " + path.string() + ": " + why};
    }
    auto writer = std::make_unique<MkvWriter>(path, options);
    Status status = writer->open(header);
    if (!status)
        return status;
    return std::unique_ptr<RecordingWriter>(std::move(writer));
}

}  // namespace mixray
