// Reading a recording frame by frame in a command's loop.
#pragma once

#include <optional>

#include "mixray/graph/frame.h"
#include "mixray/graph/recording.h"
#include "mixray/graph/result.h"

namespace mixray::cli {

// The next frame in recording order: waits a millisecond at a time while the command still holds
// every buffer of a stream (kUnavailable); nullopt after the last frame; the reader's error (a
// truncated or corrupt file) otherwise.
Result<std::optional<FrameRef>> nextFrame(RecordingReader& reader);

}  // namespace mixray::cli
