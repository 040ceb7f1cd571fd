// Opening any recording mixray can replay, recognised by its content rather than its name.
#pragma once

#include <cstddef>
#include <filesystem>
#include <memory>

#include "mixray/graph/recording.h"

namespace mixray::replay {

struct OpenRecordingOptions {
    size_t buffers_per_stream = 8;  // frames of one stream a consumer may hold at once
};

// Opens `path` as:
//   a directory with rgb.txt or depth.txt          -> TUM RGB-D folder (openTum)
//   a directory with frame_*_depth/_rgb.tiff files -> PCL OpenNI TIFF folder (openPclTiff)
//   a file                                         -> Matroska (openMkv): mixray's own
//                                                     recordings and Azure Kinect ones
// kNotFound when `path` does not exist; kUnsupported listing these formats when a directory
// matches none of them. The format's own errors are returned with the path as context.
Result<std::unique_ptr<RecordingReader>> openRecording(const std::filesystem::path& path,
                                                       const OpenRecordingOptions& options = {});

}  // namespace mixray::replay
