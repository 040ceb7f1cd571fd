// Reading a recording frame by frame (recording_frames.h).
#include "recording_frames.h"

#include <chrono>
#include <thread>

namespace mixray::cli {

Result<std::optional<FrameRef>> nextFrame(RecordingReader& reader) {
    while (true) {
        auto frame = reader.next();
        if (frame)
            return std::optional<FrameRef>(std::move(frame).value());
        if (frame.status().code() == ErrorCode::kEndOfStream)
            return std::optional<FrameRef>();
        if (frame.status().code() != ErrorCode::kUnavailable)
            return frame.status();
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
}

}  // namespace mixray::cli
