// Copying every frame of a reader into a writer.
#include "mixray/replay/convert.h"

#include <chrono>
#include <thread>

namespace mixray::replay {
namespace {
// How long a conversion waits for buffers held elsewhere before giving up: the converter
// releases each frame at once, so only a reader shared with someone else can run dry.
constexpr auto kUnavailableTimeout = std::chrono::seconds(10);
}  // namespace

RecordingHeader headerOf(const RecordingReader& reader) {
    return {reader.streams(), reader.attachments(), reader.tags()};
}

Result<ConvertSummary> convertRecording(RecordingReader& reader, RecordingWriter& writer,
                                        const ConvertProgressCallback& progress,
                                        InputDamage on_damage) {
    using Clock = std::chrono::steady_clock;
    const auto t0 = Clock::now();
    ConvertSummary summary;
    summary.frames_per_stream.assign(reader.streams().size(), 0);
    const auto fail = [&](const Status& status) -> Result<ConvertSummary> {
        (void)writer.close();  // keep what was copied readable; the first error is the story
        return status.withContext("converting (" + reader.format() + ") after " +
                                  std::to_string(summary.frames) + " frames");
    };
    auto waiting_since = Clock::time_point::max();
    while (true) {
        auto frame = reader.next();
        if (!frame) {
            const ErrorCode code = frame.status().code();
            if (code == ErrorCode::kEndOfStream)
                break;
            if (code == ErrorCode::kCorruptData && on_damage == InputDamage::kKeepWhatWasRead) {
                summary.input = frame.status();
                break;
            }
            if (code == ErrorCode::kUnavailable) {
                const auto now = Clock::now();
                if (waiting_since == Clock::time_point::max())
                    waiting_since = now;
                if (now - waiting_since < kUnavailableTimeout) {
                    std::this_thread::sleep_for(std::chrono::milliseconds(1));
                    continue;
                }
            }
            return fail(frame.status());
        }
        waiting_since = Clock::time_point::max();
        const FrameMetadata& meta = frame->meta();
        if (meta.stream >= summary.frames_per_stream.size()) {
            return fail({ErrorCode::kInternal, "reader returned a frame of unknown stream " +
                                                   std::to_string(meta.stream)});
        }
        Status status = writer.write(*frame);
        if (!status)
            return fail(status);
        if (summary.frames == 0)
            summary.first_stamp_ns = meta.host_stamp_ns;
        summary.last_stamp_ns = meta.host_stamp_ns;
        ++summary.frames;
        ++summary.frames_per_stream[meta.stream];
        if (progress && !progress({summary.frames, meta.host_stamp_ns, writer.bytesWritten()})) {
            return fail({ErrorCode::kCancelled, "stopped by the progress callback"});
        }
    }
    // The stretch the reader never read past is the one `input` names already.
    for (RecordingDamage& d : reader.damage())
        if (summary.input || d.resumed_at >= 0)
            summary.damage.push_back(std::move(d));
    MIXRAY_RETURN_IF_ERROR(writer.close().withContext("closing the converted recording"));
    summary.bytes_written = writer.bytesWritten();
    summary.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
    return summary;
}

}  // namespace mixray::replay
