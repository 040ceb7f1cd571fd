// The mixray Matroska layout: frame records, tag (de)serialisation and lossless repacking.
#include "mkv_format.h"

#include <charconv>
#include <cstring>

#include "ffmpeg_util.h"

namespace mixray::mkv {
namespace {

using ffmpeg::getLe;
using ffmpeg::putLe;

// Larger frames are refused by the writer and treated as damage by the reader: no sensor
// produces them, and a damaged header must not make the reader allocate gigabytes.
constexpr size_t kMaxFrameBytes = size_t{256} << 20;
constexpr int kMaxDimension = 32768;

bool hasNul(std::string_view text) {
    return text.find('\0') != std::string_view::npos;
}

// The bytes a CRC covers for an ordered list of tags: NUL can appear in no tag value, so
// "key\0value\0" pairs are unambiguous.
uint32_t tagsCrc(const std::vector<std::pair<std::string, std::string>>& tags,
                 std::string_view prefix) {
    std::string text(prefix);
    text.push_back('\0');
    for (const auto& [key, value] : tags) {
        text += key;
        text.push_back('\0');
        text += value;
        text.push_back('\0');
    }
    return ffmpeg::crc32(text);
}

std::string hex32(uint32_t value) {
    char text[9];
    static constexpr char kDigits[] = "0123456789abcdef";
    for (int i = 0; i < 8; ++i)
        text[i] = kDigits[(value >> (28 - 4 * i)) & 0xF];
    text[8] = '\0';
    return text;
}

template <typename T>
std::optional<T> parseNumber(std::string_view text, int base = 10) {
    T value{};
    auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value, base);
    if (ec != std::errc() || end != text.data() + text.size() || text.empty())
        return std::nullopt;
    return value;
}

std::optional<double> parseDouble(std::string_view text) {
    double value = 0;
    auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
    if (ec != std::errc() || end != text.data() + text.size() || text.empty())
        return std::nullopt;
    return value;
}

void escapeInto(std::string& out, std::string_view text) {
    static constexpr char kDigits[] = "0123456789ABCDEF";
    for (char c : text) {
        if (c == '%' || c == '=' || c == '\n' || c == '\r') {
            const auto byte = static_cast<unsigned char>(c);
            out.push_back('%');
            out.push_back(kDigits[byte >> 4]);
            out.push_back(kDigits[byte & 0xF]);
        } else {
            out.push_back(c);
        }
    }
}

std::optional<std::string> unescape(std::string_view text) {
    std::string out;
    out.reserve(text.size());
    for (size_t i = 0; i < text.size(); ++i) {
        if (text[i] != '%') {
            out.push_back(text[i]);
            continue;
        }
        if (i + 2 >= text.size())
            return std::nullopt;
        auto byte = parseNumber<unsigned>(text.substr(i + 1, 2), 16);
        if (!byte || *byte > 0xFF)
            return std::nullopt;
        out.push_back(static_cast<char>(*byte));
        i += 2;
    }
    return out;
}

std::string valueOr(const AVDictionary* dict, const char* key, bool* missing) {
    const char* value = ffmpeg::dictValue(dict, key);
    if (!value) {
        *missing = true;
        return {};
    }
    return value;
}

size_t rowBytes(const ImageDesc& desc) {
    if (desc.format == PixelFormat::kNV12)
        return static_cast<size_t>(desc.width);
    return static_cast<size_t>(desc.width) * pixelFormatInfo(desc.format).bits_per_pixel / 8;
}

}  // namespace

std::vector<uint8_t> encodeFrameRecord(const FrameRecord& record) {
    std::vector<uint8_t> out(8 + kFrameRecordBytes, 0);
    // BlockAddID, big-endian as FFmpeg's side data layout wants it.
    for (int i = 0; i < 8; ++i)
        out[i] = static_cast<uint8_t>(kBlockAddId >> (56 - 8 * i));
    uint8_t* r = out.data() + 8;
    const FrameMetadata& m = record.meta;
    r[0] = 1;
    r[1] = static_cast<uint8_t>(m.status);
    putLe(r + 4, m.stream, 4);
    putLe(r + 8, m.clock_domain, 4);
    putLe(r + 12, record.payload_crc, 4);
    putLe(r + 16, m.sequence, 8);
    putLe(r + 24, static_cast<uint64_t>(m.device_stamp_ns), 8);
    putLe(r + 32, static_cast<uint64_t>(m.host_stamp_ns), 8);
    putLe(r + 40, static_cast<uint64_t>(m.exposure_us), 8);
    putLe(r + 48, ffmpeg::crc32(r, 48), 4);
    return out;
}

Result<FrameRecord> decodeFrameRecord(const uint8_t* data, size_t size) {
    if (!data || size != 8 + kFrameRecordBytes) {
        return {ErrorCode::kCorruptData, "block without its frame record"};
    }
    uint64_t add_id = 0;
    for (int i = 0; i < 8; ++i)
        add_id = (add_id << 8) | data[i];
    const uint8_t* r = data + 8;
    if (add_id != kBlockAddId || r[0] != 1 || getLe(r + 48, 4) != ffmpeg::crc32(r, 48)) {
        return {ErrorCode::kCorruptData, "damaged frame record"};
    }
    if (r[1] > static_cast<uint8_t>(FrameStatus::kCorrupt)) {
        return {ErrorCode::kCorruptData, "frame record with an unknown status"};
    }
    FrameRecord record;
    FrameMetadata& m = record.meta;
    m.status = static_cast<FrameStatus>(r[1]);
    m.stream = static_cast<StreamId>(getLe(r + 4, 4));
    m.clock_domain = static_cast<ClockDomainId>(getLe(r + 8, 4));
    record.payload_crc = static_cast<uint32_t>(getLe(r + 12, 4));
    m.sequence = getLe(r + 16, 8);
    m.device_stamp_ns = static_cast<int64_t>(getLe(r + 24, 8));
    m.host_stamp_ns = static_cast<int64_t>(getLe(r + 32, 8));
    m.exposure_us = static_cast<int64_t>(getLe(r + 40, 8));
    return record;
}

namespace {

// Uncompressed images with MkvCompression::kNone: the packed rows as FFmpeg rawvideo, tagged
// with FFmpeg's own FourCC for the layout (its raw-video table, the one the Matroska demuxer
// and the rawvideo decoder look up), so ffprobe names the pixel format. Fixed here rather than
// asked of FFmpeg: the file format must not change with the library's table order.
std::optional<Storage> rawStorageFor(PixelFormat format) {
    auto raw = [](AVPixelFormat pixel, uint32_t tag) {
        return Storage{AVMEDIA_TYPE_VIDEO, AV_CODEC_ID_RAWVIDEO, pixel, tag};
    };
    switch (format) {
        case PixelFormat::kMono8:
            return raw(AV_PIX_FMT_GRAY8, MKTAG('Y', '8', '0', '0'));
        case PixelFormat::kMono16:
        case PixelFormat::kDepth16:
        case PixelFormat::kIR16:
            // Native 16-bit samples: little-endian on every host mixray builds for.
            return raw(AV_PIX_FMT_GRAY16LE, MKTAG('Y', '1', 0, 16));
        case PixelFormat::kRGB8:
            return raw(AV_PIX_FMT_RGB24, MKTAG('R', 'G', 'B', 24));
        case PixelFormat::kBGR8:
            return raw(AV_PIX_FMT_BGR24, MKTAG('B', 'G', 'R', 24));
        case PixelFormat::kBayerRGGB8:
            return raw(AV_PIX_FMT_BAYER_RGGB8, MKTAG(0xBA, 'R', 'G', 8));
        case PixelFormat::kBayerGRBG8:
            return raw(AV_PIX_FMT_BAYER_GRBG8, MKTAG(0xBA, 'G', 'R', 8));
        case PixelFormat::kBayerGBRG8:
            return raw(AV_PIX_FMT_BAYER_GBRG8, MKTAG(0xBA, 'G', 'B', 8));
        case PixelFormat::kBayerBGGR8:
            return raw(AV_PIX_FMT_BAYER_BGGR8, MKTAG(0xBA, 'B', 'G', 8));
        case PixelFormat::kYUYV:
            return raw(AV_PIX_FMT_YUYV422, MKTAG('Y', 'U', 'Y', '2'));
        case PixelFormat::kNV12:
            return raw(AV_PIX_FMT_NV12, MKTAG('N', 'V', '1', '2'));
        default:
            return std::nullopt;
    }
}

int storedRows(const ImageDesc& desc) {
    return desc.format == PixelFormat::kNV12 ? desc.height / 2 * 3 : desc.height;
}

}  // namespace

size_t packedBytes(const ImageDesc& desc) {
    return rowBytes(desc) * static_cast<size_t>(storedRows(desc));
}

void packRows(const ImageView& image, uint8_t* out) {
    const size_t bytes = rowBytes(image.desc);
    const int rows = storedRows(image.desc);
    if (static_cast<size_t>(image.desc.stride_bytes) == bytes) {
        std::memcpy(out, image.data, bytes * static_cast<size_t>(rows));
        return;
    }
    for (int y = 0; y < rows; ++y, out += bytes)
        std::memcpy(out, image.row<uint8_t>(y), bytes);
}

void unpackRows(const uint8_t* in, const MutableImageView& out) {
    const size_t bytes = rowBytes(out.desc);
    const int rows = storedRows(out.desc);
    if (static_cast<size_t>(out.desc.stride_bytes) == bytes) {
        std::memcpy(out.data, in, bytes * static_cast<size_t>(rows));
        return;
    }
    for (int y = 0; y < rows; ++y, in += bytes)
        std::memcpy(out.row<uint8_t>(y), in, bytes);
}

namespace {

std::optional<Storage> ffv1StorageFor(PixelFormat format) {
    switch (format) {
        case PixelFormat::kMono8:
        case PixelFormat::kBayerRGGB8:
        case PixelFormat::kBayerGRBG8:
        case PixelFormat::kBayerGBRG8:
        case PixelFormat::kBayerBGGR8:
            return Storage{AVMEDIA_TYPE_VIDEO, AV_CODEC_ID_FFV1, AV_PIX_FMT_GRAY8};
        case PixelFormat::kMono16:
        case PixelFormat::kDepth16:
        case PixelFormat::kIR16:
            return Storage{AVMEDIA_TYPE_VIDEO, AV_CODEC_ID_FFV1, AV_PIX_FMT_GRAY16};
        case PixelFormat::kRGB8:
        case PixelFormat::kBGR8:
            return Storage{AVMEDIA_TYPE_VIDEO, AV_CODEC_ID_FFV1, AV_PIX_FMT_0RGB32};
        case PixelFormat::kYUYV:
            return Storage{AVMEDIA_TYPE_VIDEO, AV_CODEC_ID_FFV1, AV_PIX_FMT_YUV422P};
        case PixelFormat::kNV12:
            return Storage{AVMEDIA_TYPE_VIDEO, AV_CODEC_ID_FFV1, AV_PIX_FMT_YUV420P};
        case PixelFormat::kMJPEG:
            return Storage{AVMEDIA_TYPE_VIDEO, AV_CODEC_ID_MJPEG, AV_PIX_FMT_NONE};
        case PixelFormat::kBinary:
            // FFmpeg 5.1's Matroska muxer takes only audio, video and known subtitle codecs.
            // HDMV TextST has no decoder in FFmpeg, so players list the track and leave it
            // alone; its blocks are opaque bytes to the demuxer.
            return Storage{AVMEDIA_TYPE_SUBTITLE, AV_CODEC_ID_HDMV_TEXT_SUBTITLE, AV_PIX_FMT_NONE};
        case PixelFormat::kUnknown:
            break;
    }
    return std::nullopt;
}

}  // namespace

std::optional<Storage> storageFor(PixelFormat format, MkvCompression compression) {
    if (compression == MkvCompression::kNone) {
        if (auto raw = rawStorageFor(format))
            return raw;
    }
    std::optional<Storage> storage = ffv1StorageFor(format);
    if (storage && compression == MkvCompression::kHuffyuv && storage->encoded()) {
        // The same planes as FFV1's, which ffvhuff takes too, but for colour: ffvhuff has no
        // 0RGB32, and RGB32 is the same bytes with the fourth one coded (as zero).
        storage->codec = AV_CODEC_ID_FFVHUFF;
        if (storage->pixel == AV_PIX_FMT_0RGB32)
            storage->pixel = AV_PIX_FMT_RGB32;
    }
    return storage;
}

void packImage(const ImageView& image, AVFrame* frame) {
    const ImageDesc& d = image.desc;
    const int w = d.width;
    switch (d.format) {
        case PixelFormat::kRGB8:
        case PixelFormat::kBGR8: {
            const bool rgb = d.format == PixelFormat::kRGB8;
            for (int y = 0; y < d.height; ++y) {
                const uint8_t* in = image.row<uint8_t>(y);
                auto* out = reinterpret_cast<uint32_t*>(frame->data[0] + y * frame->linesize[0]);
                for (int x = 0; x < w; ++x, in += 3) {
                    const uint32_t r = rgb ? in[0] : in[2];
                    const uint32_t b = rgb ? in[2] : in[0];
                    out[x] = (r << 16) | (uint32_t{in[1]} << 8) | b;
                }
            }
            return;
        }
        case PixelFormat::kYUYV:
            for (int y = 0; y < d.height; ++y) {
                const uint8_t* in = image.row<uint8_t>(y);
                uint8_t* py = frame->data[0] + y * frame->linesize[0];
                uint8_t* pu = frame->data[1] + y * frame->linesize[1];
                uint8_t* pv = frame->data[2] + y * frame->linesize[2];
                for (int x = 0; x < w / 2; ++x, in += 4) {
                    py[2 * x] = in[0];
                    pu[x] = in[1];
                    py[2 * x + 1] = in[2];
                    pv[x] = in[3];
                }
            }
            return;
        case PixelFormat::kNV12: {
            for (int y = 0; y < d.height; ++y) {
                std::memcpy(frame->data[0] + y * frame->linesize[0], image.row<uint8_t>(y),
                            static_cast<size_t>(w));
            }
            for (int y = 0; y < d.height / 2; ++y) {
                const uint8_t* in = image.row<uint8_t>(d.height + y);
                uint8_t* pu = frame->data[1] + y * frame->linesize[1];
                uint8_t* pv = frame->data[2] + y * frame->linesize[2];
                for (int x = 0; x < w / 2; ++x) {
                    pu[x] = in[2 * x];
                    pv[x] = in[2 * x + 1];
                }
            }
            return;
        }
        default: {
            const size_t bytes = rowBytes(d);
            for (int y = 0; y < d.height; ++y) {
                std::memcpy(frame->data[0] + y * frame->linesize[0], image.row<uint8_t>(y), bytes);
            }
            return;
        }
    }
}

void unpackImage(const AVFrame* frame, const MutableImageView& out) {
    const ImageDesc& d = out.desc;
    const int w = d.width;
    switch (d.format) {
        case PixelFormat::kRGB8:
        case PixelFormat::kBGR8: {
            const bool rgb = d.format == PixelFormat::kRGB8;
            for (int y = 0; y < d.height; ++y) {
                const auto* in =
                    reinterpret_cast<const uint32_t*>(frame->data[0] + y * frame->linesize[0]);
                uint8_t* o = out.row<uint8_t>(y);
                for (int x = 0; x < w; ++x, o += 3) {
                    const auto r = static_cast<uint8_t>(in[x] >> 16);
                    const auto g = static_cast<uint8_t>(in[x] >> 8);
                    const auto b = static_cast<uint8_t>(in[x]);
                    o[0] = rgb ? r : b;
                    o[1] = g;
                    o[2] = rgb ? b : r;
                }
            }
            return;
        }
        case PixelFormat::kYUYV:
            for (int y = 0; y < d.height; ++y) {
                uint8_t* o = out.row<uint8_t>(y);
                const uint8_t* py = frame->data[0] + y * frame->linesize[0];
                const uint8_t* pu = frame->data[1] + y * frame->linesize[1];
                const uint8_t* pv = frame->data[2] + y * frame->linesize[2];
                for (int x = 0; x < w / 2; ++x, o += 4) {
                    o[0] = py[2 * x];
                    o[1] = pu[x];
                    o[2] = py[2 * x + 1];
                    o[3] = pv[x];
                }
            }
            return;
        case PixelFormat::kNV12:
            for (int y = 0; y < d.height; ++y) {
                std::memcpy(out.row<uint8_t>(y), frame->data[0] + y * frame->linesize[0],
                            static_cast<size_t>(w));
            }
            for (int y = 0; y < d.height / 2; ++y) {
                uint8_t* o = out.row<uint8_t>(d.height + y);
                const uint8_t* pu = frame->data[1] + y * frame->linesize[1];
                const uint8_t* pv = frame->data[2] + y * frame->linesize[2];
                for (int x = 0; x < w / 2; ++x) {
                    o[2 * x] = pu[x];
                    o[2 * x + 1] = pv[x];
                }
            }
            return;
        default: {
            const size_t bytes = rowBytes(d);
            for (int y = 0; y < d.height; ++y) {
                std::memcpy(out.row<uint8_t>(y), frame->data[0] + y * frame->linesize[0], bytes);
            }
            return;
        }
    }
}

Status validateStreamInfo(const StreamInfo& info) {
    const std::string what = "stream '" + info.name + "'";
    auto invalid = [&](const std::string& why) {
        return Status(ErrorCode::kInvalidArgument, what + ": " + why);
    };
    if (info.name.empty())
        return {ErrorCode::kInvalidArgument, "a stream without a name"};
    if (hasNul(info.name) || hasNul(info.device))
        return invalid("NUL byte in name or device");
    for (const auto& [key, value] : info.tags) {
        if (key.empty() || hasNul(key) || hasNul(value)) {
            return invalid("tag keys must be non-empty and tags free of NUL bytes");
        }
    }
    const ImageDesc& d = info.format;
    if (!storageFor(d.format))
        return invalid("unknown pixel format");
    if (d.format == PixelFormat::kBinary) {
        if (d.width < 0 || d.height < 0)
            return invalid("negative size");
        return Status::ok();
    }
    if (d.width <= 0 || d.height <= 0 || d.width > kMaxDimension || d.height > kMaxDimension) {
        return invalid("size " + std::to_string(d.width) + "x" + std::to_string(d.height) +
                       " out of range");
    }
    if (d.format == PixelFormat::kMJPEG)
        return Status::ok();
    if (d.stride_bytes < 0 || static_cast<size_t>(d.stride_bytes) < rowBytes(d)) {
        return invalid("stride " + std::to_string(d.stride_bytes) + " shorter than a row");
    }
    if ((d.format == PixelFormat::kYUYV || d.format == PixelFormat::kNV12) && d.width % 2 != 0) {
        return invalid(std::string(toString(d.format)) + " needs an even width");
    }
    if (d.format == PixelFormat::kNV12 && d.height % 2 != 0) {
        return invalid("nv12 needs an even height");
    }
    if (d.bufferBytes() > kMaxFrameBytes)
        return invalid("frames larger than 256 MiB");
    return Status::ok();
}

std::vector<std::pair<std::string, std::string>> streamTags(const StreamInfo& info) {
    std::vector<std::pair<std::string, std::string>> tags = {
        {kTagUserTags, encodeTagMap(info.tags)},
        {"MIXRAY_DEVICE", info.device},
        {"MIXRAY_KIND", std::string(toString(info.kind))},
        {"MIXRAY_PIXEL_FORMAT", std::string(toString(info.format.format))},
        {"MIXRAY_WIDTH", std::to_string(info.format.width)},
        {"MIXRAY_HEIGHT", std::to_string(info.format.height)},
        {"MIXRAY_STRIDE", std::to_string(info.format.stride_bytes)},
        {"MIXRAY_FPS", exactDouble(info.nominal_fps)},
        {"MIXRAY_CLOCK_DOMAIN", std::to_string(info.clock_domain)},
    };
    tags.emplace_back(kTagCrc, hex32(tagsCrc(tags, info.name)));
    return tags;
}

Result<StreamInfo> parseStreamTags(const std::string& name, const AVDictionary* dict) {
    auto corrupt = [&](const std::string& why) {
        return Status(ErrorCode::kCorruptData, "track '" + name + "': " + why);
    };
    bool missing = false;
    std::vector<std::pair<std::string, std::string>> tags;
    for (const char* key :
         {kTagUserTags, "MIXRAY_DEVICE", "MIXRAY_KIND", "MIXRAY_PIXEL_FORMAT", "MIXRAY_WIDTH",
          "MIXRAY_HEIGHT", "MIXRAY_STRIDE", "MIXRAY_FPS", "MIXRAY_CLOCK_DOMAIN"}) {
        tags.emplace_back(key, valueOr(dict, key, &missing));
    }
    const std::string crc = valueOr(dict, kTagCrc, &missing);
    if (missing)
        return corrupt("stream description incomplete (header cut off?)");
    if (crc != hex32(tagsCrc(tags, name)))
        return corrupt("stream description fails its CRC");

    StreamInfo info;
    info.name = name;
    auto user = decodeTagMap(tags[0].second);
    auto kind = streamKindFromString(tags[2].second);
    auto format = pixelFormatFromString(tags[3].second);
    auto width = parseNumber<int>(tags[4].second);
    auto height = parseNumber<int>(tags[5].second);
    auto stride = parseNumber<int>(tags[6].second);
    auto fps = parseDouble(tags[7].second);
    auto clock = parseNumber<uint32_t>(tags[8].second);
    if (!user || !kind || !format || !width || !height || !stride || !fps || !clock) {
        return corrupt("unreadable stream description");
    }
    info.tags = std::move(*user);
    info.device = tags[1].second;
    info.kind = *kind;
    info.format = ImageDesc{*format, *width, *height, *stride};
    info.nominal_fps = *fps;
    info.clock_domain = *clock;
    Status valid = validateStreamInfo(info);
    if (!valid)
        return corrupt(valid.message());
    return info;
}

std::vector<std::pair<std::string, std::string>> globalTags(const RecordingHeader& header) {
    std::string attachments = std::to_string(header.attachments.size()) + "\n";
    for (const Attachment& a : header.attachments) {
        attachments += hex32(ffmpeg::crc32(a.data.data(), a.data.size()));
        attachments += " " + std::to_string(a.data.size()) + "\n";
    }
    std::vector<std::pair<std::string, std::string>> tags = {
        {kTagFormat, std::string(kFormatName)},
        {kTagFormatVersion, std::to_string(kFormatVersion)},
        {kTagUserTags, encodeTagMap(header.tags)},
        {kTagAttachments, attachments},
        {kTagStreamCount, std::to_string(header.streams.size())},
    };
    tags.emplace_back(kTagCrc, hex32(tagsCrc(tags, "")));
    return tags;
}

Result<GlobalInfo> parseGlobalTags(const AVDictionary* dict) {
    auto corrupt = [](const std::string& why) {
        return Status(ErrorCode::kCorruptData, "recording header: " + why);
    };
    bool missing = false;
    std::vector<std::pair<std::string, std::string>> tags;
    for (const char* key :
         {kTagFormat, kTagFormatVersion, kTagUserTags, kTagAttachments, kTagStreamCount}) {
        tags.emplace_back(key, valueOr(dict, key, &missing));
    }
    const std::string crc = valueOr(dict, kTagCrc, &missing);
    if (missing)
        return corrupt("incomplete (cut off?)");
    if (crc != hex32(tagsCrc(tags, "")))
        return corrupt("fails its CRC");
    if (tags[1].second != std::to_string(kFormatVersion)) {
        return Status(ErrorCode::kUnsupported,
                      "mixray-mkv format version " + tags[1].second + " (this build reads 1)");
    }
    GlobalInfo info;
    auto user = decodeTagMap(tags[2].second);
    auto count = parseNumber<size_t>(tags[4].second);
    if (!user || !count)
        return corrupt("unreadable tags");
    info.tags = std::move(*user);
    info.stream_count = *count;

    std::string_view list = tags[3].second;
    const size_t eol = list.find('\n');
    auto attachment_count = parseNumber<size_t>(list.substr(0, eol));
    if (eol == std::string_view::npos || !attachment_count)
        return corrupt("unreadable attachments");
    list.remove_prefix(eol + 1);
    for (size_t i = 0; i < *attachment_count; ++i) {
        const size_t space = list.find(' ');
        const size_t end = list.find('\n');
        if (space == std::string_view::npos || end == std::string_view::npos || space > end) {
            return corrupt("unreadable attachments");
        }
        auto crc_value = parseNumber<uint32_t>(list.substr(0, space), 16);
        auto size = parseNumber<size_t>(list.substr(space + 1, end - space - 1));
        if (!crc_value || !size)
            return corrupt("unreadable attachments");
        info.attachments.push_back({*crc_value, *size});
        list.remove_prefix(end + 1);
    }
    return info;
}

std::string encodeTagMap(const std::map<std::string, std::string>& tags) {
    std::string out = std::to_string(tags.size()) + "\n";
    for (const auto& [key, value] : tags) {
        escapeInto(out, key);
        out.push_back('=');
        escapeInto(out, value);
        out.push_back('\n');
    }
    return out;
}

std::optional<std::map<std::string, std::string>> decodeTagMap(std::string_view text) {
    size_t eol = text.find('\n');
    if (eol == std::string_view::npos)
        return std::nullopt;
    auto count = parseNumber<size_t>(text.substr(0, eol));
    if (!count)
        return std::nullopt;
    text.remove_prefix(eol + 1);
    std::map<std::string, std::string> tags;
    for (size_t i = 0; i < *count; ++i) {
        eol = text.find('\n');
        if (eol == std::string_view::npos)
            return std::nullopt;
        const std::string_view line = text.substr(0, eol);
        const size_t eq = line.find('=');
        if (eq == std::string_view::npos)
            return std::nullopt;
        auto key = unescape(line.substr(0, eq));
        auto value = unescape(line.substr(eq + 1));
        if (!key || !value)
            return std::nullopt;
        tags[std::move(*key)] = std::move(*value);
        text.remove_prefix(eol + 1);
    }
    if (!text.empty() || tags.size() != *count)
        return std::nullopt;
    return tags;
}

std::string exactDouble(double value) {
    char text[64];
    auto [end, ec] = std::to_chars(text, text + sizeof(text), value);
    if (ec != std::errc())
        return "0";
    return std::string(text, end);
}

}  // namespace mixray::mkv
