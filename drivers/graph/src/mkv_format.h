// Internal: the mixray Matroska layout shared by writer and reader — tag names, the per-frame
// record, how each pixel format is stored, and exact repacking between images and AVFrames.
#pragma once

extern "C" {
#include <libavcodec/avcodec.h>
#include <libavutil/frame.h>
#include <libavutil/pixfmt.h>
}

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "mixray/graph/frame.h"
#include "mixray/graph/image.h"
#include "mixray/graph/mkv.h"
#include "mixray/graph/recording.h"
#include "mixray/graph/result.h"
#include "mixray/graph/stream.h"

namespace mixray::mkv {

// Value of the global MIXRAY_FORMAT tag and RecordingReader::format() for our own files.
inline constexpr std::string_view kFormatName = "mixray-mkv";
inline constexpr std::string_view kAzureKinectFormatName = "azure-kinect-mkv";
inline constexpr int kFormatVersion = 1;

// Global tags. FFmpeg's muxer upper-cases tag names, so every name we rely on is upper case.
inline constexpr const char* kTagFormat = "MIXRAY_FORMAT";
inline constexpr const char* kTagFormatVersion = "MIXRAY_FORMAT_VERSION";
inline constexpr const char* kTagStreamCount = "MIXRAY_STREAM_COUNT";
inline constexpr const char* kTagAttachments = "MIXRAY_ATTACHMENTS";
// Free-form user tags (recording or stream): their keys are case-sensitive, so they travel as
// one escaped list rather than as Matroska tags of their own.
inline constexpr const char* kTagUserTags = "MIXRAY_TAGS";
// CRC-32 of the other MIXRAY_* tags of the same target: a damaged header is an error, not a
// silently different stream description.
inline constexpr const char* kTagCrc = "MIXRAY_CRC32";

// The per-frame record stored as Matroska BlockAdditional (BlockAddID 1) with every block.
// Matroska's 1 ms TimestampScale (fixed in FFmpeg 5.1's muxer) cannot carry nanoseconds; this
// record carries the exact metadata plus CRCs of itself and of the payload, so that a damaged
// or cut frame is reported instead of returned. Layout, little-endian:
//   0 u8 version, 1 u8 status, 2 u16 zero, 4 u32 stream, 8 u32 clock domain,
//   12 u32 payload CRC-32, 16 u64 sequence, 24 i64 device stamp ns, 32 i64 host stamp ns,
//   40 i64 exposure us, 48 u32 CRC-32 of bytes 0..47.
inline constexpr size_t kFrameRecordBytes = 52;
inline constexpr uint64_t kBlockAddId = 1;  // the only BlockAddID FFmpeg 5.1 writes

struct FrameRecord {
    FrameMetadata meta;  // meta.stream is the stream's index in the file
    uint32_t payload_crc = 0;
};

std::vector<uint8_t> encodeFrameRecord(const FrameRecord& record);
// Parses the side data FFmpeg returns (8-byte big-endian BlockAddID, then the record).
Result<FrameRecord> decodeFrameRecord(const uint8_t* data, size_t size);

// How one pixel format is stored in the file.
struct Storage {
    AVMediaType media = AVMEDIA_TYPE_VIDEO;
    AVCodecID codec = AV_CODEC_ID_NONE;
    // FFV1's input/output format, or the layout of raw frames; NONE for copied payloads.
    AVPixelFormat pixel = AV_PIX_FMT_NONE;
    // Raw frames: FFmpeg's FourCC for `pixel`, stored as the track's ColourSpace so that other
    // tools know the layout; 0 otherwise.
    uint32_t codec_tag = 0;
    // Coded by an FFmpeg codec (FFV1 or ffvhuff) from and to `pixel`.
    bool encoded() const { return codec == AV_CODEC_ID_FFV1 || codec == AV_CODEC_ID_FFVHUFF; }
    // Packed rows as they are (Matroska V_UNCOMPRESSED).
    bool raw() const { return codec == AV_CODEC_ID_RAWVIDEO; }
};
// With MkvCompression::kNone every uncompressed format is stored raw; MJPEG and binary streams
// are stored the same way in both modes.
std::optional<Storage> storageFor(PixelFormat format,
                                  MkvCompression compression = MkvCompression::kFfv1);

// Raw frames: the bytes of an image's rows without padding (NV12: the Y rows, then the UV rows),
// exactly the payload of a raw block.
size_t packedBytes(const ImageDesc& desc);
// Copies the rows of `image` (at its stride) to `out`, packedBytes(image.desc) bytes.
void packRows(const ImageView& image, uint8_t* out);
// The inverse of packRows: packed rows at `in` to `out`'s stride.
void unpackRows(const uint8_t* in, const MutableImageView& out);

// Copies `image` into `frame` (allocated with storageFor(format).pixel and the image's size)
// without loss: grey as is, RGB/BGR into BGR0, YUYV into planar 4:2:2, NV12 into 4:2:0.
void packImage(const ImageView& image, AVFrame* frame);
// The exact inverse of packImage, writing rows at `out`'s stride.
void unpackImage(const AVFrame* frame, const MutableImageView& out);

// Checks that a stream description can be stored (sizes, even dimensions for chroma-subsampled
// formats, no NUL bytes in strings); the message names the stream.
Status validateStreamInfo(const StreamInfo& info);

// Ordered (tag, value) pairs describing `info` (its name travels as the track name), ending
// with MIXRAY_CRC32.
std::vector<std::pair<std::string, std::string>> streamTags(const StreamInfo& info);
// Rebuilds a StreamInfo from a track's name and tags; kCorruptData when they are incomplete or
// fail their CRC.
Result<StreamInfo> parseStreamTags(const std::string& name, const AVDictionary* tags);

// Ordered (tag, value) pairs for the recording: format, tags, attachment CRCs, stream count.
std::vector<std::pair<std::string, std::string>> globalTags(const RecordingHeader& header);

struct GlobalInfo {
    std::map<std::string, std::string> tags;
    size_t stream_count = 0;
    struct AttachmentCheck {
        uint32_t crc = 0;
        size_t size = 0;
    };
    std::vector<AttachmentCheck> attachments;
};
Result<GlobalInfo> parseGlobalTags(const AVDictionary* tags);

// Free-form map <-> one tag value: "<count>\n" then "key=value\n" per entry, with '%', '=',
// '\n' and '\r' percent-escaped.
std::string encodeTagMap(const std::map<std::string, std::string>& tags);
std::optional<std::map<std::string, std::string>> decodeTagMap(std::string_view text);

// Shortest decimal text that parses back to exactly `value`.
std::string exactDouble(double value);

}  // namespace mixray::mkv
