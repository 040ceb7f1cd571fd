// Synthetic streams and frames for the recording tests, and exact comparison of frames.
#pragma once

#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "mixray/graph/frame.h"
#include "mixray/graph/recording.h"
#include "mixray/graph/stream.h"

namespace mixray::test {

// A real 16x8 baseline JPEG (made with FFmpeg's encoder), for MJPEG streams that tools decode.
const std::vector<uint8_t>& tinyJpeg();

StreamInfo makeStream(const std::string& name, PixelFormat format, int width, int height);
// One stream per pixel format, small sizes, some odd, one with padded rows.
std::vector<StreamInfo> everyFormatStreams();
// A header over `streams` with two attachments and a few awkward tags.
RecordingHeader makeHeader(std::vector<StreamInfo> streams);

// A frame of `info` with deterministic content depending on `seed` (full value range for
// 16-bit formats, variable sizes for MJPEG and binary). Owns its pool.
FrameRef makeFrame(const StreamInfo& info, const FrameMetadata& meta, uint32_t seed);

// What a reader must return for one written frame.
struct ExpectedFrame {
    FrameRef frame;
    FrameMetadata meta;
};

// Exact equality of metadata and payload (rows only for images).
void expectSameFrame(const FrameRef& got, const ExpectedFrame& want, const std::string& where);
::testing::AssertionResult sameFrame(const FrameRef& got, const ExpectedFrame& want);
void expectSameStreams(const std::vector<StreamInfo>& got, const std::vector<StreamInfo>& want);

// Writes `header` and `frames_per_stream` frames per stream, interleaved in host-stamp order,
// and returns what was written. `offsets`, when given, receives the file size after each frame.
std::vector<ExpectedFrame> writeRecording(const std::filesystem::path& path,
                                          const RecordingHeader& header, int frames_per_stream,
                                          std::vector<uint64_t>* offsets = nullptr,
                                          uint64_t* header_bytes = nullptr);

// A private copy of `frame` in its own pool, same metadata.
FrameRef copyFrame(const FrameRef& frame);

// Reads every frame (as copies) until a non-ok result; `end` receives that result's status.
std::vector<FrameRef> readAll(RecordingReader& reader, Status* end);

}  // namespace mixray::test
