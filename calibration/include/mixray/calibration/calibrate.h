// Camera calibration from target views: one camera's intrinsics, and a rig of cameras' intrinsics
// and extrinsics by joint bundle adjustment. Solved through mrcal's C API where mrcal has the
// lens model, Ceres otherwise; residuals per view and per point, outlier rejection, covariances
// and mrcal's projection uncertainty, so a user sees how far the result can be trusted.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "mixray/calibration/camera_model.h"
#include "mixray/calibration/target.h"
#include "mixray/graph/result.h"

namespace mixray::calibration {

enum class Solver : uint8_t {
    kAuto,   // mrcal where it has the lens model, Ceres otherwise
    kCeres,  // Ceres, analytic Jacobians (pinhole OpenCV 4/5/8, Kannala–Brandt fish-eye)
    kMrcal,  // mrcal_optimize (OpenCV 4/5/8, splined stereographic); kInvalidArgument otherwise
};

std::string_view toString(Solver solver);
std::optional<Solver> solverFromString(std::string_view name);

// Called during long solves: `fraction` of the work done (0..1) and what is being done.
using ProgressCallback = std::function<void(double fraction, std::string_view stage)>;

// How to calibrate. Every field has a working default.
struct CalibrationOptions {
    // The lens model to fit: "opencv4", "opencv5", "opencv8" (pinhole with that many OpenCV
    // distortion coefficients), "fisheye" (Kannala–Brandt, cv::fisheye), or a mrcal model name
    // ("LENSMODEL_SPLINED_STEREOGRAPHIC_order=3_Nx=16_Ny=12_fov_x_deg=120").
    std::string model = "opencv5";
    Solver solver = Solver::kAuto;
    bool fix_aspect_ratio = false;  // fx = fy, as OpenCV's CALIB_FIX_ASPECT_RATIO (Ceres only)
    // Outlier rejection; <= 0 turns it off. Ceres solver: points whose residual exceeds this
    // many standard deviations of all residuals (σ from their median absolute value) are
    // dropped and the solve repeated until none are. mrcal solver: any value > 0 turns on
    // mrcal's own rejection with its fixed thresholds (re-solve while a weighted residual lies
    // beyond 5σ, dropping those beyond 4σ, σ their RMS over the inliers), so the same corners
    // give the same lens and outliers as mrcal-calibrate-cameras.
    double outlier_sigma = 3.0;
    int min_views = 4;  // fewer usable views: kInvalidArgument
    int min_corners_per_view = 8;
    // Observability is judged after the solve, from its covariance (CameraCalibration::
    // observability): a core intrinsic (fx fy cx cy) whose 1σ exceeds this fraction of the
    // focal length is weakly determined. 2 %: well spread views give well under 1 % (the 13
    // OpenCV sample photos 0.07–0.08 %), four ChArUco views tilted alike 5–8 %
    // (tests/calibration/observability_test.cpp); a 2 % focal error moves a point at the
    // image border by several pixels.
    double max_relative_stddev = 0.02;
    // The corner noise (1σ per coordinate, pixels) the judgement assumes at least: a real
    // corner detector reaches 0.1–0.3 px, so views that only pass on cleaner corners (renders,
    // generated data) would not pass on real ones taken from the same poses.
    double min_judged_noise_px = 0.1;
    // A weakly determined solve is returned with its observability (and its uncertainty in the
    // covariance) instead of being kInvalidArgument.
    bool accept_weak = false;
    // An RMS reprojection error (inliers, each residual scaled by its corner's weight as the
    // solve saw it) above this is kInvalidArgument, not a result: 2 px is ten times what a
    // corner detector's 0.1–0.3 px per coordinate gives, so the corners do not fit one camera
    // and board (a board declared smaller than printed and found at different places, a wrong
    // lens model). 0: no limit.
    double max_rms_px = 2.0;
    ProgressCallback progress;
};

// How well the views determine the core intrinsics, judged from the solve.
struct Observability {
    // 1σ of fx, fy, cx, cy as a fraction of the focal length (fx for fx and cx, fy for fy and
    // cy), from the solve's covariance scaled to noise_px.
    Eigen::Vector4d relative_stddev = Eigen::Vector4d::Zero();
    // The corner noise the judgement assumes: the larger of the solve's residual noise (1σ per
    // coordinate) and CalibrationOptions::min_judged_noise_px.
    double noise_px = 0;
    // The condition number of the core intrinsics' normal equations (JᵀJ with the views' poses
    // and the distortion eliminated, focal lengths as the unit): how much worse the worst
    // determined combination of fx fy cx cy is known than the best.
    double condition = 0;
    // That worst determined combination (unit length, in fx fy cx cy order).
    Eigen::Vector4d weakest = Eigen::Vector4d::Zero();
    // The largest angle between two used views' board normals, degrees.
    double normal_spread_deg = 0;
    // The parameters whose relative 1σ exceeds CalibrationOptions::max_relative_stddev.
    std::vector<std::string> weak;
    // What is weak, by how much, and the likely cause ("fx, fy: 1σ 8.3 % of the focal length
    // ..."); empty when nothing is.
    std::string summary;
};

// A corner's fit after the solve.
struct PointResidual {
    size_t view = 0;  // index into CameraViews::views
    int id = 0;
    Eigen::Vector2d observed{0, 0};
    Eigen::Vector2d residual{0, 0};  // projected − observed, pixels
    bool outlier = false;
};

struct ViewFit {
    size_t view = 0;  // index into CameraViews::views
    int corners = 0;
    int outliers = 0;
    double rms_px = 0;
    Eigen::Isometry3d T_camera_target = Eigen::Isometry3d::Identity();
};

// One camera's calibration.
struct CameraCalibration {
    std::string camera;
    CameraModel model;
    Solver solver = Solver::kAuto;  // which one solved it
    double rms_px = 0;              // over inliers
    std::vector<ViewFit> views;     // used views, in CameraViews order
    std::vector<PointResidual> residuals;
    int outliers = 0;
    // The solve's state covariance, σ² (JᵀJ)⁻¹ with σ the observed residual noise, over
    // [intrinsics (model order: fx fy cx cy then distortion), then 6 per used view (rotation
    // vector, translation of T_camera_target)]: what projectionUncertainty() propagates.
    Eigen::MatrixXd covariance;
    Observability observability;
    Eigen::VectorXd intrinsicsStddev() const;  // square roots of the intrinsics' diagonal
};

// kInvalidArgument naming the cause: too few usable views, mismatched sizes, a chessboard
// larger than declared (views rejected as kLargerBoard: the message names the size seen), an
// RMS above max_rms_px, weakly determined intrinsics without accept_weak (the message names
// the weak parameters, their 1σ and the likely cause), an unknown model or one the solver
// lacks; kInternal when the solve does not converge.
Result<CameraCalibration> calibrateCamera(const CameraViews& views,
                                          const CalibrationOptions& options = {});

// mrcal's projection uncertainty (mrcal docs "Projection uncertainty"): how far, 1σ in pixels,
// the projection of a point at `distance_m` (0: at infinity) seen through each pixel moves when
// the calibration data is perturbed by its noise, with the reference frame defined by the
// target poses as mrcal does. Sampled on a grid of `step_px`.
struct UncertaintyMap {
    int cols = 0, rows = 0;
    double step_px = 0;
    double distance_m = 0;
    std::vector<float> stddev_px;  // row-major, cols × rows; worst direction (largest axis)
    float at(int col, int row) const { return stddev_px[static_cast<size_t>(row) * cols + col]; }
};

Result<UncertaintyMap> projectionUncertainty(const CameraCalibration& calibration,
                                             double step_px = 20, double distance_m = 0);

// A rig of rigidly mounted cameras seeing a moving target.
struct RigOptions {
    CalibrationOptions camera;  // for each camera's own intrinsic solve
    // Per camera name, a lens model other than camera.model (a fish-eye among pinholes).
    std::map<std::string, std::string> models;
    // Cameras already calibrated on the same views (by name): their own solve is taken as it is
    // instead of being repeated.
    std::map<std::string, CameraCalibration> solved;
    bool refine_intrinsics = false;  // in the joint solve too (else fixed after their own)
    std::string reference;           // the camera whose frame is the rig's; empty: the first

    // Checks of the joint solve against the cameras' own (docs/calibration.md#rigs): views of
    // one instant that disagree (a corner order the detector numbered from another corner and
    // no board symmetry explains, views paired at the wrong key, a camera that moved) must not
    // pass as a rig.
    //
    // A view whose RMS in the joint solve exceeds view_outlier_ratio × its camera's own RMS is
    // dropped (RigCalibration::changes) and the solve repeated, worst instant first; 0 keeps
    // every view.
    double view_outlier_ratio = 5.0;
    // A camera whose RMS in the joint solve exceeds max_rms_ratio × its own RMS fails the solve
    // (kInvalidArgument naming it and both RMS values).
    double max_rms_ratio = 3.0;
    // RMS values below this count as this much in both comparisons (noise-free corners).
    double rms_floor_px = 0.25;
    // A camera whose dropped views exceed this fraction of the views it shares with other
    // cameras fails the solve (kInvalidArgument): what is left is not a consensus.
    double max_dropped_fraction = 0.5;

    // kInvalidArgument naming the field.
    Status validate() const;
};

// A view the joint solve read differently from the camera's own solve.
struct RigViewChange {
    enum class Kind : uint8_t {
        // A chessboard's corners, whose grid looks the same turned by 180° (90° on square
        // boards), renumbered as the board turned by `rotation_deg`: the order that agrees with
        // the other cameras' views of the same instant.
        kReordered,
        // Left out: no corner order agrees with the other cameras' views of that instant, or its
        // residuals in the joint solve are outliers.
        kDropped,
    };
    Kind kind = Kind::kReordered;
    size_t camera = 0;  // index into RigCalibration::cameras
    size_t view = 0;    // index into that camera's CameraViews::views
    int64_t key = 0;
    int rotation_deg = 0;  // kReordered
    std::string message;   // one line for reports, naming the camera and the view's source
};

struct RigCalibration {
    std::string reference;
    // Every camera's own solve, input order (with refine_intrinsics, its model is the joint
    // solve's).
    std::vector<CameraCalibration> cameras;
    std::vector<Eigen::Isometry3d> T_ref_camera;  // per camera, reference → identity
    // Per camera, covariance of T_ref_camera as [rotation vector, translation] (6×6; zero for
    // the reference). Without refine_intrinsics it is conditional on the intrinsics: their own
    // uncertainty is not in it.
    std::vector<Eigen::Matrix<double, 6, 6>> pose_covariance;
    double rms_px = 0;                  // joint solve, all cameras
    std::vector<double> camera_rms_px;  // joint solve, per camera (input order)
    // Views renumbered or left out, in camera then view order. The cameras' own solves
    // (`cameras`) keep the corner order they were solved in.
    std::vector<RigViewChange> changes;
};

// Joint bundle adjustment (Ceres) of every camera's pose in the reference frame and the
// target's pose at every key seen by any camera. Cameras that never see the target at the same
// key as the reference are linked through chains of views; a camera linked to no other is
// kInvalidArgument naming it. Each camera's pose is seeded from the consensus of the keys it
// shares, and a chessboard view whose corner order disagrees with the other cameras' views of
// its key is renumbered; views that still disagree are dropped, and a joint solve that fits
// far worse than the cameras' own (RigOptions) is kInvalidArgument, never a rig.
Result<RigCalibration> calibrateRig(const std::vector<CameraViews>& views,
                                    const RigOptions& options = {});

}  // namespace mixray::calibration
