// calibrateKinect(): the rig of the IR and colour cameras (calibrateRig), then the depth half
// (kinect_calibration.cpp). Apart, so that the depth half links without the solvers.
#include "mixray/calibration/depth_registration.h"

namespace mixray::calibration {

Result<KinectCalibration> calibrateKinect(const CameraViews& color, const CameraViews& ir,
                                          const std::vector<KeyedDepth>& depth,
                                          const KinectCalibrationOptions& options) {
    MIXRAY_RETURN_IF_ERROR(ir.target.validate().withContext("Kinect calibration: target"));
    RigOptions rig_options = options.rig;
    rig_options.reference = color.camera;
    auto rig = calibrateRig({color, ir}, rig_options);
    if (!rig)
        return rig.status().withContext("Kinect calibration: the rig of " + color.camera + " and " +
                                        ir.camera);
    return kinectCalibrationFromRig(*rig, color.camera, ir, depth, ir.target.points(),
                                    options.depth);
}

}  // namespace mixray::calibration
