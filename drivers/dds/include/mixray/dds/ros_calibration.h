// What ROS 2 sees of a rig's calibration: each image stream's CameraInfo and the extrinsics for
// tf_static, found in the calibration files the rig names. `mixray publish --ros2` and the MCAP
// export share it.
#pragma once

#include <functional>
#include <map>
#include <string>
#include <vector>

#include "mixray/calibration/calibration_file.h"
#include "mixray/calibration/ros_camera_info.h"
#include "mixray/graph/result.h"
#include "mixray/graph/rig.h"
#include "mixray/graph/stream.h"

namespace mixray::dds {

struct RosCalibration {
    std::map<std::string, calibration::RosCameraInfo> camera_info;  // by stream name
    std::vector<calibration::RosTransform> transforms;  // every calibrated pose, once per camera
};

// Reads one calibration file the rig names (from disk, or from a recording's attachment).
using CalibrationLoader =
    std::function<Result<calibration::CalibrationFile>(const RigCalibrationFile& entry)>;

// For each of `streams` that goes to ROS 2 as an image (rosImageEncoding): the calibration the
// rig names for it (the stream's own file, else its device's, else the rig's), in which its
// camera is the one named as the stream, or the only camera of a file the rig gives that stream
// alone. Streams without one get no CameraInfo. The transforms are those of every file read.
// The loader's error for a file that cannot be read; kInvalidArgument naming the camera for a
// lens ROS cannot describe.
Result<RosCalibration> rosCalibrationOf(const RigDescription& rig,
                                        const std::vector<StreamInfo>& streams,
                                        const CalibrationLoader& load);

}  // namespace mixray::dds
