#include "ros_image.h"

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

void toRosImage(const FrameRef& frame, std::string_view frame_id, RosImage* message) {
    const ImageView image = frame.image();
    // ROS time is the wall clock; the frame's stamp is host CLOCK_MONOTONIC (steady_clock).
    const int64_t wall_minus_steady = realtimeMinusMonotonicNs();
    // A replayed frame's host stamp is the recording session's clock; it entered this graph at
    // its graph stamp.
    const FrameMetadata& meta = frame.meta();
    const int64_t steady = meta.graph_stamp_ns != 0 ? meta.graph_stamp_ns : meta.host_stamp_ns;
    const int64_t stamp = steady + wall_minus_steady;
    message->header().stamp().sec(static_cast<int32_t>(stamp / 1'000'000'000));
    message->header().stamp().nanosec(static_cast<uint32_t>(stamp % 1'000'000'000));
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
