// Image files through OpenCV (exceptions caught here), and the reader shared by folder formats.
#include "image_files.h"

#include <algorithm>
#include <fstream>
#include <iterator>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <system_error>

#include "mixray/replay/depth_units.h"

namespace mixray::replay::detail {
namespace {

std::string describe(const cv::Mat& mat) {
    const int depth = mat.depth();
    const char* bits = depth == CV_8U    ? "8-bit"
                       : depth == CV_16U ? "16-bit"
                       : depth == CV_32F ? "32-bit float"
                                         : "unusual-depth";
    return std::string(bits) + " " + std::to_string(mat.channels()) + "-channel " +
           std::to_string(mat.cols) + "x" + std::to_string(mat.rows);
}

// The OpenCV type a file must decode to for a frame format.
int cvTypeFor(PixelFormat format) {
    switch (format) {
        case PixelFormat::kRGB8:
        case PixelFormat::kBGR8:
            return CV_8UC3;
        case PixelFormat::kDepth16:
        case PixelFormat::kMono16:
        case PixelFormat::kIR16:
            return CV_16UC1;
        case PixelFormat::kMono8:
            return CV_8UC1;
        default:
            return -1;
    }
}

const char* expectedText(PixelFormat format) {
    return cvTypeFor(format) == CV_8UC3 ? "8-bit RGB" : "16-bit grey";
}

// A Mat header over a frame's pixels (no copy).
cv::Mat wrap(const ImageView& image, int type) {
    return cv::Mat(image.desc.height, image.desc.width, type, const_cast<uint8_t*>(image.data),
                   static_cast<size_t>(image.desc.stride_bytes));
}

// Swaps the first and third channel of 8-bit 3-channel images (RGB <-> BGR) with core only.
void swapRedBlue(const cv::Mat& src, cv::Mat& dst) {
    const int from_to[] = {0, 2, 1, 1, 2, 0};
    cv::mixChannels(&src, 1, &dst, 1, from_to, 3);
}

Result<cv::Mat> decode(const std::filesystem::path& file, std::string_view where) {
    std::error_code ec;
    if (!std::filesystem::is_regular_file(file, ec)) {
        return {ErrorCode::kNotFound, std::string(where) + ": file does not exist"};
    }
    try {
        cv::Mat mat = cv::imread(file.string(), cv::IMREAD_UNCHANGED);
        if (mat.empty()) {
            return {ErrorCode::kCorruptData, std::string(where) + ": not a readable image"};
        }
        return mat;
    } catch (const cv::Exception& e) {
        return {ErrorCode::kCorruptData, std::string(where) + ": " + e.what()};
    }
}

Status encode(const std::filesystem::path& file, const cv::Mat& mat) {
    try {
        if (!cv::imwrite(file.string(), mat)) {
            return {ErrorCode::kIoError, file.string() + ": the image could not be written"};
        }
    } catch (const cv::Exception& e) {
        return {ErrorCode::kIoError, file.string() + ": " + e.what()};
    }
    return Status::ok();
}

}  // namespace

Result<ImageDesc> probeImage(const std::filesystem::path& file, PixelFormat format,
                             std::string_view where) {
    auto mat = decode(file, where);
    if (!mat)
        return mat.status();
    if (mat->type() != cvTypeFor(format)) {
        return {ErrorCode::kCorruptData, std::string(where) + ": " + describe(*mat) +
                                             " image, expected " + expectedText(format)};
    }
    return ImageDesc::packed(format, mat->cols, mat->rows);
}

Status readImageInto(const std::filesystem::path& file, const MutableImageView& dst,
                     std::string_view where) {
    auto mat = decode(file, where);
    if (!mat)
        return mat.status();
    const int type = cvTypeFor(dst.desc.format);
    if (mat->type() != type || mat->cols != dst.desc.width || mat->rows != dst.desc.height) {
        return {ErrorCode::kCorruptData,
                std::string(where) + ": " + describe(*mat) + " image, expected " +
                    expectedText(dst.desc.format) + " " + std::to_string(dst.desc.width) + "x" +
                    std::to_string(dst.desc.height) + " like the stream's first image"};
    }
    try {
        cv::Mat out = wrap(dst, type);
        // imread gives BGR; mixray's rgb8 is R,G,B in memory.
        if (dst.desc.format == PixelFormat::kRGB8) {
            swapRedBlue(*mat, out);
        } else {
            mat->copyTo(out);
        }
    } catch (const cv::Exception& e) {
        return {ErrorCode::kInternal, std::string(where) + ": " + e.what()};
    }
    return Status::ok();
}

Status writeColorImage(const ImageView& image, const std::filesystem::path& file) {
    try {
        cv::Mat bgr;
        switch (image.desc.format) {
            case PixelFormat::kRGB8: {
                bgr.create(image.desc.height, image.desc.width, CV_8UC3);
                swapRedBlue(wrap(image, CV_8UC3), bgr);
                break;
            }
            case PixelFormat::kBGR8:
                bgr = wrap(image, CV_8UC3);
                break;
            case PixelFormat::kMJPEG: {
                cv::Mat bytes(1, static_cast<int>(image.size_bytes), CV_8UC1,
                              const_cast<uint8_t*>(image.data));
                bgr = cv::imdecode(bytes, cv::IMREAD_COLOR);
                if (bgr.empty()) {
                    return {ErrorCode::kCorruptData,
                            file.string() + ": the frame's JPEG data does not decode"};
                }
                break;
            }
            default:
                return {ErrorCode::kUnsupported, file.string() + ": cannot store " +
                                                     std::string(toString(image.desc.format)) +
                                                     " as an RGB image (rgb8, bgr8 and mjpeg can)"};
        }
        return encode(file, bgr);
    } catch (const cv::Exception& e) {
        return {ErrorCode::kInternal, file.string() + ": " + e.what()};
    }
}

Status writeDepthImage(const ImageView& image, int from_per_m, int to_per_m,
                       const std::filesystem::path& file) {
    if (cvTypeFor(image.desc.format) != CV_16UC1) {
        return {ErrorCode::kUnsupported, file.string() + ": cannot store " +
                                             std::string(toString(image.desc.format)) +
                                             " as 16-bit depth"};
    }
    if (from_per_m == to_per_m)
        return encode(file, wrap(image, CV_16UC1));
    Image scaled(ImageDesc::packed(PixelFormat::kDepth16, image.desc.width, image.desc.height));
    MIXRAY_RETURN_IF_ERROR(
        rescaleDepth(image, from_per_m, scaled.mutableView(), to_per_m).withContext(file.string()));
    return encode(file, wrap(scaled.view(), CV_16UC1));
}

Result<std::string> readTextFile(const std::filesystem::path& file) {
    std::ifstream in(file, std::ios::binary);
    if (!in)
        return {ErrorCode::kNotFound, file.string() + ": cannot open"};
    std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    if (in.bad())
        return {ErrorCode::kIoError, file.string() + ": read failed"};
    return text;
}

Result<uint64_t> writeSideFile(const std::filesystem::path& dir, const Attachment& attachment) {
    if (attachment.name.empty() || attachment.name.find('/') != std::string::npos ||
        attachment.name == "." || attachment.name == "..") {
        return Status(ErrorCode::kInvalidArgument,
                      "attachment name " + attachment.name + " is not a plain file name");
    }
    const std::filesystem::path path = dir / attachment.name;
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(attachment.data.data()),
              static_cast<std::streamsize>(attachment.data.size()));
    if (!out)
        return Status(ErrorCode::kIoError, path.string() + ": write failed");
    return static_cast<uint64_t>(attachment.data.size());
}

Status prepareOutputDir(const std::filesystem::path& dir) {
    std::error_code ec;
    if (std::filesystem::exists(dir, ec)) {
        if (!std::filesystem::is_directory(dir, ec)) {
            return {ErrorCode::kInvalidArgument, dir.string() + ": exists and is not a folder"};
        }
        if (!std::filesystem::is_empty(dir, ec)) {
            return {ErrorCode::kInvalidArgument,
                    dir.string() +
                        ": folder is not empty (a recording is written only into a "
                        "new or empty folder)"};
        }
        return Status::ok();
    }
    std::filesystem::create_directories(dir, ec);
    if (ec)
        return {ErrorCode::kIoError, dir.string() + ": cannot create: " + ec.message()};
    return Status::ok();
}

Result<ColorAndDepth> pickColorAndDepth(const RecordingHeader& header, std::string_view color,
                                        std::string_view depth, std::string_view writer) {
    auto c = pickStream(header, color, StreamKind::kColor, writer);
    if (!c)
        return c.status();
    auto d = pickStream(header, depth, StreamKind::kDepth, writer);
    if (!d)
        return d.status();
    if (*c == kInvalidStream && *d == kInvalidStream) {
        return {ErrorCode::kUnsupported,
                std::string(writer) +
                    ": the recording has neither a colour stream (rgb8, bgr8, "
                    "mjpeg) nor a depth16 stream"};
    }
    return ColorAndDepth{*c, *d};
}

WriteLosses folderWriterLosses(const RecordingHeader& header, const ColorAndDepth& picked,
                               std::string_view format, std::string_view color_name,
                               std::string_view depth_name,
                               const std::function<bool(const std::string&)>& keeps,
                               std::string_view kept_attachments) {
    WriteLosses losses;
    const std::string name(format);
    for (size_t i = 0; i < header.streams.size(); ++i) {
        const StreamInfo& s = header.streams[i];
        const auto id = static_cast<StreamId>(i);
        if (id == picked.color || id == picked.depth) {
            const std::string_view back = id == picked.color ? color_name : depth_name;
            if (s.name != back) {
                losses.changed.push_back("stream '" + s.name + "' is read back as '" +
                                         std::string(back) + "' (" + name +
                                         " stores no stream names)");
            }
            if (s.clock_domain != kHostClockDomain) {
                losses.changed.push_back("stream '" + s.name +
                                         "': device stamps and sequence numbers are not kept (" +
                                         name + " stores one host timestamp per frame)");
            }
            continue;
        }
        losses.dropped_streams.push_back(id);
        losses.dropped.push_back("stream '" + s.name + "' (" + std::string(toString(s.kind)) +
                                 ", " + std::string(toString(s.format.format)) + "): " + name +
                                 " holds one colour stream (rgb8, bgr8, mjpeg) and one depth16 "
                                 "stream");
    }
    for (const Attachment& a : header.attachments) {
        if (!keeps(a.name)) {
            losses.dropped.push_back("attachment '" + a.name + "': " + name + " keeps only " +
                                     std::string(kept_attachments));
        }
    }
    std::string keys;
    for (const auto& [key, value] : header.tags) {
        // What the folder readers set themselves (the format, the folder's name) is not lost.
        if (key != "source_format" && key != "title")
            keys += (keys.empty() ? "" : ", ") + key;
    }
    if (!keys.empty()) {
        losses.changed.push_back("recording tags (" + keys + "): " + name +
                                 " has no place for them");
    }
    return losses;
}

std::string_view shortStreamName(std::string_view name) {
    const size_t slash = name.rfind('/');
    return slash == std::string_view::npos ? name : name.substr(slash + 1);
}

Result<StreamId> pickStream(const RecordingHeader& header, std::string_view wanted, StreamKind kind,
                            std::string_view writer) {
    const auto encodable = [kind](const StreamInfo& s) {
        if (kind == StreamKind::kDepth)
            return s.format.format == PixelFormat::kDepth16;
        return s.format.format == PixelFormat::kRGB8 || s.format.format == PixelFormat::kBGR8 ||
               s.format.format == PixelFormat::kMJPEG;
    };
    if (!wanted.empty()) {
        for (size_t i = 0; i < header.streams.size(); ++i) {
            const StreamInfo& s = header.streams[i];
            if (s.name != wanted && shortStreamName(s.name) != wanted)
                continue;
            if (!encodable(s)) {
                return {ErrorCode::kUnsupported,
                        std::string(writer) + ": stream '" + s.name + "' is " +
                            std::string(toString(s.format.format)) + ", which it cannot store"};
            }
            return static_cast<StreamId>(i);
        }
        return {ErrorCode::kNotFound, std::string(writer) + ": the recording has no stream '" +
                                          std::string(wanted) + "'"};
    }
    for (size_t i = 0; i < header.streams.size(); ++i) {
        if (header.streams[i].kind == kind && encodable(header.streams[i])) {
            return static_cast<StreamId>(i);
        }
    }
    return kInvalidStream;
}

void sortEntries(std::vector<SequenceEntry>& entries) {
    std::stable_sort(entries.begin(), entries.end(),
                     [](const SequenceEntry& a, const SequenceEntry& b) {
                         if (a.stamp_ns != b.stamp_ns)
                             return a.stamp_ns < b.stamp_ns;
                         return a.stream < b.stream;
                     });
}

ImageSequenceReader::ImageSequenceReader(std::string format, std::vector<StreamInfo> streams,
                                         std::vector<Attachment> attachments,
                                         std::map<std::string, std::string> tags,
                                         std::vector<SequenceEntry> entries,
                                         size_t buffers_per_stream)
    : format_(std::move(format)),
      streams_(std::move(streams)),
      attachments_(std::move(attachments)),
      tags_(std::move(tags)),
      entries_(std::move(entries)) {
    for (const StreamInfo& s : streams_) {
        pools_.push_back(
            BufferPool::create({s.format, 0, std::max<size_t>(buffers_per_stream, 1), s.name}));
    }
}

Result<FrameRef> ImageSequenceReader::next() {
    if (position_ >= entries_.size()) {
        return {ErrorCode::kEndOfStream, format_ + ": end of recording"};
    }
    const SequenceEntry& entry = entries_[position_];
    BufferPool& pool = *pools_[entry.stream];
    WritableFrame frame = pool.acquire();
    if (!frame) {
        return {ErrorCode::kUnavailable, "all " + std::to_string(pool.options().buffer_count) +
                                             " buffers of '" + streams_[entry.stream].name +
                                             "' are held by consumers"};
    }
    MIXRAY_RETURN_IF_ERROR(readImageInto(entry.file, frame.image(), entry.where));
    auto post = post_.find(entry.stream);
    if (post != post_.end())
        MIXRAY_RETURN_IF_ERROR(post->second(frame.image(), entry.where));
    FrameMetadata& meta = frame.meta();
    meta.stream = entry.stream;
    meta.sequence = entry.sequence;
    meta.device_stamp_ns = entry.stamp_ns;
    meta.host_stamp_ns = entry.stamp_ns;
    meta.clock_domain = kHostClockDomain;
    ++position_;
    return std::move(frame).publish();
}

Status ImageSequenceReader::seek(int64_t host_stamp_ns) {
    auto it =
        std::lower_bound(entries_.begin(), entries_.end(), host_stamp_ns,
                         [](const SequenceEntry& e, int64_t stamp) { return e.stamp_ns < stamp; });
    position_ = static_cast<size_t>(it - entries_.begin());
    return Status::ok();
}

}  // namespace mixray::replay::detail
