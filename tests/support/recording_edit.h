// Copies a recording frame by frame into a new one, letting a test change chosen frames (their
// pixels, their status) as a driver or a damaged disk would have left them: the fault tests'
// inputs. Header-only: its users link mixray::driver_replay.
#pragma once

#include <gtest/gtest.h>

#include <filesystem>
#include <functional>
#include <map>
#include <string>

#include "mixray/graph/mkv.h"
#include "mixray/replay/open_recording.h"

namespace mixray::test {

// Calls `edit(stream, n, frame)` for every frame of `in`, n counting that stream's frames from 1,
// and writes what it leaves to `out` with `in`'s streams, attachments and tags. Failures are the
// test's (check HasFatalFailure()).
inline void copyRecordingEditing(
    const std::filesystem::path& in, const std::filesystem::path& out,
    const std::function<void(const std::string& stream, int n, WritableFrame& frame)>& edit) {
    auto reader = replay::openRecording(in);
    ASSERT_TRUE(reader.isOk()) << reader.status().toString();
    RecordingHeader header;
    header.streams = (*reader)->streams();
    header.attachments = (*reader)->attachments();
    header.tags = (*reader)->tags();
    auto writer = createMkvWriter(out, header);
    ASSERT_TRUE(writer.isOk()) << writer.status().toString();
    std::map<std::string, int> counts;
    while (true) {
        auto next = (*reader)->next();
        if (!next) {
            ASSERT_EQ(next.status().code(), ErrorCode::kEndOfStream) << next.status().toString();
            break;
        }
        FrameRef frame = std::move(next).value();
        const std::string& name = header.streams[frame.meta().stream].name;
        // Frame by frame: the reader's pools hold a few frames per stream.
        WritableFrame writable = WritableFrame::reclaim(frame);
        ASSERT_TRUE(writable) << "the reader kept a handle on its frame";
        edit(name, ++counts[name], writable);
        ASSERT_TRUE((*writer)->write(std::move(writable).publish()).isOk());
    }
    ASSERT_TRUE((*writer)->close().isOk());
}

}  // namespace mixray::test
