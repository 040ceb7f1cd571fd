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

// The ROS 2 topic of a stream's images: "rt/<rig>/<stream>/image_raw".
std::string rosImageTopic(std::string_view rig, std::string_view stream);

// The ROS 2 frame_id of a stream's camera: the stream name with '/' as '_' ("kinect_color").
std::string rosFrameId(std::string_view stream);

// Fills `message` from a frame whose format has a rosEncoding(), stamped with the frame's
// host time on the wall clock (ROS time). Reuses the message's data buffer.
void toRosImage(const FrameRef& frame, std::string_view frame_id, RosImage* message);

}  // namespace mixray::dds::detail
