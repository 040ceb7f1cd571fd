// Graph frames as ROS 2 sensor_msgs/msg/Image. Internal to drivers/dds.
#pragma once

#include <cstdint>
#include <fastdds/dds/topic/TypeSupport.hpp>
#include <optional>
#include <string>
#include <string_view>

#include "mixray/graph/frame.h"
#include "sensor_msgs/msg/ImagePubSubTypes.h"

namespace mixray::dds::detail {

using RosImage = sensor_msgs::msg::dds_::Image_;

eprosima::fastdds::dds::TypeSupport rosImageType();

// The sensor_msgs/image_encodings name of a graph pixel format; nullopt for formats ROS 2
// has no uncompressed encoding of (MJPEG, NV12, binary records).
std::optional<std::string_view> rosEncoding(PixelFormat format);

// Whether `name` is made of what ROS 2 names take: letters, digits, '_' and '/' (and is not
// empty).
bool isRosName(std::string_view name);

// The ROS 2 topic of a stream's images: "rt/<rig>/<stream>/image_raw".
std::string rosImageTopic(std::string_view rig, std::string_view stream);

// The ROS 2 frame_id of a stream's camera: the stream name with '/' as '_' ("kinect_color").
std::string rosFrameId(std::string_view stream);

// ROS time (builtin_interfaces/Time) of ns since the Unix epoch: whole seconds rounded down and
// 0 <= nanosec < 1e9, as ROS 2 has negative times too.
builtin_interfaces::msg::dds_::Time_ rosTime(int64_t stamp_ns);

// A live frame's ROS time: when it entered this graph (a replayed frame's host stamp is the
// recording session's clock), on the wall clock.
int64_t liveRosStampNs(const FrameMetadata& meta);

// Fills `message` from a frame whose format has a rosEncoding(), stamped `stamp_ns` (ROS time,
// ns since the Unix epoch). Reuses the message's data buffer.
void toRosImage(const FrameRef& frame, std::string_view frame_id, int64_t stamp_ns,
                RosImage* message);

}  // namespace mixray::dds::detail
