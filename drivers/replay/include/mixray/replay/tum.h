// TUM RGB-D benchmark folders (rgb/, depth/, rgb.txt, depth.txt) as mixray recordings.
//
// Layout (https://cvg.cit.tum.de/data/datasets/rgbd-dataset/file_formats):
//   rgb.txt, depth.txt   "# comment" lines, then "timestamp filename" lines; timestamps are
//                        seconds with a fractional part ("1305031102.175304")
//   rgb/*.png            8-bit RGB
//   depth/*.png          16-bit grey, 5000 units per metre (0 = no measurement)
//   accelerometer.txt, groundtruth.txt   optional; kept verbatim as attachments
//
// Timestamps are parsed from their decimal text straight to integer nanoseconds (no double on
// the way), so they survive any number of conversions exactly. Depth keeps the raw PNG values
// in a kDepth16 stream tagged depth_scale_per_m=5000 (see depth_units.h): mm would lose the
// 0.2 mm steps, and the PNG values must come back bit-exactly.
#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "mixray/graph/recording.h"
#include "mixray/replay/convert.h"

namespace mixray::replay {

// Stream tags a TUM reader sets and the TUM writer honours.
inline constexpr const char* kTumStampDigitsTag = "tum_stamp_digits";  // fractional digits
inline constexpr const char* kTumHeaderTag = "tum_header";             // the list's comment lines

// One "timestamp filename" line of a TUM list file.
struct TumListEntry {
    int64_t stamp_ns = 0;
    std::string file;  // relative to the folder: "rgb/1305031102.175304.png"
    int line = 0;      // 1-based line in the list file, for messages
};

// A parsed rgb.txt / depth.txt. Plain value.
struct TumList {
    std::vector<std::string> comments;  // the "# ..." lines, '#' included, in order
    std::vector<TumListEntry> entries;  // in file order; stamps never decrease
    int stamp_digits = 0;               // most fractional digits any timestamp had
};

// Parses a TUM timestamp ("1305031102.175304", "12", "0.5") into nanoseconds exactly.
// kCorruptData for signs, exponents, more than 9 fractional digits or overflow.
Result<int64_t> parseTumStamp(std::string_view text);

// Formats nanoseconds as TUM seconds with `digits` fractional digits (0..9); the result
// parses back to the same value when the stamp is a multiple of 10^(9 - digits) ns.
std::string formatTumStamp(int64_t stamp_ns, int digits);

// Parses the text of a list file; `file_name` only labels messages ("rgb.txt:7: ...").
// kCorruptData names the file and line of the first malformed line: wrong field count, bad
// timestamp, timestamps going backwards, an absolute path or one leaving the folder.
Result<TumList> parseTumList(std::string_view text, std::string_view file_name);

struct TumReaderOptions {
    size_t buffers_per_stream = 8;  // frames of one stream a consumer may hold at once
};

// Opens a TUM folder as a RecordingReader (format "tum") with streams "tum/color" (kColor,
// rgb8) and "tum/depth" (kDepth, depth16 in raw TUM units, tagged depth_scale_per_m=5000),
// each present when its list file is. Frame host and device stamps both hold the list's
// timestamp (one clock, kHostClockDomain); sequence is the index in the list. Checks at open
// that every listed image exists and that the first of each list decodes with the right bit
// depth; later images are checked as they are read (kCorruptData with list file:line).
Result<std::unique_ptr<RecordingReader>> openTum(const std::filesystem::path& dir,
                                                 const TumReaderOptions& options = {});

struct TumWriterOptions {
    // Which streams become rgb/ and depth/: full or short names ("tum/color", "color").
    // Empty: the first kColor stream (rgb8, bgr8 or mjpeg) and the first kDepth16 stream.
    std::string color_stream;
    std::string depth_stream;
};

// Creates a TUM folder at `dir` (which must not exist or be empty) and returns a writer for
// recordings described by `header`. Frames of the chosen colour and depth streams become PNGs
// named by their host stamp; frames of other streams are ignored. Depth is written in 5000
// units per metre: raw TUM depth as is, mm multiplied by 5 (a write fails when a value exceeds
// 16 bits, i.e. beyond 13.107 m). Attachments named accelerometer.txt and groundtruth.txt are
// written back verbatim; others are ignored. List files are flushed after every frame, so a
// writer destroyed without close() leaves a readable folder.
Result<std::unique_ptr<RecordingWriter>> createTumWriter(const std::filesystem::path& dir,
                                                         const RecordingHeader& header,
                                                         const TumWriterOptions& options = {});

// What createTumWriter(dir, header, options) would not store (streams other than the chosen
// colour and depth, attachments other than the side files) or would change (stream names,
// tags, device stamps). Errors as createTumWriter's for a header it cannot write at all.
Result<WriteLosses> tumLosses(const RecordingHeader& header, const TumWriterOptions& options = {});

// Writes every frame `reader` has left (from its current position) into a new TUM folder.
// Equivalent to createTumWriter(dir, headerOf(reader)) + convertRecording().
Result<ConvertSummary> exportTum(RecordingReader& reader, const std::filesystem::path& dir,
                                 const TumWriterOptions& options = {});

}  // namespace mixray::replay
