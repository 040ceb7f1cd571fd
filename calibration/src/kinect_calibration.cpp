// The depth half of the Kinect's depth↔colour calibration: the depth correction from the IR
// views' board planes and the registration, for a solved rig (depth_registration.h).
#include <map>
#include <string>

#include "mixray/calibration/depth_registration.h"

namespace mixray::calibration {

namespace detail {

Result<KinectCalibration> calibrateKinectWith(
    const CameraViews& color, const CameraViews& ir, const std::vector<KeyedDepth>& depth,
    const KinectCalibrationOptions& options,
    Result<RigCalibration> (*solve_rig)(const std::vector<CameraViews>&, const RigOptions&),
    Status (*validate_target)(const CalibrationTarget&),
    std::vector<Eigen::Vector3d> (*target_points)(const CalibrationTarget&)) {
    MIXRAY_RETURN_IF_ERROR(validate_target(ir.target).withContext("Kinect calibration: target"));
    RigOptions rig_options = options.rig;
    rig_options.reference = color.camera;
    auto rig = solve_rig({color, ir}, rig_options);
    if (!rig)
        return rig.status().withContext("Kinect calibration: the rig of " + color.camera + " and " +
                                        ir.camera);
    return kinectCalibrationFromRig(*rig, color.camera, ir, depth, target_points(ir.target),
                                    options.depth);
}

}  // namespace detail

Result<KinectCalibration> kinectCalibrationFromRig(const RigCalibration& rig,
                                                   std::string_view color_camera,
                                                   const CameraViews& ir,
                                                   const std::vector<KeyedDepth>& depth,
                                                   const std::vector<Eigen::Vector3d>& board_points,
                                                   const DepthCorrectionOptions& options) {
    const auto find = [&](std::string_view name) -> int {
        for (size_t i = 0; i < rig.cameras.size(); ++i)
            if (rig.cameras[i].camera == name)
                return static_cast<int>(i);
        return -1;
    };
    const int c = find(color_camera), d = find(ir.camera);
    if (c < 0 || d < 0)
        return Status(ErrorCode::kInvalidArgument,
                      "Kinect calibration: the rig has no camera " +
                          std::string(c < 0 ? color_camera : std::string_view(ir.camera)));
    if (rig.reference != color_camera)
        return Status(ErrorCode::kInvalidArgument, "Kinect calibration: the rig's reference is " +
                                                       rig.reference + ", not the colour camera " +
                                                       std::string(color_camera));
    if (rig.T_ref_camera.size() != rig.cameras.size())
        return Status(ErrorCode::kInvalidArgument,
                      "Kinect calibration: the rig has no pose for every camera");
    const CameraCalibration& ir_cal = rig.cameras[static_cast<size_t>(d)];

    std::map<int64_t, ImageView> depth_by_key;
    for (const KeyedDepth& k : depth)
        depth_by_key[k.key] = k.depth_mm;
    std::vector<DepthPlaneView> planes;
    for (const ViewFit& fit : ir_cal.views) {
        if (fit.view >= ir.views.size())
            return Status(ErrorCode::kInvalidArgument,
                          "Kinect calibration: the IR solve names view " +
                              std::to_string(fit.view) + " of " + std::to_string(ir.views.size()));
        const auto it = depth_by_key.find(ir.views[fit.view].key);
        if (it != depth_by_key.end())
            planes.push_back({fit.T_camera_target, it->second});
    }
    if (planes.empty())
        return Status(ErrorCode::kInvalidArgument,
                      "Kinect calibration: no depth image has the key of a used IR view (" +
                          std::to_string(depth.size()) + " depth images, " +
                          std::to_string(ir_cal.views.size()) + " IR views)");
    auto fitted = fitDepthCorrection(ir_cal.model, board_points, planes, options);
    if (!fitted)
        return fitted.status().withContext("Kinect calibration");

    KinectCalibration out;
    out.rig = rig;
    out.depth_fit = std::move(fitted).value();
    out.registration.depth = ir_cal.model;
    out.registration.color = rig.cameras[static_cast<size_t>(c)].model;
    out.registration.T_color_depth = rig.T_ref_camera[static_cast<size_t>(d)];
    out.registration.correction = out.depth_fit.correction;
    MIXRAY_RETURN_IF_ERROR(out.registration.validate().withContext("Kinect calibration"));
    return out;
}

}  // namespace mixray::calibration
