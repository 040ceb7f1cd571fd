// Copying a recording from any reader into any writer (mkv, TUM folder, PCL TIFF folder).
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "mixray/graph/recording.h"

namespace mixray::replay {

// The header a writer needs to reproduce `reader`: its streams, attachments and tags.
RecordingHeader headerOf(const RecordingReader& reader);

// What a target format cannot hold of a recording, found from its header before anything is
// written, so a conversion can refuse or say it (never drop data without a word).
struct WriteLosses {
    // Streams whose frames the format does not store, indexed like header.streams.
    std::vector<StreamId> dropped_streams;
    // Data left out, one line each: streams (with why) and attachments.
    std::vector<std::string> dropped;
    // What is kept but changed: stream names read back differently, tags, device stamps.
    std::vector<std::string> changed;
    bool dropsData() const { return !dropped.empty(); }
};

// Where a conversion stands, passed to the progress callback after every frame.
struct ConvertProgress {
    uint64_t frames = 0;         // frames copied so far
    int64_t stamp_ns = 0;        // host stamp of the last frame copied
    uint64_t bytes_written = 0;  // writer's bytesWritten()
};

// Return false to stop the conversion (convertRecording then fails with kCancelled).
using ConvertProgressCallback = std::function<bool(const ConvertProgress&)>;

// What a conversion did.
struct ConvertSummary {
    uint64_t frames = 0;                      // frames copied
    std::vector<uint64_t> frames_per_stream;  // indexed like reader.streams()
    int64_t first_stamp_ns = 0;               // host stamps of the first and last frame
    int64_t last_stamp_ns = 0;
    uint64_t bytes_written = 0;  // after close()
    double seconds = 0;          // wall time taken
    // With InputDamage::kKeepWhatWasRead: the reader's error when the input ended in damage
    // (a cut-off file: kCorruptData naming it and the frames read); ok otherwise.
    Status input;
    // Damaged stretches the reader skipped and read past (RecordingReader::damage()): their
    // frames are not in the output. The one it never read past is `input`'s.
    std::vector<RecordingDamage> damage;
    // The output holds less than the input was meant to: it ended in damage or skipped some.
    bool partial() const { return !input || !damage.empty(); }
};

// What convertRecording does when the reader fails midway (kCorruptData: a cut-off file).
enum class InputDamage {
    kFail,             // return the error (the output is closed, holding what was copied)
    kKeepWhatWasRead,  // close the output and return the summary, the error in `input`
};

// Copies every frame `reader` has left (from its current position) into `writer` and closes
// the writer. `writer` must have been created with headerOf(reader) (stream ids are passed
// through unchanged). Waits briefly and retries when the reader reports kUnavailable. Errors of
// the reader or writer are returned with the frame count reached; the writer is closed then
// too, so what was copied stays readable (`on_damage` may keep a reader's kCorruptData as the
// summary's `input` instead). Does not take ownership of either.
Result<ConvertSummary> convertRecording(RecordingReader& reader, RecordingWriter& writer,
                                        const ConvertProgressCallback& progress = {},
                                        InputDamage on_damage = InputDamage::kFail);

}  // namespace mixray::replay
