// Recognising a recording by its content and opening it with the right reader.
#include "mixray/replay/open_recording.h"

#include <fstream>
#include <system_error>

#include "mixray/graph/mkv.h"
#include "mixray/replay/pcl_tiff.h"
#include "mixray/replay/tum.h"

namespace mixray::replay {
namespace {

constexpr const char* kFormatsUnderstood =
    "formats understood: a Matroska file (.mkv, written by mixray or the Azure Kinect "
    "recorder); a TUM RGB-D folder (rgb.txt and/or depth.txt with rgb/ and depth/); a PCL "
    "OpenNI TIFF folder (frame_<YYYYMMDDTHHMMSS.ffffff>_depth.tiff / _rgb.tiff)";

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

Result<std::unique_ptr<RecordingReader>> openRecording(const std::filesystem::path& path,
                                                       const OpenRecordingOptions& options) {
    std::error_code ec;
    const auto status = std::filesystem::status(path, ec);
    if (!std::filesystem::exists(status)) {
        return {ErrorCode::kNotFound, path.string() + ": no such file or folder"};
    }
    Result<std::unique_ptr<RecordingReader>> reader =
        Status(ErrorCode::kUnsupported, path.string() + ": not a recording; " + kFormatsUnderstood);
    if (std::filesystem::is_directory(status)) {
        if (std::filesystem::exists(path / "rgb.txt", ec) ||
            std::filesystem::exists(path / "depth.txt", ec)) {
            reader = openTum(path, {options.buffers_per_stream});
        } else if (hasPclFrames(path)) {
            reader = openPclTiff(path, {options.buffers_per_stream});
        } else {
            return reader;
        }
    } else if (looksLikeMatroska(path)) {
        reader = openMkv(path, {options.buffers_per_stream});
    } else {
        return reader;
    }
    if (!reader)
        return reader.status().withContext("opening recording " + path.string());
    return reader;
}

}  // namespace mixray::replay
