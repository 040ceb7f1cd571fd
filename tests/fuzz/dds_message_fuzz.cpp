// libFuzzer target for the DDS messages another host sends (drivers/dds): the first byte picks
// a mixray_msgs Frame (deserializeFrame, against a small rgb8 stream), a StreamAnnouncement
// (deserializeAnnouncement) or a TimeExchange (deserializeTimeExchange), or from 0xF0 on a ROS 2
// node's sensor_msgs Image (rosImageStream, rosImageFrame); the rest is the CDR sample as a DDS
// reader receives it. Any bytes give a clean kCorruptData, never a throw or a
// crash (fastcdr throws more than Fast DDS's generated code catches); an accepted frame fits the
// stream and serializes and reads back to the same frame; an accepted announcement is a stream
// the graph can declare; an accepted exchange reads back the same, and its stamps, fed to a
// HostClockEstimator and mapped through its fit, overflow nothing (UBSan watches); an image
// that makes a stream is a frame of that stream with exactly its bytes.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <span>
#include <string>

#include "mixray/dds/frame_message.h"
#include "mixray/dds/host_clock.h"
#include "mixray/dds/ros2_source.h"

namespace {

[[noreturn]] void broken(const char* what, const std::string& detail) {
    std::fprintf(stderr, "dds_message_fuzz: %s: %s\n", what, detail.c_str());
    std::abort();
}

mixray::StreamInfo smallStream() {
    mixray::StreamInfo info;
    info.name = "cam/color";
    info.device = "cam";
    info.kind = mixray::StreamKind::kColor;
    info.format = mixray::ImageDesc::packed(mixray::PixelFormat::kRGB8, 8, 4);
    return info;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    using namespace mixray;
    if (size == 0)
        return 0;
    const std::span<const uint8_t> bytes(data + 1, size - 1);
    if (data[0] >= 0xF0) {
        auto stream = dds::rosImageStream(bytes, "robot", "/robot/image_raw");
        if (!stream.isOk()) {
            const ErrorCode code = stream.status().code();
            if (code != ErrorCode::kCorruptData && code != ErrorCode::kUnsupported)
                broken("image rejection is neither kCorruptData nor kUnsupported",
                       stream.status().toString());
            return 0;
        }
        const ImageDesc& f = stream->format;
        if (f.width <= 0 || f.height <= 0 ||
            f.stride_bytes < ImageDesc::packed(f.format, f.width, f.height).stride_bytes)
            broken("accepted image makes no stream", stream->name);
        FrameMetadata meta;
        Image image;
        const Status frame = dds::rosImageFrame(bytes, *stream, &meta, &image);
        if (!frame.isOk())
            broken("the image that made the stream is no frame of it", frame.toString());
        if (image.bytes().size() != f.bufferBytes() || meta.clock_domain != stream->clock_domain)
            broken("the frame does not fit its stream", "");
        return 0;
    }
    if (data[0] % 3 == 2) {
        auto exchange = dds::deserializeTimeExchange(bytes);
        if (!exchange.isOk()) {
            if (exchange.status().code() != ErrorCode::kCorruptData)
                broken("exchange rejection is not kCorruptData", exchange.status().toString());
            return 0;
        }
        auto again = dds::deserializeTimeExchange(dds::serializeTimeExchange(*exchange));
        if (!again.isOk() || again->requester != exchange->requester ||
            again->sequence != exchange->sequence || again->t2_ns != exchange->t2_ns ||
            again->t3_ns != exchange->t3_ns ||
            again->realtime_minus_monotonic_ns != exchange->realtime_minus_monotonic_ns ||
            again->ptp_locked != exchange->ptp_locked ||
            again->ptp_grandmaster != exchange->ptp_grandmaster)
            broken("accepted exchange does not read back the same", "");
        // The requester's own t1 and t4 around the other host's t2 and t3, four times over.
        dds::HostClockEstimator estimator;
        for (int i = 0; i < 4; ++i) {
            (void)estimator.add({exchange->t1_ns, exchange->t2_ns, exchange->t3_ns,
                                 exchange->t1_ns / 2 + 1000 * (i + 1)});
        }
        if (const auto fit = estimator.estimate()) {
            (void)fit->toLocal(exchange->t2_ns);
            (void)fit->toRemote(exchange->t3_ns);
            (void)fit->describe();
        }
        return 0;
    }
    if (data[0] % 3 == 0) {
        const StreamInfo stream = smallStream();
        FrameMetadata meta;
        Image image;
        const Status status = dds::deserializeFrame(bytes, stream, &meta, &image);
        if (!status.isOk()) {
            if (status.code() != ErrorCode::kCorruptData)
                broken("frame rejection is not kCorruptData", status.toString());
            return 0;
        }
        if (image.desc() != stream.format || image.bytes().size() != stream.format.bufferBytes())
            broken("accepted frame does not fit the stream", "");
        FrameMetadata again;
        Image again_image;
        const auto reserialized = dds::serializeFrame(meta, image.view());
        if (!dds::deserializeFrame(reserialized, stream, &again, &again_image).isOk() ||
            again.sequence != meta.sequence || again.device_stamp_ns != meta.device_stamp_ns ||
            again.status != meta.status || again_image.bytes() != image.bytes())
            broken("accepted frame does not read back the same", "");
        return 0;
    }
    auto stream = dds::deserializeAnnouncement(bytes);
    if (!stream.isOk()) {
        if (stream.status().code() != ErrorCode::kCorruptData)
            broken("announcement rejection is not kCorruptData", stream.status().toString());
        return 0;
    }
    const ImageDesc& f = stream->format;
    if (f.width <= 0 || f.height <= 0 || f.format == PixelFormat::kUnknown ||
        stream->name.rfind(stream->device + "/", 0) != 0)
        broken("accepted announcement is no stream", stream->name);
    return 0;
}
