// How strong lights of known direction are, from the shading of a diffuse light-probe sphere:
// an 8-bit fish-eye image clips at its lights, so their strength comes from a surface they
// light instead (the probe's albedo known, Lambert's law linear in the irradiances).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <vector>

#include "mixray/calibration/camera_model.h"
#include "mixray/graph/image.h"
#include "mixray/graph/result.h"
#include "mixray/tracking/lights.h"

namespace mixray::tracking {

// Every field has a working default.
struct IntensityFitOptions {
    double albedo = 0.8;          // the probe's diffuse reflectance (linear, grey)
    bool ambient = false;         // also fit a constant ambient radiance
    int max_samples = 4000;       // pixels used, spread over the probe's disc
    double edge_margin_px = 2.0;  // pixels this close to the outline are mixed with background
    int saturated_code = 250;     // 8-bit codes at or above this are clipped: not used

    Status validate() const;
};

// Per light, the irradiance (linear RGB) it gives a surface facing it; `rms` is the fit's
// residual in linear units.
struct IntensityFit {
    std::vector<Eigen::Vector3d> irradiance;  // one per direction, in the order given
    Eigen::Vector3d ambient{0, 0, 0};         // radiance of the ambient term (when fitted)
    double rms = 0;
    int samples = 0;
};

// Fits the irradiance of lights from `to_light_world` (unit, world frame) to the diffuse
// probe's pixels in an sRGB colour image (kRGB8 or kBGR8): linear value = albedo/π · Σ E_k
// max(0, n·l_k) (+ ambient), non-negative least squares per channel. kNotFound when the probe
// shows too few usable pixels (out of view, clipped); kInvalidArgument for bad inputs.
// Reentrant.
Result<IntensityFit> fitLightIntensities(const ImageView& color,
                                         const calibration::CameraModel& camera,
                                         const Eigen::Isometry3d& T_world_camera,
                                         const LightProbe& probe,
                                         const std::vector<Eigen::Vector3d>& to_light_world,
                                         const IntensityFitOptions& options = {});

}  // namespace mixray::tracking
