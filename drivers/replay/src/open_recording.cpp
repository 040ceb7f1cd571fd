// Recognising a recording by its content and opening it with the right reader.
#include "mixray/replay/open_recording.h"

#include <algorithm>
#include <fstream>
#include <mutex>
#include <system_error>
#include <vector>

#include "mixray/graph/mkv.h"
#include "mixray/replay/pcl_tiff.h"
#include "mixray/replay/rgbd_datasets.h"
#include "mixray/replay/tum.h"

namespace mixray::replay {
namespace {

constexpr const char* kFormatsUnderstood =
    "formats understood: a Matroska file (.mkv, written by mixray or the Azure Kinect "
    "recorder); a TUM RGB-D folder (rgb.txt and/or depth.txt with rgb/ and depth/); a SUN "
    "RGB-D frame folder (intrinsics.txt, image/, depth/); an NYU Depth V2 raw scene folder "
    "(d-<s>.<f>-<n>.pgm, r-...ppm); a PCL OpenNI TIFF folder "
    "(frame_<YYYYMMDDTHHMMSS.ffffff>_depth.tiff / _rgb.tiff)";

std::mutex& formatsMutex() {
    static std::mutex mutex;
    return mutex;
}
std::vector<RecordingFormat>& registeredFormats() {
    static std::vector<RecordingFormat> formats;
    return formats;
}

std::string formatsUnderstood() {
    std::string text = kFormatsUnderstood;
    std::lock_guard lock(formatsMutex());
    for (const auto& f : registeredFormats())
        text += "; " + f.description;
    return text;
}

// Matroska (like all EBML files) starts with the EBML header element's id.
bool looksLikeMatroska(const std::filesystem::path& file) {
    std::ifstream in(file, std::ios::binary);
    unsigned char magic[4] = {};
    in.read(reinterpret_cast<char*>(magic), sizeof(magic));
    return in.gcount() == 4 && magic[0] == 0x1A && magic[1] == 0x45 && magic[2] == 0xDF &&
           magic[3] == 0xA3;
}

bool hasPclFrames(const std::filesystem::path& dir) {
    std::error_code ec;
    for (const auto& item : std::filesystem::directory_iterator(dir, ec)) {
        const std::string name = item.path().filename().string();
        if (name.rfind("frame_", 0) != 0)
            continue;
        for (const char* suffix : {"_depth.tiff", "_rgb.tiff", "_depth.tif", "_rgb.tif"}) {
            const std::string_view s(suffix);
            if (name.size() > s.size() && name.compare(name.size() - s.size(), s.size(), s) == 0) {
                return true;
            }
        }
    }
    return false;
}

}  // namespace

void registerRecordingFormat(RecordingFormat format) {
    std::lock_guard lock(formatsMutex());
    auto& formats = registeredFormats();
    for (auto& f : formats) {
        if (f.name == format.name) {
            f = std::move(format);
            return;
        }
    }
    formats.push_back(std::move(format));
}

Result<std::unique_ptr<RecordingReader>> openRecording(const std::filesystem::path& path,
                                                       const OpenRecordingOptions& options) {
    std::error_code ec;
    const auto status = std::filesystem::status(path, ec);
    if (!std::filesystem::exists(status)) {
        return {ErrorCode::kNotFound, path.string() + ": no such file or folder"};
    }
    Result<std::unique_ptr<RecordingReader>> reader = Status(
        ErrorCode::kUnsupported, path.string() + ": not a recording; " + formatsUnderstood());
    if (std::filesystem::is_directory(status)) {
        if (std::filesystem::exists(path / "rgb.txt", ec) ||
            std::filesystem::exists(path / "depth.txt", ec)) {
            reader = openTum(path, {options.buffers_per_stream});
        } else if (looksLikeSunRgbd(path)) {
            reader = openSunRgbd(path, {options.buffers_per_stream});
        } else if (looksLikeNyuRaw(path)) {
            reader = openNyuRaw(path, {options.buffers_per_stream});
        } else if (hasPclFrames(path)) {
            reader = openPclTiff(path, {options.buffers_per_stream});
        } else {
            return reader;
        }
    } else if (looksLikeMatroska(path)) {
        reader = openMkv(path, {options.buffers_per_stream});
    } else {
        std::vector<RecordingFormat> formats;
        {
            std::lock_guard lock(formatsMutex());
            formats = registeredFormats();
        }
        auto it = std::find_if(formats.begin(), formats.end(), [&](const RecordingFormat& f) {
            return f.recognises && f.open && f.recognises(path);
        });
        if (it == formats.end())
            return reader;
        reader = it->open(path, options);
    }
    if (!reader)
        return reader.status().withContext("opening recording " + path.string());
    return reader;
}

}  // namespace mixray::replay
