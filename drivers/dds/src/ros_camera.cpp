#include "ros_camera.h"

#include "frame_message.h"
#include "ros_image.h"

namespace mixray::dds::detail {

eprosima::fastdds::dds::TypeSupport rosCameraInfoType() {
    return eprosima::fastdds::dds::TypeSupport(
        new GuardedType<sensor_msgs::msg::dds_::CameraInfo_PubSubType>());
}

eprosima::fastdds::dds::TypeSupport rosTfType() {
    return eprosima::fastdds::dds::TypeSupport(
        new GuardedType<tf2_msgs::msg::dds_::TFMessage_PubSubType>());
}

std::string rosCameraInfoTopic(std::string_view rig, std::string_view stream) {
    return "rt/" + std::string(rig) + "/" + std::string(stream) + "/camera_info";
}

std::string rosTfFrame(std::string_view name) {
    std::string id(name);
    for (char& c : id) {
        if (c == '/' || c == ':')
            c = '_';
    }
    return id;
}

void toRosCameraInfo(const calibration::RosCameraInfo& info, RosCameraInfoMessage* message) {
    message->height(info.height);
    message->width(info.width);
    message->distortion_model(info.distortion_model);
    message->d(info.d);
    message->k(info.k);
    message->r(info.r);
    message->p(info.p);
    // Full resolution, no binning: what the calibration describes.
    message->binning_x(0);
    message->binning_y(0);
    message->roi(sensor_msgs::msg::dds_::RegionOfInterest_());
}

RosTfMessage toRosTf(const std::vector<calibration::RosTransform>& transforms, int64_t wall_ns) {
    RosTfMessage message;
    for (const calibration::RosTransform& t : transforms) {
        geometry_msgs::msg::dds_::TransformStamped_ stamped;
        stamped.header().stamp(rosTime(wall_ns));
        stamped.header().frame_id(rosTfFrame(t.parent));
        stamped.child_frame_id(rosTfFrame(t.child));
        stamped.transform().translation().x(t.translation[0]);
        stamped.transform().translation().y(t.translation[1]);
        stamped.transform().translation().z(t.translation[2]);
        stamped.transform().rotation().x(t.rotation_xyzw[0]);
        stamped.transform().rotation().y(t.rotation_xyzw[1]);
        stamped.transform().rotation().z(t.rotation_xyzw[2]);
        stamped.transform().rotation().w(t.rotation_xyzw[3]);
        message.transforms().push_back(std::move(stamped));
    }
    return message;
}

}  // namespace mixray::dds::detail
