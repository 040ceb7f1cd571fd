// PCL OpenNI TIFF folders: timestamped file names, the reader and the writer.
#include "mixray/replay/pcl_tiff.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <regex>
#include <set>
#include <system_error>

#include "image_files.h"
#include "mixray/replay/convert.h"
#include "mixray/replay/depth_units.h"
#include "mixray/replay/point_cloud.h"

namespace mixray::replay {
namespace {

constexpr int64_t kNsPerSecond = 1'000'000'000;
constexpr int64_t kSecondsPerDay = 86'400;
constexpr int kDefaultStampDigits = 6;  // what pcl::ImageGrabber writes and expects

int64_t pow10(int n) {
    int64_t p = 1;
    while (n-- > 0)
        p *= 10;
    return p;
}

int exactDigits(int64_t stamp_ns, int digits) {
    while (digits < 9 && stamp_ns % pow10(9 - digits) != 0)
        ++digits;
    return digits;
}

int stampDigitsOf(const StreamInfo& stream) {
    auto it = stream.tags.find(kPclStampDigitsTag);
    if (it != stream.tags.end() && it->second.size() == 1 && it->second[0] >= '0' &&
        it->second[0] <= '9') {
        return it->second[0] - '0';
    }
    return kDefaultStampDigits;
}

bool endsWith(std::string_view s, std::string_view suffix) {
    return s.size() >= suffix.size() && s.substr(s.size() - suffix.size()) == suffix;
}

// One of the two image kinds a PCL writer stores.
struct PclOutput {
    StreamId stream = kInvalidStream;
    const char* suffix = "";
    int digits = kDefaultStampDigits;
    int depth_from_per_m = 0;  // 0 for colour
    std::set<int64_t> stamps;
};

class PclTiffWriter : public RecordingWriter {
public:
    static Result<std::unique_ptr<RecordingWriter>> create(const std::filesystem::path& dir,
                                                           const RecordingHeader& header,
                                                           const PclTiffWriterOptions& options) {
        auto picked = detail::pickColorAndDepth(header, options.color_stream, options.depth_stream,
                                                "PCL TIFF writer");
        if (!picked)
            return picked.status();
        MIXRAY_RETURN_IF_ERROR(detail::prepareOutputDir(dir));
        std::unique_ptr<PclTiffWriter> writer(new PclTiffWriter(dir));
        writer->color_.suffix = "_rgb.tiff";
        writer->depth_.suffix = "_depth.tiff";
        if (picked->color != kInvalidStream) {
            writer->color_.stream = picked->color;
            writer->color_.digits = stampDigitsOf(header.streams[picked->color]);
        }
        if (picked->depth != kInvalidStream) {
            auto scale = depthScalePerMetre(header.streams[picked->depth]);
            if (!scale)
                return scale.status();
            writer->depth_.stream = picked->depth;
            writer->depth_.digits = stampDigitsOf(header.streams[picked->depth]);
            writer->depth_.depth_from_per_m = *scale;
        }
        for (const Attachment& a : header.attachments) {
            // Sidecars only; a name with directories would write outside the folder.
            if (!endsWith(a.name, ".xml") || a.name.find('/') != std::string::npos)
                continue;
            auto written = detail::writeSideFile(dir, a);
            if (!written)
                return written.status();
            writer->bytes_ += *written;
        }
        return std::unique_ptr<RecordingWriter>(std::move(writer));
    }

    Status write(const FrameRef& frame) override {
        if (!frame)
            return {ErrorCode::kInvalidArgument, "PCL TIFF writer: empty frame"};
        return writeAs(frame.meta().stream, frame);
    }

    Status writeAs(StreamId stream, const FrameRef& frame) override {
        if (!frame)
            return {ErrorCode::kInvalidArgument, "PCL TIFF writer: empty frame"};
        if (closed_)
            return {ErrorCode::kInvalidArgument, "PCL TIFF writer: closed"};
        PclOutput* out = stream == color_.stream   ? &color_
                         : stream == depth_.stream ? &depth_
                                                   : nullptr;
        if (!out || stream == kInvalidStream)
            return Status::ok();  // not stored in PCL TIFF
        const int64_t stamp = frame.meta().host_stamp_ns;
        if (!out->stamps.insert(stamp).second) {
            return {ErrorCode::kInvalidArgument,
                    "PCL TIFF writer: two frames share the timestamp " + formatPclStamp(stamp, 9) +
                        " (files are named by timestamp)"};
        }
        const auto file =
            dir_ /
            ("frame_" + formatPclStamp(stamp, exactDigits(stamp, out->digits)) + out->suffix);
        if (out == &color_) {
            MIXRAY_RETURN_IF_ERROR(detail::writeColorImage(frame.image(), file));
        } else {
            MIXRAY_RETURN_IF_ERROR(detail::writeDepthImage(frame.image(), out->depth_from_per_m,
                                                           kMillimetresPerMetre, file));
        }
        std::error_code ec;
        const auto size = std::filesystem::file_size(file, ec);
        if (!ec)
            bytes_ += size;
        return Status::ok();
    }

    // Every file is complete when write() returns; nothing is left to finish.
    Status close() override {
        closed_ = true;
        return Status::ok();
    }
    uint64_t bytesWritten() const override { return bytes_; }

private:
    explicit PclTiffWriter(std::filesystem::path dir) : dir_(std::move(dir)) {}

    std::filesystem::path dir_;
    PclOutput color_;
    PclOutput depth_;
    uint64_t bytes_ = 0;
    bool closed_ = false;
};

}  // namespace

Result<int64_t> parsePclStamp(std::string_view text) {
    const auto bad = [text](const char* why) -> Result<int64_t> {
        return {ErrorCode::kCorruptData, "bad timestamp '" + std::string(text) + "': " + why};
    };
    // YYYYMMDDTHHMMSS, then optionally '.' and 1..9 digits.
    if (text.size() < 15 || text[8] != 'T')
        return bad("expected YYYYMMDDTHHMMSS.ffffff");
    const auto number = [text](size_t at, size_t n, int64_t* value) {
        *value = 0;
        for (size_t i = at; i < at + n; ++i) {
            if (text[i] < '0' || text[i] > '9')
                return false;
            *value = *value * 10 + (text[i] - '0');
        }
        return true;
    };
    int64_t y = 0, mo = 0, d = 0, h = 0, mi = 0, s = 0;
    if (!number(0, 4, &y) || !number(4, 2, &mo) || !number(6, 2, &d) || !number(9, 2, &h) ||
        !number(11, 2, &mi) || !number(13, 2, &s)) {
        return bad("expected YYYYMMDDTHHMMSS.ffffff");
    }
    int64_t fraction = 0;
    if (text.size() > 15) {
        const size_t digits = text.size() - 16;
        if (text[15] != '.' || digits == 0)
            return bad("expected '.' and fractional digits");
        if (digits > 9)
            return bad("more than 9 fractional digits (finer than 1 ns)");
        if (!number(16, digits, &fraction))
            return bad("fraction is not digits");
        fraction *= pow10(9 - static_cast<int>(digits));
    }
    const std::chrono::year_month_day date{std::chrono::year(static_cast<int>(y)),
                                           std::chrono::month(static_cast<unsigned>(mo)),
                                           std::chrono::day(static_cast<unsigned>(d))};
    if (!date.ok() || h > 23 || mi > 59 || s > 59)
        return bad("not a valid date and time");
    const int64_t days = std::chrono::sys_days(date).time_since_epoch().count();
    // Four-digit years reach far beyond what 64-bit nanoseconds hold (1677 to 2262).
    const int64_t seconds = days * kSecondsPerDay + h * 3600 + mi * 60 + s;
    if (seconds < INT64_MIN / kNsPerSecond || seconds > (INT64_MAX - fraction) / kNsPerSecond)
        return bad("beyond 64-bit nanoseconds since 1970 (1677-09-21 to 2262-04-11)");
    return seconds * kNsPerSecond + fraction;
}

std::string formatPclStamp(int64_t stamp_ns, int digits) {
    digits = std::clamp(digits, 0, 9);
    // Floor division, so stamps before 1970 still name the right second.
    int64_t seconds = stamp_ns / kNsPerSecond;
    int64_t fraction = stamp_ns % kNsPerSecond;
    if (fraction < 0) {
        fraction += kNsPerSecond;
        --seconds;
    }
    int64_t days = seconds / kSecondsPerDay;
    int64_t second_of_day = seconds % kSecondsPerDay;
    if (second_of_day < 0) {
        second_of_day += kSecondsPerDay;
        --days;
    }
    const std::chrono::year_month_day date{std::chrono::sys_days(std::chrono::days(days))};
    char text[48];
    std::snprintf(text, sizeof(text), "%04d%02u%02uT%02d%02d%02d", static_cast<int>(date.year()),
                  static_cast<unsigned>(date.month()), static_cast<unsigned>(date.day()),
                  static_cast<int>(second_of_day / 3600), static_cast<int>(second_of_day / 60 % 60),
                  static_cast<int>(second_of_day % 60));
    std::string out = text;
    if (digits > 0) {
        // digits is 1..9 (clamped above); clamping again tells the compiler the field is short.
        std::snprintf(text, sizeof(text), ".%0*lld", std::clamp(digits, 1, 9),
                      static_cast<long long>(fraction / pow10(9 - digits)));
        out += text;
    }
    return out;
}

Result<std::unique_ptr<RecordingReader>> openPclTiff(const std::filesystem::path& dir,
                                                     const PclTiffReaderOptions& options) {
    std::error_code ec;
    if (!std::filesystem::is_directory(dir, ec)) {
        return {ErrorCode::kNotFound, dir.string() + ": not a folder"};
    }
    static const std::regex kName(R"(frame_(.*)_(depth|rgb)\.tiff?)");
    struct Found {
        int64_t stamp_ns;
        bool depth;
        std::filesystem::path file;
        int digits;
    };
    std::vector<Found> found;
    std::vector<std::filesystem::path> sidecars;
    for (const auto& item : std::filesystem::directory_iterator(dir, ec)) {
        if (!item.is_regular_file(ec))
            continue;
        const std::string name = item.path().filename().string();
        if (endsWith(name, ".xml")) {
            sidecars.push_back(item.path());
            continue;
        }
        std::smatch match;
        if (!std::regex_match(name, match, kName))
            continue;
        auto stamp = parsePclStamp(match[1].str());
        if (!stamp)
            return stamp.status().withContext(item.path().string());
        const size_t dot = match[1].str().find('.');
        const int digits =
            dot == std::string::npos ? 0 : static_cast<int>(match[1].str().size() - dot - 1);
        found.push_back({*stamp, match[2].str() == "depth", item.path(), digits});
    }
    if (ec)
        return {ErrorCode::kIoError, dir.string() + ": cannot list: " + ec.message()};
    if (found.empty()) {
        return {ErrorCode::kNotFound, dir.string() +
                                          ": no frame_*_depth.tiff or "
                                          "frame_*_rgb.tiff files"};
    }
    std::sort(found.begin(), found.end(), [](const Found& a, const Found& b) {
        return a.stamp_ns != b.stamp_ns ? a.stamp_ns < b.stamp_ns : a.depth < b.depth;
    });

    // Colour first, then depth, as in TUM folders.
    std::vector<StreamInfo> streams;
    std::vector<detail::SequenceEntry> entries;
    for (const bool depth : {false, true}) {
        const auto stream = static_cast<uint32_t>(streams.size());
        uint64_t sequence = 0;
        int digits = 0;
        int64_t first = 0, last = 0;
        for (const Found& f : found) {
            if (f.depth != depth)
                continue;
            if (sequence == 0)
                first = f.stamp_ns;
            last = f.stamp_ns;
            digits = std::max(digits, f.digits);
            entries.push_back({f.stamp_ns, stream, sequence++, f.file, f.file.string()});
        }
        if (sequence == 0)
            continue;
        const PixelFormat format = depth ? PixelFormat::kDepth16 : PixelFormat::kRGB8;
        const auto& first_entry = entries[entries.size() - sequence];
        auto desc = detail::probeImage(first_entry.file, format, first_entry.where);
        if (!desc)
            return desc.status();
        StreamInfo info;
        info.name = depth ? "pcl/depth" : "pcl/color";
        info.device = "pcl";
        info.kind = depth ? StreamKind::kDepth : StreamKind::kColor;
        info.format = *desc;
        if (sequence >= 2 && last > first) {
            info.nominal_fps = std::round(static_cast<double>(sequence - 1) * 1e9 /
                                          static_cast<double>(last - first) * 1000.0) /
                               1000.0;
        }
        info.tags[kPclStampDigitsTag] = std::to_string(digits);
        streams.push_back(std::move(info));
    }
    detail::sortEntries(entries);
    // PCL's recorder stores OpenNI depth registered to the colour image (its grabber colours
    // point (u,v) with pixel (u,v)): say so, for point clouds with colour.
    if (streams.size() == 2 && streams[0].format.width == streams[1].format.width &&
        streams[0].format.height == streams[1].format.height) {
        for (StreamInfo& s : streams) {
            if (s.kind == StreamKind::kDepth)
                s.tags[kRegisteredToTag] = "pcl/color";
        }
    }

    std::sort(sidecars.begin(), sidecars.end());
    std::vector<Attachment> attachments;
    for (const auto& file : sidecars) {
        auto text = detail::readTextFile(file);
        if (!text)
            return text.status();
        // An empty file carries nothing, and Matroska cannot store an empty attachment.
        if (text->empty())
            continue;
        attachments.push_back(
            {file.filename().string(), "application/xml", {text->begin(), text->end()}});
    }
    std::map<std::string, std::string> tags = {{"source_format", "pcl-tiff"}};
    return std::unique_ptr<RecordingReader>(std::make_unique<detail::ImageSequenceReader>(
        "pcl-tiff", std::move(streams), std::move(attachments), std::move(tags), std::move(entries),
        options.buffers_per_stream));
}

Result<std::unique_ptr<RecordingWriter>> createPclTiffWriter(const std::filesystem::path& dir,
                                                             const RecordingHeader& header,
                                                             const PclTiffWriterOptions& options) {
    return PclTiffWriter::create(dir, header, options);
}

Result<WriteLosses> pclTiffLosses(const RecordingHeader& header,
                                  const PclTiffWriterOptions& options) {
    auto picked = detail::pickColorAndDepth(header, options.color_stream, options.depth_stream,
                                            "PCL TIFF writer");
    if (!picked)
        return picked.status();
    const auto keeps = [](const std::string& name) {
        return endsWith(name, ".xml") && name.find('/') == std::string::npos;
    };
    return detail::folderWriterLosses(header, *picked, "PCL TIFF", "pcl/color", "pcl/depth", keeps,
                                      "*.xml camera files");
}

Result<ConvertSummary> exportPclTiff(RecordingReader& reader, const std::filesystem::path& dir,
                                     const PclTiffWriterOptions& options) {
    auto writer = createPclTiffWriter(dir, headerOf(reader), options);
    if (!writer)
        return writer.status();
    return convertRecording(reader, **writer);
}

}  // namespace mixray::replay
