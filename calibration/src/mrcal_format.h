// mrcal's .cameramodel files through mrcal's own reader; written in mrcal's format at full
// precision (mrcal 2.2's C writer keeps six decimals) and checked with mrcal's reader.
#pragma once

#include <filesystem>

#include "mixray/calibration/calibration_file.h"

namespace mixray::calibration::detail {

// The model and its pose (mrcal's extrinsics rt_cam_ref, stored as T_parent_camera with parent
// "reference"); errors name the file and the cause (mrcal prints its parser's complaint on
// stderr). Writing refuses lenses mrcal has no model for (Kannala–Brandt) naming the camera.
Result<CalibratedCamera> readMrcalCameramodel(const std::filesystem::path& path);
Status writeMrcalCameramodel(const std::filesystem::path& path, const CalibratedCamera& camera);

}  // namespace mixray::calibration::detail
