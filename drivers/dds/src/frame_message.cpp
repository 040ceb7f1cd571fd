#include "frame_message.h"

#include <cstring>
#include <string>

#include "mixray/dds/dds_options.h"
#include "mixray/dds/frame_message.h"

namespace mixray::dds {
namespace detail {
namespace {

Status corrupt(const std::string& what) {
    return {ErrorCode::kCorruptData, "dds frame: " + what};
}

}  // namespace

eprosima::fastdds::dds::TypeSupport frameType() {
    return eprosima::fastdds::dds::TypeSupport(
        new GuardedType<mixray_msgs::msg::dds_::Frame_PubSubType>());
}

eprosima::fastdds::dds::TypeSupport announcementType() {
    return eprosima::fastdds::dds::TypeSupport(
        new GuardedType<mixray_msgs::msg::dds_::StreamAnnouncement_PubSubType>());
}

eprosima::fastdds::dds::TypeSupport timeExchangeType() {
    return eprosima::fastdds::dds::TypeSupport(
        new GuardedType<mixray_msgs::msg::dds_::TimeExchange_PubSubType>());
}

TimeExchangeMessage toMessage(const TimeExchange& exchange) {
    TimeExchangeMessage m;
    m.requester(exchange.requester);
    m.responder(exchange.responder);
    m.sequence_number(exchange.sequence);
    m.t1_ns(exchange.t1_ns);
    m.t2_ns(exchange.t2_ns);
    m.t3_ns(exchange.t3_ns);
    m.protocol(exchange.protocol);
    m.realtime_minus_monotonic_ns(exchange.realtime_minus_monotonic_ns);
    m.ptp_locked(exchange.ptp_locked);
    m.ptp_grandmaster(exchange.ptp_grandmaster);
    return m;
}

TimeExchange exchangeOf(const TimeExchangeMessage& m) {
    return {.requester = m.requester(),
            .responder = m.responder(),
            .sequence = m.sequence_number(),
            .t1_ns = m.t1_ns(),
            .t2_ns = m.t2_ns(),
            .t3_ns = m.t3_ns(),
            .protocol = m.protocol(),
            .realtime_minus_monotonic_ns = m.realtime_minus_monotonic_ns(),
            .ptp_locked = m.ptp_locked(),
            .ptp_grandmaster = m.ptp_grandmaster()};
}

void toMessage(const FrameMetadata& meta, const ImageView& image, FrameMessage* message) {
    message->sequence_number(meta.sequence);
    message->device_stamp_ns(meta.device_stamp_ns);
    message->host_stamp_ns(meta.host_stamp_ns);
    message->clock_domain(meta.clock_domain);
    message->exposure_us(meta.exposure_us);
    message->status(static_cast<uint8_t>(meta.status));
    message->format(std::string(toString(image.desc.format)));
    message->width(image.desc.width);
    message->height(image.desc.height);
    message->stride_bytes(image.desc.stride_bytes);
    std::vector<uint8_t>& data = message->data();
    data.resize(image.size_bytes);
    if (image.size_bytes > 0)
        std::memcpy(data.data(), image.data, image.size_bytes);
}

Status checkMessage(const FrameMessage& message, const StreamInfo& stream) {
    const ImageDesc& desc = stream.format;
    const std::string expected(toString(desc.format));
    if (message.format() != expected)
        return corrupt("pixel format '" + message.format() + "', the stream's is " + expected);
    if (message.status() > static_cast<uint8_t>(FrameStatus::kCorrupt))
        return corrupt("status " + std::to_string(message.status()) + " is not 0, 1 or 2");
    const bool compressed = pixelFormatInfo(desc.format).compressed;
    const bool varying = desc.format == PixelFormat::kBinary;  // records vary in length
    if (!varying && (message.width() != desc.width || message.height() != desc.height ||
                     message.stride_bytes() != desc.stride_bytes)) {
        return corrupt(std::to_string(message.width()) + "x" + std::to_string(message.height()) +
                       " stride " + std::to_string(message.stride_bytes()) + ", the stream's is " +
                       std::to_string(desc.width) + "x" + std::to_string(desc.height) + " stride " +
                       std::to_string(desc.stride_bytes));
    }
    const size_t bytes = message.data().size();
    if (varying) {
        if (message.height() != 1 || message.width() < 0 ||
            static_cast<size_t>(message.width()) != bytes ||
            message.stride_bytes() != message.width())
            return corrupt("a binary record's width, stride and length disagree");
        if (bytes > desc.bufferBytes())
            return corrupt(std::to_string(bytes) + " bytes, the stream's records hold " +
                           std::to_string(desc.bufferBytes()));
    } else if (compressed ? bytes > desc.bufferBytes() : bytes != desc.bufferBytes()) {
        return corrupt(std::to_string(bytes) + " bytes of payload, the stream's frames have " +
                       (compressed ? "at most " : "") + std::to_string(desc.bufferBytes()));
    }
    return Status::ok();
}

FrameMetadata metadataOf(const FrameMessage& message) {
    FrameMetadata meta;
    meta.sequence = message.sequence_number();
    meta.device_stamp_ns = message.device_stamp_ns();
    meta.host_stamp_ns = message.host_stamp_ns();
    meta.clock_domain = message.clock_domain();
    meta.exposure_us = message.exposure_us();
    meta.status = static_cast<FrameStatus>(message.status());
    return meta;
}

AnnouncementMessage toAnnouncement(const StreamInfo& stream, const std::string& host,
                                   const std::vector<std::string>& device_streams) {
    AnnouncementMessage message;
    message.host(host);
    message.stream(stream.name);
    message.device(stream.device);
    message.device_streams(device_streams);
    message.topic(frameTopic(host, stream.name));
    message.kind(std::string(toString(stream.kind)));
    message.format(std::string(toString(stream.format.format)));
    message.width(stream.format.width);
    message.height(stream.format.height);
    message.stride_bytes(stream.format.stride_bytes);
    message.nominal_fps(stream.nominal_fps);
    message.clock_domain(stream.clock_domain);
    for (const auto& [name, value] : stream.tags) {
        mixray_msgs::msg::dds_::StreamTag_ tag;
        tag.name(name);
        tag.value(value);
        message.tags().push_back(std::move(tag));
    }
    message.protocol(kProtocolVersion);
    return message;
}

Result<StreamInfo> streamOf(const AnnouncementMessage& announcement) {
    const std::string who =
        "dds announcement of " + announcement.host() + " " + announcement.stream() + ": ";
    if (announcement.protocol() > kProtocolVersion) {
        return Status{ErrorCode::kCorruptData,
                      who + "protocol " + std::to_string(announcement.protocol()) +
                          ", this build speaks up to " + std::to_string(kProtocolVersion)};
    }
    StreamInfo info;
    info.name = announcement.stream();
    info.device = announcement.device();
    if (info.device.empty() || info.name.size() <= info.device.size() + 1 ||
        info.name.compare(0, info.device.size() + 1, info.device + "/") != 0)
        return Status{ErrorCode::kCorruptData, who + "the stream is not named device/stream"};
    const auto kind = streamKindFromString(announcement.kind());
    if (!kind)
        return Status{ErrorCode::kCorruptData, who + "unknown kind '" + announcement.kind() + "'"};
    info.kind = *kind;
    const auto format = pixelFormatFromString(announcement.format());
    if (!format || *format == PixelFormat::kUnknown) {
        return Status{ErrorCode::kCorruptData,
                      who + "unknown pixel format '" + announcement.format() + "'"};
    }
    info.format.format = *format;
    info.format.width = announcement.width();
    info.format.height = announcement.height();
    info.format.stride_bytes = announcement.stride_bytes();
    // The size every buffer of the stream will have: refuse what no camera makes rather than
    // let a peer make this host allocate gigabytes.
    constexpr int kMaxSide = 16384;
    const bool compressed = pixelFormatInfo(*format).compressed;
    if (info.format.width <= 0 || info.format.height <= 0 || info.format.width > kMaxSide ||
        info.format.height > kMaxSide || info.format.stride_bytes < 0 ||
        (!compressed && info.format.stride_bytes <
                            ImageDesc::packed(*format, info.format.width, 1).stride_bytes) ||
        info.format.stride_bytes > 8 * kMaxSide) {
        return Status{ErrorCode::kCorruptData, who + "impossible size " +
                                                   std::to_string(info.format.width) + "x" +
                                                   std::to_string(info.format.height) + " stride " +
                                                   std::to_string(info.format.stride_bytes)};
    }
    if (!(announcement.nominal_fps() >= 0 && announcement.nominal_fps() <= 100000))
        return Status{ErrorCode::kCorruptData, who + "impossible frame rate"};
    info.nominal_fps = announcement.nominal_fps();
    info.clock_domain = announcement.clock_domain();
    for (const auto& tag : announcement.tags())
        info.tags[tag.name()] = tag.value();
    return info;
}

}  // namespace detail

std::vector<uint8_t> serializeFrame(const FrameMetadata& meta, const ImageView& image) {
    detail::FrameMessage message;
    detail::toMessage(meta, image, &message);
    return detail::serializeSample<mixray_msgs::msg::dds_::Frame_PubSubType>(message);
}

std::vector<uint8_t> serializeAnnouncement(const StreamInfo& stream, const std::string& host) {
    detail::AnnouncementMessage message = detail::toAnnouncement(stream, host, {stream.name});
    return detail::serializeSample<mixray_msgs::msg::dds_::StreamAnnouncement_PubSubType>(message);
}

Result<StreamInfo> deserializeAnnouncement(std::span<const uint8_t> bytes) {
    detail::AnnouncementMessage message;
    if (!detail::deserializeSample<mixray_msgs::msg::dds_::StreamAnnouncement_PubSubType>(
            bytes, &message)) {
        return Status{ErrorCode::kCorruptData,
                      "dds announcement: not a mixray_msgs StreamAnnouncement in CDR"};
    }
    return detail::streamOf(message);
}

std::vector<uint8_t> serializeTimeExchange(const TimeExchange& exchange) {
    detail::TimeExchangeMessage message = detail::toMessage(exchange);
    return detail::serializeSample<mixray_msgs::msg::dds_::TimeExchange_PubSubType>(message);
}

Result<TimeExchange> deserializeTimeExchange(std::span<const uint8_t> bytes) {
    detail::TimeExchangeMessage message;
    if (!detail::deserializeSample<mixray_msgs::msg::dds_::TimeExchange_PubSubType>(bytes,
                                                                                    &message)) {
        return Status{ErrorCode::kCorruptData,
                      "dds time exchange: not a mixray_msgs TimeExchange in CDR"};
    }
    // CDR strings may hold a NUL that no host name has (and that fastcdr would drop on the way
    // back out).
    if (message.requester().find('\0') != std::string::npos ||
        message.responder().find('\0') != std::string::npos ||
        message.ptp_grandmaster().find('\0') != std::string::npos)
        return Status{ErrorCode::kCorruptData, "dds time exchange: a name holds a NUL byte"};
    return detail::exchangeOf(message);
}

Status deserializeFrame(std::span<const uint8_t> bytes, const StreamInfo& stream,
                        FrameMetadata* meta, Image* image) {
    detail::FrameMessage message;
    if (!detail::deserializeSample<mixray_msgs::msg::dds_::Frame_PubSubType>(bytes, &message))
        return {ErrorCode::kCorruptData, "dds frame: not a mixray_msgs Frame in CDR"};
    MIXRAY_RETURN_IF_ERROR(detail::checkMessage(message, stream));
    *meta = detail::metadataOf(message);
    ImageDesc desc = stream.format;
    if (desc.format == PixelFormat::kBinary) {
        desc.width = message.width();
        desc.stride_bytes = message.stride_bytes();
    }
    *image = Image(desc);
    image->bytes().assign(message.data().begin(), message.data().end());
    return Status::ok();
}

}  // namespace mixray::dds
