#include "ros_image.h"

#include <algorithm>
#include <cstring>

#include "frame_message.h"
#include "mixray/graph/host_time.h"

namespace mixray::dds::detail {

eprosima::fastdds::dds::TypeSupport rosImageType() {
    return eprosima::fastdds::dds::TypeSupport(
        new GuardedType<sensor_msgs::msg::dds_::Image_PubSubType>());
}

std::optional<std::string_view> rosEncoding(PixelFormat format) {
    switch (format) {
        case PixelFormat::kMono8:
            return "mono8";
        case PixelFormat::kMono16:
        case PixelFormat::kIR16:
            return "mono16";
        case PixelFormat::kRGB8:
            return "rgb8";
        case PixelFormat::kBGR8:
            return "bgr8";
        case PixelFormat::kBayerRGGB8:
            return "bayer_rggb8";
        case PixelFormat::kBayerGRBG8:
            return "bayer_grbg8";
        case PixelFormat::kBayerGBRG8:
            return "bayer_gbrg8";
        case PixelFormat::kBayerBGGR8:
            return "bayer_bggr8";
        case PixelFormat::kYUYV:
            return "yuv422_yuy2";
        case PixelFormat::kDepth16:
            return "16UC1";  // millimetres, as REP 118 has depth images in 16UC1
        default:
            return std::nullopt;
    }
}

bool isRosName(std::string_view name) {
    return !name.empty() && std::all_of(name.begin(), name.end(), [](char c) {
        return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
               c == '_' || c == '/';
    });
}

std::string rosImageTopic(std::string_view rig, std::string_view stream) {
    std::string topic = "rt/";
    topic += rig;
    topic += '/';
    topic += stream;
    topic += "/image_raw";
    return topic;
}

std::string rosFrameId(std::string_view stream) {
    std::string id(stream);
    for (char& c : id) {
        if (c == '/')
            c = '_';
    }
    return id;
}

builtin_interfaces::msg::dds_::Time_ rosTime(int64_t stamp_ns) {
    int64_t sec = stamp_ns / 1'000'000'000;
    int64_t nanosec = stamp_ns % 1'000'000'000;
    if (nanosec < 0) {
        --sec;
        nanosec += 1'000'000'000;
    }
    builtin_interfaces::msg::dds_::Time_ time;
    time.sec(static_cast<int32_t>(sec));
    time.nanosec(static_cast<uint32_t>(nanosec));
    return time;
}

int64_t liveRosStampNs(const FrameMetadata& meta) {
    // ROS time is the wall clock; the frame's stamp is host CLOCK_MONOTONIC (steady_clock).
    const int64_t steady = meta.graph_stamp_ns != 0 ? meta.graph_stamp_ns : meta.host_stamp_ns;
    return steady + realtimeMinusMonotonicNs();
}

void toRosImage(const FrameRef& frame, std::string_view frame_id, int64_t stamp,
                RosImage* message) {
    const ImageView image = frame.image();
    message->header().stamp(rosTime(stamp));
    message->header().frame_id(std::string(frame_id));
    message->height(static_cast<uint32_t>(image.desc.height));
    message->width(static_cast<uint32_t>(image.desc.width));
    message->encoding(std::string(rosEncoding(image.desc.format).value_or("")));
    message->is_bigendian(0);
    message->step(static_cast<uint32_t>(image.desc.stride_bytes));
    std::vector<uint8_t>& data = message->data();
    const size_t bytes = static_cast<size_t>(image.desc.stride_bytes) * image.desc.height;
    data.resize(bytes);
    std::memcpy(data.data(), image.data, bytes);
}

}  // namespace mixray::dds::detail
