#include "mixray/calibration/ros_camera_info.h"

#include <Eigen/Geometry>

#include "mixray/calibration/calibration_file.h"

namespace mixray::calibration {

Result<RosCameraInfo> toRosCameraInfo(const CalibratedCamera& camera) {
    const CameraModel& m = camera.model;
    RosCameraInfo info;
    info.d = m.distortion;
    if (m.lens == LensModel::kFisheye) {
        info.distortion_model = "equidistant";
    } else if (m.lens != LensModel::kPinhole) {
        return Status(ErrorCode::kInvalidArgument,
                      "ROS's camera_info cannot describe camera " + camera.name + "'s " +
                          std::string(toString(m.lens)) +
                          " lens (it holds pinhole models with OpenCV's distortion and "
                          "cv::fisheye's)");
    } else if (info.d.size() == 8) {
        info.distortion_model = "rational_polynomial";
    } else {
        // plumb_bob is always k1 k2 t1 t2 k3: the missing terms are zero.
        info.distortion_model = "plumb_bob";
        info.d.resize(5, 0.0);
    }
    info.width = static_cast<uint32_t>(m.width);
    info.height = static_cast<uint32_t>(m.height);
    info.k = {m.fx, 0, m.cx, 0, m.fy, m.cy, 0, 0, 1};
    info.r = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    info.p = {m.fx, 0, m.cx, 0, 0, m.fy, m.cy, 0, 0, 0, 1, 0};
    return info;
}

std::vector<RosTransform> toRosTransforms(const CalibrationFile& file) {
    std::vector<RosTransform> out;
    for (const CalibratedCamera& c : file.cameras) {
        if (c.parent.empty())
            continue;
        const Eigen::Vector3d t = c.T_parent_camera.translation();
        const Eigen::Quaterniond q(c.T_parent_camera.rotation());
        out.push_back({.parent = c.parent,
                       .child = c.name,
                       .translation = {t.x(), t.y(), t.z()},
                       .rotation_xyzw = {q.x(), q.y(), q.z(), q.w()}});
    }
    return out;
}

}  // namespace mixray::calibration
