// OpenCV's custom ArUco dictionary files (marker_dictionary.h), read through cv::FileStorage as
// OpenCV's own readDictionary() reads them, but every field checked and named on error.
#include "mixray/calibration/marker_dictionary.h"

#include <algorithm>
#include <fstream>
#include <iterator>
#include <opencv2/core.hpp>
#include <string>
#include <system_error>

#include "file_storage_guard.h"

namespace mixray::calibration {
namespace {

// OpenCV's 1000-marker 7x7 dictionary takes 60 kB written out: 4 MiB is ample and bounds
// what a wrong file (an image, a video) costs before it is refused.
constexpr size_t kMaxFileBytes = 4u << 20;

Status corrupt(const std::string& file, std::string_view what) {
    return Status(ErrorCode::kCorruptData, file + ": " + std::string(what));
}

// The first of `keys` present in the root mapping; an empty node when none is.
cv::FileNode first(const cv::FileNode& root, std::initializer_list<const char*> keys,
                   std::string& found) {
    for (const char* key : keys) {
        cv::FileNode node = root[key];
        if (!node.empty()) {
            found = key;
            return node;
        }
    }
    return {};
}

Result<int> readInt(const std::string& file, const cv::FileNode& root,
                    std::initializer_list<const char*> keys, bool required, int min, int max) {
    std::string key = *keys.begin();
    const cv::FileNode node = first(root, keys, key);
    if (node.empty()) {
        if (required)
            return corrupt(file, key + ": missing (an integer)");
        return 0;
    }
    if (!node.isInt())
        return corrupt(file, key + ": expected an integer");
    const int value = static_cast<int>(node);
    if (value < min || value > max)
        return corrupt(file, key + ": " + std::to_string(value) + " is outside [" +
                                 std::to_string(min) + ", " + std::to_string(max) + "]");
    return value;
}

std::string nameFor(const std::string& file) {
    const std::string stem = std::filesystem::path(file).stem().string();
    return "custom:" + (stem.empty() ? std::string("dictionary") : stem);
}

}  // namespace

Status MarkerDictionary::validate() const {
    const auto invalid = [](std::string what) {
        return Status(ErrorCode::kInvalidArgument, "marker dictionary: " + std::move(what));
    };
    if (marker_size < 2 || marker_size > kMaxMarkerSize)
        return invalid("marker_size must be in [2, " + std::to_string(kMaxMarkerSize) + "], got " +
                       std::to_string(marker_size));
    if (markers.empty() || markers.size() > static_cast<size_t>(kMaxMarkers))
        return invalid("needs 1 to " + std::to_string(kMaxMarkers) + " markers, has " +
                       std::to_string(markers.size()));
    const int cells = marker_size * marker_size;
    if (max_correction_bits < 0 || max_correction_bits > cells)
        return invalid("max_correction_bits must be in [0, " + std::to_string(cells) + "], got " +
                       std::to_string(max_correction_bits));
    for (size_t i = 0; i < markers.size(); ++i) {
        const std::string& bits = markers[i];
        if (bits.size() != static_cast<size_t>(cells) ||
            !std::all_of(bits.begin(), bits.end(), [](char c) { return c == '0' || c == '1'; }))
            return invalid("marker_" + std::to_string(i) + " must be " + std::to_string(cells) +
                           " characters '0' or '1'");
    }
    return Status::ok();
}

Result<MarkerDictionary> parseMarkerDictionary(std::string_view text, const std::string& file) {
    if (text.empty())
        return corrupt(file,
                       "empty (expected an OpenCV dictionary: nmarkers, markersize, "
                       "marker_0 ...)");
    if (text.size() > kMaxFileBytes)
        return corrupt(file, "larger than " + std::to_string(kMaxFileBytes >> 20) +
                                 " MiB, too large for a marker dictionary");
    // cv::FileStorage reads a memory buffer as a C string.
    if (text.find('\0') != std::string_view::npos)
        return corrupt(file, "holds a NUL byte (not a text file)");
    if (const char* why = detail::crashesFileStorage(text))
        return corrupt(file, why);
    if (const char* why = detail::hangsFileStorageYaml(text))
        return corrupt(file, std::string(why) + ", which OpenCV's reader may never return from");
    MarkerDictionary dict;
    dict.name = nameFor(file);
    try {
        cv::FileStorage fs(std::string(text), cv::FileStorage::READ | cv::FileStorage::MEMORY);
        if (!fs.isOpened())
            return corrupt(file, "OpenCV's FileStorage cannot read it");
        const cv::FileNode root = fs.root();
        if (!root.isMap())
            return corrupt(file, "expected a mapping with nmarkers, markersize and marker_0 ...");
        auto count = readInt(file, root, {"nmarkers"}, true, 1, MarkerDictionary::kMaxMarkers);
        if (!count)
            return count.status();
        auto size = readInt(file, root, {"markersize", "marker_size"}, true, 2,
                            MarkerDictionary::kMaxMarkerSize);
        if (!size)
            return size.status();
        const int cells = *size * *size;
        auto correction =
            readInt(file, root, {"maxCorrectionBits", "max_correction_bits"}, false, 0, cells);
        if (!correction)
            return correction.status();
        dict.marker_size = *size;
        dict.max_correction_bits = *correction;
        dict.markers.reserve(static_cast<size_t>(*count));
        for (int i = 0; i < *count; ++i) {
            const std::string key = "marker_" + std::to_string(i);
            const cv::FileNode node = root[key];
            if (node.empty())
                return corrupt(file,
                               key + ": missing (nmarkers is " + std::to_string(*count) + ")");
            if (!node.isString())
                return corrupt(file, key + ": expected a quoted string of " +
                                         std::to_string(cells) + " '0'/'1' characters");
            std::string bits = static_cast<std::string>(node);
            if (bits.size() != static_cast<size_t>(cells))
                return corrupt(file, key + ": " + std::to_string(bits.size()) +
                                         " characters, markersize " + std::to_string(*size) +
                                         " needs " + std::to_string(cells));
            const auto bad =
                std::find_if(bits.begin(), bits.end(), [](char c) { return c != '0' && c != '1'; });
            if (bad != bits.end())
                return corrupt(file, key + ": character " + std::to_string(bad - bits.begin() + 1) +
                                         " is not '0' or '1'");
            dict.markers.push_back(std::move(bits));
        }
    } catch (const cv::Exception& e) {
        return corrupt(file, "OpenCV's FileStorage: " + e.msg);
    }
    if (Status s = dict.validate(); !s)
        return corrupt(file, s.message());
    return dict;
}

Result<MarkerDictionary> readMarkerDictionary(const std::filesystem::path& path) {
    std::error_code ec;
    const auto bytes = std::filesystem::file_size(path, ec);
    if (ec)
        return Status(ErrorCode::kNotFound, path.string() + ": " + ec.message());
    if (bytes > kMaxFileBytes)
        return corrupt(path.string(), "larger than " + std::to_string(kMaxFileBytes >> 20) +
                                          " MiB, too large for a marker dictionary");
    std::ifstream in(path, std::ios::binary);
    if (!in)
        return Status(ErrorCode::kNotFound, path.string() + ": cannot be opened");
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    return parseMarkerDictionary(text, path.string());
}

std::string markerDictionaryYaml(const MarkerDictionary& dictionary) {
    std::string out = "%YAML:1.0\n---\n";
    out += "nmarkers: " + std::to_string(dictionary.markers.size()) + "\n";
    out += "markersize: " + std::to_string(dictionary.marker_size) + "\n";
    out += "maxCorrectionBits: " + std::to_string(dictionary.max_correction_bits) + "\n";
    for (size_t i = 0; i < dictionary.markers.size(); ++i)
        out += "marker_" + std::to_string(i) + ": \"" + dictionary.markers[i] + "\"\n";
    return out;
}

}  // namespace mixray::calibration
