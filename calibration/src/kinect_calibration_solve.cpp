// calibrateKinect(): the rig solve and the target's geometry handed to the rest of the
// calibration (kinect_calibration.cpp). Alone in its file and with no code of its own (no
// strings built, nothing instantiated), so that linking the depth half never pulls in the
// solvers.
#include "mixray/calibration/depth_registration.h"

namespace mixray::calibration {

Result<KinectCalibration> calibrateKinect(const CameraViews& color, const CameraViews& ir,
                                          const std::vector<KeyedDepth>& depth,
                                          const KinectCalibrationOptions& options) {
    return detail::calibrateKinectWith(
        color, ir, depth, options, &calibrateRig,
        [](const CalibrationTarget& target) { return target.validate(); },
        [](const CalibrationTarget& target) { return target.points(); });
}

}  // namespace mixray::calibration
