// Lens models: where a point in the camera frame lands in the image, and the ray back through
// a pixel. The renderer traces through them so virtual and real line up to the image border.
#pragma once

#include <Eigen/Core>
#include <optional>
#include <string>
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
    // mrcal's LENSMODEL_STEREOGRAPHIC: u = 2 tan(θ/2) along the ray's azimuth, pixel =
    // (fx u_x + cx, fy u_y + cy); no distortion coefficients. Sees behind the camera.
    kStereographic,
    // mrcal's LENSMODEL_SPLINED_STEREOGRAPHIC (mrcal docs "Lens models"): the stereographic u
    // plus a B-spline correction over a grid of control points (CameraModel::spline); the
    // distortion holds the 2·Nx·Ny control-point values in mrcal's order. Projected by
    // mrcal_project/mrcal_unproject.
    kSplinedStereographic,
};

// "pinhole", "fisheye", "stereographic", "splined_stereographic".
std::string_view toString(LensModel model);
// Also accepts mrcal's names LENSMODEL_STEREOGRAPHIC and LENSMODEL_SPLINED_STEREOGRAPHIC_...
// (whose configuration splineConfigFromString() reads).
std::optional<LensModel> lensModelFromString(std::string_view name);

// The configuration of a splined model: a Nx × Ny grid of control points of polynomial order
// 2 or 3 spanning fov_x_deg horizontally (and proportionally vertically).
struct SplineConfig {
    int order = 3;
    int nx = 0, ny = 0;
    int fov_x_deg = 0;
    bool operator==(const SplineConfig&) const = default;
};

// mrcal's configured name, "LENSMODEL_SPLINED_STEREOGRAPHIC_order=3_Nx=16_Ny=12_fov_x_deg=120".
std::string toString(const SplineConfig& config);
// Parses that name (mrcal's parser); nullopt when it is not a configured splined model name.
std::optional<SplineConfig> splineConfigFromString(std::string_view name);

// Intrinsics of one camera (docs/conventions.md: pixel (0,0) is the centre of the top-left
// pixel; camera frame +x right, +y down, +z forward). Plain value; reentrant.
struct CameraModel {
    LensModel lens = LensModel::kPinhole;
    int width = 0;  // image size in pixels
    int height = 0;
    double fx = 0, fy = 0;           // focal lengths in pixels
    double cx = 0, cy = 0;           // principal point in pixels
    std::vector<double> distortion;  // as LensModel says
    SplineConfig spline;             // kSplinedStereographic only

    static CameraModel pinhole(int width, int height, double fx, double fy, double cx, double cy);

    // The lens as files name it: toString(lens), or for kSplinedStereographic its configured
    // mrcal name (toString(spline)), which lensModelFromString() and splineConfigFromString()
    // read back.
    std::string lensName() const;

    // kInvalidArgument naming the field: sizes > 0, focal lengths > 0 and finite, the right
    // number of distortion coefficients, all finite; a splined configuration mrcal accepts.
    Status validate() const;

    // The pixel a camera-frame point projects to; nullopt for points behind the camera
    // (z <= 0 for pinhole; beyond the model's field of view for fish-eye). Pixels outside the
    // image are returned: callers decide about bounds. The fish-eye field of view is θ ≤ 100°
    // off the optical axis (so it includes directions with z <= 0), less where the polynomial
    // θ_d(θ) stops increasing; unproject() returns nullopt for pixels beyond it. The
    // stereographic models see every direction but straight back; the splined one only
    // directions whose stereographic u lies within its control-point grid (outside it mrcal
    // extrapolates the spline).
    std::optional<Eigen::Vector2d> project(const Eigen::Vector3d& p_cam) const;

    // The unit-length direction in the camera frame whose projection is `pixel`; nullopt where
    // the distortion cannot be inverted (the iteration does not converge). Inverse of
    // project(): project(unproject(p)) == p within 1e-6 px over the image.
    std::optional<Eigen::Vector3d> unproject(const Eigen::Vector2d& pixel) const;

    // A model for an image `scale` times the size (binning, pyramids): focal lengths and
    // principal point scaled about the pixel-centre convention, distortion unchanged. Exact for
    // every lens (all apply their distortion before the focal lengths and principal point),
    // up to the rounding of the image size to whole pixels.
    CameraModel scaled(double scale) const;
};

}  // namespace mixray::calibration
