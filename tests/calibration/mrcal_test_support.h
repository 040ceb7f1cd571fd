// Helpers of the mrcal tests: chessboard views generated through a known lens, the seeded
// problem the front end would hand a back end, and mrcal's own tools on the same corners.
#pragma once

#include <Eigen/Geometry>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "mixray/calibration/calibrate.h"
#include "solve_internal.h"

namespace mixray::calibration::test {

// The board and lens the mrcal tests share: 10x7 inner corners of 40 mm, and a real-lens-like
// rational model (mrcal's cam0.opencv8 scaled to 1280x704).
CalibrationTarget mrcalChessboard();
CameraModel opencv8Truth();

// `count` views of `target` through `truth` from poses spread over the image and tilted up to
// ~35°, every corner inside the image, with Gaussian pixel noise of `noise_px` (seeded).
struct SyntheticViews {
    CameraViews views;
    std::vector<Eigen::Isometry3d> T_camera_target;  // the true poses
};
SyntheticViews syntheticViews(const CameraModel& truth, const CalibrationTarget& target, int count,
                              double noise_px, unsigned seed);

// The seeded problem: every view used, every corner an inlier, the model `seed` (only its
// pinhole core is used to seed) and each pose from cv::solvePnP through that pinhole core.
detail::SolveInput seededInput(const CameraViews& views, const CameraModel& seed);

// mrcal's corners cache: "filename x y level" per corner (level −log2 of the corner's weight),
// files "view%03d.png" in view order.
void writeCornersVnl(const std::filesystem::path& path, const CameraViews& views);

// /usr/bin/python3 with mrcal importable and mrcal-calibrate-cameras present.
bool mrcalPythonAvailable();

// Runs mrcal-calibrate-cameras on the cache with `extra` arguments; the written model's path
// and the RMS it reported ("## RMS error" on stderr), or nullopt with `log` holding why.
struct CliResult {
    std::filesystem::path model;
    double rms_px = 0;
};
std::optional<CliResult> runMrcalCalibrateCameras(const std::filesystem::path& vnl,
                                                  const CameraViews& views,
                                                  const std::string& lensmodel, double focal_px,
                                                  const std::string& extra,
                                                  const std::filesystem::path& outdir,
                                                  std::string* log);

// Runs a Python program with /usr/bin/python3; its stdout, or nullopt.
std::optional<std::string> runPython(const std::string& program, const std::filesystem::path& dir);

// The distances between the two models' projections of the rays through a grid of `step_px`
// over the image (the first model unprojects, both project; infinite where one cannot), and
// their largest and median value.
std::vector<double> projectionDifferencesPx(const CameraModel& a, const CameraModel& b,
                                            double step_px);
double maxProjectionDifferencePx(const CameraModel& a, const CameraModel& b, double step_px);
double medianProjectionDifferencePx(const CameraModel& a, const CameraModel& b, double step_px);

}  // namespace mixray::calibration::test
