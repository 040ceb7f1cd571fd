// Graph frames, announcements and clock exchanges in their DDS wire form (mixray_msgs in CDR),
// for tests, fuzzing and benchmarks: the publisher and the dds backend convert the same way.
#pragma once

#include <cstdint>
#include <span>
#include <string>
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

// A stream's announcement as the publisher puts it on the wire (mixray_msgs/msg/
// StreamAnnouncement in CDR), and read back as the dds backend accepts announcements:
// kCorruptData saying what is wrong. Never throws.
std::vector<uint8_t> serializeAnnouncement(const StreamInfo& stream, const std::string& host);
Result<StreamInfo> deserializeAnnouncement(std::span<const uint8_t> bytes);

// One clock exchange between two hosts (mixray_msgs/msg/TimeExchange): a request carries t1,
// the answer the same fields with t2 and t3 (mixray/dds/host_clock.h).
struct TimeExchange {
    std::string requester;
    std::string responder;
    uint64_t sequence = 0;
    int64_t t1_ns = 0;
    int64_t t2_ns = 0;
    int64_t t3_ns = 0;
    uint32_t protocol = 0;
    int64_t realtime_minus_monotonic_ns = 0;
    bool ptp_locked = false;
    std::string ptp_grandmaster;
};

// In CDR as the hosts send it, and read back as they accept it: kCorruptData when the bytes
// are not a TimeExchange, or a name in it holds a NUL. Never throws.
std::vector<uint8_t> serializeTimeExchange(const TimeExchange& exchange);
Result<TimeExchange> deserializeTimeExchange(std::span<const uint8_t> bytes);

}  // namespace mixray::dds
