// A camera's calibration and the rig's extrinsics as ROS 2 messages: sensor_msgs/CameraInfo
// beside each image topic, tf2_msgs/TFMessage on tf_static. Internal to drivers/dds.
#pragma once

#include <cstdint>
#include <fastdds/dds/topic/TypeSupport.hpp>
#include <string>
#include <string_view>
#include <vector>

#include "mixray/calibration/ros_camera_info.h"
#include "sensor_msgs/msg/CameraInfoPubSubTypes.h"
#include "tf2_msgs/msg/TFMessagePubSubTypes.h"

namespace mixray::dds::detail {

using RosCameraInfoMessage = sensor_msgs::msg::dds_::CameraInfo_;
using RosTfMessage = tf2_msgs::msg::dds_::TFMessage_;

eprosima::fastdds::dds::TypeSupport rosCameraInfoType();
eprosima::fastdds::dds::TypeSupport rosTfType();

// "rt/<rig>/<stream>/camera_info", beside rosImageTopic()'s image_raw.
std::string rosCameraInfoTopic(std::string_view rig, std::string_view stream);
// tf2's topics: transforms that never change (read transient-local), and those that do.
inline constexpr const char* kRosTfStaticTopic = "rt/tf_static";
inline constexpr const char* kRosTfTopic = "rt/tf";

// A tf frame id for a pose anchor or camera: "kinect/color" is "kinect_color", "marker:23" is
// "marker_23" (tf2 frame ids take neither '/' inside a name part nor ':').
std::string rosTfFrame(std::string_view name);

// Fills every field but the header, which is the image's.
void toRosCameraInfo(const calibration::RosCameraInfo& info, RosCameraInfoMessage* message);

// The transforms as one tf message stamped `wall_ns` (ROS time), frames named by rosTfFrame()
// ("kinect/color" is frame "kinect_color"; "world" stays "world").
RosTfMessage toRosTf(const std::vector<calibration::RosTransform>& transforms, int64_t wall_ns);

}  // namespace mixray::dds::detail
