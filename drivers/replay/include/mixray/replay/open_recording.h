// Opening any recording mixray can replay, recognised by its content rather than its name.
#pragma once

#include <cstddef>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>

#include "mixray/graph/recording.h"

namespace mixray::replay {

struct OpenRecordingOptions {
    size_t buffers_per_stream = 8;  // frames of one stream a consumer may hold at once
};

// A recording format read by a library the replay driver does not link (a device backend's own
// file format, such as OpenNI's .oni through the openni2 backend). apps/ registers them.
struct RecordingFormat {
    std::string name;         // "oni"
    std::string description;  // for the "formats understood" message: "an OpenNI .oni file"
    // Whether `path` is of this format, by its content (cheap: a magic number).
    std::function<bool(const std::filesystem::path& path)> recognises;
    std::function<Result<std::unique_ptr<RecordingReader>>(const std::filesystem::path& path,
                                                           const OpenRecordingOptions& options)>
        open;
};

// Adds `format` to those openRecording() tries before its own file formats; a format of the
// same name is replaced. Thread-safe.
void registerRecordingFormat(RecordingFormat format);

// Opens `path` as:
//   a directory with rgb.txt or depth.txt          -> TUM RGB-D folder (openTum)
//   a directory with intrinsics.txt, depth/*.png and image/ -> SUN RGB-D frame (openSunRgbd)
//   a directory with d-<s>.<f>-<n>.pgm files       -> NYU Depth V2 raw scene (openNyuRaw)
//   a directory with frame_*_depth/_rgb.tiff files -> PCL OpenNI TIFF folder (openPclTiff)
//   a file a registered format recognises          -> that format (.oni with the openni2 backend)
//   a file                                         -> Matroska (openMkv): mixray's own
//                                                     recordings and Azure Kinect ones
// kNotFound when `path` does not exist; kUnsupported listing these formats when a path
// matches none of them. The format's own errors are returned with the path as context.
Result<std::unique_ptr<RecordingReader>> openRecording(const std::filesystem::path& path,
                                                       const OpenRecordingOptions& options = {});

}  // namespace mixray::replay
