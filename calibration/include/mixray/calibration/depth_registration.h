// Kinect depth↔colour: the depth (IR) camera's geometry, its pose in the colour camera, and the
// correction of its depth readings; registration of a depth image into the colour camera.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <vector>

#include "mixray/calibration/camera_model.h"
#include "mixray/graph/result.h"

namespace mixray::calibration {

// Corrects a raw depth reading z (metres, along the depth camera's axis) at pixel (u, v):
// z' = scale · z + offset_m, then, when `distortion` is present, Herrera et al.'s spatially
// varying term (Herrera, Kannala, Heikkilä, "Joint depth and color camera calibration with
// distortion correction", TPAMI 2012): z'' = z' + D(u, v) · exp(α0 − α1 · z'), D sampled on
// the depth image's pixel grid (row-major, width × height of the depth camera). Plain value.
struct DepthCorrection {
    double scale = 1;
    double offset_m = 0;
    std::vector<float> distortion;  // empty: no spatial term
    double alpha0 = 0, alpha1 = 0;

    bool isIdentity() const { return scale == 1 && offset_m == 0 && distortion.empty(); }
};

// How a depth image maps into the colour camera. Plain value.
struct DepthRegistration {
    CameraModel depth;  // the IR camera the depth image is aligned with
    CameraModel color;
    Eigen::Isometry3d T_color_depth = Eigen::Isometry3d::Identity();
    DepthCorrection correction;
};

}  // namespace mixray::calibration
