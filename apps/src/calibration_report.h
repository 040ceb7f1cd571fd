// The pictures and tables of a calibration report (docs/calibration.md#report): residual
// vectors over the image, where corners were observed, projection uncertainty with labelled
// contours, the rig seen from above and from the side, and a per-view table. `mixray calibrate`
// writes them beside the calibration file. All functions are reentrant.
#pragma once

#include <Eigen/Core>
#include <filesystem>
#include <string>
#include <vector>

#include "mixray/calibration/calibrate.h"
#include "mixray/graph/result.h"

namespace mixray::cli {

// How image pixels land in the residual, coverage and uncertainty pictures: the image area sits
// at the top left, `scale` picture pixels per image pixel (pixel centres map to
// ((u + 0.5)·scale − 0.5, (v + 0.5)·scale − 0.5)), with a legend band of `legend_px` rows below.
struct ImagePlotLayout {
    double scale = 1;
    int width = 0, height = 0;  // the image area, picture pixels
    int legend_px = 0;
    Eigen::Vector2d toPlot(const Eigen::Vector2d& image_px) const {
        return (image_px.array() + 0.5) * scale - 0.5;
    }
};

// Image areas are at most 1280 picture pixels on their longer side (1 when the image is
// smaller).
ImagePlotLayout imagePlotLayout(int image_width, int image_height);

// Residual vectors: an arrow from each observed corner along its residual (projected −
// observed), lengthened `arrow_scale` times (0: chosen so that the 95th-percentile residual is
// 5 % of the image width, rounded to 1, 2 or 5 × 10^k), coloured by length on the legend's
// colour bar; outliers in red with a cross. kInvalidArgument without residuals or with a
// model of no size; kIoError naming the path when it cannot be written.
Status writeResidualPlot(const std::filesystem::path& png,
                         const calibration::CameraCalibration& calibration, double arrow_scale = 0);

// Where corners were observed: the count of observed corners (inliers and outliers) in cells
// of `cell_px` image pixels as a heat map, black where none were, the corners as dots, and
// the share of cells with corners in the legend. The source of the corners is
// CameraCalibration::residuals.
Status writeCoverageMap(const std::filesystem::path& png,
                        const calibration::CameraCalibration& calibration, int cell_px = 40);

// The contour levels drawn on an uncertainty map whose values lie in [low, high]: 1, 2 and 5
// × 10^k between them, at most `max_levels` (the coarser decades dropped first).
std::vector<double> uncertaintyLevels(double low, double high, int max_levels = 6);

// Projection uncertainty (projectionUncertainty()): sample (col, row) lies at image pixel
// (col · step_px, row · step_px), bilinearly interpolated between samples (clamped to the
// grid beyond its last row and column); coloured on a scale from 0 to the largest level (or
// the map's maximum), with the contours of uncertaintyLevels() drawn in white and labelled in
// pixels. kInvalidArgument for an empty map or one whose size does not match cols × rows.
Status writeUncertaintyMap(const std::filesystem::path& png, const calibration::UncertaintyMap& map,
                           int image_width, int image_height);

// The rig seen from above (reference x to the right, z up the picture) and from the side
// (z to the right, y down), side by side: each camera's frustum (its image corners' rays to a
// depth of a quarter of the rig's extent, at least 5 cm), its axes (x red, y green, z blue)
// and its name, and a scale bar.
struct RigDiagramLayout {
    double px_per_m = 0;
    Eigen::Vector2d top_origin{0, 0};   // picture pixel of the reference origin, top view
    Eigen::Vector2d side_origin{0, 0};  // picture pixel of the reference origin, side view
    int width = 0, height = 0;
    int side_left = 0;  // first picture column of the side view
    double frustum_depth_m = 0;
    // Picture pixels of a point in the reference frame, in each view.
    Eigen::Vector2d top(const Eigen::Vector3d& p_ref) const {
        return top_origin + px_per_m * Eigen::Vector2d(p_ref.x(), -p_ref.z());
    }
    Eigen::Vector2d side(const Eigen::Vector3d& p_ref) const {
        return side_origin + px_per_m * Eigen::Vector2d(p_ref.z(), p_ref.y());
    }
};

RigDiagramLayout rigDiagramLayout(const calibration::RigCalibration& rig);
// kInvalidArgument when the rig has no cameras or its per-camera lists differ in length.
Status writeRigDiagram(const std::filesystem::path& png, const calibration::RigCalibration& rig);

// The per-view table in Markdown, after the solve's RMS and observability (the intrinsics' 1σ
// relative to the focal length, the condition, and what is weak when it was kept): view,
// source and key (from `views` when given: the CameraViews the calibration was solved from),
// corners, outliers, RMS, and a note for views
// whose RMS exceeds twice the median; then the views the solve did not use with their
// rejection and reason.
std::string viewTable(const calibration::CameraCalibration& calibration,
                      const calibration::CameraViews* views = nullptr);
Status writeViewTable(const std::filesystem::path& md,
                      const calibration::CameraCalibration& calibration,
                      const calibration::CameraViews* views = nullptr);

// File names for a camera's pictures: its name with every character but letters, digits,
// '-' and '.' replaced by '_' ("kinect/color" → "kinect_color").
std::string reportFileStem(const std::string& camera);

}  // namespace mixray::cli
