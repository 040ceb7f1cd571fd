// NYU Depth V2 raw and SUN RGB-D folders: layout rules, content checks, depth to millimetres.
#include "mixray/replay/rgbd_datasets.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <iomanip>
#include <sstream>
#include <system_error>
#include <vector>

#include "image_files.h"
#include "mixray/replay/depth_units.h"
#include "mixray/replay/tum.h"

namespace mixray::replay {
namespace {

bool allDigits(std::string_view text) {
    return !text.empty() &&
           std::all_of(text.begin(), text.end(), [](char c) { return c >= '0' && c <= '9'; });
}

// "<prefix>-<digits>.<digits>-<digits><suffix>": the stamp text, or empty.
std::string_view nyuStampText(std::string_view name, char prefix, std::string_view suffix) {
    if (name.size() < suffix.size() + 6 || name[0] != prefix || name[1] != '-' ||
        name.substr(name.size() - suffix.size()) != suffix) {
        return {};
    }
    const std::string_view middle = name.substr(2, name.size() - 2 - suffix.size());
    const size_t dash = middle.find('-');
    if (dash == std::string_view::npos || !allDigits(middle.substr(dash + 1)))
        return {};
    const std::string_view stamp = middle.substr(0, dash);
    const size_t dot = stamp.find('.');
    if (dot == std::string_view::npos || !allDigits(stamp.substr(0, dot)) ||
        !allDigits(stamp.substr(dot + 1))) {
        return {};
    }
    return stamp;
}

std::vector<std::filesystem::path> filesIn(const std::filesystem::path& dir) {
    std::vector<std::filesystem::path> files;
    std::error_code ec;
    for (const auto& item : std::filesystem::directory_iterator(dir, ec)) {
        if (item.is_regular_file(ec))
            files.push_back(item.path());
    }
    std::sort(files.begin(), files.end());
    return files;
}

bool hasExtension(const std::filesystem::path& file, std::initializer_list<const char*> exts) {
    std::string ext = file.extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    return std::any_of(exts.begin(), exts.end(), [&](const char* e) { return ext == e; });
}

StreamInfo makeStream(const std::string& device, const char* short_name, StreamKind kind,
                      const ImageDesc& desc, size_t frames, int64_t first, int64_t last) {
    StreamInfo info;
    info.name = device + "/" + short_name;
    info.device = device;
    info.kind = kind;
    info.format = desc;
    if (frames >= 2 && last > first) {
        info.nominal_fps = std::round(static_cast<double>(frames - 1) * 1e9 /
                                      static_cast<double>(last - first) * 1000.0) /
                           1000.0;
    }
    return info;
}

// Decodes `file` as a 16-bit image for a content check at open.
Result<Image> decodeDepth(const std::filesystem::path& file, const std::string& where) {
    auto desc = detail::probeImage(file, PixelFormat::kDepth16, where);
    if (!desc)
        return desc.status();
    Image image(*desc);
    MIXRAY_RETURN_IF_ERROR(detail::readImageInto(file, image.mutableView(), where));
    return image;
}

}  // namespace

PinholeIntrinsics nyuDepthIntrinsics() {
    return {582.62448167737955, 582.69103270988637, 313.04475870804731 - 1.0,
            238.44389626620386 - 1.0};
}

Result<int64_t> parseNyuFileName(std::string_view name) {
    std::string_view stamp = nyuStampText(name, 'd', ".pgm");
    if (stamp.empty())
        stamp = nyuStampText(name, 'r', ".ppm");
    if (stamp.empty()) {
        return {ErrorCode::kCorruptData,
                std::string(name) + ": not an NYU raw frame name (d-<s>.<f>-<n>.pgm, r-...ppm)"};
    }
    auto ns = parseTumStamp(stamp);
    if (!ns)
        return ns.status().withContext(std::string(name));
    return ns;
}

Result<PinholeIntrinsics> parseSunIntrinsics(std::string_view text, std::string_view file_name) {
    std::vector<double> values;
    size_t i = 0;
    while (i < text.size()) {
        while (i < text.size() && std::isspace(static_cast<unsigned char>(text[i])))
            ++i;
        size_t j = i;
        while (j < text.size() && !std::isspace(static_cast<unsigned char>(text[j])))
            ++j;
        if (j == i)
            break;
        double v = 0;
        auto [end, ec] = std::from_chars(text.data() + i, text.data() + j, v);
        if (ec != std::errc() || end != text.data() + j || values.size() == 9) {
            return {
                ErrorCode::kCorruptData,
                std::string(file_name) + ": expected 9 numbers (K = [fx 0 cx; 0 fy cy; 0 0 1])"};
        }
        values.push_back(v);
        i = j;
    }
    if (values.size() != 9 || values[1] != 0 || values[3] != 0 || values[6] != 0 ||
        values[7] != 0 || values[8] != 1) {
        return {ErrorCode::kCorruptData,
                std::string(file_name) + ": expected K = [fx 0 cx; 0 fy cy; 0 0 1] (9 numbers)"};
    }
    const PinholeIntrinsics k{values[0], values[4], values[2] - 1.0, values[5] - 1.0};
    Status valid = k.validate();
    if (!valid)
        return {ErrorCode::kCorruptData, std::string(file_name) + ": " + valid.message()};
    return k;
}

bool looksLikeNyuRaw(const std::filesystem::path& dir) {
    for (const auto& file : filesIn(dir)) {
        if (!nyuStampText(file.filename().string(), 'd', ".pgm").empty())
            return true;
    }
    return false;
}

bool looksLikeSunRgbd(const std::filesystem::path& dir) {
    std::error_code ec;
    if (!std::filesystem::is_regular_file(dir / "intrinsics.txt", ec) ||
        !std::filesystem::is_directory(dir / "image", ec) ||
        !std::filesystem::is_directory(dir / "depth", ec)) {
        return false;
    }
    for (const auto& file : filesIn(dir / "depth")) {
        if (hasExtension(file, {".png"}))
            return true;
    }
    return false;
}

Result<std::unique_ptr<RecordingReader>> openNyuRaw(const std::filesystem::path& dir,
                                                    const DatasetReaderOptions& options) {
    std::vector<detail::SequenceEntry> color, depth;
    for (const auto& file : filesIn(dir)) {
        const std::string name = file.filename().string();
        const bool is_depth = !nyuStampText(name, 'd', ".pgm").empty();
        const bool is_color = !nyuStampText(name, 'r', ".ppm").empty();
        if (!is_depth && !is_color)
            continue;
        auto stamp = parseNyuFileName(name);
        if (!stamp)
            return stamp.status().withContext(dir.string());
        auto& list = is_depth ? depth : color;
        list.push_back({*stamp, 0, 0, file, file.string()});
    }
    if (depth.empty()) {
        return {ErrorCode::kNotFound,
                dir.string() + ": no NYU raw depth file (d-<seconds>.<fraction>-<n>.pgm)"};
    }
    std::vector<StreamInfo> streams;
    std::vector<detail::SequenceEntry> entries;
    uint32_t depth_stream = 0;
    for (auto* list : {&color, &depth}) {
        if (list->empty())
            continue;
        const bool is_depth = list == &depth;
        std::sort(list->begin(), list->end(),
                  [](const auto& a, const auto& b) { return a.stamp_ns < b.stamp_ns; });
        const auto stream = static_cast<uint32_t>(streams.size());
        const auto& first = list->front();
        auto desc = detail::probeImage(
            first.file, is_depth ? PixelFormat::kDepth16 : PixelFormat::kRGB8, first.where);
        if (!desc)
            return desc.status();
        StreamInfo info = makeStream("nyu", is_depth ? "depth" : "color",
                                     is_depth ? StreamKind::kDepth : StreamKind::kColor, *desc,
                                     list->size(), first.stamp_ns, list->back().stamp_ns);
        if (is_depth) {
            info.tags[kIntrinsicsTag] = formatIntrinsics(nyuDepthIntrinsics());
            depth_stream = stream;
            // The content rule: the first depth image must be Kinect raw depth.
            auto image = decodeDepth(first.file, first.where);
            if (!image)
                return image.status();
            MIXRAY_RETURN_IF_ERROR(convertNyuRawToMm(image->mutableView(), first.where));
        }
        streams.push_back(std::move(info));
        uint64_t sequence = 0;
        for (auto& e : *list) {
            e.stream = stream;
            e.sequence = sequence++;
            entries.push_back(e);
        }
    }
    detail::sortEntries(entries);
    auto reader = std::make_unique<detail::ImageSequenceReader>(
        "nyu-raw", std::move(streams), std::vector<Attachment>{},
        std::map<std::string, std::string>{}, std::move(entries), options.buffers_per_stream);
    reader->setPostDecode(depth_stream, [](const MutableImageView& image, std::string_view where) {
        return convertNyuRawToMm(image, where);
    });
    return std::unique_ptr<RecordingReader>(std::move(reader));
}

Result<std::unique_ptr<RecordingReader>> openSunRgbd(const std::filesystem::path& dir,
                                                     const DatasetReaderOptions& options) {
    const auto intrinsics_file = dir / "intrinsics.txt";
    auto text = detail::readTextFile(intrinsics_file);
    if (!text)
        return text.status();
    auto k = parseSunIntrinsics(*text, intrinsics_file.string());
    if (!k)
        return k.status();
    const auto pick =
        [&](const char* sub,
            std::initializer_list<const char*> exts) -> Result<std::filesystem::path> {
        std::vector<std::filesystem::path> found;
        for (const auto& file : filesIn(dir / sub)) {
            if (hasExtension(file, exts))
                found.push_back(file);
        }
        if (found.size() != 1) {
            return Status(ErrorCode::kCorruptData,
                          (dir / sub).string() + ": expected one image, found " +
                              std::to_string(found.size()) + " (a SUN RGB-D folder is one frame)");
        }
        return found.front();
    };
    auto depth_file = pick("depth", {".png"});
    if (!depth_file)
        return depth_file.status();
    const std::string depth_where = depth_file->string();
    auto depth = decodeDepth(*depth_file, depth_where);
    if (!depth)
        return depth.status();
    const double share = sunRotatedShare(depth->view());
    if (share < kSunMinRotatedShare) {
        std::ostringstream why;
        why << depth_where << ": not SUN RGB-D depth: only " << std::fixed << std::setprecision(1)
            << share * 100 << " % of its non-zero values have the low 3 bits clear (SUN RGB-D "
            << "stores mm rotated left by 3 bits, so nearly all do; plain mm would give ~12.5 %)";
        return {ErrorCode::kCorruptData, why.str()};
    }
    std::vector<StreamInfo> streams;
    std::vector<detail::SequenceEntry> entries;
    auto image_file = pick("image", {".jpg", ".jpeg", ".png"});
    if (!image_file)
        return image_file.status();
    auto color_desc = detail::probeImage(*image_file, PixelFormat::kRGB8, image_file->string());
    if (!color_desc)
        return color_desc.status();
    streams.push_back(makeStream("sun", "color", StreamKind::kColor, *color_desc, 1, 0, 0));
    entries.push_back({0, 0, 0, *image_file, image_file->string()});
    StreamInfo depth_info = makeStream("sun", "depth", StreamKind::kDepth, depth->desc(), 1, 0, 0);
    depth_info.tags[kIntrinsicsTag] = formatIntrinsics(*k);
    if (color_desc->width == depth->desc().width && color_desc->height == depth->desc().height)
        depth_info.tags[kRegisteredToTag] = "sun/color";
    streams.push_back(std::move(depth_info));
    entries.push_back({0, 1, 0, *depth_file, depth_where});
    std::vector<Attachment> attachments;
    if (!text->empty())
        attachments.push_back({"intrinsics.txt", "text/plain", {text->begin(), text->end()}});
    auto reader = std::make_unique<detail::ImageSequenceReader>(
        "sun-rgbd", std::move(streams), std::move(attachments),
        std::map<std::string, std::string>{}, std::move(entries), options.buffers_per_stream);
    reader->setPostDecode(1, [](const MutableImageView& image, std::string_view) {
        convertSunDepthToMm(image);
        return Status::ok();
    });
    return std::unique_ptr<RecordingReader>(std::move(reader));
}

}  // namespace mixray::replay
