// Recordings as the graph sees them: a set of streams, their frames in time order, attached
// files. Formats (Matroska, TUM folders, ...) implement these interfaces.
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "mixray/graph/frame.h"
#include "mixray/graph/result.h"
#include "mixray/graph/stream.h"

namespace mixray {

// A file stored inside a recording (rig description, calibration, factory calibration JSON).
struct Attachment {
    std::string name;       // file name, no directories: "rig.yaml"
    std::string mime_type;  // "application/x-yaml", "application/json", ...
    std::vector<uint8_t> data;
    bool operator==(const Attachment&) const = default;
};

// A damaged stretch of a recording that a reader skipped to read on: where it is, and what
// the reader saw there.
struct RecordingDamage {
    int64_t byte_offset = -1;     // where the reader found it in the file; -1 unknown
    int64_t resumed_at = -1;      // the byte where it read frames again; -1 never
    int64_t after_stamp_ns = -1;  // host stamp of the last frame read before it; -1 none
    std::string what;             // the reader's description ("Invalid EBML number ...")
};

// Sequential reader of one recording. Frames come from pools the reader owns; StreamIds in
// frame metadata index streams(). Thread-bound.
class RecordingReader {
public:
    virtual ~RecordingReader() = default;

    // Short format name for messages: "mixray-mkv", "azure-kinect-mkv", "tum", ...
    virtual std::string format() const = 0;
    virtual const std::vector<StreamInfo>& streams() const = 0;
    virtual const std::vector<Attachment>& attachments() const = 0;
    // Recording-level metadata (title, software, device serials, ...).
    virtual const std::map<std::string, std::string>& tags() const = 0;

    // The next frame in recording order (host_stamp_ns non-decreasing across the file).
    // kEndOfStream after the last frame. kCorruptData when the rest of the file cannot be read
    // (a truncated file): every frame returned before it was complete and exact.
    // kUnavailable when all of a stream's buffers are still held by consumers: release some
    // and call again.
    virtual Result<FrameRef> next() = 0;

    // Positions the reader so that next() returns, for every stream, the first frame whose
    // host_stamp_ns >= stamp_ns.
    virtual Status seek(int64_t host_stamp_ns) = 0;

    // Damage found so far and read past (frames in it are lost). Readers that stop at the
    // first damage (next() returns kCorruptData) report none here.
    virtual std::vector<RecordingDamage> damage() const { return {}; }
};

// What a writer is asked to store besides frames.
// Recording tag: UTC minus the host clock, in ns, at the start of recording (decimal), so a
// frame's host_stamp_ns maps to UTC (the sun's position needs the time of day).
inline constexpr std::string_view kUtcMinusHostTag = "utc_minus_host_ns";

struct RecordingHeader {
    std::vector<StreamInfo> streams;  // frame.meta().stream indexes this list
    std::vector<Attachment> attachments;
    std::map<std::string, std::string> tags;
};

// Sequential writer of one recording. Thread-bound.
class RecordingWriter {
public:
    virtual ~RecordingWriter() = default;
    // Appends one frame of header.streams[frame.meta().stream]. Frames of one stream must come
    // in non-decreasing host_stamp_ns.
    virtual Status write(const FrameRef& frame) = 0;
    // Appends `frame` as a frame of header.streams[stream], whatever frame.meta().stream says:
    // for writers fed a subset of a graph's streams, whose graph ids differ from the header's
    // indices (published frames are immutable, so the id cannot be rewritten). Writers that
    // cannot remap accept only stream == frame.meta().stream.
    virtual Status writeAs(StreamId stream, const FrameRef& frame) {
        if (frame && stream == frame.meta().stream)
            return write(frame);
        return {ErrorCode::kUnsupported, "this recording writer cannot remap stream ids"};
    }
    // Finishes the file (index, durations). A writer destroyed without close() leaves a file
    // that is still readable up to its last complete frame.
    virtual Status close() = 0;
    // Bytes written to disk so far.
    virtual uint64_t bytesWritten() const = 0;
};

}  // namespace mixray
