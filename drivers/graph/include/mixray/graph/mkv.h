// Matroska recordings through FFmpeg's libavformat: mixray's own lossless session files, and
// other tools' Matroska recordings (Azure Kinect) read through the same interface.
#pragma once

#include <filesystem>
#include <memory>

#include "mixray/graph/recording.h"

namespace mixray {

struct MkvWriterOptions {
    // FFV1 slices per frame (more slices: more threads can encode/decode one frame).
    int ffv1_slices = 4;
    // Encoder threads per stream; 0 lets FFmpeg choose.
    int threads = 0;
    // Flush the file to the OS after every frame, so a crash loses at most the frame being
    // written. Costs a little throughput.
    bool flush_every_frame = true;
};

// Creates `path` (overwriting it) and writes the header: streams, attachments, tags.
// Depth, IR, mono, Bayer and raw colour are stored losslessly with FFV1 (16 bits kept
// exactly); MJPEG is stored as delivered; binary streams as opaque blocks. Every frame's
// metadata (sequence, device and host stamps in ns, clock domain, exposure, status) is stored
// with it exactly.
Result<std::unique_ptr<RecordingWriter>> createMkvWriter(const std::filesystem::path& path,
                                                         const RecordingHeader& header,
                                                         const MkvWriterOptions& options = {});

struct MkvReaderOptions {
    size_t buffers_per_stream = 8;  // frames of one stream a consumer may hold at once
};

// Opens a Matroska file written by mixray or by the Azure Kinect recorder (its COLOR, DEPTH,
// IR and IMU tracks, timestamps and calibration.json attachment). Errors name the file and
// what is wrong with it (missing, empty, not Matroska, no usable track).
Result<std::unique_ptr<RecordingReader>> openMkv(const std::filesystem::path& path,
                                                 const MkvReaderOptions& options = {});

}  // namespace mixray
