// mrcal's .cameramodel files through mrcal's own reader and writer.
#pragma once

#include <filesystem>

#include "mixray/calibration/calibration_file.h"

namespace mixray::calibration::detail {

// The model and its pose (mrcal's extrinsics rt_cam_ref, stored as T_parent_camera with parent
// "reference"); errors name the file and mrcal's complaint.
Result<CalibratedCamera> readMrcalCameramodel(const std::filesystem::path& path);
Status writeMrcalCameramodel(const std::filesystem::path& path, const CalibratedCamera& camera);

}  // namespace mixray::calibration::detail
