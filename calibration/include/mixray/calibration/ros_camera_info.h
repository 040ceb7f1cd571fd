// A calibration as ROS describes it: sensor_msgs/CameraInfo's calibration fields for a camera,
// and the rig's extrinsics as tf transforms. The ROS camera_info file export
// (CalibrationFormat::kRos) and the ROS 2 topics of drivers/dds both write these.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "mixray/graph/result.h"

namespace mixray::calibration {

struct CalibratedCamera;
struct CalibrationFile;

// sensor_msgs/CameraInfo's calibration of one camera. Plain value.
struct RosCameraInfo {
    uint32_t width = 0;
    uint32_t height = 0;
    // "plumb_bob" (k1 k2 t1 t2 k3), "rational_polynomial" (k1 k2 t1 t2 k3 k4 k5 k6) or
    // "equidistant" (cv::fisheye's k1..k4).
    std::string distortion_model;
    std::vector<double> d;
    std::array<double, 9> k{};   // intrinsic matrix, row-major
    std::array<double, 9> r{};   // rectification: identity for a single camera
    std::array<double, 12> p{};  // projection [K | 0], row-major
};

// The camera's CameraInfo. kInvalidArgument naming the camera for models ROS cannot describe
// (the stereographic ones: ROS's models are OpenCV's pinhole and fisheye).
Result<RosCameraInfo> toRosCameraInfo(const CalibratedCamera& camera);

// One calibrated pose as a tf transform: `child`'s pose in `parent`. The names are the
// calibration's (camera names, which are stream names such as "kinect/color", or "world").
struct RosTransform {
    std::string parent;
    std::string child;
    std::array<double, 3> translation{};    // metres
    std::array<double, 4> rotation_xyzw{};  // unit quaternion
};

// Every camera of the file whose pose is calibrated, in its parent's frame, in file order.
std::vector<RosTransform> toRosTransforms(const CalibrationFile& file);

}  // namespace mixray::calibration
