// TUM RGB-D folders: list-file parsing, the reader and the writer.
#include "mixray/replay/tum.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <set>
#include <system_error>

#include "image_files.h"
#include "mixray/replay/convert.h"
#include "mixray/replay/depth_units.h"
#include "mixray/replay/point_cloud.h"

namespace mixray::replay {
namespace {

constexpr int64_t kNsPerSecond = 1'000'000'000;
constexpr int kDefaultStampDigits = 6;  // what the TUM benchmark's own files use

// The optional side files kept as attachments, verbatim.
constexpr const char* kSideFiles[] = {"accelerometer.txt", "groundtruth.txt"};

int64_t pow10(int n) {
    int64_t p = 1;
    while (n-- > 0)
        p *= 10;
    return p;
}

std::string_view trim(std::string_view s) {
    const char* ws = " \t\r\n\v\f";
    const size_t b = s.find_first_not_of(ws);
    if (b == std::string_view::npos)
        return {};
    const size_t e = s.find_last_not_of(ws);
    return s.substr(b, e - b + 1);
}

std::vector<std::string_view> splitFields(std::string_view s) {
    std::vector<std::string_view> fields;
    size_t i = 0;
    while (i < s.size()) {
        while (i < s.size() && (s[i] == ' ' || s[i] == '\t'))
            ++i;
        size_t j = i;
        while (j < s.size() && s[j] != ' ' && s[j] != '\t')
            ++j;
        if (j > i)
            fields.push_back(s.substr(i, j - i));
        i = j;
    }
    return fields;
}

// Fewest fractional digits, at least `digits`, that hold `stamp_ns` exactly.
int exactDigits(int64_t stamp_ns, int digits) {
    while (digits < 9 && stamp_ns % pow10(9 - digits) != 0)
        ++digits;
    return digits;
}

int stampDigitsOf(const StreamInfo& stream) {
    auto it = stream.tags.find(kTumStampDigitsTag);
    if (it != stream.tags.end() && it->second.size() == 1 && it->second[0] >= '0' &&
        it->second[0] <= '9') {
        return it->second[0] - '0';
    }
    return kDefaultStampDigits;
}

StreamInfo makeStream(const char* short_name, StreamKind kind, const ImageDesc& desc,
                      const TumList& list) {
    StreamInfo info;
    info.name = std::string("tum/") + short_name;
    info.device = "tum";
    info.kind = kind;
    info.format = desc;
    const auto& entries = list.entries;
    if (entries.size() >= 2 && entries.back().stamp_ns > entries.front().stamp_ns) {
        const double span_s =
            static_cast<double>(entries.back().stamp_ns - entries.front().stamp_ns) / 1e9;
        info.nominal_fps =
            std::round(static_cast<double>(entries.size() - 1) / span_s * 1000.0) / 1000.0;
    }
    info.tags[kTumStampDigitsTag] = std::to_string(list.stamp_digits);
    std::string header;
    for (const auto& line : list.comments)
        header += (header.empty() ? "" : "\n") + line;
    if (!header.empty())
        info.tags[kTumHeaderTag] = header;
    return info;
}

// Reads and parses `dir/name` when it exists; nullopt when it does not.
Result<std::optional<TumList>> readList(const std::filesystem::path& dir, const char* name) {
    std::error_code ec;
    const auto file = dir / name;
    if (!std::filesystem::exists(file, ec))
        return std::optional<TumList>();
    auto text = detail::readTextFile(file);
    if (!text)
        return text.status();
    auto list = parseTumList(*text, file.string());
    if (!list)
        return list.status();
    return std::optional<TumList>(std::move(*list));
}

// Writes one list file: header comments, then a line per frame, flushed as it goes.
class TumListWriter {
public:
    Status open(const std::filesystem::path& file, const std::string& header) {
        out_.open(file, std::ios::binary | std::ios::trunc);
        if (!out_)
            return {ErrorCode::kIoError, file.string() + ": cannot create"};
        file_ = file;
        return append(header);
    }
    bool isOpen() const { return out_.is_open(); }
    Status append(const std::string& text) {
        out_ << text;
        out_.flush();
        bytes_ += text.size();
        if (!out_)
            return {ErrorCode::kIoError, file_.string() + ": write failed"};
        return Status::ok();
    }
    Status close() {
        if (!out_.is_open())
            return Status::ok();
        out_.close();
        if (out_.fail())
            return {ErrorCode::kIoError, file_.string() + ": close failed"};
        return Status::ok();
    }
    uint64_t bytes() const { return bytes_; }

private:
    std::filesystem::path file_;
    std::ofstream out_;
    uint64_t bytes_ = 0;
};

// One of the two image lists a TUM writer keeps.
struct TumOutput {
    StreamId stream = kInvalidStream;
    const char* folder = "";
    int digits = kDefaultStampDigits;
    int depth_from_per_m = 0;  // 0 for colour
    TumListWriter list;
    std::set<int64_t> stamps;  // file names must stay unique
};

class TumWriter : public RecordingWriter {
public:
    static Result<std::unique_ptr<RecordingWriter>> create(const std::filesystem::path& dir,
                                                           const RecordingHeader& header,
                                                           const TumWriterOptions& options) {
        auto picked = detail::pickColorAndDepth(header, options.color_stream, options.depth_stream,
                                                "TUM writer");
        if (!picked)
            return picked.status();
        MIXRAY_RETURN_IF_ERROR(detail::prepareOutputDir(dir));
        std::unique_ptr<TumWriter> writer(new TumWriter(dir));
        if (picked->color != kInvalidStream) {
            MIXRAY_RETURN_IF_ERROR(
                writer->openOutput(writer->color_, header, picked->color, "rgb", "# color images"));
        }
        if (picked->depth != kInvalidStream) {
            auto scale = depthScalePerMetre(header.streams[picked->depth]);
            if (!scale)
                return scale.status();
            writer->depth_.depth_from_per_m = *scale;
            MIXRAY_RETURN_IF_ERROR(
                writer->openOutput(writer->depth_, header, picked->depth, "depth", "# depth maps"));
        }
        for (const Attachment& a : header.attachments) {
            for (const char* side : kSideFiles) {
                if (a.name != side)
                    continue;
                auto written = detail::writeSideFile(dir, a);
                if (!written)
                    return written.status();
                writer->bytes_ += *written;
            }
        }
        return std::unique_ptr<RecordingWriter>(std::move(writer));
    }

    Status write(const FrameRef& frame) override {
        if (!frame)
            return {ErrorCode::kInvalidArgument, "TUM writer: empty frame"};
        return writeAs(frame.meta().stream, frame);
    }

    Status writeAs(StreamId stream, const FrameRef& frame) override {
        if (!frame)
            return {ErrorCode::kInvalidArgument, "TUM writer: empty frame"};
        TumOutput* out = stream == color_.stream   ? &color_
                         : stream == depth_.stream ? &depth_
                                                   : nullptr;
        if (!out || stream == kInvalidStream)
            return Status::ok();  // not stored in TUM
        if (!out->list.isOpen())
            return {ErrorCode::kInvalidArgument, "TUM writer: closed"};
        const int64_t stamp = frame.meta().host_stamp_ns;
        if (stamp < 0) {
            return {ErrorCode::kInvalidArgument,
                    "TUM writer: negative timestamp " + std::to_string(stamp) + " ns"};
        }
        if (!out->stamps.insert(stamp).second) {
            return {ErrorCode::kInvalidArgument,
                    "TUM writer: two " + std::string(out->folder) + " frames share the timestamp " +
                        formatTumStamp(stamp, 9) + " (TUM names files by timestamp)"};
        }
        const std::string text = formatTumStamp(stamp, exactDigits(stamp, out->digits));
        const std::string relative = std::string(out->folder) + "/" + text + ".png";
        const auto file = dir_ / relative;
        if (out == &color_) {
            MIXRAY_RETURN_IF_ERROR(detail::writeColorImage(frame.image(), file));
        } else {
            MIXRAY_RETURN_IF_ERROR(detail::writeDepthImage(frame.image(), out->depth_from_per_m,
                                                           kTumDepthPerMetre, file));
        }
        std::error_code ec;
        const auto size = std::filesystem::file_size(file, ec);
        if (!ec)
            bytes_ += size;
        return out->list.append(text + " " + relative + "\n");
    }

    Status close() override {
        Status a = color_.list.close();
        Status b = depth_.list.close();
        return a.isOk() ? b : a;
    }

    uint64_t bytesWritten() const override {
        return bytes_ + color_.list.bytes() + depth_.list.bytes();
    }

private:
    explicit TumWriter(std::filesystem::path dir) : dir_(std::move(dir)) {}

    Status openOutput(TumOutput& out, const RecordingHeader& header, StreamId stream,
                      const char* folder, const char* default_header) {
        const StreamInfo& info = header.streams[stream];
        out.stream = stream;
        out.folder = folder;
        out.digits = stampDigitsOf(info);
        std::error_code ec;
        std::filesystem::create_directories(dir_ / folder, ec);
        if (ec)
            return {ErrorCode::kIoError, (dir_ / folder).string() + ": " + ec.message()};
        auto it = info.tags.find(kTumHeaderTag);
        std::string text = it != info.tags.end() ? it->second
                                                 : std::string(default_header) + "\n# file: '" +
                                                       info.name + "'\n# timestamp filename";
        return out.list.open(dir_ / (std::string(folder) + ".txt"), text + "\n");
    }

    std::filesystem::path dir_;
    TumOutput color_;
    TumOutput depth_;
    uint64_t bytes_ = 0;
};

}  // namespace

Result<int64_t> parseTumStamp(std::string_view text) {
    const auto bad = [text](const char* why) -> Result<int64_t> {
        return {ErrorCode::kCorruptData, "bad timestamp '" + std::string(text) + "': " + why};
    };
    if (text.empty())
        return bad("empty");
    const size_t dot = text.find('.');
    const std::string_view whole = text.substr(0, dot);
    const std::string_view frac =
        dot == std::string_view::npos ? std::string_view() : text.substr(dot + 1);
    if (whole.empty())
        return bad("no digits before the decimal point");
    if (dot != std::string_view::npos && frac.empty()) {
        return bad("no digits after the decimal point");
    }
    if (frac.size() > 9)
        return bad("more than 9 fractional digits (finer than 1 ns)");
    if (whole.size() > 10)
        return bad("too large for 64-bit nanoseconds");
    int64_t seconds = 0;
    for (char c : whole) {
        if (c < '0' || c > '9')
            return bad("expected decimal seconds like 1305031102.175304");
        seconds = seconds * 10 + (c - '0');
    }
    int64_t fraction = 0;
    for (char c : frac) {
        if (c < '0' || c > '9')
            return bad("expected decimal seconds like 1305031102.175304");
        fraction = fraction * 10 + (c - '0');
    }
    fraction *= pow10(9 - static_cast<int>(frac.size()));
    if (seconds > (INT64_MAX - fraction) / kNsPerSecond) {
        return bad("too large for 64-bit nanoseconds");
    }
    return seconds * kNsPerSecond + fraction;
}

std::string formatTumStamp(int64_t stamp_ns, int digits) {
    digits = digits < 0 ? 0 : digits > 9 ? 9 : digits;
    const bool negative = stamp_ns < 0;
    const uint64_t magnitude =
        negative ? 0 - static_cast<uint64_t>(stamp_ns) : static_cast<uint64_t>(stamp_ns);
    std::string text = (negative ? "-" : "") + std::to_string(magnitude / kNsPerSecond);
    if (digits > 0) {
        const uint64_t fraction =
            magnitude % kNsPerSecond / static_cast<uint64_t>(pow10(9 - digits));
        std::string f = std::to_string(fraction);
        text += "." + std::string(static_cast<size_t>(digits) - f.size(), '0') + f;
    }
    return text;
}

Result<TumList> parseTumList(std::string_view text, std::string_view file_name) {
    TumList list;
    int line_number = 0;
    size_t pos = 0;
    while (pos < text.size()) {
        size_t end = text.find('\n', pos);
        if (end == std::string_view::npos)
            end = text.size();
        std::string_view raw = text.substr(pos, end - pos);
        pos = end + 1;
        ++line_number;
        if (!raw.empty() && raw.back() == '\r')
            raw.remove_suffix(1);
        const std::string_view line = trim(raw);
        if (line.empty())
            continue;
        const std::string where = std::string(file_name) + ":" + std::to_string(line_number);
        if (line.front() == '#') {
            list.comments.emplace_back(line);
            continue;
        }
        const auto fields = splitFields(line);
        if (fields.size() != 2) {
            return {ErrorCode::kCorruptData, where + ": expected 'timestamp filename', found " +
                                                 std::to_string(fields.size()) + " fields"};
        }
        auto stamp = parseTumStamp(fields[0]);
        if (!stamp)
            return stamp.status().withContext(where);
        const std::filesystem::path file(fields[1]);
        if (file.is_absolute()) {
            return {ErrorCode::kCorruptData, where + ": '" + std::string(fields[1]) +
                                                 "' is absolute; TUM lists name "
                                                 "files relative to the folder"};
        }
        for (const auto& part : file) {
            if (part == "..") {
                return {ErrorCode::kCorruptData,
                        where + ": '" + std::string(fields[1]) + "' leaves the folder"};
            }
        }
        if (!list.entries.empty() && *stamp < list.entries.back().stamp_ns) {
            return {ErrorCode::kCorruptData,
                    where + ": timestamp " + std::string(fields[0]) +
                        " is earlier than the previous line's (lists must be in time order)"};
        }
        const size_t dot = fields[0].find('.');
        if (dot != std::string_view::npos) {
            list.stamp_digits =
                std::max(list.stamp_digits, static_cast<int>(fields[0].size() - dot - 1));
        }
        list.entries.push_back({*stamp, std::string(fields[1]), line_number});
    }
    return list;
}

Result<std::unique_ptr<RecordingReader>> openTum(const std::filesystem::path& dir,
                                                 const TumReaderOptions& options) {
    std::error_code ec;
    if (!std::filesystem::is_directory(dir, ec)) {
        return {ErrorCode::kNotFound, dir.string() + ": not a folder"};
    }
    auto rgb = readList(dir, "rgb.txt");
    if (!rgb)
        return rgb.status();
    auto depth = readList(dir, "depth.txt");
    if (!depth)
        return depth.status();
    const bool has_rgb = rgb->has_value() && !(*rgb)->entries.empty();
    const bool has_depth = depth->has_value() && !(*depth)->entries.empty();
    if (!has_rgb && !has_depth) {
        return {ErrorCode::kNotFound,
                dir.string() + ": neither rgb.txt nor depth.txt lists any image"};
    }

    std::vector<StreamInfo> streams;
    std::vector<detail::SequenceEntry> entries;
    const auto addList = [&](const TumList& list, const char* list_name, const char* short_name,
                             StreamKind kind, PixelFormat format) -> Status {
        const auto stream = static_cast<uint32_t>(streams.size());
        const std::string list_path = (dir / list_name).string();
        for (size_t i = 0; i < list.entries.size(); ++i) {
            const TumListEntry& e = list.entries[i];
            std::string where = list_path + ":" + std::to_string(e.line) + ": " + e.file;
            const auto file = dir / e.file;
            if (!std::filesystem::is_regular_file(file, ec)) {
                return {ErrorCode::kNotFound, where + ": listed image does not exist"};
            }
            entries.push_back({e.stamp_ns, stream, i, file, std::move(where)});
        }
        auto desc = detail::probeImage(entries[entries.size() - list.entries.size()].file, format,
                                       entries[entries.size() - list.entries.size()].where);
        if (!desc)
            return desc.status();
        StreamInfo info = makeStream(short_name, kind, *desc, list);
        if (kind == StreamKind::kDepth) {
            info.tags[kDepthScaleTag] = std::to_string(kTumDepthPerMetre);
        }
        streams.push_back(std::move(info));
        return Status::ok();
    };
    if (has_rgb) {
        MIXRAY_RETURN_IF_ERROR(
            addList(**rgb, "rgb.txt", "color", StreamKind::kColor, PixelFormat::kRGB8));
    }
    if (has_depth) {
        MIXRAY_RETURN_IF_ERROR(
            addList(**depth, "depth.txt", "depth", StreamKind::kDepth, PixelFormat::kDepth16));
    }
    // The benchmark's depth images are registered to its colour images (same pixel grid, the
    // colour camera's intrinsics): say so, for point clouds with colour.
    if (streams.size() == 2 && streams[0].format.width == streams[1].format.width &&
        streams[0].format.height == streams[1].format.height) {
        streams[1].tags[kRegisteredToTag] = streams[0].name;
    }
    detail::sortEntries(entries);

    std::vector<Attachment> attachments;
    for (const char* side : kSideFiles) {
        const auto file = dir / side;
        if (!std::filesystem::is_regular_file(file, ec))
            continue;
        auto text = detail::readTextFile(file);
        if (!text)
            return text.status();
        // An empty file carries nothing, and Matroska cannot store an empty attachment.
        if (text->empty())
            continue;
        attachments.push_back({side, "text/plain", {text->begin(), text->end()}});
    }
    std::map<std::string, std::string> tags = {{"source_format", "tum"}};
    auto folder = std::filesystem::absolute(dir, ec).lexically_normal();
    if (folder.filename().empty())
        folder = folder.parent_path();
    if (!folder.filename().empty())
        tags["title"] = folder.filename().string();

    return std::unique_ptr<RecordingReader>(std::make_unique<detail::ImageSequenceReader>(
        "tum", std::move(streams), std::move(attachments), std::move(tags), std::move(entries),
        options.buffers_per_stream));
}

Result<std::unique_ptr<RecordingWriter>> createTumWriter(const std::filesystem::path& dir,
                                                         const RecordingHeader& header,
                                                         const TumWriterOptions& options) {
    return TumWriter::create(dir, header, options);
}

Result<WriteLosses> tumLosses(const RecordingHeader& header, const TumWriterOptions& options) {
    auto picked =
        detail::pickColorAndDepth(header, options.color_stream, options.depth_stream, "TUM writer");
    if (!picked)
        return picked.status();
    const auto keeps = [](const std::string& name) {
        return std::any_of(std::begin(kSideFiles), std::end(kSideFiles),
                           [&](const char* side) { return name == side; });
    };
    return detail::folderWriterLosses(header, *picked, "TUM", "tum/color", "tum/depth", keeps,
                                      "accelerometer.txt and groundtruth.txt");
}

Result<ConvertSummary> exportTum(RecordingReader& reader, const std::filesystem::path& dir,
                                 const TumWriterOptions& options) {
    auto writer = createTumWriter(dir, headerOf(reader), options);
    if (!writer)
        return writer.status();
    return convertRecording(reader, **writer);
}

}  // namespace mixray::replay
