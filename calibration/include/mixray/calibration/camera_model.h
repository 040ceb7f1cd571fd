// Lens models: where a point in the camera frame lands in the image, and the ray back through
// a pixel. The renderer traces through them so virtual and real line up to the image border.
#pragma once

#include <Eigen/Core>
#include <optional>
#include <string_view>
#include <vector>

#include "mixray/graph/result.h"

namespace mixray::calibration {

enum class LensModel : uint8_t {
    // Pinhole with OpenCV's distortion (cv::projectPoints): k1 k2 p1 p2 [k3 [k4 k5 k6]] —
    // 0, 4, 5 or 8 coefficients.
    kPinhole,
    // Kannala–Brandt equidistant fish-eye as OpenCV's cv::fisheye: k1 k2 k3 k4.
    kFisheye,
};

std::string_view toString(LensModel model);
std::optional<LensModel> lensModelFromString(std::string_view name);

// Intrinsics of one camera (docs/conventions.md: pixel (0,0) is the centre of the top-left
// pixel; camera frame +x right, +y down, +z forward). Plain value; reentrant.
struct CameraModel {
    LensModel lens = LensModel::kPinhole;
    int width = 0;  // image size in pixels
    int height = 0;
    double fx = 0, fy = 0;  // focal lengths in pixels
    double cx = 0, cy = 0;  // principal point in pixels
    std::vector<double> distortion;  // as LensModel says

    static CameraModel pinhole(int width, int height, double fx, double fy, double cx, double cy);

    // kInvalidArgument naming the field: sizes > 0, focal lengths > 0 and finite, the right
    // number of distortion coefficients, all finite.
    Status validate() const;

    // The pixel a camera-frame point projects to; nullopt for points behind the camera
    // (z <= 0 for pinhole; beyond the model's field of view for fish-eye). Pixels outside the
    // image are returned: callers decide about bounds. The fish-eye field of view is θ ≤ 100°
    // off the optical axis (so it includes directions with z <= 0), less where the polynomial
    // θ_d(θ) stops increasing; unproject() returns nullopt for pixels beyond it.
    std::optional<Eigen::Vector2d> project(const Eigen::Vector3d& p_cam) const;

    // The unit-length direction in the camera frame whose projection is `pixel`; nullopt where
    // the distortion cannot be inverted (the iteration does not converge). Inverse of
    // project(): project(unproject(p)) == p within 1e-6 px over the image.
    std::optional<Eigen::Vector3d> unproject(const Eigen::Vector2d& pixel) const;

    // A model for an image `scale` times the size (binning, pyramids): focal lengths and
    // principal point scaled about the pixel-centre convention, distortion unchanged.
    CameraModel scaled(double scale) const;
};

}  // namespace mixray::calibration
