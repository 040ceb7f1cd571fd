// Reads mixray and Azure Kinect Matroska recordings through libavformat into pooled frames, in
// host-stamp order, stopping cleanly at the first damaged or missing byte.
#include <algorithm>
#include <array>
#include <charconv>
#include <cstring>
#include <deque>
#include <fstream>
#include <limits>

#include "ffmpeg_util.h"
#include "mixray/graph/mkv.h"
#include "mkv_format.h"

extern "C" {
#include <libavutil/log.h>
#include <libavutil/pixdesc.h>
}

namespace mixray {
namespace {

namespace fs = std::filesystem;
using ffmpeg::CodecContextPtr;
using ffmpeg::FramePtr;
using ffmpeg::PacketPtr;

constexpr int64_t kNsPerMs = 1000000;
constexpr size_t kMaxPayloadBytes = size_t{256} << 20;
// Seeks land this far before the target and skip forward, so frames of other streams stored
// a little out of order (the recorder's reorder window) are not missed.
constexpr int64_t kSeekMarginMs = 1000;

struct FormatCloser {
    void operator()(AVFormatContext* context) const { avformat_close_input(&context); }
};
using FormatPtr = std::unique_ptr<AVFormatContext, FormatCloser>;

// How a track's packets become frame payloads.
enum class Payload {
    kDecoded,      // FFV1- or ffvhuff-decoded then unpacked (mixray images)
    kRawRows,      // packed rows (mixray MkvCompression::kNone), copied to the stream's stride
    kCopy,         // the packet bytes as they are (MJPEG, binary, Azure NV12/YUY2)
    kBigEndian16,  // Azure "b16g": 16-bit big-endian samples, swapped to native
    kImuSamples,   // Azure IMU: one frame per 40-byte sample in the packet
};

struct Track {
    StreamInfo info;
    int av_index = -1;
    Payload payload = Payload::kCopy;
    size_t exact_bytes = 0;  // packets must have this size (raw video); 0: any size
    CodecContextPtr decoder;
    FramePtr decoded;
    std::shared_ptr<BufferPool> pool;
    size_t pool_bytes = 0;
    uint64_t next_sequence = 0;  // Azure frames: counted in file order
};

// A demuxed frame waiting for its turn (frames are returned in host-stamp order).
struct Pending {
    std::shared_ptr<AVPacket> packet;
    size_t offset = 0;  // the frame's bytes within the packet
    size_t size = 0;
    size_t track = 0;
    FrameMetadata meta;
};

std::string describeMagic(const uint8_t* b, size_t n) {
    auto starts = [&](std::string_view magic) {
        return n >= magic.size() && std::memcmp(b, magic.data(), magic.size()) == 0;
    };
    if (starts("\x89PNG"))
        return " (it is a PNG image)";
    if (starts("\xFF\xD8\xFF"))
        return " (it is a JPEG image)";
    if (starts("RIFF"))
        return " (it is a RIFF file: AVI or WAV)";
    if (n >= 8 && std::memcmp(b + 4, "ftyp", 4) == 0)
        return " (it is an MP4/QuickTime file)";
    if (starts("NI10"))
        return " (it is an OpenNI .oni recording)";
    if (starts("\x76\x2F\x31\x01"))
        return " (it is an OpenEXR image)";
    if (starts("#?RADIANCE"))
        return " (it is a Radiance HDR image)";
    return "";
}

std::shared_ptr<AVPacket> sharePacket(AVPacket* packet) {
    AVPacket* copy = av_packet_alloc();
    if (!copy)
        return nullptr;
    av_packet_move_ref(copy, packet);
    return std::shared_ptr<AVPacket>(copy, [](AVPacket* p) { av_packet_free(&p); });
}

// openMkv's reader: demuxes a few frames ahead, merges them by host stamp, decodes the one it
// returns into its stream's pool. Thread-bound, like every RecordingReader.
class MkvReader final : public RecordingReader {
public:
    MkvReader(fs::path path, const MkvReaderOptions& options)
        : path_(std::move(path)), options_(options), packet_(av_packet_alloc()) {}

    Status open();

    std::string format() const override { return format_; }
    const std::vector<StreamInfo>& streams() const override { return infos_; }
    const std::vector<Attachment>& attachments() const override { return attachments_; }
    const std::map<std::string, std::string>& tags() const override { return tags_; }
    Result<FrameRef> next() override;
    Status seek(int64_t host_stamp_ns) override;
    std::vector<RecordingDamage> damage() const override { return damage_; }

private:
    Status openInput();
    Status openMixray();
    Status openAzure();
    Status addAttachment(const AVStream* st);
    Status openDecoder(Track& track, const AVStream* st);
    void fill();
    // Turns the demuxer's logged errors into damage; `packet` is the packet read after them.
    void noteDamage(const AVPacket* packet);
    // A frame whose block the demuxer read whole but whose content fails mixray's checks (its
    // record, its payload CRC, its size): the frame is lost, reported as damage, and reading
    // goes on with the next block, which the container's framing still finds.
    Status skipDamagedFrame(const AVPacket* packet, std::string what);
    Status demux(AVPacket* packet);
    Status demuxMixray(Track& track, size_t index, AVPacket* packet);
    Status demuxAzure(Track& track, size_t index, AVPacket* packet);
    void enqueue(Pending pending);
    Result<FrameRef> materialize(const Pending& pending);
    Status ensurePool(Track& track, size_t bytes);
    Status endOfData() const;

    Status corrupt(const std::string& why) const {
        return {ErrorCode::kCorruptData, path_.string() + ": " + why};
    }

    fs::path path_;
    MkvReaderOptions options_;
    FormatPtr fmt_;
    // Declared after fmt_: unregistered before the context it watches is freed.
    std::unique_ptr<ffmpeg::DemuxerErrors> errors_;
    PacketPtr packet_;
    std::string format_;
    bool azure_ = false;
    std::vector<Track> tracks_;
    std::vector<int> track_of_;  // AVStream index -> tracks_ index, -1 when unused
    std::vector<StreamInfo> infos_;
    std::vector<Attachment> attachments_;
    std::map<std::string, std::string> tags_;

    std::deque<Pending> pending_;
    size_t window_ = 8;
    bool demux_done_ = false;
    Status terminal_;  // what next() says once pending_ is empty and demux_done_
    int64_t skip_before_ns_ = std::numeric_limits<int64_t>::min();

    // pts (ms) <-> host stamp, learnt from the first frame (mixray) or the start offset (Azure).
    bool have_base_ = false;
    int64_t base_ns_ = 0;
    int64_t max_pts_ms_ = std::numeric_limits<int64_t>::min();
    int64_t azure_offset_ns_ = 0;
    uint64_t frames_read_ = 0;
    std::vector<RecordingDamage> damage_;
    bool resync_pending_ = false;  // damage_.back() waits for the byte reading resumed at
    int64_t last_stamp_ns_ = -1;   // host stamp of the last frame demuxed
};

Status MkvReader::openInput() {
    errors_.reset();
    fmt_.reset();
    AVFormatContext* context = avformat_alloc_context();
    if (!context)
        return {ErrorCode::kUnavailable, path_.string() + ": out of memory"};
    const AVInputFormat* matroska = av_find_input_format("matroska");
    if (!matroska)
        return {ErrorCode::kUnsupported, "this FFmpeg has no Matroska demuxer"};
    // "file:" keeps a colon in the path from being read as a protocol name.
    const std::string url = "file:" + path_.string();
    const int err = avformat_open_input(&context, url.c_str(), matroska, nullptr);
    if (err < 0) {
        // avformat_open_input frees the context on failure.
        if (err == AVERROR_EOF) {
            return corrupt("ends inside its Matroska header, before the first frame (cut off?)");
        }
        return corrupt("not a readable Matroska file: " + ffmpeg::errorString(err));
    }
    fmt_.reset(context);
    errors_ = std::make_unique<ffmpeg::DemuxerErrors>(context);
    for (unsigned i = 0; i < fmt_->nb_streams; ++i) {
        const bool used = i < track_of_.size() && track_of_[i] >= 0;
        fmt_->streams[i]->discard = used ? AVDISCARD_DEFAULT : AVDISCARD_ALL;
    }
    return Status::ok();
}

Status MkvReader::open() {
    std::error_code ec;
    const fs::file_status status = fs::status(path_, ec);
    if (ec || !fs::exists(status)) {
        return {ErrorCode::kNotFound, path_.string() + ": no such file"};
    }
    if (fs::is_directory(status)) {
        return {ErrorCode::kInvalidArgument,
                path_.string() + ": is a directory, not a Matroska recording"};
    }
    if (!fs::is_regular_file(status)) {
        return {ErrorCode::kInvalidArgument, path_.string() + ": not a regular file"};
    }
    std::array<uint8_t, 16> magic{};
    size_t magic_bytes = 0;
    {
        std::ifstream in(path_, std::ios::binary);
        if (!in)
            return {ErrorCode::kIoError, path_.string() + ": cannot be opened for reading"};
        in.read(reinterpret_cast<char*>(magic.data()), magic.size());
        magic_bytes = static_cast<size_t>(in.gcount());
    }
    if (magic_bytes == 0)
        return corrupt("empty file (0 bytes), not a Matroska recording");
    static constexpr uint8_t kEbml[4] = {0x1A, 0x45, 0xDF, 0xA3};
    if (magic_bytes < 4 || std::memcmp(magic.data(), kEbml, 4) != 0) {
        return corrupt("not a Matroska file: no EBML header" +
                       describeMagic(magic.data(), magic_bytes));
    }

    MIXRAY_RETURN_IF_ERROR(openInput());
    track_of_.assign(fmt_->nb_streams, -1);
    if (ffmpeg::dictValue(fmt_->metadata, mkv::kTagFormat)) {
        MIXRAY_RETURN_IF_ERROR(openMixray());
    } else {
        bool k4a_track = false;
        for (unsigned i = 0; i < fmt_->nb_streams; ++i) {
            const char* title = ffmpeg::dictValue(fmt_->streams[i]->metadata, "title");
            const std::string_view t = title ? title : "";
            if (t == "COLOR" || t == "DEPTH" || t == "IR" || t == "IMU")
                k4a_track = true;
        }
        if (!k4a_track) {
            return {ErrorCode::kUnsupported,
                    path_.string() +
                        ": a Matroska file, but neither a mixray recording (no MIXRAY_FORMAT "
                        "tag: another program's file, or a header cut off) nor an Azure Kinect "
                        "recording (no COLOR, DEPTH, IR or IMU track)"};
        }
        MIXRAY_RETURN_IF_ERROR(openAzure());
    }
    for (size_t i = 0; i < tracks_.size(); ++i) {
        track_of_[static_cast<size_t>(tracks_[i].av_index)] = static_cast<int>(i);
        infos_.push_back(tracks_[i].info);
    }
    for (unsigned i = 0; i < fmt_->nb_streams; ++i) {
        fmt_->streams[i]->discard = track_of_[i] >= 0 ? AVDISCARD_DEFAULT : AVDISCARD_ALL;
    }
    window_ = std::max<size_t>(8, 4 * tracks_.size());
    return Status::ok();
}

Status MkvReader::addAttachment(const AVStream* st) {
    const char* name = ffmpeg::dictValue(st->metadata, "filename");
    const char* mime = ffmpeg::dictValue(st->metadata, "mimetype");
    if (!name || !st->codecpar->extradata || st->codecpar->extradata_size <= 0) {
        return corrupt("incomplete attachment (file cut off?)");
    }
    Attachment attachment;
    attachment.name = name;
    attachment.mime_type = mime ? mime : "";
    attachment.data.assign(st->codecpar->extradata,
                           st->codecpar->extradata + st->codecpar->extradata_size);
    attachments_.push_back(std::move(attachment));
    return Status::ok();
}

Status MkvReader::openDecoder(Track& track, const AVStream* st) {
    const AVCodec* codec = avcodec_find_decoder(st->codecpar->codec_id);
    if (!codec)
        return {ErrorCode::kUnsupported, std::string("this FFmpeg has no ") +
                                             avcodec_get_name(st->codecpar->codec_id) + " decoder"};
    track.decoder.reset(avcodec_alloc_context3(codec));
    track.decoded.reset(av_frame_alloc());
    if (!track.decoder || !track.decoded) {
        return {ErrorCode::kUnavailable, path_.string() + ": out of memory"};
    }
    AVCodecContext* c = track.decoder.get();
    int err = avcodec_parameters_to_context(c, st->codecpar);
    if (err < 0)
        return ffmpeg::toStatus(err, path_.string());
    c->thread_count = options_.decoder_threads;
    // Slice threads only: frame threads would hold frames back and break one-in, one-out.
    c->thread_type = FF_THREAD_SLICE;
    // A slice failing its CRC is an error, not a frame with concealed holes.
    c->err_recognition |= AV_EF_CRCCHECK | AV_EF_EXPLODE;
    err = avcodec_open2(c, codec, nullptr);
    if (err < 0) {
        return corrupt("track '" + track.info.name + "': " + codec->name +
                       " decoder refuses its parameters: " + ffmpeg::errorString(err));
    }
    return Status::ok();
}

Status MkvReader::openMixray() {
    format_ = std::string(mkv::kFormatName);
    if (std::string_view(ffmpeg::dictValue(fmt_->metadata, mkv::kTagFormat)) != mkv::kFormatName) {
        return corrupt("MIXRAY_FORMAT tag names an unknown format");
    }
    auto global = mkv::parseGlobalTags(fmt_->metadata);
    if (!global)
        return global.status().withContext(path_.string());
    tags_ = global->tags;

    for (unsigned i = 0; i < fmt_->nb_streams; ++i) {
        const AVStream* st = fmt_->streams[i];
        if (st->codecpar->codec_type == AVMEDIA_TYPE_ATTACHMENT) {
            MIXRAY_RETURN_IF_ERROR(addAttachment(st));
            continue;
        }
        const char* title = ffmpeg::dictValue(st->metadata, "title");
        if (!title || !*title)
            return corrupt("a track without a name");
        auto info = mkv::parseStreamTags(title, st->metadata);
        if (!info)
            return info.status().withContext(path_.string());
        // The codec says how the writer stored the images (MkvCompression): FFV1, ffvhuff or
        // raw.
        const MkvCompression compression =
            st->codecpar->codec_id == AV_CODEC_ID_RAWVIDEO  ? MkvCompression::kNone
            : st->codecpar->codec_id == AV_CODEC_ID_FFVHUFF ? MkvCompression::kHuffyuv
                                                            : MkvCompression::kFfv1;
        const mkv::Storage storage = *mkv::storageFor(info->format.format, compression);
        const bool image = storage.encoded() || storage.raw();
        if (st->codecpar->codec_id != storage.codec ||
            (storage.raw() && st->codecpar->codec_tag != storage.codec_tag) ||
            (image && (st->codecpar->width != info->format.width ||
                       st->codecpar->height != info->format.height))) {
            return corrupt("track '" + info->name + "' is not stored as its description says");
        }
        Track track;
        track.info = std::move(*info);
        track.av_index = static_cast<int>(i);
        track.payload = storage.encoded() ? Payload::kDecoded
                        : storage.raw()   ? Payload::kRawRows
                                          : Payload::kCopy;
        if (storage.raw())
            track.exact_bytes = mkv::packedBytes(track.info.format);
        if (storage.encoded())
            MIXRAY_RETURN_IF_ERROR(openDecoder(track, st));
        tracks_.push_back(std::move(track));
    }
    if (tracks_.size() != global->stream_count) {
        return corrupt("header lists " + std::to_string(global->stream_count) +
                       " streams but the file holds " + std::to_string(tracks_.size()) +
                       " (cut off?)");
    }
    if (attachments_.size() != global->attachments.size()) {
        return corrupt("header lists " + std::to_string(global->attachments.size()) +
                       " attachments but the file holds " + std::to_string(attachments_.size()));
    }
    for (size_t i = 0; i < attachments_.size(); ++i) {
        const auto& data = attachments_[i].data;
        if (data.size() != global->attachments[i].size ||
            ffmpeg::crc32(data.data(), data.size()) != global->attachments[i].crc) {
            return corrupt("attachment '" + attachments_[i].name + "' fails its CRC");
        }
    }
    return Status::ok();
}

Status MkvReader::openAzure() {
    format_ = std::string(mkv::kAzureKinectFormatName);
    azure_ = true;
    const AVDictionaryEntry* entry = nullptr;
    while ((entry = av_dict_get(fmt_->metadata, "", entry, AV_DICT_IGNORE_SUFFIX))) {
        tags_[entry->key] = entry->value;
    }
    if (const char* offset = ffmpeg::dictValue(fmt_->metadata, "K4A_START_OFFSET_NS")) {
        const std::string_view text(offset);
        auto [end, errc] =
            std::from_chars(text.data(), text.data() + text.size(), azure_offset_ns_);
        if (errc != std::errc() || end != text.data() + text.size() || azure_offset_ns_ < 0) {
            return corrupt("unreadable K4A_START_OFFSET_NS '" + std::string(text) + "'");
        }
    }
    have_base_ = true;
    base_ns_ = azure_offset_ns_;

    for (unsigned i = 0; i < fmt_->nb_streams; ++i) {
        const AVStream* st = fmt_->streams[i];
        const AVCodecParameters* par = st->codecpar;
        if (par->codec_type == AVMEDIA_TYPE_ATTACHMENT) {
            MIXRAY_RETURN_IF_ERROR(addAttachment(st));
            continue;
        }
        const char* title_value = ffmpeg::dictValue(st->metadata, "title");
        const std::string title = title_value ? title_value : "";
        Track track;
        track.av_index = static_cast<int>(i);
        StreamInfo& info = track.info;
        info.device = "azure_kinect";
        info.clock_domain = kAzureKinectClockDomain;
        const AVDictionaryEntry* tag = nullptr;
        while ((tag = av_dict_get(st->metadata, "K4A_", tag, AV_DICT_IGNORE_SUFFIX))) {
            info.tags[tag->key] = tag->value;
        }
        if (st->avg_frame_rate.num > 0 && st->avg_frame_rate.den > 0) {
            info.nominal_fps = av_q2d(st->avg_frame_rate);
        }
        const int w = par->width;
        const int h = par->height;
        const bool video = title == "COLOR" || title == "DEPTH" || title == "IR";
        if (video && (w <= 0 || h <= 0 || w > 16384 || h > 16384)) {
            return corrupt("track " + title + " has an impossible size " + std::to_string(w) + "x" +
                           std::to_string(h));
        }
        const auto w_bytes = static_cast<size_t>(w);
        const auto h_bytes = static_cast<size_t>(h);
        if (title == "COLOR") {
            info.name = "azure_kinect/color";
            info.kind = StreamKind::kColor;
            char fourcc_text[AV_FOURCC_MAX_STRING_SIZE] = {};
            const std::string fourcc =
                par->codec_tag ? av_fourcc_make_string(fourcc_text, par->codec_tag) : "";
            if (par->codec_id == AV_CODEC_ID_MJPEG) {
                info.format = ImageDesc::packed(PixelFormat::kMJPEG, w, h);
            } else if (par->codec_id == AV_CODEC_ID_RAWVIDEO &&
                       (fourcc == "NV12" || par->format == AV_PIX_FMT_NV12)) {
                if (w % 2 || h % 2)
                    return corrupt("NV12 COLOR track with odd size");
                info.format = ImageDesc::packed(PixelFormat::kNV12, w, h);
                track.exact_bytes = w_bytes * h_bytes * 3 / 2;
            } else if (par->codec_id == AV_CODEC_ID_RAWVIDEO &&
                       (fourcc == "YUY2" || par->format == AV_PIX_FMT_YUYV422)) {
                if (w % 2)
                    return corrupt("YUY2 COLOR track with odd width");
                info.format = ImageDesc::packed(PixelFormat::kYUYV, w, h);
                track.exact_bytes = w_bytes * h_bytes * 2;
            } else {
                return {ErrorCode::kUnsupported, path_.string() + ": COLOR track in format '" +
                                                     fourcc + "' (codec " +
                                                     avcodec_get_name(par->codec_id) +
                                                     "); mixray reads MJPG, NV12 and YUY2"};
            }
        } else if (title == "DEPTH" || title == "IR") {
            const bool depth = title == "DEPTH";
            info.name = depth ? "azure_kinect/depth" : "azure_kinect/ir";
            info.kind = depth ? StreamKind::kDepth : StreamKind::kInfrared;
            if (par->codec_id != AV_CODEC_ID_RAWVIDEO ||
                (par->codec_tag != MKTAG('b', '1', '6', 'g') &&
                 par->format != AV_PIX_FMT_GRAY16BE)) {
                return {ErrorCode::kUnsupported, path_.string() + ": " + title +
                                                     " track is not 16-bit big-endian grey (b16g)"};
            }
            info.format =
                ImageDesc::packed(depth ? PixelFormat::kDepth16 : PixelFormat::kIR16, w, h);
            track.payload = Payload::kBigEndian16;
            track.exact_bytes = w_bytes * h_bytes * 2;
        } else if (title == "IMU") {
            info.name = "azure_kinect/imu";
            info.kind = StreamKind::kImu;
            info.nominal_fps = 0;
            info.format = ImageDesc::packed(PixelFormat::kBinary,
                                            static_cast<int>(kAzureKinectImuSampleBytes), 1);
            info.tags["record"] = "azure_kinect_imu_sample";
            track.payload = Payload::kImuSamples;
        } else {
            continue;  // a track another tool added: not part of the Kinect's data
        }
        if (const char* serial = ffmpeg::dictValue(fmt_->metadata, "K4A_DEVICE_SERIAL_NUMBER")) {
            info.tags["serial"] = serial;
        }
        tracks_.push_back(std::move(track));
    }
    if (tracks_.empty())
        return corrupt("Azure Kinect recording without COLOR, DEPTH, IR or IMU");
    return Status::ok();
}

void MkvReader::enqueue(Pending pending) {
    last_stamp_ns_ = std::max(last_stamp_ns_, pending.meta.host_stamp_ns);
    // Stable: equal stamps keep file order.
    auto at = std::upper_bound(
        pending_.begin(), pending_.end(), pending.meta.host_stamp_ns,
        [](int64_t stamp, const Pending& p) { return stamp < p.meta.host_stamp_ns; });
    pending_.insert(at, std::move(pending));
}

Status MkvReader::demuxMixray(Track& track, size_t index, AVPacket* packet) {
    size_t side_size = 0;
    const uint8_t* side =
        av_packet_get_side_data(packet, AV_PKT_DATA_MATROSKA_BLOCKADDITIONAL, &side_size);
    const std::string where = "frame " + std::to_string(frames_read_) + " (stream '" +
                              track.info.name + "', byte " + std::to_string(packet->pos) + ")";
    auto record = mkv::decodeFrameRecord(side, side_size);
    if (!record)
        return skipDamagedFrame(packet, where + ": " + record.status().message());
    if (record->meta.stream != index) {
        return skipDamagedFrame(packet, where + ": its record belongs to stream " +
                                            std::to_string(record->meta.stream));
    }
    if (static_cast<size_t>(packet->size) > kMaxPayloadBytes ||
        ffmpeg::crc32(packet->data, static_cast<size_t>(packet->size)) != record->payload_crc) {
        return skipDamagedFrame(packet, where + ": damaged or cut off (payload CRC mismatch)");
    }
    if (track.exact_bytes && static_cast<size_t>(packet->size) != track.exact_bytes) {
        return skipDamagedFrame(packet, where + ": holds " + std::to_string(packet->size) +
                                            " bytes, the image " +
                                            std::to_string(track.exact_bytes));
    }
    const FrameMetadata& meta = record->meta;
    if (packet->pts != AV_NOPTS_VALUE) {
        const int64_t pts_ms = av_rescale_q(
            packet->pts, fmt_->streams[packet->stream_index]->time_base, AVRational{1, 1000});
        max_pts_ms_ = std::max(max_pts_ms_, pts_ms);
        int64_t offset_ns = 0;
        if (!have_base_ && !__builtin_mul_overflow(pts_ms, kNsPerMs, &offset_ns) &&
            !__builtin_sub_overflow(meta.host_stamp_ns, offset_ns, &base_ns_)) {
            have_base_ = true;
        }
    }
    ++frames_read_;
    if (meta.host_stamp_ns < skip_before_ns_)
        return Status::ok();
    Pending pending;
    pending.track = index;
    pending.meta = meta;
    pending.size = static_cast<size_t>(packet->size);
    pending.packet = sharePacket(packet);
    if (!pending.packet)
        return {ErrorCode::kUnavailable, path_.string() + ": out of memory"};
    enqueue(std::move(pending));
    return Status::ok();
}

Status MkvReader::demuxAzure(Track& track, size_t index, AVPacket* packet) {
    const AVStream* st = fmt_->streams[packet->stream_index];
    const int64_t pts = packet->pts != AV_NOPTS_VALUE ? packet->pts : packet->dts;
    const std::string where =
        "block of " + track.info.name + " at byte " + std::to_string(packet->pos);
    if (pts == AV_NOPTS_VALUE)
        return corrupt(where + " has no timestamp");
    const auto size = static_cast<size_t>(packet->size);
    if (size > kMaxPayloadBytes)
        return corrupt(where + " is impossibly large");
    const int64_t stamp_ns =
        av_rescale_q(pts, st->time_base, AVRational{1, 1000000000}) + azure_offset_ns_;
    max_pts_ms_ = std::max(max_pts_ms_, av_rescale_q(pts, st->time_base, AVRational{1, 1000}));
    ++frames_read_;

    FrameMetadata meta;
    meta.stream = static_cast<StreamId>(index);
    meta.clock_domain = kAzureKinectClockDomain;
    auto shared = sharePacket(packet);
    if (!shared)
        return {ErrorCode::kUnavailable, path_.string() + ": out of memory"};

    if (track.payload == Payload::kImuSamples) {
        if (size == 0 || size % kAzureKinectImuSampleBytes != 0) {
            return corrupt(where + ": " + std::to_string(size) +
                           " bytes is not a whole number of 40-byte IMU samples");
        }
        for (size_t offset = 0; offset < size; offset += kAzureKinectImuSampleBytes) {
            meta.sequence = track.next_sequence++;
            // The sample's own accelerometer stamp, as the SDK's playback reports it.
            meta.device_stamp_ns = static_cast<int64_t>(ffmpeg::getLe(shared->data + offset, 8));
            meta.host_stamp_ns = meta.device_stamp_ns;
            if (meta.host_stamp_ns < skip_before_ns_)
                continue;
            enqueue({shared, offset, kAzureKinectImuSampleBytes, index, meta});
        }
        return Status::ok();
    }
    if (track.exact_bytes && size != track.exact_bytes) {
        return corrupt(where + " holds " + std::to_string(size) + " bytes, expected " +
                       std::to_string(track.exact_bytes));
    }
    if (size == 0)
        return corrupt(where + " is empty");
    meta.sequence = track.next_sequence++;
    meta.device_stamp_ns = stamp_ns;
    meta.host_stamp_ns = stamp_ns;
    if (meta.host_stamp_ns < skip_before_ns_)
        return Status::ok();
    enqueue({std::move(shared), 0, size, index, meta});
    return Status::ok();
}

Status MkvReader::demux(AVPacket* packet) {
    if (packet->stream_index < 0 || static_cast<size_t>(packet->stream_index) >= track_of_.size()) {
        return Status::ok();
    }
    const int index = track_of_[static_cast<size_t>(packet->stream_index)];
    if (index < 0)
        return Status::ok();
    Track& track = tracks_[static_cast<size_t>(index)];
    return azure_ ? demuxAzure(track, static_cast<size_t>(index), packet)
                  : demuxMixray(track, static_cast<size_t>(index), packet);
}

Status MkvReader::endOfData() const {
    if (!azure_) {
        // FFmpeg writes each track's DURATION tag and the file's duration only when it
        // finishes the file: without them the recording was cut off (crash, full disk); with
        // them the last block must reach the duration (every block lasts 1 ms).
        bool finished = false;
        for (const Track& track : tracks_) {
            if (ffmpeg::dictValue(fmt_->streams[track.av_index]->metadata, "DURATION")) {
                finished = true;
            }
        }
        if (!finished) {
            return corrupt("recording was never finished (crash or full disk?): it ends after " +
                           std::to_string(frames_read_) + " complete frames");
        }
        const int64_t duration_ms =
            fmt_->duration == AV_NOPTS_VALUE ? 0 : av_rescale(fmt_->duration, 1000, AV_TIME_BASE);
        if (duration_ms > 0 && max_pts_ms_ + 1 < duration_ms) {
            return corrupt("file is cut off: it ends after " + std::to_string(frames_read_) +
                           " complete frames, before its recorded duration");
        }
    }
    return {ErrorCode::kEndOfStream, "end of " + path_.string()};
}

void MkvReader::fill() {
    AVPacket* packet = packet_.get();
    while (!demux_done_ && pending_.size() < window_) {
        av_packet_unref(packet);
        const int err = av_read_frame(fmt_.get(), packet);
        noteDamage(err >= 0 ? packet : nullptr);
        if (err == AVERROR(EAGAIN))
            continue;
        if (err < 0) {
            demux_done_ = true;
            if (err == AVERROR_EOF) {
                terminal_ = endOfData();
            } else {
                terminal_ = corrupt("unreadable after " + std::to_string(frames_read_) +
                                    " frames: " + ffmpeg::errorString(err));
            }
            break;
        }
        Status status = demux(packet);
        if (!status) {
            demux_done_ = true;
            terminal_ = status;
        }
    }
    av_packet_unref(packet);
}

Status MkvReader::skipDamagedFrame(const AVPacket* packet, std::string what) {
    ++frames_read_;  // frames keep their numbers in the file
    // A loop or seek reads it again: reported once.
    const bool known = std::any_of(damage_.begin(), damage_.end(),
                                   [&](const auto& d) { return d.byte_offset == packet->pos; });
    if (!known) {
        RecordingDamage d;
        d.byte_offset = packet->pos;
        d.resumed_at = packet->pos >= 0 ? packet->pos + packet->size : -1;
        d.after_stamp_ns = last_stamp_ns_;
        d.what = std::move(what);
        damage_.push_back(std::move(d));
    }
    return Status::ok();
}

void MkvReader::noteDamage(const AVPacket* packet) {
    std::vector<ffmpeg::DemuxerErrors::Entry> errors =
        errors_ ? errors_->take() : std::vector<ffmpeg::DemuxerErrors::Entry>{};
    // A seek back over damage already found reads it again: it is reported once.
    const bool known =
        !errors.empty() && std::any_of(damage_.begin(), damage_.end(), [&](const auto& d) {
            return d.byte_offset == errors.front().byte_offset;
        });
    if (!errors.empty() && !resync_pending_ && !known) {
        RecordingDamage d;
        d.byte_offset = errors.front().byte_offset;
        d.after_stamp_ns = last_stamp_ns_;
        d.what = errors.front().message;
        damage_.push_back(std::move(d));
        resync_pending_ = true;
    }
    if (resync_pending_ && packet) {
        damage_.back().resumed_at = packet->pos;
        resync_pending_ = false;
    }
}

Status MkvReader::ensurePool(Track& track, size_t bytes) {
    if (track.pool && track.pool_bytes >= bytes)
        return Status::ok();
    const ImageDesc& desc = track.info.format;
    size_t buffer = std::max(bytes, desc.format == PixelFormat::kBinary ? size_t{4096} : size_t{0});
    if (desc.format == PixelFormat::kMJPEG) {
        // Start near a real JPEG's size rather than the format's worst case; a larger frame
        // replaces the pool (frames still out keep the old one alive).
        const size_t typical =
            static_cast<size_t>(desc.width) * static_cast<size_t>(desc.height) + 65536;
        buffer = std::max(bytes, std::min(typical, desc.bufferBytes()));
    }
    if (track.pool)
        buffer = std::max(buffer, track.pool_bytes * 2);
    BufferPoolOptions options;
    options.desc = desc;
    options.buffer_bytes = buffer;
    options.buffer_count = options_.buffers_per_stream;
    options.name = track.info.name;
    std::string why;
    if (!options.validate(&why))
        return corrupt(why);
    track.pool = BufferPool::create(options);
    if (!track.pool)
        return corrupt("cannot allocate buffers for '" + track.info.name + "'");
    track.pool_bytes = buffer;
    return Status::ok();
}

Result<FrameRef> MkvReader::materialize(const Pending& pending) {
    Track& track = tracks_[pending.track];
    const ImageDesc& desc = track.info.format;
    const bool image = desc.format != PixelFormat::kBinary && desc.format != PixelFormat::kMJPEG;
    MIXRAY_RETURN_IF_ERROR(ensurePool(track, image ? desc.bufferBytes() : pending.size));
    WritableFrame frame = track.pool->acquire();
    if (!frame) {
        return Status(ErrorCode::kUnavailable,
                      "all " + std::to_string(options_.buffers_per_stream) + " buffers of '" +
                          track.info.name + "' are held by consumers: release frames");
    }
    const uint8_t* bytes = pending.packet->data + pending.offset;
    MutableImageView out = frame.image();
    switch (track.payload) {
        case Payload::kDecoded: {
            AVCodecContext* decoder = track.decoder.get();
            AVFrame* decoded = track.decoded.get();
            av_frame_unref(decoded);
            int err = avcodec_send_packet(decoder, pending.packet.get());
            if (err >= 0)
                err = avcodec_receive_frame(decoder, decoded);
            if (err < 0) {
                return corrupt("frame of '" + track.info.name + "' at byte " +
                               std::to_string(pending.packet->pos) +
                               " does not decode: " + ffmpeg::errorString(err));
            }
            const auto expected =
                mkv::storageFor(desc.format, decoder->codec_id == AV_CODEC_ID_FFVHUFF
                                                 ? MkvCompression::kHuffyuv
                                                 : MkvCompression::kFfv1)
                    ->pixel;
            if (decoded->width != desc.width || decoded->height != desc.height ||
                decoded->format != expected) {
                return corrupt("frame of '" + track.info.name + "' decodes to the wrong layout");
            }
            mkv::unpackImage(decoded, out);
            av_frame_unref(decoded);
            break;
        }
        case Payload::kRawRows:
            mkv::unpackRows(bytes, out);
            break;
        case Payload::kBigEndian16: {
            auto* samples = reinterpret_cast<uint16_t*>(out.data);
            for (size_t i = 0; i < pending.size / 2; ++i) {
                samples[i] = static_cast<uint16_t>((bytes[2 * i] << 8) | bytes[2 * i + 1]);
            }
            break;
        }
        case Payload::kCopy:
        case Payload::kImuSamples:
            if (desc.format == PixelFormat::kBinary) {
                const int width = static_cast<int>(pending.size);
                frame.setDesc(ImageDesc{PixelFormat::kBinary, width, 1, width});
            }
            if (pending.size > 0)
                std::memcpy(out.data, bytes, pending.size);
            if (!image)
                frame.setPayloadBytes(pending.size);
            break;
    }
    frame.meta() = pending.meta;
    return std::move(frame).publish();
}

Result<FrameRef> MkvReader::next() {
    fill();
    if (pending_.empty())
        return terminal_.isOk() ? endOfData() : terminal_;
    Result<FrameRef> frame = materialize(pending_.front());
    if (frame) {
        pending_.pop_front();
        return frame;
    }
    if (frame.status().code() != ErrorCode::kUnavailable) {
        // The rest of the file is not trusted after a frame that fails to decode.
        pending_.clear();
        demux_done_ = true;
        terminal_ = frame.status();
    }
    return frame;
}

Status MkvReader::seek(int64_t host_stamp_ns) {
    pending_.clear();
    resync_pending_ = false;
    demux_done_ = false;
    terminal_ = Status::ok();
    skip_before_ns_ = host_stamp_ns;
    for (Track& track : tracks_) {
        track.next_sequence = 0;
        if (track.decoder)
            avcodec_flush_buffers(track.decoder.get());
    }
    int64_t target_ms = -1;
    int64_t delta = 0;
    if (have_base_ && !__builtin_sub_overflow(host_stamp_ns, base_ns_, &delta) && delta >= 0) {
        target_ms = delta / kNsPerMs - kSeekMarginMs;
    }
    if (target_ms > 0 && fmt_) {
        const int err =
            av_seek_frame(fmt_.get(), -1, target_ms * (AV_TIME_BASE / 1000), AVSEEK_FLAG_BACKWARD);
        if (err >= 0)
            return Status::ok();
    }
    // From the start: reopening is the one way back that works without an index (a file cut
    // off before its Cues).
    frames_read_ = 0;
    Status status = openInput();
    if (!status) {
        demux_done_ = true;
        terminal_ = status;
    }
    return status;
}

}  // namespace

bool MkvReaderOptions::validate(std::string* why) const {
    if (buffers_per_stream == 0 || buffers_per_stream > 4096) {
        if (why)
            *why = "buffers_per_stream must be between 1 and 4096";
        return false;
    }
    if (decoder_threads < 0) {
        if (why)
            *why = "decoder_threads must not be negative";
        return false;
    }
    return true;
}

Result<std::unique_ptr<RecordingReader>> openMkv(const std::filesystem::path& path,
                                                 const MkvReaderOptions& options) {
    std::string why;
    if (!options.validate(&why)) {
        return {ErrorCode::kInvalidArgument, path.string() + ": " + why};
    }
    auto reader = std::make_unique<MkvReader>(path, options);
    Status status = reader->open();
    if (!status)
        return status;
    return std::unique_ptr<RecordingReader>(std::move(reader));
}

std::optional<AzureKinectImuSample> parseAzureKinectImuSample(const ImageView& payload) {
    if (!payload.data || payload.size_bytes != kAzureKinectImuSampleBytes)
        return std::nullopt;
    const uint8_t* b = payload.data;
    auto f32 = [](const uint8_t* p) {
        const auto bits = static_cast<uint32_t>(ffmpeg::getLe(p, 4));
        float value = 0;
        std::memcpy(&value, &bits, sizeof(value));
        return value;
    };
    AzureKinectImuSample sample;
    sample.acc_stamp_ns = static_cast<int64_t>(ffmpeg::getLe(b, 8));
    for (int i = 0; i < 3; ++i)
        sample.acc_m_s2[i] = f32(b + 8 + 4 * i);
    sample.gyro_stamp_ns = static_cast<int64_t>(ffmpeg::getLe(b + 20, 8));
    for (int i = 0; i < 3; ++i)
        sample.gyro_rad_s[i] = f32(b + 28 + 4 * i);
    return sample;
}

void setFfmpegLogging(bool enabled) {
    av_log_set_level(enabled ? AV_LOG_WARNING : AV_LOG_QUIET);
}

}  // namespace mixray
