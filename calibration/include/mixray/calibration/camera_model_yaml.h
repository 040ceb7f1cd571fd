// Reading and writing camera models in mixray's YAML files (scene files, tracking setups, truth
// files): {lens: pinhole|fisheye|stereographic|LENSMODEL_SPLINED_STEREOGRAPHIC_order=..., width,
// height, fx, fy, cx, cy, distortion: [...]}; a splined model's configuration is its lens name.
// Include it from parsers' sources: it brings yaml-cpp's headers.
#pragma once

#include <string>

#include "mixray/calibration/camera_model.h"
#include "mixray/graph/yaml_reader.h"

namespace mixray::calibration {

// A camera model mapping; errors name the file, line and field. lens defaults to pinhole;
// distortion to none.
Result<CameraModel> readCameraModel(const yaml::Reader& reader, const yaml::Item& item);

// The flow-style mapping readCameraModel() reads, numbers at full precision.
std::string cameraModelYaml(const CameraModel& model);

}  // namespace mixray::calibration
