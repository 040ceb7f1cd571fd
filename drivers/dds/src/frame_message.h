// Conversions between graph frames and streams and their mixray_msgs messages, and the DDS
// types that carry them. Internal to drivers/dds.
#pragma once

#include <fastdds/rtps/common/SerializedPayload.h>

#include <cstring>
#include <fastdds/dds/topic/TypeSupport.hpp>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "mixray/dds/frame_message.h"
#include "mixray/graph/frame.h"
#include "mixray/graph/result.h"
#include "mixray/graph/stream.h"
#include "mixray_msgs/msg/FramePubSubTypes.h"
#include "mixray_msgs/msg/StreamAnnouncementPubSubTypes.h"
#include "mixray_msgs/msg/TimeExchangePubSubTypes.h"

namespace mixray::dds::detail {

using FrameMessage = mixray_msgs::msg::dds_::Frame_;
using AnnouncementMessage = mixray_msgs::msg::dds_::StreamAnnouncement_;
using TimeExchangeMessage = mixray_msgs::msg::dds_::TimeExchange_;

// A generated type whose deserialize() survives any bytes: fastcdr throws more exceptions than
// the generated code catches (a bad encapsulation, an impossible length), and a throw from a
// DDS receive thread would end the process. Every topic mixray reads uses one of these.
template <typename Generated>
class GuardedType : public Generated {
public:
    bool deserialize(eprosima::fastrtps::rtps::SerializedPayload_t* payload, void* data) override {
        try {
            return Generated::deserialize(payload, data);
        } catch (...) {
            return false;
        }
    }
};

// A message in CDR with its encapsulation header, as a writer of `Type` sends it.
template <typename Type, typename Message>
std::vector<uint8_t> serializeSample(Message& message) {
    Type type;
    eprosima::fastrtps::rtps::SerializedPayload_t payload(
        type.getSerializedSizeProvider(&message)());
    type.serialize(&message, &payload);
    return {payload.data, payload.data + payload.length};
}

// What a reader of a `Type` topic does with the bytes of a sample: false for bytes that are not
// one. Never throws.
template <typename Type, typename Message>
bool deserializeSample(std::span<const uint8_t> bytes, Message* message) {
    GuardedType<Type> type;
    eprosima::fastrtps::rtps::SerializedPayload_t payload(static_cast<uint32_t>(bytes.size()));
    if (!bytes.empty())
        std::memcpy(payload.data, bytes.data(), bytes.size());
    payload.length = static_cast<uint32_t>(bytes.size());
    return type.deserialize(&payload, message);
}

// The topic type of frames and of announcements (type names as mixray_msgs puts them on the
// wire: "mixray_msgs::msg::dds_::Frame_").
eprosima::fastdds::dds::TypeSupport frameType();
eprosima::fastdds::dds::TypeSupport announcementType();
eprosima::fastdds::dds::TypeSupport timeExchangeType();

TimeExchangeMessage toMessage(const TimeExchange& exchange);
TimeExchange exchangeOf(const TimeExchangeMessage& message);

// Fills `message` from a frame. Reuses the message's data buffer.
void toMessage(const FrameMetadata& meta, const ImageView& image, FrameMessage* message);

// kCorruptData naming the problem when `message` is not a frame of `stream`.
Status checkMessage(const FrameMessage& message, const StreamInfo& stream);

// The metadata `message` carries, exactly as sent (stream, graph stamp: unset).
FrameMetadata metadataOf(const FrameMessage& message);

// The announcement of graph stream `stream` published by `host`, one of `device_streams` (the
// graph names of every stream of its device that the host publishes).
AnnouncementMessage toAnnouncement(const StreamInfo& stream, const std::string& host,
                                   const std::vector<std::string>& device_streams);

// The stream an announcement describes, its name and device as announced. kCorruptData naming
// the problem when a field is not something this build knows (kind, format, size, protocol).
Result<StreamInfo> streamOf(const AnnouncementMessage& announcement);

}  // namespace mixray::dds::detail
