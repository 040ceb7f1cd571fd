// Graph frames in their DDS wire form (mixray_msgs/msg/Frame as CDR), for tests, fuzzing and
// benchmarks: the publisher and the dds backend convert the same way.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "mixray/graph/frame.h"
#include "mixray/graph/image.h"
#include "mixray/graph/result.h"
#include "mixray/graph/stream.h"

namespace mixray::dds {

// `meta` and `image` as the publisher puts them on the wire: a mixray_msgs/msg/Frame in CDR
// with its 4-byte encapsulation header. Stream and graph stamp are not sent (the topic names
// the stream; the graph stamp is the receiving graph's).
std::vector<uint8_t> serializeFrame(const FrameMetadata& meta, const ImageView& image);

// Reads serialized bytes back as a frame of `stream`, as the dds backend accepts frames:
// kCorruptData saying what is wrong when the bytes are not a Frame message, or when the frame
// does not fit the stream (pixel format, size, stride, payload length, status). Never throws.
Status deserializeFrame(std::span<const uint8_t> bytes, const StreamInfo& stream,
                        FrameMetadata* meta, Image* image);

}  // namespace mixray::dds
