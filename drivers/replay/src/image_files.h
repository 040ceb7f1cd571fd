// Internal: folders of image files as recordings — decoding, encoding, the shared reader.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "mixray/graph/recording.h"
#include "mixray/replay/convert.h"

namespace mixray::replay::detail {

// One image file of a sequence, in recording order.
struct SequenceEntry {
    int64_t stamp_ns = 0;
    uint32_t stream = 0;  // index into the reader's streams
    uint64_t sequence = 0;
    std::filesystem::path file;
    std::string where;  // how messages name it: "depth.txt:12: depth/1.png"
};

// The layout an image file must decode to for a stream of `format` (kRGB8 from an 8-bit
// 3-channel file, kDepth16 from a 16-bit 1-channel file): reads the file once. Errors name
// `where` and say what was found.
Result<ImageDesc> probeImage(const std::filesystem::path& file, PixelFormat format,
                             std::string_view where);

// Decodes `file` into `dst` (whose desc is the stream's layout). kCorruptData naming `where`
// for a wrong bit depth, channel count or size; kNotFound when the file is gone.
Status readImageInto(const std::filesystem::path& file, const MutableImageView& dst,
                     std::string_view where);

// Writes an rgb8, bgr8 or mjpeg (decoded) frame as an 8-bit RGB image file; the extension of
// `file` picks the codec (.png, .tiff).
Status writeColorImage(const ImageView& image, const std::filesystem::path& file);

// Writes a 16-bit depth frame, rescaled from `from_per_m` to `to_per_m` units per metre, as a
// 16-bit grey image file.
Status writeDepthImage(const ImageView& image, int from_per_m, int to_per_m,
                       const std::filesystem::path& file);

// Reads a whole small file (list files, attachments).
Result<std::string> readTextFile(const std::filesystem::path& file);

// Creates `dir` for a writer, refusing one that exists and holds anything (mixing two
// recordings in one folder would corrupt both).
Status prepareOutputDir(const std::filesystem::path& dir);

// Writes an attachment as a side file of a folder recording (dir / attachment.name, which must
// be a plain file name). Returns the bytes written.
Result<uint64_t> writeSideFile(const std::filesystem::path& dir, const Attachment& attachment);

// The stream a folder writer stores as its colour (kind kColor) or depth (kind kDepth)
// images: `wanted` by full or short name, else the first stream of `kind` whose format the
// writer can encode. kInvalidStream when none and nothing was asked for.
Result<StreamId> pickStream(const RecordingHeader& header, std::string_view wanted, StreamKind kind,
                            std::string_view writer);

// The colour and depth streams a folder writer stores (see pickStream); at least one of them.
struct ColorAndDepth {
    StreamId color = kInvalidStream;
    StreamId depth = kInvalidStream;
};
Result<ColorAndDepth> pickColorAndDepth(const RecordingHeader& header, std::string_view color,
                                        std::string_view depth, std::string_view writer);

// What a folder writer that stores `picked` as images named by host stamp loses of `header`.
// `format` names it in messages ("TUM"); `color_name`/`depth_name` are the stream names its
// reader gives back; `keeps` tells which attachments it writes back (`kept_attachments` says
// which in words).
WriteLosses folderWriterLosses(const RecordingHeader& header, const ColorAndDepth& picked,
                               std::string_view format, std::string_view color_name,
                               std::string_view depth_name,
                               const std::function<bool(const std::string&)>& keeps,
                               std::string_view kept_attachments);

// Part of a stream name after its last '/': "kinect/depth" -> "depth".
std::string_view shortStreamName(std::string_view name);

// A RecordingReader over a sorted list of image files, one pool per stream. Decodes a file
// per next(); seek() is a binary search. Thread-bound.
class ImageSequenceReader : public RecordingReader {
public:
    ImageSequenceReader(std::string format, std::vector<StreamInfo> streams,
                        std::vector<Attachment> attachments,
                        std::map<std::string, std::string> tags, std::vector<SequenceEntry> entries,
                        size_t buffers_per_stream);

    std::string format() const override { return format_; }
    const std::vector<StreamInfo>& streams() const override { return streams_; }
    const std::vector<Attachment>& attachments() const override { return attachments_; }
    const std::map<std::string, std::string>& tags() const override { return tags_; }
    Result<FrameRef> next() override;
    Status seek(int64_t host_stamp_ns) override;

    // Turns a stream's decoded file into the frame's values in place (datasets that store
    // depth in their own encoding: NYU's raw disparity, SUN RGB-D's rotated bits). `where`
    // names the file for messages.
    using PostDecode = std::function<Status(const MutableImageView& image, std::string_view where)>;
    void setPostDecode(uint32_t stream, PostDecode post) { post_[stream] = std::move(post); }

private:
    std::string format_;
    std::vector<StreamInfo> streams_;
    std::vector<Attachment> attachments_;
    std::map<std::string, std::string> tags_;
    std::vector<SequenceEntry> entries_;
    std::vector<std::shared_ptr<BufferPool>> pools_;
    std::map<uint32_t, PostDecode> post_;
    size_t position_ = 0;
};

// Sorts entries into recording order: by stamp, then by stream index (stable otherwise).
void sortEntries(std::vector<SequenceEntry>& entries);

}  // namespace mixray::replay::detail
