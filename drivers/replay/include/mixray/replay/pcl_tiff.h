// PCL OpenNI TIFF sequences (pcl::ImageGrabber's folders) as mixray recordings.
//
// Layout, one pair per capture:
//   frame_<YYYYMMDDTHHMMSS.ffffff>_depth.tiff   16-bit grey, millimetres (0 = no measurement)
//   frame_<YYYYMMDDTHHMMSS.ffffff>_rgb.tiff     8-bit RGB
//   frame_<YYYYMMDDTHHMMSS.ffffff>.xml          optional intrinsics sidecar, kept verbatim
// The name's timestamp is UTC with microseconds (PCL writes 6 digits; 1 to 9 are accepted).
#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <string_view>

#include "mixray/graph/recording.h"
#include "mixray/replay/convert.h"

namespace mixray::replay {

// Stream tag holding the fractional digits of the file names' timestamps.
inline constexpr const char* kPclStampDigitsTag = "pcl_stamp_digits";

// "20121214T142255.814212" (UTC) to nanoseconds since the Unix epoch, exactly.
// kCorruptData for anything else (bad digits, invalid date, more than 9 fractional digits, a
// time 64-bit nanoseconds do not hold: before 1677-09-21T00:12:44 or after
// 2262-04-11T23:47:16.854775807).
Result<int64_t> parsePclStamp(std::string_view text);
// Nanoseconds since the epoch to "YYYYMMDDTHHMMSS.fff..." with `digits` (0..9) fractional
// digits (none and no dot when 0), truncating.
std::string formatPclStamp(int64_t stamp_ns, int digits);

struct PclTiffReaderOptions {
    size_t buffers_per_stream = 8;  // frames of one stream a consumer may hold at once
};

// Opens a PCL TIFF folder as a RecordingReader (format "pcl-tiff") with streams "pcl/color"
// (kColor, rgb8) and "pcl/depth" (kDepth, depth16 mm), each present when such files are.
// Frames come in timestamp order, colour before depth at equal stamps; host and device stamps
// both hold the name's timestamp. Every *.xml file in the folder becomes an attachment
// (application/xml). Errors name the file: bad name, wrong bit depth, size changing.
Result<std::unique_ptr<RecordingReader>> openPclTiff(const std::filesystem::path& dir,
                                                     const PclTiffReaderOptions& options = {});

struct PclTiffWriterOptions {
    // Which streams become _rgb.tiff and _depth.tiff: full or short names. Empty: the first
    // kColor stream (rgb8, bgr8 or mjpeg) and the first kDepth16 stream.
    std::string color_stream;
    std::string depth_stream;
};

// Creates a PCL TIFF folder at `dir` (must not exist or be empty). Files are named by each
// frame's host stamp (the stream's pcl_stamp_digits, default 6; 9 when a stamp has sub-µs
// parts, so nothing is rounded). Depth is written in mm: depth in other units (TUM's 5000/m)
// is rounded to mm. Attachments named *.xml are written back verbatim; others are ignored.
Result<std::unique_ptr<RecordingWriter>> createPclTiffWriter(
    const std::filesystem::path& dir, const RecordingHeader& header,
    const PclTiffWriterOptions& options = {});

// What createPclTiffWriter(dir, header, options) would not store (streams other than the
// chosen colour and depth, attachments other than *.xml) or would change (stream names, tags,
// device stamps). Errors as createPclTiffWriter's for a header it cannot write at all.
Result<WriteLosses> pclTiffLosses(const RecordingHeader& header,
                                  const PclTiffWriterOptions& options = {});

// Writes every frame `reader` has left into a new PCL TIFF folder.
Result<ConvertSummary> exportPclTiff(RecordingReader& reader, const std::filesystem::path& dir,
                                     const PclTiffWriterOptions& options = {});

}  // namespace mixray::replay
