// Test helpers for markers: an antialiased ray-cast render of printed markers through a lens
// model (truth by construction), and the simulated tabletop session with its truth.
#pragma once

#include <Eigen/Geometry>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "mixray/calibration/camera_model.h"
#include "mixray/graph/image.h"
#include "mixray/tracking/markers.h"

namespace mixray::tracking::synth {

// A printed marker: the black square of side `size_m` centred at its frame's origin (+x right,
// +y up the marker image, +z out) with a white quiet zone of two cells around it.
struct PrintedMarker {
    std::string dictionary = "DICT_6X6_250";
    int id = 23;
    double size_m = 0.1;
    Eigen::Isometry3d T_world_marker = Eigen::Isometry3d::Identity();
};

// Any printed plane: `grey` (8-bit, its pixels as printed cells) spanning width_m x height_m,
// centred at its frame's origin, +x right, +y up the image, +z out.
struct PrintedPlane {
    cv::Mat grey;
    double width_m = 0, height_m = 0;
    Eigen::Isometry3d T_world_plane = Eigen::Isometry3d::Identity();
};
PrintedPlane printed(const PrintedMarker& marker);

// An rgb8 sRGB image of the planes seen from T_world_camera: `samples`² rays per pixel, the
// coverage averaged in linear light, as a camera integrates; the background is dark grey.
Image renderPlanes(const calibration::CameraModel& camera, const Eigen::Isometry3d& T_world_camera,
                   const std::vector<PrintedPlane>& planes, int samples = 4);

// An rgb8 sRGB image of the markers seen from T_world_camera: `samples`² rays per pixel, the
// coverage averaged in linear light, as a camera integrates; the background is mid-grey.
Image renderMarkers(const calibration::CameraModel& camera, const Eigen::Isometry3d& T_world_camera,
                    const std::vector<PrintedMarker>& markers, int samples = 4);

// Where the marker's corners project (OpenCV's order).
std::vector<Eigen::Vector2d> projectCorners(const calibration::CameraModel& camera,
                                            const Eigen::Isometry3d& T_world_camera,
                                            const PrintedMarker& marker);

// A camera at `distance_m` from the world origin looking at it, from azimuth/elevation.
Eigen::Isometry3d lookAt(const Eigen::Vector3d& eye, const Eigen::Vector3d& target);

// Rotation angle (degrees) between two poses and their translation difference (m).
double angleDeg(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b);

// The ChArUco board of OpenCV's tutorial photo choriginal.jpg: 5x7 squares of 40 mm, 20 mm
// DICT_6X6_250 markers from id 0.
MarkerTarget tutorialCharucoBoard();

}  // namespace mixray::tracking::synth
